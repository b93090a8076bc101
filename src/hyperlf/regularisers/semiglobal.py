"""Semi-global matching (Hirschmüller 2008): path-wise aggregation of a cost volume."""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from .._options import choice, number
from ._checks import check_cost, check_guide
from .basic import wta

__all__ = ["sgm", "sgm_labels", "SGM_SMOOTHNESS", "SGM_PATHS"]

_DIRECTIONS_8 = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (-1, -1), (1, -1), (-1, 1))
_SMOOTH_CODES = {"p1p2": 0, "truncated_linear": 1}

#: Smoothness terms :func:`sgm` accepts.
SGM_SMOOTHNESS = tuple(_SMOOTH_CODES)
#: Numbers of path directions :func:`sgm` accepts.
SGM_PATHS = (2, 4, 8)


def _sgm_directions(paths: int):
    if paths == 8:
        return _DIRECTIONS_8
    if paths == 4:
        return _DIRECTIONS_8[:4]
    if paths == 2:
        return _DIRECTIONS_8[:2]
    raise InvalidInputError(f"paths must be 2, 4 or 8, got {paths!r}")


def _neighbour_diff(g: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """|g(p) - g(p - r)| (Euclidean over channels) for r = (dy, dx); 0 where p - r is outside."""
    H, W = g.shape[:2]
    out = np.zeros((H, W), dtype=np.float64)
    ys = slice(max(dy, 0), H + min(dy, 0))
    xs = slice(max(dx, 0), W + min(dx, 0))
    ps = slice(max(-dy, 0), H + min(-dy, 0))
    qs = slice(max(-dx, 0), W + min(-dx, 0))
    out[ys, xs] = np.sqrt(((g[ys, xs] - g[ps, qs]) ** 2).sum(axis=-1))
    return out


def _sgm_p2_maps(H, W, directions, p1, p2, guide, guide_scale):
    """Per direction, the (H, W) map of the effective P2 at each pixel (for the step into it)."""
    if guide is None:  # one read-only map shared by every direction
        return [np.full((H, W), p2, dtype=np.float64)] * len(directions)
    g = check_guide(guide, H, W)
    diffs = [_neighbour_diff(g, dy, dx) for dy, dx in directions]
    if guide_scale is None:
        # mean absolute neighbour difference over horizontal + vertical pairs
        parts = []
        if W > 1:
            parts.append(_neighbour_diff(g, 0, 1)[:, 1:].ravel())
        if H > 1:
            parts.append(_neighbour_diff(g, 1, 0)[1:, :].ravel())
        s = float(np.concatenate(parts).mean()) if parts else 0.0
        guide_scale = s if s > 0 else 1.0
    else:
        guide_scale = number(guide_scale, "guide_scale", positive=True)
    return [np.maximum(p1, p2 / (1.0 + d / guide_scale)) for d in diffs]


def _sgm_starts(H, W, dy, dx):
    ys, xs = np.mgrid[0:H, 0:W]
    py, px = ys - dy, xs - dx
    start = (py < 0) | (py >= H) | (px < 0) | (px >= W)
    return ys[start].astype(np.int64), xs[start].astype(np.int64)


def _scan_front(C, acc, p2map, dy, dx):
    """How one path direction walks the volume: the order of its fronts (rows when ``dy``,
    else columns), a front's costs, its P2 and its accumulator, and the shift of a front's
    predecessors along it (``dx`` for rows, 0 for columns)."""
    H, W, _ = C.shape
    if dy != 0:  # predecessor of (y, x) is (y - dy, x - dx)
        order = range(H) if dy > 0 else range(H - 1, -1, -1)
        return order, (lambda i: C[i]), (lambda i: p2map[i]), (lambda i: acc[i]), dx
    order = range(W) if dx > 0 else range(W - 1, -1, -1)
    return order, (lambda i: C[:, i]), (lambda i: p2map[:, i]), (lambda i: acc[:, i]), 0


def _predecessors(prev, shift):
    """The previous front's values at each front index ``j`` (those of ``j - shift``), and
    whether ``j`` has a predecessor at all."""
    pv = np.empty_like(prev)
    has = np.ones(prev.shape[0], dtype=bool)
    if shift == 0:
        pv[:] = prev
    elif shift > 0:
        pv[shift:] = prev[:-shift]
        pv[:shift] = 0.0
        has[:shift] = False
    else:
        pv[:shift] = prev[-shift:]
        pv[shift:] = 0.0
        has[shift:] = False
    return pv, has


def _path_minimum(pv, p1, p2, mode):
    """``min_k [L(p - r, k) + V(l, k)]`` for every label ``l`` of a front, and the
    predecessors' own minimum; ``mode`` 0 is ``p1p2``, else truncated linear (a distance
    transform both ways)."""
    L = pv.shape[1]
    mprev = pv.min(axis=1, keepdims=True)
    jump = mprev + p2[:, None]
    if mode == 0:
        v = pv.copy()
        if L > 1:
            v[:, 1:] = np.minimum(v[:, 1:], pv[:, :-1] + p1)
            v[:, :-1] = np.minimum(v[:, :-1], pv[:, 1:] + p1)
        return np.minimum(v, jump), mprev
    dt = pv.copy()
    for l in range(1, L):
        np.minimum(dt[:, l], dt[:, l - 1] + p1, out=dt[:, l])
    for l in range(L - 2, -1, -1):
        np.minimum(dt[:, l], dt[:, l + 1] + p1, out=dt[:, l])
    return np.minimum(dt, jump), mprev


def _sgm_numpy_direction(C, acc, dy, dx, p1, p2map, mode):
    """Reference: one path direction, vectorised along the scan front (a row or a column)."""
    order, costs_of, p2_of, acc_of, shift = _scan_front(C, acc, p2map, dy, dx)
    prev = None
    for i in order:
        c = costs_of(i).astype(np.float64)
        cur = c
        if prev is not None:
            pv, has = _predecessors(prev, shift)
            v, mprev = _path_minimum(pv, p1, p2_of(i), mode)
            cur = c + v - mprev
            cur[~has] = c[~has]
        acc_of(i)[...] += cur
        prev = cur


def _path_kernel(impl: str):
    """The numba path kernel for ``impl`` ("auto"/"numba"), or None for the numpy reference."""
    choice(impl, "impl", ("auto", "numba", "numpy"))
    if impl == "numpy":
        return None
    try:
        from . import _kernels
    except ImportError:
        if impl == "numba":
            raise InvalidInputError("impl='numba' requested but numba is not installed") from None
        return None
    return _kernels.sgm_path


def sgm(cost, p1: float, p2: float, paths: int = 8, guide=None, impl: str = "auto", *,
        smoothness: str = "p1p2", guide_scale: float | None = None) -> np.ndarray:
    """Semi-global matching: the cost volume aggregated along ``paths`` directions.

    For each path direction ``r`` the recursion is::

        L_r(p, l) = C(p, l) + min_k [L_r(p - r, k) + V(l, k)] - min_k L_r(p - r, k)

    and ``S = sum_r L_r`` (float32; the recursion itself runs in float64).

    Parameters
    ----------
    cost : array_like, shape (L, H, W)
        Finite cost volume.
    p1, p2 : float
        Penalties, in cost units and **label units** (``Δl`` = difference of label indices;
        with evenly spaced labels of step ``s``, a slope ``lam`` per disparity unit is
        ``p1 = lam * s``).  The effective P2 is never below P1.
    paths : {8, 4, 2}
        8: horizontal, vertical and both diagonals, both ways; 4: horizontal and vertical;
        2: horizontal.
    guide : array_like, shape (H, W) or (H, W, K), optional
        When given, P2 adapts per step to the guide's change along the path:
        ``P2(p) = max(P1, p2 / (1 + |ΔI| / guide_scale))``, ``|ΔI| = ||I(p) - I(p - r)||``
        (Euclidean over channels).  A bounded variant of Hirschmüller's ``P2 / |ΔI|`` (which
        is infinite on flat regions); ``p2`` is the penalty on flat regions.
    impl : {"auto", "numba", "numpy"}
        ``"numba"`` (parallel over the scanlines of each direction), ``"numpy"`` (reference,
        vectorised along the scan front) or ``"auto"`` (numba when importable).
    smoothness : {"p1p2", "truncated_linear"}
        ``"p1p2"``: ``V = 0`` for ``Δl = 0``, ``p1`` for ``|Δl| = 1``, ``p2`` for larger
        jumps.  ``"truncated_linear"``: ``V = min(p1 |Δl|, p2)``, so ``lam min(|Δd|, T)`` is
        ``p1 = lam s``, ``p2 = lam T``.
    guide_scale : float, optional
        Scale of ``|ΔI|``; default the mean absolute 4-neighbour difference of the guide.

    Returns
    -------
    ndarray, float32, shape (L, H, W)
        The aggregated volume ``S``; its per-pixel minimum is the SGM label.

    Raises
    ------
    InvalidInputError
        A non-finite volume, negative penalties, unknown ``paths``/``smoothness``/``impl``.

    References
    ----------
    .. [1] H. Hirschmüller, "Stereo processing by semiglobal matching and mutual information",
       IEEE Trans. Pattern Anal. Mach. Intell. 30(2), 328-341, 2008.
       https://doi.org/10.1109/TPAMI.2007.1166

    Examples
    --------
    Along two horizontal paths the odd pixel's own label 2 pays ``p1`` on each path (0.8 in
    all), more than the 2 x 0.3 its neighbours' label 1 costs it:

    >>> import numpy as np
    >>> noisy = np.ones((3, 1, 7), np.float32); noisy[1] = 0.0
    >>> noisy[1:, 0, 3] = [0.3, 0.0]
    >>> S = sgm(noisy, 0.4, 1.0, paths=2, impl="numpy")
    >>> [round(float(v), 2) for v in S[:, 0, 3]], S.argmin(axis=0)[0].tolist()
    ([2.8, 0.6, 0.8], [1, 1, 1, 1, 1, 1, 1])
    """
    c = check_cost(cost)
    p1 = number(p1, "p1")
    p2 = number(p2, "p2")
    choice(smoothness, "smoothness", sorted(_SMOOTH_CODES))
    mode = _SMOOTH_CODES[smoothness]
    p2 = max(p1, p2)
    kernel = _path_kernel(impl)
    directions = _sgm_directions(choice(paths, "paths", SGM_PATHS))
    L, H, W = c.shape
    p2maps = _sgm_p2_maps(H, W, directions, p1, p2, guide, guide_scale)
    C = np.ascontiguousarray(c.transpose(1, 2, 0))
    acc = np.zeros((H, W, L), dtype=np.float32)
    for (dy, dx), p2map in zip(directions, p2maps):
        if kernel is not None:
            sy, sx = _sgm_starts(H, W, dy, dx)
            kernel(C, acc, sy, sx, dy, dx, p1, np.ascontiguousarray(p2map), mode)
        else:
            _sgm_numpy_direction(C, acc, dy, dx, p1, p2map, mode)
    del C  # one volume fewer while the result is laid out label-first
    return np.ascontiguousarray(acc.transpose(2, 0, 1))


def sgm_labels(cost, p1: float, p2: float, paths: int = 8, guide=None, impl: str = "auto",
               **kwargs) -> np.ndarray:
    """WTA on the SGM-aggregated volume.

    Parameters
    ----------
    cost, p1, p2, paths, guide, impl, **kwargs
        As in :func:`sgm`.

    Returns
    -------
    ndarray, int32, shape (H, W)
        Label indices.

    Examples
    --------
    A pixel whose own costs prefer label 1 by 0.2 takes its neighbours' label 0 when a
    jump costs 0.5 on each of the two paths, and keeps its own without smoothness:

    >>> cost = np.stack([np.zeros((1, 5)), np.ones((1, 5))]).astype(np.float32)
    >>> cost[0, 0, 2] = 1.2
    >>> sgm_labels(cost, 0.5, 2.0, paths=2).tolist(), sgm_labels(cost, 0.0, 0.0, paths=2).tolist()
    ([[0, 0, 0, 0, 0]], [[0, 0, 1, 0, 0]])
    """
    return wta(sgm(cost, p1, p2, paths=paths, guide=guide, impl=impl, **kwargs))
