"""Two-view (cross-spectral) stereo: cost volume + optimiser + occlusion handling (SPEC §4).

:func:`stereo` is the one-call pipeline used by Table 1 (``benchmarks/table1.py``)::

    res = stereo(left, right, disparity_range=(0, 15), metric="rsncc", optimizer="graphcut",
                 channel=(0, 2))          # red channel of the left image vs blue of the right
    res.disparity   # float32 (H, W), every pixel filled (occlusions from the background side)

Pipeline
--------
1. **Inputs.** 2-D arrays, or ``(H, W, K)`` images with ``channel`` selecting one channel index
   per side (``channel=c`` for both, ``channel=(cl, cr)`` for left ``cl`` and right ``cr``: the
   Table 1 protocol is ``(0, 2)``, red vs blue).  A colour image with ``channel=None`` is
   reduced to the mean of its channels.
2. **Cost volumes** (:func:`hyperlf.costs.cost_volume`): left-referenced ``C_L[d, y, x]`` (left
   ``x`` vs right ``x - d``), out-of-image candidates already carrying the pixel's worst valid
   cost.
3. **Right-referenced volume** (only for ``occlusion="lr-fill"``):
   ``C_R[d, y, x_r] = C_L[d, y, x_r + d]`` (:func:`hyperlf.regularisers.right_cost_from_left`).
   This is **exact** for every windowed cost of :mod:`hyperlf.costs` (ssd, ncc, rsncc, census,
   bwncc, bwncc-paper): each compares the left patch around ``x`` with the right patch around
   ``x - d``, both built with each view's own replicated border, so the cost of the pair
   ``(x_l, x_r = x_l - d)`` does not depend on which view is the reference.  Entries whose left
   partner ``x_r + d`` is outside the image get the right pixel's worst valid cost (same rule).
   It costs no second volume computation.  Computing the volume again with swapped and mirrored
   inputs would *not* be exact for ``bwncc`` (mirroring maps gradient directions
   ``theta -> 1 - theta``, and the overlapping, asymmetric bins are not mirror-symmetric) and
   would double the cost time.  The exceptions are the fusions ``fused`` and
   ``census-rsncc`` (``auto``): their normalisation subtracts a *per-pixel* minimum, which is
   referenced to the left pixel; so their raw parts (``bwncc`` or ``rsncc``, and ``census``)
   are shifted separately and fused again with the right view's validity
   (:func:`compute_volumes`), which is exact as well.
4. **Data term** ``D = (C - min_d C) / s`` per pixel (paper ``|C(f(p)) - C(f*(p))|``), with
   one global scale ``s`` per pair = the standard deviation of the valid raw entries of
   ``C_L`` (the same value for both references).  Dividing by ``s`` makes the smoothness
   parameters comparable between costs of very different ranges (census: 0..48, ncc: 0..2);
   they are still tuned per cost (:data:`DEFAULT_PARAMS`).
5. **Optimiser**, the same for both references: ``wta``; ``sgm`` (8 paths, P1/P2 on label
   steps, :func:`hyperlf.regularisers.sgm`); ``graphcut`` (alpha-expansion, truncated-linear
   smoothness ``weight * w_pq * min(|d_p - d_q|, truncation)`` with contrast-sensitive
   ``w_pq = exp(-dI^2 / (2 edge_sigma^2))`` from the reference view's input image,
   solved coarse-to-fine by :func:`hyperlf.regularisers.graphcut_multiscale`: parameter
   ``levels``, default 2 halvings; ``levels=0`` is plain alpha-expansion, slower for a
   slightly lower energy).  Each optimiser's parameters become a typed object
   (:func:`hyperlf.regularisers.make_params`) run by :func:`hyperlf.regularisers.optimise`.
6. **Occlusions** (``"lr-fill"``): :func:`~hyperlf.regularisers.left_right_check` (tolerance
   1 px) on the integer maps, then :func:`~hyperlf.regularisers.fill_occlusions` (each
   inconsistent pixel takes the lower of the nearest consistent disparities on its row, i.e.
   the background).  ``"none"``: every pixel counts as valid.
7. **Sub-pixel** (optional): parabola through the optimised volume (SGM: the aggregated
   volume; WTA/graphcut: the data term) at the chosen label, before the fill.

Confidence is :func:`hyperlf.regularisers.confidence` of the volume that chose the labels,
set to 0 where the left-right check failed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import costs as _costs
from . import regularisers as _reg
from .errors import InvalidInputError

__all__ = [
    "OPTIMIZERS",
    "OCCLUSION_MODES",
    "DEFAULT_PARAMS",
    "DEFAULT_WINDOWS",
    "StereoResult",
    "stereo",
    "select_channels",
    "compute_volumes",
    "stereo_from_volumes",
    "default_params",
    "default_window",
]

#: Optimiser names (:data:`hyperlf.regularisers.OPTIMISERS`).
OPTIMIZERS = tuple(_reg.OPTIMISERS)
OCCLUSION_MODES = ("lr-fill", "none")

# Two-view's own fallback parameters per optimiser, in units of the normalised data term
# (module doc, step 4); graph cuts run coarse to fine (``levels=2``).
_BASE_PARAMS: dict[str, dict[str, Any]] = {
    "wta": {},
    "sgm": {"p1": 0.5, "p2": 2.0, "paths": 8, "smoothness": "p1p2"},
    "graphcut": {"smoothness": "truncated_linear", "weight": 1.0, "truncation": 2.0,
                 "edge_sigma": None, "max_cycles": 3, "levels": 2},
}

#: Default optimiser parameters per ``(metric, optimizer)``; a pair that is not listed uses the
#: optimiser's fallback (``_BASE_PARAMS``).  Tuned on **Venus only** (SPEC §4), red vs blue,
#: LR check + background fill, by ``benchmarks/table1.py --tune`` (grid: graph cuts weight
#: {1,2,4,8} x truncation {2,4,8} with the coarse-to-fine solver, SGM p1 {0.5,1,2} x p2
#: {4,8,16}; windows {5,9} for ssd/ncc/rsncc, {5,7} for census; criterion Venus bad5.0, ties by
#: bad2.0), then fixed for every other scene.  Graph-cut rows: 2026-11-23, after the solver
#: became coarse-to-fine; SGM rows: the earlier tuning run.  Venus is piecewise planar and
#: rewards strong smoothing: several picks sit on the grid's upper edge, and on Tsukuba a
#: weight of 4 or more can make the MRF give the weakly textured lamp the background's
#: disparity (BENCHMARKS.md, Table 1).
DEFAULT_PARAMS: dict[tuple[str, str], dict[str, Any]] = {
    # Tuned on Venus only (R vs B) by `benchmarks/table1.py --tune`; fixed for every other scene.
    ("ssd", "graphcut"): {"smoothness": "truncated_linear", "weight": 8.0, "truncation": 8.0, "edge_sigma": None, "max_cycles": 3, "levels": 2},  # Venus bad5 9.53, window 9
    ("ssd", "sgm"): {"p1": 1.0, "p2": 16.0, "paths": 8, "smoothness": "p1p2"},  # Venus bad5 11.80, window 5
    ("rsncc", "graphcut"): {"smoothness": "truncated_linear", "weight": 8.0, "truncation": 4.0, "edge_sigma": None, "max_cycles": 3, "levels": 2},  # Venus bad5 0.49, window 5
    ("rsncc", "sgm"): {"p1": 2.0, "p2": 16.0, "paths": 8, "smoothness": "p1p2"},  # Venus bad5 1.03, window 5
    ("bwncc", "graphcut"): {"smoothness": "truncated_linear", "weight": 4.0, "truncation": 8.0, "edge_sigma": None, "max_cycles": 3, "levels": 2},  # Venus bad5 0.04, window None
    ("bwncc", "sgm"): {"p1": 2.0, "p2": 16.0, "paths": 8, "smoothness": "p1p2"},  # Venus bad5 4.14, window None
    ("bwncc-paper", "graphcut"): {"smoothness": "truncated_linear", "weight": 2.0, "truncation": 8.0, "edge_sigma": None, "max_cycles": 3, "levels": 2},  # Venus bad5 1.07, window None
    ("bwncc-paper", "sgm"): {"p1": 2.0, "p2": 16.0, "paths": 8, "smoothness": "p1p2"},  # Venus bad5 8.12, window None
    ("fused", "graphcut"): {"smoothness": "truncated_linear", "weight": 4.0, "truncation": 8.0, "edge_sigma": None, "max_cycles": 3, "levels": 2},  # Venus bad5 0.09, window None
    ("fused", "sgm"): {"p1": 2.0, "p2": 16.0, "paths": 8, "smoothness": "p1p2"},  # Venus bad5 2.15, window None
    ("ncc", "graphcut"): {"smoothness": "truncated_linear", "weight": 8.0, "truncation": 4.0, "edge_sigma": None, "max_cycles": 3, "levels": 2},  # Venus bad5 0.91, window 5
    ("ncc", "sgm"): {"p1": 2.0, "p2": 16.0, "paths": 8, "smoothness": "p1p2"},
    ("census", "graphcut"): {"smoothness": "truncated_linear", "weight": 4.0, "truncation": 8.0, "edge_sigma": None, "max_cycles": 3, "levels": 2},  # Venus bad5 1.23, window 7
    ("census", "sgm"): {"p1": 2.0, "p2": 16.0, "paths": 8, "smoothness": "p1p2"},
    ("census-rsncc", "graphcut"): {"smoothness": "truncated_linear", "weight": 2.0, "truncation": 4.0, "edge_sigma": None, "max_cycles": 3, "levels": 2},  # Venus bad5 0.38, window None
    ("census-rsncc", "sgm"): {"p1": 2.0, "p2": 16.0, "paths": 8, "smoothness": "p1p2"},  # Venus bad5 0.92, window None
}

#: Cost window used when ``window=None``, per ``(metric, optimizer)`` or, failing that, per
#: metric (None = the metric's own default in :mod:`hyperlf.costs`: 5 for ssd/ncc/rsncc, 7 for
#: census, per level for bwncc).  Tuned on Venus together with :data:`DEFAULT_PARAMS`
#: (:func:`default_window`).
DEFAULT_WINDOWS: dict = {
    "ssd": None, "ncc": 5, "rsncc": None, "census": 5,
    "bwncc": None, "bwncc-paper": None, "fused": None, "census-rsncc": None,
    ("ssd", "graphcut"): 9, ("ncc", "graphcut"): 5, ("rsncc", "graphcut"): 5,
    ("census", "graphcut"): 7,
}


def default_window(metric: str, optimizer: str) -> int | None:
    """The default cost window of ``(metric, optimizer)`` (:data:`DEFAULT_WINDOWS`)."""
    m = _costs.resolve_metric(metric)
    opt = _check_optimizer(optimizer)
    return DEFAULT_WINDOWS.get((m, opt), DEFAULT_WINDOWS.get(m))


def default_params(metric: str, optimizer: str) -> dict:
    """The default optimiser parameters for ``(metric, optimizer)`` (a fresh copy)."""
    m = _costs.resolve_metric(metric)
    opt = _check_optimizer(optimizer)
    return {**_BASE_PARAMS[opt], **DEFAULT_PARAMS.get((m, opt), {})}


@dataclass
class StereoResult:
    """Output of :func:`stereo`.

    Attributes
    ----------
    disparity : float32 (H, W)
        Final left-view disparity (after the occlusion fill: every pixel has a value).
    raw : float32 (H, W)
        Disparity before the fill (sub-pixel if requested).
    valid : bool (H, W)
        Left-right consistent pixels (all True with ``occlusion="none"``).
    confidence : float32 (H, W)
        Cost-margin confidence in [0, 1] (0 where not LR-consistent).
    timings : dict
        Seconds: ``cost`` (both volumes), ``optimiser`` (both references), ``total``.
    metric, optimizer, occlusion : str
        What was run (``metric`` resolved, e.g. ``"auto"`` -> ``"fused"``).
    params : dict
        The optimiser parameters actually used (defaults merged with the caller's).
    window : int or None
        Cost window (None: the metric's default).
    disparity_range : (int, int)
    right_disparity : float32 (H, W) or None
        Right-view disparity map (integer labels) when ``occlusion="lr-fill"``.
    """

    disparity: np.ndarray
    raw: np.ndarray
    valid: np.ndarray
    confidence: np.ndarray
    timings: dict
    metric: str
    optimizer: str
    params: dict
    occlusion: str = "lr-fill"
    window: int | None = None
    disparity_range: tuple = (0, 0)
    right_disparity: np.ndarray | None = None
    extra: dict = field(default_factory=dict)


# ----------------------------------------------------------------------------------------------
# validation
# ----------------------------------------------------------------------------------------------

def _check_optimizer(optimizer) -> str:
    if not isinstance(optimizer, str) or optimizer.strip().lower() not in OPTIMIZERS:
        raise InvalidInputError(f"optimizer must be one of {', '.join(OPTIMIZERS)}, got {optimizer!r}")
    return optimizer.strip().lower()


def _check_occlusion(occlusion) -> str:
    if not isinstance(occlusion, str) or occlusion.strip().lower() not in OCCLUSION_MODES:
        raise InvalidInputError(
            f"occlusion must be one of {', '.join(OCCLUSION_MODES)}, got {occlusion!r}")
    return occlusion.strip().lower()


def _check_range(disparity_range, W: int) -> tuple[int, int]:
    try:
        dmin, dmax = disparity_range
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"disparity_range must be a pair (dmin, dmax), got {disparity_range!r}") from None
    for v in (dmin, dmax):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer, float, np.floating)) \
                or not float(v).is_integer():
            raise InvalidInputError(
                f"disparity_range must hold integers, got {disparity_range!r}")
    dmin, dmax = int(dmin), int(dmax)
    if dmin >= dmax:
        raise InvalidInputError(f"disparity_range needs dmin < dmax, got dmin={dmin}, dmax={dmax}")
    if dmax - dmin >= W or max(abs(dmin), abs(dmax)) >= W:
        raise InvalidInputError(
            f"disparity_range ({dmin}, {dmax}) is wider than the image (width {W}): "
            f"|d| and dmax - dmin must be < {W}")
    return dmin, dmax


def _pick(img, ch, side: str) -> np.ndarray:
    a = np.asarray(img)
    if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
        raise InvalidInputError(f"{side} image must be a real numeric array, got dtype {a.dtype}")
    if a.ndim == 2:
        if ch not in (None, 0):
            raise InvalidInputError(
                f"channel {ch!r} given for the {side} image, but it is 2-D {a.shape}")
        out = a
    elif a.ndim == 3:
        K = a.shape[2]
        if ch is None:
            out = a.mean(axis=2)
        else:
            if isinstance(ch, bool) or not isinstance(ch, (int, np.integer)) or not 0 <= ch < K:
                raise InvalidInputError(
                    f"channel for the {side} image must be an integer in [0, {K}), got {ch!r}")
            out = a[:, :, int(ch)]
    else:
        raise InvalidInputError(
            f"{side} image must be (H, W) or (H, W, K), got shape {a.shape}")
    out = np.asarray(out, dtype=np.float32)
    if out.shape[0] < 2 or out.shape[1] < 2:
        raise InvalidInputError(f"{side} image is too small: {out.shape}")
    if not np.isfinite(out).all():
        raise InvalidInputError(f"{side} image contains NaN or infinite values; fill them first")
    return out


def select_channels(left, right, channel=None) -> tuple[np.ndarray, np.ndarray]:
    """Return the two 2-D float32 images :func:`stereo` matches.

    ``channel``: None (2-D inputs as they are; colour inputs -> mean of channels), an int (the
    same channel of both), or a pair ``(left_channel, right_channel)``.
    """
    if channel is None or isinstance(channel, (int, np.integer)):
        cl = cr = channel
    else:
        try:
            cl, cr = channel
        except (TypeError, ValueError):
            raise InvalidInputError(
                f"channel must be None, an int or a pair (left, right), got {channel!r}") from None
    L = _pick(left, cl, "left")
    R = _pick(right, cr, "right")
    if L.shape != R.shape:
        raise InvalidInputError(
            f"left and right images must have the same size, got {L.shape} and {R.shape}")
    return L, R


def _merge_params(metric: str, optimizer: str, params) -> dict:
    """Defaults of ``(metric, optimizer)`` updated with ``params``, checked by the optimiser's
    parameter dataclass (unknown keys and invalid values raise InvalidInputError)."""
    p = default_params(metric, optimizer)
    if params is not None:
        if not isinstance(params, dict):
            raise InvalidInputError(f"params must be a dict, got {type(params).__name__}")
        p.update(params)
    _reg.make_params(optimizer, p)
    return p


# ----------------------------------------------------------------------------------------------
# volumes
# ----------------------------------------------------------------------------------------------

def _right_validity(shape, dmin: int, dmax: int) -> np.ndarray:
    """``valid_R[L, H, W]``: True where the right pixel's partner ``x_r + d`` is in the image."""
    H, W = shape
    d = np.arange(dmin, dmax + 1)[:, None, None]
    x = np.arange(W)[None, None, :]
    return np.broadcast_to((x + d >= 0) & (x + d < W), (d.shape[0], H, W))


def compute_volumes(left, right, dmin: int, dmax: int, metric: str = "auto", window=None,
                    need_right: bool = True, cost_params: dict | None = None):
    """Left- and right-referenced cost volumes ``(C_L, C_R)`` of two 2-D images.

    ``C_R`` is None unless ``need_right``.  See the module docstring (step 3) for why the
    re-referencing is exact.  ``cost_params`` go to :func:`hyperlf.costs.cost_volume`.
    """
    name = _costs.resolve_metric(metric)
    kw = dict(cost_params or {})
    labels = np.arange(dmin, dmax + 1, dtype=np.float64)
    if name in ("fused", "census-rsncc") and need_right:
        # Shift the raw parts, then fuse each reference with its own validity (exact).
        cw = kw.pop("census_window", 7)
        weights = kw.pop("weights", (1.0, 1.0))
        impl = kw.pop("impl", "auto")
        if name == "fused":
            bw = kw.pop("bwncc_window", None)
            b = _costs.bwncc_volume(left, right, dmin, dmax, "default", window=bw, impl=impl,
                                    **kw)
        else:
            b = _costs.rsncc_volume(left, right, dmin, dmax,
                                    window=kw.pop("rsncc_window", 5), impl=impl, **kw)
        c = _costs.census_volume(left, right, dmin, dmax, window=cw, impl=impl)
        cl = _costs.fuse([b, c], weights, dmin)
        vr = _right_validity(cl.shape[1:], dmin, dmax)
        br = _reg.right_cost_from_left(b, labels)
        crr = _reg.right_cost_from_left(c, labels)
        cr = _costs.fuse([br, crr], weights, dmin, valid=vr)
        return cl, cr
    cl = _costs.cost_volume(left, right, dmin, dmax, metric=name, window=window, **kw)
    cl = np.asarray(cl, dtype=np.float32)
    cr = _reg.right_cost_from_left(cl, labels) if need_right else None
    return cl, cr


def _data_scale(cost_left: np.ndarray, dmin: int) -> float:
    Lc, H, W = cost_left.shape
    valid = _costs.candidate_validity((H, W), dmin, dmin + Lc - 1)
    vals = cost_left[valid]
    s = float(vals.std(dtype=np.float64)) if vals.size else 0.0
    return s if s > 0 and np.isfinite(s) else 1.0


def _optimise(D: np.ndarray, params, guide, labels, subpixel: bool, progress: bool):
    """Return (integer label map, float disparity, volume used for confidence)."""
    res = _reg.optimise(D, params, guide=guide, labels=labels, progress=progress)
    if subpixel:
        disp = _reg.subpixel_refine(res.volume, res.labels, labels)
    else:
        disp = labels[res.labels].astype(np.float32)
    return res.labels, disp, res.volume


def stereo_from_volumes(cost_left, cost_right, dmin: int, optimizer: str = "graphcut",
                        occlusion: str = "lr-fill", params: dict | None = None,
                        guide_left=None, guide_right=None, subpixel: bool = False,
                        metric: str = "auto", progress: bool = False) -> StereoResult:
    """Steps 4-7 of the pipeline on precomputed volumes (see :func:`compute_volumes`).

    ``params`` here must be complete (use :func:`default_params`); ``metric`` is only recorded
    (and used to look up defaults when ``params`` is None).  ``guide_*`` are the input images
    used for graph-cut edge weights.  ``timings`` holds only ``optimiser``.
    """
    optimizer = _check_optimizer(optimizer)
    occlusion = _check_occlusion(occlusion)
    name = _costs.resolve_metric(metric)
    p = _merge_params(name, optimizer, params)
    opt = _reg.make_params(optimizer, p)
    cl = np.asarray(cost_left, dtype=np.float32)
    if cl.ndim != 3:
        raise InvalidInputError(f"cost_left must be (L, H, W), got {cl.shape}")
    Lc = cl.shape[0]
    labels = np.arange(dmin, dmin + Lc, dtype=np.float64)
    s = _data_scale(cl, dmin)
    t0 = time.perf_counter()
    DL = _reg.data_term(cl) / np.float32(s)
    fl, disp_l, vol_l = _optimise(DL, opt, guide_left, labels, subpixel, progress)
    conf = _reg.confidence(vol_l, fl)
    disp_r = None
    if occlusion == "lr-fill":
        if cost_right is None:
            raise InvalidInputError("occlusion='lr-fill' needs the right-referenced volume")
        cr = np.asarray(cost_right, dtype=np.float32)
        if cr.shape != cl.shape:
            raise InvalidInputError(f"cost_right shape {cr.shape} != cost_left shape {cl.shape}")
        DR = _reg.data_term(cr) / np.float32(s)
        fr, _, _ = _optimise(DR, opt, guide_right, labels, False, progress)
        disp_r = labels[fr].astype(np.float32)
        valid = _reg.left_right_check(labels[fl], disp_r, tol=1.0)
        if valid.any():
            final = _reg.fill_occlusions(disp_l, valid)
        else:  # nothing consistent: keep the left map rather than fail
            final = disp_l.copy()
        conf = np.where(valid, conf, 0.0).astype(np.float32)
    else:
        valid = np.ones(disp_l.shape, dtype=bool)
        final = disp_l.copy()
    t_opt = time.perf_counter() - t0
    return StereoResult(disparity=np.asarray(final, np.float32), raw=np.asarray(disp_l, np.float32),
                        valid=valid, confidence=conf, timings={"optimiser": t_opt}, metric=name,
                        optimizer=optimizer, params=p, occlusion=occlusion,
                        disparity_range=(int(dmin), int(dmin + Lc - 1)), right_disparity=disp_r,
                        extra={"data_scale": s})


def stereo(left, right, disparity_range, metric: str = "auto", optimizer: str = "graphcut",
           occlusion: str = "lr-fill", subpixel: bool = False, params: dict | None = None,
           window: int | None = None, channel=None, progress: bool = False,
           cost_params: dict | None = None) -> StereoResult:
    """Disparity of the left view of a rectified pair (SPEC §4; module docstring).

    Parameters
    ----------
    left, right : (H, W) or (H, W, K) arrays (linear intensities; any positive scale).
    disparity_range : (dmin, dmax) integers, ``dmin < dmax``; left ``x`` matches right ``x - d``.
    metric : a name of :data:`hyperlf.costs.METRIC_NAMES` (``"auto"`` = the library default).
    optimizer : ``"graphcut"`` (default), ``"sgm"`` or ``"wta"``.
    occlusion : ``"lr-fill"`` (left-right check + background fill) or ``"none"``.
    subpixel : parabola refinement of the chosen labels.
    params : optimiser parameters overriding :data:`DEFAULT_PARAMS` — sgm: ``p1``, ``p2``
        (``paths``, ``smoothness``); graphcut: ``smoothness``, ``weight``, ``truncation``,
        ``edge_sigma``, ``max_cycles``, ``levels`` (coarse-to-fine halvings, 0 = plain
        alpha-expansion); in units of the normalised data term.
    window : cost window (odd); None uses :data:`DEFAULT_WINDOWS` / the metric's default.
    channel : None, int, or ``(left_channel, right_channel)`` for colour inputs.
    progress : show a progress bar during graph cuts.
    cost_params : extra keyword arguments of :func:`hyperlf.costs.cost_volume`.

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN, ``dmin >= dmax``, a range wider than the image, unknown names/params.
    """
    t_all = time.perf_counter()
    name = _costs.resolve_metric(metric)
    optimizer = _check_optimizer(optimizer)
    occlusion = _check_occlusion(occlusion)
    L, R = select_channels(left, right, channel)
    dmin, dmax = _check_range(disparity_range, L.shape[1])
    p = _merge_params(name, optimizer, params)
    if window is None:
        window = default_window(name, optimizer)
    if not isinstance(subpixel, (bool, np.bool_)):
        raise InvalidInputError(f"subpixel must be True or False, got {subpixel!r}")
    if L.mean() <= 0 or R.mean() <= 0:
        raise InvalidInputError("images must have a positive mean (linear intensities expected)")
    t0 = time.perf_counter()
    cl, cr = compute_volumes(L, R, dmin, dmax, name, window, need_right=(occlusion == "lr-fill"),
                             cost_params=cost_params)
    t_cost = time.perf_counter() - t0
    res = stereo_from_volumes(cl, cr, dmin, optimizer, occlusion, p, guide_left=L, guide_right=R,
                              subpixel=bool(subpixel), metric=name, progress=progress)
    res.window = window
    res.timings = {"cost": t_cost, "optimiser": res.timings["optimiser"],
                   "total": time.perf_counter() - t_all}
    return res
