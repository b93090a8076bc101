"""Segment-wise slanted-plane fill of unreliable disparities (SPEC §4 occlusions, issue 12 item 3).

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
from .params import _integer, _number, _share

__all__ = ["PlaneFillParams", "segment", "fit_plane", "plane_fill"]


@dataclass(frozen=True)
class PlaneFillParams:
    """Constants of :func:`plane_fill`.

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
    """

    name: ClassVar[str] = "plane fill"
    scale: float = 300.0
    sigma: float = 0.8
    min_size: int = 50
    min_support: int = 30
    min_reliable: float = 0.3
    inlier_tol: float = 1.0
    min_inliers: float = 0.8

    def __post_init__(self):
        for name in ("scale", "inlier_tol"):
            _number(self, name, positive=True)
        _number(self, "sigma")
        for name in ("min_size", "min_support"):
            _integer(self, name, 1)
        for name in ("min_reliable", "min_inliers"):
            _share(self, name)


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

    g = np.asarray(guide, dtype=np.float64)
    if g.ndim != 2 or not np.all(np.isfinite(g)):
        raise InvalidInputError(f"guide must be a finite (H, W) image, got shape {g.shape}")
    return felzenszwalb(_unit_range(g), scale=float(scale), sigma=float(sigma),
                        min_size=int(min_size), channel_axis=None)


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
    A = np.column_stack([np.ravel(x), np.ravel(y), np.ones(np.size(x))]).astype(np.float64)
    d = np.asarray(d, dtype=np.float64).ravel()
    if d.size < 3 or A.shape[0] != d.size:
        raise InvalidInputError(f"fit_plane needs >= 3 points of equal count, got {d.size}")
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
    p = params or PlaneFillParams()
    d = np.asarray(disparity, dtype=np.float64)
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
