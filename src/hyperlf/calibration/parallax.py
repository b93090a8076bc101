"""Parallax of off-board scene content after plane registration, and its rank-1 factorisation.

After every view is registered onto the reference at the board plane, rotations, focal lengths
and principal points are absorbed by the homographies; what remains for a scene point off the
board is plane-induced parallax. For cameras in a plane parallel to the reference image plane
it is ``flow_v(x) = -d(x) (p_v - p_ref)``: along each view's baseline, proportional to its
length, with one scalar ``d(x) = f B (1/Z - 1/Z_board)`` per point (SPEC §11). Measuring the
flow of many points in every view and factoring the ``views x points`` matrix into that product
gives every view's offset ``p_v - p_ref`` up to one common scale and sign, from the images alone.

Cross-spectral matching: the views see different bands, so raw intensities do not match (their
contrast may even be inverted). Points are matched on gradient-magnitude images by normalised
cross-correlation, which ignores gain, offset and the sign of the contrast.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._options import (bool_mask, check_values, flag, index, int_pair, integer, number, real,
                        real_array, rule, shown)
from ..errors import InvalidInputError

__all__ = ["feature_image", "select_points", "match_flows", "factor_rank1", "Rank1",
           "fitting_entries", "hub_camera", "measured_disparity_range"]


#: The search options of the parallax matching (:func:`measured_disparity_range`,
#: :func:`hyperlf.calibration.plane.register_plane`): the largest side (px) matched, the search
#: radius as a fraction of that side.
SEARCH_RULES = {"work_size": rule(integer, minimum=64),
                "max_parallax": rule(number, positive=True, at_most=1)}
#: Their defaults.
SEARCH_DEFAULTS = {"work_size": 800, "max_parallax": 0.08}


def _image(value, label: str) -> np.ndarray:
    """``value`` as a float32 image ``(H, W)`` (its values are not scanned)."""
    img = real_array(value, label, np.float32)
    if img.ndim != 2 or not img.size:
        raise InvalidInputError(f"{label} must be an image (H, W), got shape {img.shape}")
    return img


def feature_image(image: np.ndarray, *, sigma: float = 1.0) -> np.ndarray:
    """Gradient magnitude of the percentile-normalised, slightly blurred image (float32).

    Parameters
    ----------
    image : ndarray (H, W)
    sigma : float
        Gaussian blur (px) before the Sobel gradient.

    Examples
    --------
    A vertical step edge: the gradient is high on either side of it and zero elsewhere:

    >>> step = np.zeros((10, 10), np.float32)
    >>> step[:, 5:] = 1.0
    >>> f = feature_image(step, sigma=0)
    >>> f.dtype, f[5].tolist()
    (dtype('float32'), [0.0, 0.0, 0.0, 0.0, 4.0, 4.0, 0.0, 0.0, 0.0, 0.0])
    """
    import cv2

    img = _image(image, "image")
    sigma = number(sigma, "sigma", at_most=max(img.shape))  # a wider blur only costs time
    finite = np.isfinite(img)
    lo, hi = np.percentile(img[finite], [1, 99]) if finite.any() else (0.0, 1.0)
    img = np.where(finite, (img - lo) / max(hi - lo, 1e-6), 0.0).astype(np.float32)
    if sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), sigma)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3)
    return np.sqrt(gx * gx + gy * gy)


def select_points(image: np.ndarray, allowed: np.ndarray, *, spacing: int,
                  max_points: int = 600) -> np.ndarray:
    """Well-textured points ``(N, 2)`` (``x, y``) inside ``allowed`` (Shi-Tomasi corners).

    Examples
    --------
    Points of a smooth random texture, searched in its left half only:

    >>> from scipy.ndimage import gaussian_filter
    >>> texture = gaussian_filter(np.random.default_rng(0).random((64, 64)), 2.0)
    >>> allowed = np.zeros((64, 64), bool)
    >>> allowed[:, :32] = True
    >>> pts = select_points(texture, allowed, spacing=6)
    >>> pts.shape[1], bool(len(pts) > 10), bool((pts[:, 0] < 32).all())
    (2, True, True)
    """
    import cv2

    img = real_array(image, "image", np.float32)
    ok = real_array(allowed, "allowed", np.float32)
    if img.ndim != 2 or ok.shape != img.shape or not np.isfinite(img).all():
        raise InvalidInputError(f"image must be a finite 2-D image and allowed a mask of its "
                                f"shape, got shapes {img.shape} and {ok.shape}")
    spacing = integer(spacing, "spacing", minimum=1, maximum=max(img.shape))  # a huge one
    max_points = integer(max_points, "max_points", minimum=1, maximum=10 ** 6)  # crashed cv2
    lo, hi = np.percentile(img, [1, 99])
    img8 = np.clip((img - lo) / max(hi - lo, 1e-6) * 255, 0, 255).astype(np.uint8)
    pts = cv2.goodFeaturesToTrack(img8, maxCorners=max_points, qualityLevel=0.005,
                                  minDistance=max(3, spacing),
                                  mask=np.asarray(allowed).astype(np.uint8),
                                  blockSize=5)
    return np.zeros((0, 2)) if pts is None else pts.reshape(-1, 2).astype(np.float64)


def _subpixel(score: np.ndarray, iy: int, ix: int) -> tuple[float, float]:
    """Parabola vertex around the integer peak (0 offset on the border)."""
    def vertex(a, b, c):
        den = a - 2 * b + c
        return 0.0 if den >= 0 else float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))

    H, W = score.shape
    dx = vertex(score[iy, ix - 1], score[iy, ix], score[iy, ix + 1]) if 0 < ix < W - 1 else 0.0
    dy = vertex(score[iy - 1, ix], score[iy, ix], score[iy + 1, ix]) if 0 < iy < H - 1 else 0.0
    return dx, dy


def match_flows(ref_feat: np.ndarray, view_feat: np.ndarray, points: np.ndarray,
                view_valid: np.ndarray, *, half: int, radius: int,
                min_score: float = 0.6, clip: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Flow ``(N, 2)`` of every point from the reference into a view, and its NCC score.

    A point's patch (``2 half + 1`` px) is searched in ``view_feat`` within ``radius`` px.
    Points whose patch or search window leaves the image or the view's valid region, whose
    score is below ``min_score`` or whose peak sits on the search border get NaN flow.
    With ``clip`` the search window is cut to the image instead (only the patch must lie
    inside it), and searched where the patch lies in the view's valid region: a wide radius
    then still searches the points away from the image's centre and beside the edge of a
    far view's overlap, and a peak on either cut is refused as one on the window's border
    is.

    Examples
    --------
    A texture moved 3 px right and 2 px up; the third point lies too near the border to be
    searched:

    >>> from scipy.ndimage import gaussian_filter
    >>> texture = gaussian_filter(np.random.default_rng(0).random((64, 64)), 2.0)
    >>> moved = np.roll(texture, (-2, 3), axis=(0, 1))
    >>> points = np.array([[32.0, 32.0], [20.0, 40.0], [2.0, 2.0]])
    >>> flows, scores = match_flows(feature_image(texture), feature_image(moved), points,
    ...                             np.ones((64, 64), bool), half=5, radius=6)
    >>> np.round(flows, 1).tolist()
    [[3.0, -2.0], [3.0, -2.0], [nan, nan]]
    >>> (scores > 0.99).tolist()
    [True, True, False]
    """
    import cv2

    ref_feat = _image(ref_feat, "ref_feat")
    view_feat = _image(view_feat, "view_feat")
    if view_feat.shape != ref_feat.shape:
        raise InvalidInputError(f"view_feat must have ref_feat's shape {ref_feat.shape}, got "
                                f"{view_feat.shape}")
    points = real_array(points, "points")
    if points.ndim != 2 or points.shape[1] != 2 or not np.isfinite(points).all():
        raise InvalidInputError(f"points must be finite (N, 2) pixels (x, y), got shape "
                                f"{points.shape}")
    view_valid = bool_mask(view_valid, "view_valid", ref_feat.shape, of="the feature images")
    side = max(ref_feat.shape)
    half = integer(half, "half", maximum=side)
    radius = integer(radius, "radius", 1, maximum=side)
    min_score = real(min_score, "min_score")
    H, W = ref_feat.shape
    flows = np.full((len(points), 2), np.nan)
    scores = np.zeros(len(points))
    clip = flag(clip, "clip")
    reach = half + radius
    for i, (x, y) in enumerate(np.round(points).astype(int)):
        x0, y0, x1, y1 = x - reach, y - reach, x + reach + 1, y + reach + 1
        if clip:
            if x - half < 0 or y - half < 0 or x + half >= W or y + half >= H:
                continue
            x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
        elif x0 < 0 or y0 < 0 or x1 > W or y1 > H:
            continue
        seen = view_valid[y0:y1, x0:x1]
        cut = not seen.all()    # only with clip: then searched where the view is valid
        if cut and not (clip and seen.any()):
            continue
        tpl = ref_feat[y - half:y + half + 1, x - half:x + half + 1]
        if tpl.std() < 1e-6:
            continue
        score = cv2.matchTemplate(view_feat[y0:y1, x0:x1], tpl, cv2.TM_CCOEFF_NORMED)
        if cut:
            score = _cut_to_valid(score, seen, half)
        iy, ix = np.unravel_index(int(np.argmax(score)), score.shape)
        best = float(score[iy, ix])
        on_border = ix in (0, score.shape[1] - 1) or iy in (0, score.shape[0] - 1)
        if cut:   # a peak next to the valid part's cut is refused too
            on_border |= np.isneginf(score[iy - 1:iy + 2, ix - 1:ix + 2]).any()
        if not np.isfinite(best) or best < min_score or on_border:
            continue
        dx, dy = _subpixel(score, iy, ix)
        # the window's cut (0 unless clipped) added last: unclipped flows keep their bits
        flows[i] = (ix + dx - radius + (x0 - x + reach), iy + dy - radius + (y0 - y + reach))
        scores[i] = best
    return flows, scores


def _cut_to_valid(score: np.ndarray, seen: np.ndarray, half: int) -> np.ndarray:
    """``score`` with ``-inf`` where the patch would cover a pixel outside ``seen`` (the
    search window's valid pixels), so that a peak next to the cut is refused as one on the
    window's border is."""
    import cv2

    inside = cv2.erode(seen.astype(np.uint8), np.ones((2 * half + 1,) * 2, np.uint8))
    inside = inside[half:half + score.shape[0], half:half + score.shape[1]] > 0
    return np.where(inside, score, -np.inf)


@dataclass
class Rank1:
    """Result of :func:`factor_rank1`: ``flow[v, i] ~= -d[i] * offsets[v]``."""

    offsets: np.ndarray   # (V, 2)
    d: np.ndarray         # (N,), NaN for dropped points
    inliers: np.ndarray   # (V, N) bool
    rms: float            # residual RMS over inliers (px)


def _als(F: np.ndarray, w: np.ndarray, d: np.ndarray, iters: int = 30):
    """Alternating weighted least squares of ``F[v, i] = -d[i] o[v]``."""
    o = np.zeros((F.shape[0], 2))
    Fz = np.where(w[..., None], F, 0.0)
    for _ in range(iters):
        den = (w * d[None] ** 2).sum(1)
        o = -(Fz * (w * d[None])[..., None]).sum(1) / np.maximum(den, 1e-12)[:, None]
        den = (w * (o ** 2).sum(1)[:, None]).sum(0)
        d = -(Fz * o[:, None, :]).sum(-1)
        d = (w * d).sum(0) / np.maximum(den, 1e-12)
    return o, d


def _fit_d(F: np.ndarray, w: np.ndarray, o: np.ndarray) -> np.ndarray:
    """Least-squares ``d`` per point given the offsets (0 where a point has no entry)."""
    num = -(np.where(w[..., None], F, 0.0) * o[:, None, :]).sum(-1)
    den = (w * (o ** 2).sum(1)[:, None]).sum(0)
    return (w * num).sum(0) / np.maximum(den, 1e-12)


def _distinct_places(o: np.ndarray, seen: np.ndarray, share: float = 0.2) -> bool:
    """Whether offsets ``(V, 2)`` and the reference's (0, 0) put every camera that has a flow
    (``seen``, (V,) bool) at its own place: each one's nearest neighbour at least ``share``
    of ``extent / n`` away (the array's largest distance over its ``n`` cameras, which even a
    row of cameras spaces by more). A wrong match that recurs in several views (the same flow
    everywhere) would put those cameras on one spot."""
    pts = np.vstack([np.zeros((1, 2)), o[seen]])
    dd = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    extent = float(dd.max())
    np.fill_diagonal(dd, np.inf)
    return bool(dd.min() >= share * extent / len(pts))


def _hypotheses(F: np.ndarray, w: np.ndarray, tol: float) -> np.ndarray:
    """Points that may start a hypothesis: measured in every view, or (three or more views)
    in all but one, with flows of at least ``3 tol`` px on average (off the plane) when any."""
    moved = np.linalg.norm(np.nan_to_num(F), axis=-1)
    seen = w & (moved > 0)
    need = F.shape[0] - (1 if F.shape[0] >= 3 else 0)
    cands = np.flatnonzero(seen.sum(0) >= need)
    if cands.size == 0:
        return cands
    mags = np.array([moved[seen[:, i], i].mean() for i in cands])
    return cands[mags >= 3 * tol] if (mags >= 3 * tol).any() else cands


def _hypothesis(F: np.ndarray, w: np.ndarray, i: int) -> np.ndarray:
    """Offsets ``o = -F[:, i]``; a view the point was not measured in gets the least-squares
    offset of the other points' flows, their ``d`` fitted on the other views."""
    o = -np.nan_to_num(F[:, i])
    for u in np.flatnonzero(~w[:, i]):
        rest = w.copy()
        rest[u] = False
        d = _fit_d(F, rest, o)
        wu = w[u] & rest.any(0)
        den = float((wu * d ** 2).sum())
        o[u] = -(np.nan_to_num(F[u]) * (wu * d)[:, None]).sum(0) / max(den, 1e-12)
    return o


def fitting_entries(flows: np.ndarray, d: np.ndarray, offsets: np.ndarray, *,
                    tol: float = 1.0, measured: np.ndarray | None = None) -> np.ndarray:
    """Which entries of ``flows`` ``(V, N, 2)`` the parallax model ``-d[i] offsets[v]`` explains
    within a fixed tolerance: ``tol`` px plus 5 % of the modelled flow; ``(V, N)`` bool.

    The tolerance does not follow the residuals, as :func:`factor_rank1`'s inliers do, so the
    counts of two models of the same flows compare: a loose model (one view's flows all
    wrong) keeps most entries as inliers but explains few of them within ``tol``. NaN flows
    or ``d`` (a dropped point) never fit.

    Parameters
    ----------
    flows : ndarray (V, N, 2)
    d : ndarray (N,)
    offsets : ndarray (V, 2)
    tol : float
        Tolerance (px) at zero flow.
    measured : ndarray (V, N) bool, optional
        The entries to consider (default: the finite flows).

    Examples
    --------
    Two views, three points; the second view's last flow is off by 3 px:

    >>> o = np.array([[1.0, 0.0], [2.0, 0.0]])
    >>> d = np.array([1.0, -2.0, 4.0])
    >>> flows = -d[None, :, None] * o[:, None, :]
    >>> flows[1, 2, 1] += 3.0
    >>> fitting_entries(flows, d, o).tolist()
    [[True, True, True], [True, True, False]]
    """
    F = real_array(flows, "flows")
    if F.ndim != 3 or F.shape[-1] != 2:
        raise InvalidInputError(f"flows must be (V, N, 2), got shape {F.shape}")
    d, o = real_array(d, "d"), real_array(offsets, "offsets")
    if d.shape != F.shape[1:2] or o.shape != (F.shape[0], 2):
        raise InvalidInputError(f"d must be ({F.shape[1]},) and offsets ({F.shape[0]}, 2) for "
                                f"flows of shape {F.shape}, got {d.shape} and {o.shape}")
    tol = number(tol, "tol")
    w = (np.all(np.isfinite(F), axis=-1) if measured is None
         else bool_mask(measured, "measured", F.shape[:2], of="the flows"))
    return _fitting(F, d, o, tol, w)


def _fitting(F: np.ndarray, d: np.ndarray, o: np.ndarray, tol: float,
             w: np.ndarray) -> np.ndarray:
    """:func:`fitting_entries` on checked arrays (the RANSAC start's inner loop)."""
    res = np.linalg.norm(np.nan_to_num(F) + d[None, :, None] * o[:, None, :], axis=-1)
    flow = np.abs(d)[None] * np.linalg.norm(o, axis=1)[:, None]
    with np.errstate(invalid="ignore"):
        return w & (res <= tol + 0.05 * flow)


def _ransac_offsets(F: np.ndarray, w: np.ndarray, tol: float, trials: int,
                    seed: int) -> np.ndarray | None:
    """Offsets from the one point whose flows explain the most entries (a hypothesis is one
    point's flow vector, ``-d o``: :func:`_hypotheses`, :func:`_hypothesis`; it must put
    every camera at its own place); None if no point qualifies.

    Every point off the plane may start a hypothesis: the larger flows are not the safer
    ones, as wrong matches (repeated texture, peaks at the search border) have large flows
    too (with the reference at the array's edge they were half of the lab capture's
    largest); and one view whose every flow is wrong (a camera mounted turned, before
    :func:`hyperlf.calibration.plane.turned_cameras` finds it) must not leave no point seen
    everywhere."""
    cands = _hypotheses(F, w, tol)
    if cands.size == 0:
        return None
    rng = np.random.default_rng(seed)
    pick = rng.choice(cands, size=min(trials, cands.size), replace=False)
    best, score = None, -1.0
    for i in pick:
        o = _hypothesis(F, w, i)
        if not _distinct_places(o, w.any(1)):
            continue
        sc = float(_fitting(F, _fit_d(F, w, o), o, tol, w).sum())
        if sc > score:
            best, score = o, sc
    return best


#: A view fitted again alone (:func:`_readmit_views`) must then fit at least this many
#: entries, and this share of the median view's.
READMIT_MIN_POINTS = 8
READMIT_SHARE = 0.25


def _readmit_views(F: np.ndarray, measured: np.ndarray, w: np.ndarray, d: np.ndarray,
                   o: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Offsets and inliers with each view fitted again alone where that fits far more.

    The trimming only ever drops entries, so a view whose offset started wrong (the RANSAC
    start's point had a wrong flow there) or was spoilt by another view's wrong flows (a
    camera mounted turned) loses every entry and never gets them back. With the points' ``d``
    fixed by the *other* views' inliers, each of the view's measured flows proposes an
    offset; the one that fits the most of its entries within ``tol`` px plus 5 % of the flow
    replaces the view's offset (least squares over those entries) when it fits at least
    twice as many as the present one, :data:`READMIT_MIN_POINTS` and :data:`READMIT_SHARE`
    of the median view's count. A view of wrong flows fits a few entries at most, and stays
    as it was. ``d`` itself is left as it is."""
    V = F.shape[0]
    alone = []                                  # (points' d from the others, where known)
    for v in range(V):
        rest = w.copy()
        rest[v] = False
        dv = _fit_d(F, rest, o)
        alone.append((dv, measured[v] & rest.any(0) & (np.abs(dv) > 0)))
    fits = np.array([_fitting(F[v:v + 1], dv, o[v:v + 1], tol, m[None]).sum()
                     for v, (dv, m) in enumerate(alone)])
    need = max(READMIT_MIN_POINTS, READMIT_SHARE * float(np.median(fits)))
    o, w = o.copy(), w.copy()
    for v, (dv, m) in enumerate(alone):
        if m.sum() < max(need, 2 * fits[v]):
            continue
        f, dm = F[v, m], dv[m]
        cand = -f / dm[:, None]                                       # one offset per flow
        ok = _fitting(np.broadcast_to(f, (len(f),) + f.shape), dm, cand, tol,
                      np.ones((len(f), len(f)), bool))               # candidate x point
        i = int(np.argmax(ok.sum(1)))
        if ok[i].sum() >= max(need, 2 * fits[v]):
            keep = np.flatnonzero(m)[ok[i]]
            w[v] = False
            w[v, keep] = True
            o[v] = -(F[v, keep] * dv[keep, None]).sum(0) / float((dv[keep] ** 2).sum())
    return o, w


#: How :func:`factor_rank1` checks its options: the rounds and trials are loops (``1e300``
#: never ended), the tolerances px.
_RANK1_RULES = {
    "min_views": rule(integer, minimum=1, maximum=10 ** 6),
    "floor": rule(number, positive=True, at_most=1e6),
    "rounds": rule(integer, maximum=1000), "tol": rule(number, positive=True, at_most=1e6),
    "trials": rule(integer, minimum=1, maximum=10 ** 6), "seed": rule(integer, maximum=2 ** 63),
}


def factor_rank1(flows: np.ndarray, *, min_views: int = 2, floor: float = 0.25,
                 rounds: int = 5, tol: float = 1.0, trials: int = 200, seed: int = 0) -> Rank1:
    """Robust rank-1 factorisation of measured flows ``(V, N, 2)`` (NaN = not measured).

    A view in which no point fits the model gets NaN offsets.

    A RANSAC start (the flows of one point seen in every view, the one that explains most
    entries within ``tol`` px plus 5 % of the flow) picks the inliers; then alternating least
    squares, after each round dropping entries whose residual exceeds
    ``max(floor, median + 3 * 1.4826 * MAD)`` px, and points left with fewer than ``min_views``
    views. A view the trimming left with few entries is then fitted alone to the points'
    ``d`` (:func:`_readmit_views`). The common scale and sign stay free: the caller fixes
    them.

    Examples
    --------
    >>> o = np.array([[1.0, 0.0], [0.0, 2.0], [-1.0, 1.0]])
    >>> d = np.linspace(-3, 4, 20)
    >>> fac = factor_rank1(-d[None, :, None] * o[:, None, :])
    >>> bool(np.allclose(fac.offsets / fac.offsets[0, 0], o))
    True
    """
    F = real_array(flows, "flows")
    if F.ndim != 3 or F.shape[-1] != 2:
        raise InvalidInputError(f"flows must be (V, N, 2), got shape {F.shape}")
    o = check_values(dict(min_views=min_views, floor=floor, rounds=rounds, tol=tol,
                          trials=trials, seed=seed), _RANK1_RULES)
    min_views, floor, rounds, tol, trials = (o[k] for k in ("min_views", "floor", "rounds",
                                                            "tol", "trials"))
    w = np.all(np.isfinite(F), axis=-1)
    V, N = w.shape
    o = _ransac_offsets(F, w, tol, trials, seed)
    if o is None:
        return Rank1(np.full((V, 2), np.nan), np.full(N, np.nan), np.zeros_like(w), np.nan)
    d = _fit_d(F, w, o)
    for _ in range(rounds):
        res = np.linalg.norm(np.nan_to_num(F) + d[None, :, None] * o[:, None, :], axis=-1)
        r = res[w]
        if r.size == 0:
            break
        med = float(np.median(r))
        tau = max(floor, med + 3 * 1.4826 * float(np.median(np.abs(r - med))))
        w &= res <= tau
        w &= (w.sum(0) >= min_views)[None]
        o, d = _als(F, w, d)
    o, w = _readmit_views(F, np.all(np.isfinite(F), axis=-1), w, d, o, tol)
    res = np.linalg.norm(np.nan_to_num(F) + d[None, :, None] * o[:, None, :], axis=-1)
    rms = float(np.sqrt(np.mean(res[w] ** 2))) if w.any() else np.nan
    d = np.where(w.any(0), d, np.nan)
    o = np.where(w.any(1)[:, None], o, np.nan)   # a view no point fits: unknown, not (0, 0)
    return Rank1(o, d, w, rms)


def hub_camera(keys, reference):
    """The camera to match parallax from: ``reference``, unless another is nearer (in grid
    places) to its farthest camera.

    From a corner the farthest view moves twice as far as from the centre, beyond a search
    radius that suits the centre's neighbours.

    Parameters
    ----------
    keys : iterable of (int, int)
        The cameras' grid places.
    reference : (int, int)

    Returns
    -------
    (int, int)

    Examples
    --------
    >>> grid = [(r, c) for r in range(3) for c in range(3)]
    >>> hub_camera(grid, (0, 0)), hub_camera(grid, (1, 1))
    ((1, 1), (1, 1))
    """
    if isinstance(keys, (str, bytes)) or not hasattr(keys, "__iter__"):
        raise InvalidInputError(f"keys must be the cameras' (row, col) places, got {shown(keys)}")
    keys = [int_pair(k, "a camera", 0, what="(row, col)") for k in keys]
    reference = int_pair(reference, "reference", 0, what="(row, col)")
    if reference not in keys:
        raise InvalidInputError(f"reference {reference} is not one of the cameras")
    reach = {k: max(np.hypot(k[0] - j[0], k[1] - j[1]) for j in keys) for k in keys}
    if reach[tuple(reference)] <= min(reach.values()) + 1e-9:
        return tuple(reference)
    return min(keys, key=reach.get)


def _grid_points(image: np.ndarray, allowed: np.ndarray, *, cell: int) -> np.ndarray:
    """The most corner-like pixel (Shi-Tomasi response) of every ``cell`` x ``cell`` block
    inside ``allowed``, ``(N, 2)`` as ``x, y``: every textured region gets points, also where
    the strongest corners of the image lie elsewhere (the matching judges them)."""
    import cv2

    ev = cv2.cornerMinEigenVal(np.asarray(image, np.float32), 5)
    ev = np.where(allowed, ev, 0.0)
    H, W = ev.shape
    pts = []
    for y0 in range(0, H - cell + 1, cell):
        for x0 in range(0, W - cell + 1, cell):
            block = ev[y0:y0 + cell, x0:x0 + cell]
            iy, ix = np.unravel_index(int(np.argmax(block)), block.shape)
            if block[iy, ix] > 0:
                pts.append((x0 + ix, y0 + iy))
    return np.asarray(pts, np.float64).reshape(-1, 2)


def measured_disparity_range(views: np.ndarray, valid: np.ndarray, positions: np.ndarray,
                             reference, *, work_size: int = SEARCH_DEFAULTS["work_size"],
                             max_parallax: float = SEARCH_DEFAULTS["max_parallax"],
                             margin: float = 1.25, min_points: int = 8,
                             max_residual: float = 1.0):
    """A disparity range for registered or rectified views, measured from the scene.

    The most textured point of every block of the camera nearest the grid's centre (the
    reference unless it lies off-centre, :func:`hub_camera`, among the views mostly valid) is
    matched in every other view (gradient images, NCC: cross-spectral, :func:`match_flows`);
    each point's disparity is the least-squares ``d`` of ``flow_v = -d (p_v - p_hub)`` over the
    views that matched it (two at least; points the fit leaves more than ``max_residual`` px
    off on average are mismatches). The range is ``margin`` times the 1st and 99th percentiles,
    widened to include 0 and rounded outwards to whole px per baseline; one without any
    parallax is (-1, 1).

    Parameters
    ----------
    views, valid : ndarray (R, C, H, W)
    positions : ndarray (R, C, 2)
        ``(px, py)`` in baselines.
    reference : (int, int)
    work_size : int
        Matching runs at a scale whose larger side is at most this many px.
    max_parallax : float
        Search radius as a fraction of the larger image side: with neighbours one baseline
        apart, disparities up to ``max_parallax`` times that side (px per baseline) are seen.
    margin : float
    min_points : int
        Fewer matched points: no range (None).
    max_residual : float
        Mean distance (px, at the matching scale) of a point's flows from its fit.

    Returns
    -------
    (float, float) or None

    Examples
    --------
    Three views in a row whose scene lies at a disparity of 2 px per baseline everywhere: the
    range, widened by ``margin`` and to include 0, is rounded out to whole px:

    >>> from scipy.ndimage import gaussian_filter
    >>> texture = gaussian_filter(np.random.default_rng(0).random((60, 90)), 1.5)
    >>> views = np.stack([np.roll(texture, -2 * (c - 1), axis=1) for c in range(3)])[None]
    >>> positions = np.array([[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]])
    >>> valid = np.ones(views.shape, bool)
    >>> measured_disparity_range(views, valid, positions, (0, 1))
    (0.0, 3.0)

    Views without parallax (the scene at the zero-disparity plane) get one px each way:

    >>> measured_disparity_range(np.repeat(views[:, 1:2], 3, axis=1), valid, positions, (0, 1))
    (-1.0, 1.0)

    Views without texture give no range:

    >>> print(measured_disparity_range(np.zeros_like(views), valid, positions, (0, 1)))
    None
    """
    views, valid, positions, reference = _range_inputs(views, valid, positions, reference)
    o = check_values(dict(work_size=work_size, max_parallax=max_parallax, margin=margin,
                          min_points=min_points, max_residual=max_residual),
                     {**SEARCH_RULES, "margin": rule(number, positive=True, at_most=1e3),
                      "min_points": rule(integer, minimum=1),
                      "max_residual": rule(number, positive=True)})
    work_size, max_parallax, margin, min_points, max_residual = o.values()
    flows, offsets = _hub_flows(views, valid, positions, reference, work_size, max_parallax)
    if not flows:
        return None
    d, use = _point_disparities(np.stack(flows), np.stack(offsets), max_residual)
    if use.sum() < min_points:
        return None
    lo, hi = np.percentile(d[use], [1, 99]) * margin
    lo, hi = float(np.floor(min(lo, 0.0))) + 0.0, float(np.ceil(max(hi, 0.0))) + 0.0  # no -0.0
    if hi <= lo:  # no parallax at all (every point at the zero-disparity plane): one px each way
        lo, hi = lo - 1.0, hi + 1.0
    return lo, hi


def _range_inputs(views, valid, positions, reference) -> tuple:
    """The checked inputs of :func:`measured_disparity_range`."""
    views = real_array(views, "views", None)
    if views.ndim != 4 or not views.size or not (np.issubdtype(views.dtype, np.number)
                                                 or views.dtype == bool):
        raise InvalidInputError(f"views must be numbers (R, C, H, W), got shape {views.shape}")
    R, C = views.shape[:2]
    valid = bool_mask(valid, "valid", views.shape, of="the views")
    positions = real_array(positions, "positions")
    if positions.shape != (R, C, 2) or not np.isfinite(positions).all():
        raise InvalidInputError(f"positions must be finite ({R}, {C}, 2), got shape "
                                f"{positions.shape}")
    return views, valid, positions, index(reference, "reference", (R, C))


def _hub_flows(views, valid, positions, reference, work_size, max_parallax) -> tuple:
    """The flows of the hub camera's textured points in every other mostly valid view at
    the matching scale, with those views' offsets from the hub (px at that scale)."""
    import cv2

    R, C, H, W = views.shape
    scale = min(1.0, work_size / max(W, H))
    size = (max(1, int(round(W * scale))), max(1, int(round(H * scale))))

    def small(img):
        return cv2.resize(np.asarray(img, np.float32), size, interpolation=cv2.INTER_AREA)

    present = [(r, c) for r in range(R) for c in range(C) if valid[r, c].mean() >= 0.5]
    ref = hub_camera(set(present) | {tuple(reference)}, reference)
    feat_ref = feature_image(small(views[ref]))
    allowed = small(valid[ref].astype(np.float32)) > 0.999
    half = max(5, int(round(max(size) / 60)))
    radius = max(6, int(round(max_parallax * max(size))))
    pts = _grid_points(feat_ref, allowed, cell=2 * half)
    flows, offsets = [], []
    for k in [(r, c) for r in range(R) for c in range(C) if (r, c) != ref]:
        o = (np.asarray(positions[k], np.float64) - np.asarray(positions[ref])) * scale
        if np.any(o) and len(pts):
            ok = small(valid[k].astype(np.float32)) > 0.999
            flows.append(match_flows(feat_ref, feature_image(small(views[k])), pts, ok,
                                     half=half, radius=radius)[0])
            offsets.append(o)
    return flows, offsets


def _point_disparities(F: np.ndarray, O: np.ndarray, max_residual: float) -> tuple:
    """Each point's least-squares disparity ``d`` of ``flow_v = -d o_v`` over the views that
    matched it (``F`` (V, N, 2), NaN where unmatched; ``O`` (V, 2)), and which points to use:
    matched in two views at least and within ``max_residual`` px of the fit on average."""
    hit = np.all(np.isfinite(F), axis=2)                 # (V, N)
    Fz = np.where(hit[..., None], F, 0.0)
    den = (hit * (O * O).sum(1)[:, None]).sum(0)
    d = -np.einsum("vnk,vk->n", Fz, O) / np.maximum(den, 1e-12)
    resid = np.where(hit, np.linalg.norm(Fz + d[None, :, None] * O[:, None], axis=2), 0.0)
    mean_resid = resid.sum(0) / np.maximum(hit.sum(0), 1)
    return d, (hit.sum(0) >= 2) & (mean_resid <= max_residual)
