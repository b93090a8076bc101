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

__all__ = ["feature_image", "select_points", "match_flows", "factor_rank1", "Rank1"]


def feature_image(image: np.ndarray, *, sigma: float = 1.0) -> np.ndarray:
    """Gradient magnitude of the percentile-normalised, slightly blurred image (float32).

    Parameters
    ----------
    image : ndarray (H, W)
    sigma : float
        Gaussian blur (px) before the Sobel gradient.
    """
    import cv2

    img = np.asarray(image, np.float32)
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
    """Well-textured points ``(N, 2)`` (``x, y``) inside ``allowed`` (Shi-Tomasi corners)."""
    import cv2

    img = np.asarray(image, np.float32)
    lo, hi = np.percentile(img, [1, 99])
    img8 = np.clip((img - lo) / max(hi - lo, 1e-6) * 255, 0, 255).astype(np.uint8)
    pts = cv2.goodFeaturesToTrack(img8, maxCorners=max_points, qualityLevel=0.005,
                                  minDistance=max(3, spacing), mask=allowed.astype(np.uint8),
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
                min_score: float = 0.6) -> tuple[np.ndarray, np.ndarray]:
    """Flow ``(N, 2)`` of every point from the reference into a view, and its NCC score.

    A point's patch (``2 half + 1`` px) is searched in ``view_feat`` within ``radius`` px.
    Points whose patch or search window leaves the image or the view's valid region, whose
    score is below ``min_score`` or whose peak sits on the search border get NaN flow.
    """
    import cv2

    H, W = ref_feat.shape
    flows = np.full((len(points), 2), np.nan)
    scores = np.zeros(len(points))
    reach = half + radius
    for i, (x, y) in enumerate(np.round(points).astype(int)):
        if x - reach < 0 or y - reach < 0 or x + reach >= W or y + reach >= H:
            continue
        if not view_valid[y - reach:y + reach + 1, x - reach:x + reach + 1].all():
            continue
        tpl = ref_feat[y - half:y + half + 1, x - half:x + half + 1]
        if tpl.std() < 1e-6:
            continue
        win = view_feat[y - reach:y + reach + 1, x - reach:x + reach + 1]
        score = cv2.matchTemplate(win, tpl, cv2.TM_CCOEFF_NORMED)
        iy, ix = np.unravel_index(int(np.argmax(score)), score.shape)
        best = float(score[iy, ix])
        on_border = ix in (0, score.shape[1] - 1) or iy in (0, score.shape[0] - 1)
        if not np.isfinite(best) or best < min_score or on_border:
            continue
        dx, dy = _subpixel(score, iy, ix)
        flows[i] = (ix + dx - radius, iy + dy - radius)
        scores[i] = best
    return flows, scores


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


def _ransac_offsets(F: np.ndarray, w: np.ndarray, tol: float, trials: int,
                    seed: int) -> np.ndarray | None:
    """Offsets from the one point whose flows explain the most entries (a hypothesis is one
    point measured in every view: its flow vector is ``-d o``); None if no point qualifies."""
    full = np.flatnonzero(w.all(0) & (np.linalg.norm(np.nan_to_num(F), axis=-1).min(0) > 0))
    if full.size == 0:
        return None
    mags = np.linalg.norm(F[:, full], axis=-1).mean(0)
    cands = full[mags >= np.median(mags)] if full.size > 4 else full
    rng = np.random.default_rng(seed)
    pick = rng.choice(cands, size=min(trials, cands.size), replace=False)
    best, score = None, -1.0
    for i in pick:
        o = -F[:, i]
        d = _fit_d(F, w, o)
        res = np.linalg.norm(np.nan_to_num(F) + d[None, :, None] * o[:, None, :], axis=-1)
        sc = float(np.sum(w & (res <= tol + 0.05 * np.abs(d)[None] * np.linalg.norm(o, axis=1)
                               [:, None])))
        if sc > score:
            best, score = o, sc
    return best


def factor_rank1(flows: np.ndarray, *, min_views: int = 2, floor: float = 0.25,
                 rounds: int = 5, tol: float = 1.0, trials: int = 200, seed: int = 0) -> Rank1:
    """Robust rank-1 factorisation of measured flows ``(V, N, 2)`` (NaN = not measured).

    A RANSAC start (the flows of one point seen in every view, the one that explains most
    entries within ``tol`` px plus 5 % of the flow) picks the inliers; then alternating least
    squares, after each round dropping entries whose residual exceeds
    ``max(floor, median + 3 * 1.4826 * MAD)`` px, and points left with fewer than ``min_views``
    views. The common scale and sign stay free: the caller fixes them.

    Examples
    --------
    >>> o = np.array([[1.0, 0.0], [0.0, 2.0], [-1.0, 1.0]])
    >>> d = np.linspace(-3, 4, 20)
    >>> fac = factor_rank1(-d[None, :, None] * o[:, None, :])
    >>> bool(np.allclose(fac.offsets / fac.offsets[0, 0], o))
    True
    """
    F = np.asarray(flows, np.float64)
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
    res = np.linalg.norm(np.nan_to_num(F) + d[None, :, None] * o[:, None, :], axis=-1)
    rms = float(np.sqrt(np.mean(res[w] ** 2))) if w.any() else np.nan
    d = np.where(w.any(0), d, np.nan)
    return Rank1(o, d, w, rms)
