"""Slanted planes: the segment-wise fill of unreliable disparities (SPEC §4 occlusions, issue 12
item 3), and planes fitted to a cost volume's pooled costs (:func:`cost_planes`, issue 11).

A pixel whose disparity is not trusted (it failed the left-right check, or its matching window
held no texture) usually lies on a surface whose other pixels were matched well.  Segmenting the
reference image into regions of similar intensity and fitting one plane ``d = a x + b y + c``
to the trusted pixels of each region gives such a pixel the disparity of its own surface,
slant included, where a scanline fill can only copy a constant from a neighbour that may belong
to another surface.

The segmentation is Felzenszwalb and Huttenlocher's graph method (scikit-image), on the guide
rescaled so that its 1st and 99th percentiles map to 0 and 1 (so ``scale`` means the same for
any exposure).  A plane is fitted by iteratively re-weighted least squares that drops pixels
farther than 2.5 robust standard deviations (at least ``floor`` px) from the current plane.
A region's plane is used only when the region is planar as measured in px, independently of
the region's size: enough trusted pixels (``min_support``, ``min_reliable`` of the region) and
at least ``min_inliers`` of them within ``inlier_tol`` px of the plane.  A region spanning
two surfaces fails that test and is left alone: its pixels keep whatever fill the caller
applies next.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..errors import InvalidInputError
from .._options import (bool_mask, check_fields, choice, integer, number, params_of, real_array,
                        rule, share, shown)
from .postprocess import MIN_WMF_SIGMA

__all__ = ["PlaneFillParams", "segment", "fit_plane", "plane_fill", "cost_planes"]


@dataclass(frozen=True)
class PlaneFillParams:
    """Constants of the two-view ``"lr-plane"`` occlusion step
    (:func:`hyperlf.twoview.fill_inconsistent`): :func:`plane_fill`'s, and the guided weighted
    median that the pixels which failed the left-right check take after the fill.

    Attributes
    ----------
    scale : float
        Felzenszwalb's scale on the guide rescaled to 0..1 (in 1/255 units, as in
        scikit-image): larger gives larger regions.
    sigma : float
        Gaussian smoothing of the guide before segmenting, px.
    min_size : int
        Smallest region, px (smaller ones are merged into a neighbour).
    min_support : int
        Fewest trusted pixels a region needs for a plane.
    min_reliable : float
        Smallest share of trusted pixels in a region for a plane.
    inlier_tol : float
        A trusted pixel within this many px of the plane is an inlier.
    min_inliers : float
        Smallest share of inliers among the trusted pixels for the plane to be used.
    median_radius : int
        Window radius, px, of the weighted median (:func:`hyperlf.regularisers.weighted_median`,
        guided by the left image) that replaces the filled values, as Hosni et al. do after
        their fill: a row fill copies whatever consistent value it meets first, and the
        median removes the streaks this leaves; 0: off, at most 255. :func:`plane_fill` does
        not use it.
    median_sigma : float
        The median's guide similarity scale, relative to the guide's mean.

    References
    ----------
    .. [1] A. Hosni, C. Rhemann, M. Bleyer, C. Rother, M. Gelautz, "Fast cost-volume filtering
       for visual correspondence and beyond", IEEE TPAMI 35(2), 2013 (section 3.3).
    """

    name: ClassVar[str] = "plane fill"
    scale: float = 300.0
    sigma: float = 0.8
    min_size: int = 50
    min_support: int = 30
    min_reliable: float = 0.3
    inlier_tol: float = 1.0
    min_inliers: float = 0.8
    median_radius: int = 5
    median_sigma: float = 0.4

    def __post_init__(self):
        positive, count = rule(number, positive=True), rule(integer, minimum=1)
        check_fields(self, {"scale": positive, "inlier_tol": positive, "sigma": number,
                            "min_size": count, "min_support": count, "min_reliable": share,
                            "min_inliers": share, "median_radius": rule(integer, maximum=255),
                            "median_sigma": rule(number, positive=True, at_least=MIN_WMF_SIGMA)},
                     f"{self.name} ")


def _unit_range(guide: np.ndarray) -> np.ndarray:
    lo, hi = np.percentile(guide, [1.0, 99.0])
    if not hi > lo:
        return np.zeros(guide.shape, np.float64)
    return np.clip((guide - lo) / (hi - lo), 0.0, 1.0)


def segment(guide, *, scale: float = 300.0, sigma: float = 0.8, min_size: int = 50) -> np.ndarray:
    """Regions of similar intensity of a one-channel image (Felzenszwalb-Huttenlocher).

    Parameters
    ----------
    guide : array_like, shape (H, W)
        Finite image, any positive scale (rescaled so that its 1st / 99th percentiles are 0 / 1).
    scale, sigma, min_size
        As :class:`PlaneFillParams`.

    Returns
    -------
    ndarray of int, shape (H, W)
        Region index of every pixel, ``0..n-1``.

    References
    ----------
    .. [1] P. F. Felzenszwalb, D. P. Huttenlocher, "Efficient graph-based image segmentation",
       IJCV 59(2), 2004.

    Examples
    --------
    >>> import numpy as np
    >>> g = np.zeros((20, 40)); g[:, 20:] = 1.0
    >>> seg = segment(g, min_size=10)
    >>> np.intersect1d(seg[:, :18], seg[:, 22:]).size     # no region crosses the step
    0
    """
    from skimage.segmentation import felzenszwalb

    g = real_array(guide, "guide")
    if g.ndim != 2 or not np.all(np.isfinite(g)):
        raise InvalidInputError(f"guide must be a finite (H, W) image, got shape {g.shape}")
    scale, sigma = number(scale, "scale"), number(sigma, "sigma", at_most=max(g.shape))
    return felzenszwalb(_unit_range(g), scale=scale, sigma=sigma,
                        min_size=integer(min_size, "min_size", maximum=g.size),
                        channel_axis=None)


def fit_plane(x, y, d, *, iterations: int = 4, floor: float = 0.5):
    """Robust plane ``d = a x + b y + c`` through scattered disparities.

    Least squares, then ``iterations - 1`` refits on the points within 2.5 robust standard
    deviations (1.4826 x the median absolute residual of the current inliers, at least
    ``floor``) of the previous plane.

    Parameters
    ----------
    x, y, d : array_like, shape (N,)
        Pixel coordinates and disparities, ``N >= 3``.

    Returns
    -------
    ndarray, shape (3,)
        ``(a, b, c)``.

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[:10, :10]
    >>> d = 0.5 * x - 0.25 * y + 3.0
    >>> d[0, 0] = 40.0                                   # an outlier
    >>> np.round(fit_plane(x.ravel(), y.ravel(), d.ravel()), 6).tolist()
    [0.5, -0.25, 3.0]
    """
    # called once per region: conversions and counts only (no pass over the values)
    x, y, d = real_array(x, "x"), real_array(y, "y"), real_array(d, "d")
    if d.size < 3 or not x.size == y.size == d.size:
        raise InvalidInputError(f"fit_plane needs >= 3 points of equal count, got "
                                f"{x.size}, {y.size} and {d.size} values of x, y and d")
    iterations = integer(iterations, "iterations", maximum=1000)
    floor = number(floor, "floor")
    A = np.column_stack([np.ravel(x), np.ravel(y), np.ones(np.size(x))]).astype(np.float64)
    d = d.ravel()
    keep = np.ones(d.size, dtype=bool)
    coef = np.zeros(3)
    for _ in range(max(1, int(iterations))):
        coef = np.linalg.lstsq(A[keep], d[keep], rcond=None)[0]
        r = np.abs(A @ coef - d)
        s = max(1.4826 * float(np.median(r[keep])), float(floor))
        new = r <= 2.5 * s
        if new.sum() < 3 or np.array_equal(new, keep):
            break
        keep = new
    return coef


def _regions(seg: np.ndarray):
    """Flat pixel indices of each region (one sort, no per-region scan of the image)."""
    flat = seg.ravel()
    order = np.argsort(flat, kind="stable")
    cuts = np.flatnonzero(np.diff(flat[order])) + 1
    return np.split(order, cuts)


def plane_fill(disparity, reliable, guide, *, targets=None, params: PlaneFillParams | None = None):
    """Replace untrusted disparities by the plane of their region's trusted pixels.

    Parameters
    ----------
    disparity : array_like, shape (H, W)
        Disparity map, px (values at untrusted pixels are ignored).
    reliable : array_like of bool, shape (H, W)
        Pixels whose disparity is trusted (the plane's support).
    guide : array_like, shape (H, W)
        Reference image the regions are taken from.
    targets : array_like of bool, shape (H, W), optional
        Pixels that may be replaced (default: every untrusted pixel).
    params : PlaneFillParams, optional

    Returns
    -------
    filled : ndarray, float32 (H, W)
        ``disparity`` with the replaced pixels set to their region's plane.
    replaced : ndarray of bool, shape (H, W)
        The pixels that got a plane value (targets in a planar region with enough support).

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[:30, :40]
    >>> d = 0.1 * x + 5.0                        # one slanted surface
    >>> ok = np.ones(d.shape, bool); ok[10:20, 15:25] = False
    >>> out, rep = plane_fill(np.where(ok, d, 0.0), ok, np.ones(d.shape))
    >>> float(np.abs(out - d).max()) < 1e-4, int(rep.sum())
    (True, 100)
    """
    p = params_of(params, "params", PlaneFillParams)
    d = real_array(disparity, "disparity")
    if d.ndim != 2:
        raise InvalidInputError(f"disparity must be a 2-D map, got shape {d.shape}")
    ok = np.asarray(reliable, dtype=bool)
    tg = ~ok if targets is None else np.asarray(targets, dtype=bool)
    if ok.shape != d.shape or tg.shape != d.shape or np.shape(guide) != d.shape:
        raise InvalidInputError(f"reliable, targets and guide must have the disparity's shape "
                                f"{d.shape}")
    ok = ok & np.isfinite(d)
    out = d.copy()
    replaced = np.zeros(d.shape, dtype=bool)
    if not tg.any():
        return out.astype(np.float32), replaced
    seg = segment(guide, scale=p.scale, sigma=p.sigma, min_size=p.min_size)
    xs = np.broadcast_to(np.arange(d.shape[1], dtype=np.float64), d.shape).ravel()
    ys = np.broadcast_to(np.arange(d.shape[0], dtype=np.float64)[:, None], d.shape).ravel()
    dv, okv, tgv = d.ravel(), ok.ravel(), tg.ravel()
    out_v, rep_v = out.reshape(-1), replaced.reshape(-1)
    for idx in _regions(seg):
        t = idx[tgv[idx]]
        s = idx[okv[idx]]
        if t.size == 0 or s.size < p.min_support or s.size < p.min_reliable * idx.size:
            continue
        a, b, c = fit_plane(xs[s], ys[s], dv[s])
        if np.mean(np.abs(a * xs[s] + b * ys[s] + c - dv[s]) <= p.inlier_tol) < p.min_inliers:
            continue
        out_v[t] = a * xs[t] + b * ys[t] + c
        rep_v[t] = True
    return out.astype(np.float32), replaced


def _plane_scores_numpy(P, dx, dy, A, B, c, min_inside):
    """Reference of :func:`hyperlf.regularisers._kernels.plane_scores` (same arguments,
    returns ``out``)."""
    n, L = P.shape
    out = np.empty((A.size, B.size, c.size))
    rows = np.arange(n)[None]
    for i, a in enumerate(A):
        for j, b in enumerate(B):
            f = c[:, None] + a * dx[None] + b * dy[None]  # (c, n) label positions
            inside = (f >= 0) & (f <= L - 1)
            l0 = np.clip(np.floor(f).astype(np.int64), 0, L - 2)
            t = np.clip(f - l0, 0.0, 1.0)
            v = (1 - t) * P[rows, l0] + t * P[rows, l0 + 1]
            m = inside.sum(axis=1)
            mean = np.where(inside, v, 0.0).sum(axis=1) / np.maximum(m, 1)
            out[i, j] = np.where((m >= min_inside) & (m > 0), mean, np.inf)
    return out


def _plane_scores(P, dx, dy, A, B, c, min_inside, impl):
    if impl == "numpy":
        return _plane_scores_numpy(P, dx, dy, A, B, c, min_inside)
    from . import _kernels

    out = np.empty((A.size, B.size, c.size))
    f8 = np.float64
    _kernels.plane_scores(np.ascontiguousarray(P, f8), np.ascontiguousarray(dx, f8),
                          np.ascontiguousarray(dy, f8), np.ascontiguousarray(A, f8),
                          np.ascontiguousarray(B, f8), np.ascontiguousarray(c, f8),
                          float(min_inside), out)
    return out


def _best_plane(P, dx, dy, slopes, c, min_inside, impl):
    """``(a, b, c, on_edge)`` of the lowest mean cost: slopes on every other step of
    ``slopes`` first, then the full steps around that best; ``on_edge`` when a slope is an end
    of ``slopes`` (the search did not bracket it)."""
    coarse = slopes[::2]
    s = _plane_scores(P, dx, dy, coarse, coarse, c, min_inside, impl)
    i, j, _ = np.unravel_index(np.argmin(s), s.shape)
    k0 = 2 * np.array([i, j])
    near = [np.arange(max(k - 1, 0), min(k + 2, slopes.size)) for k in k0]
    s = _plane_scores(P, dx, dy, slopes[near[0]], slopes[near[1]], c, min_inside, impl)
    i, j, k = np.unravel_index(np.argmin(s), s.shape)
    if not np.isfinite(s[i, j, k]):
        return None
    ia, ib = near[0][i], near[1][j]
    on_edge = ia in (0, slopes.size - 1) or ib in (0, slopes.size - 1)
    return slopes[ia], slopes[ib], c[k], on_edge


def _located_plane(P, dx, dy, slopes, c, tile, L, impl):
    """``(best, located)``: the tile's plane ``(a, b, c)`` of the lowest mean cost (None when
    no hypothesis has enough samples inside the label range), and whether the search locates
    it.  It does not when a slope is at the end of its range, the plane comes within one label
    of the range's ends in the tile, or the two halves of the samples (a checkerboard of blocks
    a quarter of the tile wide, so that both halves span the tile and share no matching
    window) choose planes more than one label apart at the tile's centre or two at a corner
    (noise alone gives a minimum too; half the samples pin the slope less well than the
    centre)."""
    half = tile / 2
    reach = lambda a, b: abs(a) * half + abs(b) * half  # noqa: E731
    best = _best_plane(P, dx, dy, slopes, c, 0.9 * len(dx), impl)
    if best is None:
        return None, False
    if best[3] or not 1.0 <= best[2] - reach(*best[:2]) <= best[2] + reach(*best[:2]) <= L - 2.0:
        return best[:3], False
    side = (sum(_blocks(dx, dy, tile)) % 2).astype(bool)
    fits = [_best_plane(P[k], dx[k], dy[k], slopes, c, 0.9 * k.sum(), impl) if k.sum() else None
            for k in (side, ~side)]
    if any(f is None for f in fits):
        return best[:3], False
    (a1, b1, c1, _), (a2, b2, c2, _) = fits
    if abs(c1 - c2) > 1.0 or abs(c1 - c2) + reach(a1 - a2, b1 - b2) > 2.0:
        return best[:3], False
    return best[:3], True


def _blocks(dx, dy, tile):
    """Each sample's block column and row, blocks a quarter of the tile wide."""
    half, block = tile / 2, max(tile // 4, 1)
    return (np.floor((dx + half) / block).astype(np.int64),
            np.floor((dy + half) / block).astype(np.int64))


def _standardised(P: np.ndarray) -> np.ndarray:
    """Each row (a pixel's costs over the labels) to mean 0 and standard deviation 1."""
    return (P - P.mean(axis=1, keepdims=True)) / (P.std(axis=1, keepdims=True) + 1e-9)


def _over_one_pixel(P: np.ndarray, period: float) -> np.ndarray:
    """Each row averaged over ``period`` labels (one pixel of shift, rounded: a box over an odd
    count, a trapezoid with half-weight ends over an even one, so that a component of that
    period averages out), or as it is when ``period`` is below 1.5 labels."""
    k = int(round(period))
    if k < 2:
        return P
    # centred: an odd period is a box of k labels, an even one a trapezoid over k + 1
    kernel = np.ones(k) / k if k % 2 else np.r_[0.5, np.ones(k - 1), 0.5] / k
    r = kernel.size // 2
    padded = np.pad(P, ((0, 0), (r, r)), mode="edge")
    out = np.zeros_like(P)
    for i, wt in enumerate(kernel):
        out += wt * padded[:, i:i + P.shape[1]]
    return out


def _tile_starts(n: int, tile: int) -> list[int]:
    """Starts of tiles of ``tile`` px overlapping by half over ``n`` px, the last one flush
    with the end."""
    starts = list(range(0, n - tile + 1, max(tile // 2, 1)))
    return starts if starts[-1] == n - tile else starts + [n - tile]


def _tent(n: int) -> np.ndarray:
    r = 1.0 - np.abs(np.arange(n) + 0.5 - n / 2) / (n / 2)
    return np.outer(r, r)


def _plane_costs(P, dx, dy, plane) -> np.ndarray:
    """Each sample's cost along ``plane = (a, b, c)`` (linear between labels), NaN where the
    plane leaves the label range."""
    a, b, c = plane
    L = P.shape[1]
    f = c + a * dx + b * dy
    l0 = np.clip(np.floor(f).astype(np.int64), 0, L - 2)
    t = np.clip(f - l0, 0.0, 1.0)
    rows = np.arange(dx.size)
    v = (1 - t) * P[rows, l0] + t * P[rows, l0 + 1]
    return np.where((f >= 0) & (f <= L - 1), v, np.nan)


def _excess(P, dx, dy, own, other, tile) -> tuple[float, float]:
    """``(mean, t)``: how much more the samples cost along ``other`` than along ``own``, as a
    mean over the samples and in standard errors of the mean over the blocks a quarter of the
    tile wide (blocks share no matching window: they are the independent measurements; a
    pixel's own costs are not, its neighbours' windows overlap it).  Both are infinite when
    either plane leaves the label range at more than 10 % of the samples or fewer than 3
    blocks hold samples."""
    d = _plane_costs(P, dx, dy, other) - _plane_costs(P, dx, dy, own)
    ok = np.isfinite(d)
    if ok.mean() < 0.9:
        return np.inf, np.inf
    i, j = _blocks(dx[ok], dy[ok], tile)
    _, block = np.unique(64 * i + j, return_inverse=True)
    means = np.bincount(block, d[ok]) / np.bincount(block)
    if means.size < 3:
        return np.inf, np.inf
    se = means.std(ddof=1) / np.sqrt(means.size)
    t = means.mean() / se if se > 0 else (0.0 if means.mean() <= 0 else np.inf)
    return float(d[ok].mean()), float(t)


def _carried_plane(P, dx, dy, own, at, accepted, tile, carry):
    """The plane carried into the refused tile at ``at`` (its top-left corner): of the
    accepted planes of the tiles that overlap it, moved to its centre, the one its samples
    cost least along among those they do not contradict (an excess of at most ``carry``
    standard errors over ``own``, :func:`_excess`); None when there is none."""
    y0, x0 = at
    found = []
    for (yn, xn), (a, b, c) in accepted.items():
        if abs(yn - y0) >= tile or abs(xn - x0) >= tile:
            continue
        plane = (a, b, c + a * (x0 - xn) + b * (y0 - yn))
        mean, t = _excess(P, dx, dy, own, plane, tile)
        if t <= carry:
            found.append((mean, plane))
    return min(found, key=lambda f: f[0])[1] if found else None


def _tile_samples(C, m, y0, x0, tile, samples, period):
    """Up to ``samples`` masked pixels of the tile at ``(y0, x0)``: their costs (averaged over
    one pixel of shift, standardised) and offsets from the tile's centre."""
    sub = m[y0:y0 + tile, x0:x0 + tile]
    ys, xs = np.nonzero(sub)
    k = max(1, ys.size // int(samples))
    ys, xs = ys[::k], xs[::k]
    P = _standardised(_over_one_pixel(C[:, y0 + ys, x0 + xs].T.astype(np.float64), period))
    return P, xs - (tile - 1) / 2, ys - (tile - 1) / 2


def cost_planes(volume, mask, *, tile: int, max_slope: float, period: float = 1.0,
                samples: int = 1000, min_share: float = 0.3, carry: float | None = 2.0,
                impl: str = "auto") -> np.ndarray:
    """The slanted planes that the pooled costs of the masked pixels choose, tile by tile.

    For every square ``tile`` (overlapping its neighbours by half) in which at least
    ``min_share`` of the pixels are masked, up to ``samples`` of its masked pixels are pooled:
    each pixel's costs are standardised over the labels (mean 0, standard deviation 1, so
    that every pixel weighs the same), and the plane ``l = c + a (x - x_0) + b (y - y_0)``
    (label units, ``(x_0, y_0)`` the tile's centre) of the lowest mean cost is searched over
    ``c`` in half labels and ``a``, ``b`` within ``max_slope`` in steps of ``1 / tile`` (half
    a label at the tile's edges).  A hypothesis counts only when at least 90 % of the samples
    lie inside the label range.  A tile's plane is refused when a slope lies at the end of its
    search range or the plane comes within one label of the range's ends inside the tile (a
    minimum the search does not bracket is not located), and when the two halves of its
    samples, taken as a checkerboard of blocks a quarter of the tile wide, choose planes
    more than one label apart at the tile's centre or two at a corner (pure noise has a
    minimum too, but not the same one in both halves).  A refused tile then takes the plane
    of an overlapping accepted tile that its own samples do not contradict (``carry``): moved
    to the refused tile's centre, the plane may cost its samples at most ``carry`` standard
    errors more than their own lowest-cost plane, the error taken over the blocks of the
    checkerboard (they share no matching window); of several such, the one that costs least.
    Refused tiles do not pass carried planes on.  Each pixel gets the accepted and carried
    planes of the tiles over it, weighted by a tent that falls to 0 at the tile's edges.

    Where each pixel's own costs are too weak to show their minimum (a white table, a wall),
    thousands of them together do; a plane, unlike one constant per region, follows a
    surface seen at a slant.

    Parameters
    ----------
    volume : array_like, shape (L, H, W)
        Finite costs, lower is better, at evenly spaced labels.
    mask : array_like of bool, shape (H, W)
        The pixels whose costs are pooled.
    tile : int
        Side of the tiles, px (>= 4).
    max_slope : float
        Largest slope searched, labels per px; at most ``2 (L - 1)`` labels across a tile
        are searched whatever it is (a steeper plane spans the label range twice over
        inside the tile, and the search grid grows with the square of the steps).
    period : float
        Labels per pixel of shift.  Each pixel's costs are first averaged over that many
        labels (when at least 1.5): bilinear sampling halves white noise's variance at
        half-pixel shifts, so the costs of pure noise are lower there, a bias that pooling
        would turn into a plane.
    samples : int
        Most pixels pooled per tile (every k-th masked pixel).
    min_share : float
        Smallest share of masked pixels for a tile to be fitted.
    carry : float or None
        Largest excess, in standard errors, of a refused tile's costs along an overlapping
        accepted tile's plane over their own lowest, for that plane to be carried into it
        (None: refused tiles stay without a plane).  A textureless corner or a vignetted
        border otherwise keeps no plane where the surface next to it has one.
    impl : {"auto", "numba", "numpy"}

    Returns
    -------
    ndarray, float32 (H, W)
        The plane's label position (fractional), NaN where no accepted or carried plane lies.

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[:48, :48]
    >>> truth = 4.0 + 0.05 * y                     # a slanted plane, in labels
    >>> rng = np.random.default_rng(0)
    >>> C = np.abs(np.arange(12)[:, None, None] - truth) + 4 * rng.random((12, 48, 48))
    >>> plane = cost_planes(C, np.ones((48, 48), bool), tile=24, max_slope=0.1)
    >>> bool(np.nanmax(np.abs(plane - truth)) < 0.5)
    True
    """
    C = np.asarray(volume)
    if C.ndim != 3 or C.dtype.kind not in "biuf":
        raise InvalidInputError(f"cost_planes needs a real volume (L, H, W), got "
                                f"{shown(volume)}")
    m = bool_mask(mask, "mask", C.shape[1:], of="the volume")
    # a slope and a period of at most 1e4 labels per px: their grids stay small
    tile, samples = integer(tile, "tile", 4), integer(samples, "samples", 1)
    max_slope = number(max_slope, "max_slope", positive=True, at_most=1e4)
    period = number(period, "period", positive=True, at_most=1e4)
    min_share = share(min_share, "min_share")
    carry = number(carry, "carry", optional=True)
    choice(impl, "impl", ("auto", "numba", "numpy"))
    L, H, W = C.shape
    T = min(int(tile), H, W)
    n_steps = max(1, min(int(round(max_slope * T)), 2 * (L - 1)))
    slopes = np.arange(-n_steps, n_steps + 1) / T
    c = np.arange(0.0, L - 1 + 1e-9, 0.5)
    accepted, refused = {}, {}
    for y0 in _tile_starts(H, T):
        for x0 in _tile_starts(W, T):
            if m[y0:y0 + T, x0:x0 + T].mean() < min_share:
                continue
            P, dx, dy = _tile_samples(C, m, y0, x0, T, samples, period)
            best, located = _located_plane(P, dx, dy, slopes, c, T, L, impl)
            if best is not None:
                (accepted if located else refused)[(y0, x0)] = best
    planes = dict(accepted)
    for at, own in refused.items() if carry is not None else ():
        # gathered again rather than kept from the first pass: a few refused tiles cost a
        # gather each, every tile's samples kept would cost (samples x L) floats per tile
        P, dx, dy = _tile_samples(C, m, *at, T, samples, period)
        plane = _carried_plane(P, dx, dy, own, at, accepted, T, carry)
        if plane is not None:
            planes[at] = plane
    return _blend(planes, (H, W), T)


def _blend(planes: dict, shape, tile: int) -> np.ndarray:
    """Each pixel's mean of the planes (label positions, keyed by their tile's top-left
    corner) of the tiles over it, weighted by a tent that falls to 0 at a tile's edges; NaN
    under none."""
    num, den = np.zeros(shape), np.zeros(shape)
    tent = _tent(tile)
    yy, xx = np.mgrid[:tile, :tile] - (tile - 1) / 2
    for (y0, x0), (a, b, c0) in planes.items():
        num[y0:y0 + tile, x0:x0 + tile] += tent * (c0 + a * xx + b * yy)
        den[y0:y0 + tile, x0:x0 + tile] += tent
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan).astype(np.float32)
