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
   would double the cost time.  The exceptions are the fused costs (``fused``,
   ``census-rsncc`` = ``auto``; :class:`hyperlf.costs.FusedCost`): their normalisation
   subtracts a *per-pixel* minimum, which is referenced to the left pixel; so their raw parts
   are shifted separately and fused again with the right view's validity
   (:meth:`hyperlf.costs.FusedCost.pair_volumes`), which is exact as well.
   *Aggregation* (optional, ``aggregation``; :mod:`hyperlf.costs.aggregation`): each volume
   is then filtered edge-aware with its own image as the guide (``"guided"``), the
   out-of-image rule applied again; the default ``"none"`` leaves both as they are.
4. **Data term** ``D = (C - min_d C) / s`` per pixel (paper ``|C(f(p)) - C(f*(p))|``), with
   one global scale ``s`` per pair = the standard deviation of the valid raw entries of
   ``C_L`` (the same value for both references).  Dividing by ``s`` makes the smoothness
   parameters comparable between costs of very different ranges (census: 0..48, ncc: 0..2);
   they are still tuned per cost (:attr:`hyperlf.costs.Cost.params`, :func:`default_params`).
5. **Optimiser**, the same for both references: ``wta``; ``sgm`` (8 paths, P1/P2 on label
   steps, :func:`hyperlf.regularisers.sgm`); ``graphcut`` (alpha-expansion, truncated-linear
   smoothness ``weight * w_pq * min(|d_p - d_q|, truncation)`` with contrast-sensitive
   ``w_pq = exp(-dI^2 / (2 edge_sigma^2))`` from the reference view's input image,
   solved coarse-to-fine by :func:`hyperlf.regularisers.graphcut_multiscale`: parameter
   ``levels``, default 2 halvings; ``levels=0`` is plain alpha-expansion, slower for a
   slightly lower energy).  Each optimiser's parameters become a typed object
   (:func:`hyperlf.regularisers.make_params`) run by :func:`hyperlf.regularisers.optimise`.
   *Holes* (graph cuts only; :func:`open_holes`, constants ``hole_params``): graph cuts
   charge a hole's whole outline (the inside of a ring, a gap between two objects) against
   the few pixels of background that vouch for it, and fill it with the foreground around
   it.  Each reference is solved again at half the smoothness weight, and the components
   that this second answer puts farther, that are enclosed by the first answer's
   foreground, that the data term prefers and on which the second answer holds one depth
   (:func:`hyperlf.regularisers.enclosed_background`) and that both references' second
   answers agree on take its labels; on by default (``HoleParams(enabled=False)`` turns it
   off).
6. **Occlusions** (``"lr-fill"``): :func:`~hyperlf.regularisers.left_right_check` (tolerance
   1 px) on the integer maps, then :func:`~hyperlf.regularisers.fill_occlusions` (each
   inconsistent pixel takes the lower of the nearest consistent disparities on its row, i.e.
   the background).  ``"lr-plane"`` (the default) first splits the inconsistent pixels into
   occlusions (no right pixel maps to them: :func:`~hyperlf.regularisers.left_occlusions`)
   and mismatches; a mismatch in a planar region of the left image with enough consistent
   pixels takes that region's plane (:func:`~hyperlf.regularisers.plane_fill`, constants
   ``plane_params``), everything else the background fill; then every inconsistent pixel
   takes the guided weighted median of the filled map around it (radius 5 px, after Hosni et
   al. 2013; ``PlaneFillParams.median_radius``), which removes the streaks a row fill leaves.
   ``"none"``: every pixel counts as valid.
7. **Sub-pixel** (optional): parabola through the optimised volume (SGM: the aggregated
   volume; WTA/graphcut: the data term) at the chosen label, before the fill.

Confidence (:class:`hyperlf.regularisers.ConfidenceParams`): the cost margin of the volume
that chose the labels (:func:`hyperlf.regularisers.confidence`) from a floor of 0.1 up, 0 where
the left-right check failed, scaled by the distance to the final map's depth edges
(:func:`hyperlf.regularisers.edge_confidence`, 0 on a jump of more than 1.5 px, 1 from 8 px
away).  The margin alone is 0 on 15-65 % of the consistent pixels (weak and repeated
textures), where it ranked them with the inconsistent ones, and it does not see the depth
edges, where most of the error is; with the floor and the edge factor the sparsification
error (the share of bad pixels among the most confident ones) is 32-75 % lower on the tuning
scenes (BENCHMARKS.md, fortieth session).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from . import costs as _costs
from . import regularisers as _reg
from ._options import bool_mask, choice, flag, integer, mapping, params_of, real_array, shown
from .costs._validate import MAX_DISPARITY
from .errors import InvalidInputError
from .regularisers._checks import check_cost, check_guide, check_label_map, check_labels

__all__ = [
    "OPTIMIZERS",
    "OCCLUSION_MODES",
    "DEFAULT_OCCLUSION",
    "StereoResult",
    "stereo",
    "select_channels",
    "compute_volumes",
    "stereo_from_volumes",
    "fill_inconsistent",
    "open_holes",
    "default_params",
    "default_window",
]

#: Optimiser names (:data:`hyperlf.regularisers.OPTIMISERS`).
OPTIMIZERS = tuple(_reg.OPTIMISERS)
OCCLUSION_MODES = ("lr-plane", "lr-fill", "none")
#: The occlusion handling of :func:`stereo` by default (chosen on Venus: BENCHMARKS.md).
DEFAULT_OCCLUSION = "lr-plane"

# Two-view's own fallback parameters per optimiser, in units of the normalised data term
# (module doc, step 4); graph cuts run coarse to fine (``levels=2``).
_BASE_PARAMS: dict[str, dict[str, Any]] = {
    "wta": {},
    "sgm": {"p1": 0.5, "p2": 2.0, "paths": 8, "smoothness": "p1p2"},
    "graphcut": {"smoothness": "truncated_linear", "weight": 1.0, "truncation": 2.0,
                 "edge_sigma": None, "max_cycles": 3, "levels": 2},
}

def default_window(metric: str, optimizer: str) -> int | None:
    """The default cost window of ``(metric, optimizer)``.

    The cost's :meth:`~hyperlf.costs.Cost.default_window` (None = the cost's own default).

    Examples
    --------
    >>> from hyperlf.twoview import default_window
    >>> default_window("census", "graphcut")
    7
    """
    cost = _costs.get_cost(metric)
    return cost.default_window(_check_optimizer(optimizer))


def default_params(metric: str, optimizer: str) -> dict:
    """The default optimiser parameters of two-view stereo for ``(metric, optimizer)``.

    The optimiser's two-view fallback updated with the cost's own tuned values
    (:attr:`hyperlf.costs.Cost.params`); a fresh dict, in units of the normalised data term.

    Examples
    --------
    >>> from hyperlf.twoview import default_params
    >>> p = default_params("census-rsncc", "graphcut")
    >>> p["weight"], p["truncation"], p["levels"]
    (2.0, 4.0, 2)
    """
    cost = _costs.get_cost(metric)
    opt = _check_optimizer(optimizer)
    return {**_BASE_PARAMS[opt], **cost.default_params(opt)}


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
        Confidence in [0, 1] (module docstring; 0 where not LR-consistent and on the map's
        depth edges).
    timings : dict
        Seconds: ``cost`` (both volumes), ``optimiser`` (both references), ``total``.
    metric, optimizer, occlusion : str
        What was run (``metric`` resolved, e.g. ``"auto"`` -> ``"census-rsncc"``).
    params : dict
        The optimiser parameters actually used (defaults merged with the caller's).
    window : int or None
        Cost window (None: the metric's default).
    disparity_range : (int, int)
    right_disparity : float32 (H, W) or None
        Right-view disparity map (integer labels) when the left-right check ran.
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

    Parameters
    ----------
    left, right : array_like, (H, W) or (H, W, K)
    channel : None, int or (int, int)
        None: 2-D inputs as they are, colour inputs reduced to the mean of their channels; an
        int: the same channel of both; a pair: ``(left_channel, right_channel)``.

    Returns
    -------
    (ndarray, ndarray)
        float32 (H, W) each.

    Raises
    ------
    InvalidInputError
        Different sizes, a channel out of range, non-finite values, images under 2 x 2.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.twoview import select_channels
    >>> rgb = np.ones((4, 5, 3))
    >>> [a.shape for a in select_channels(rgb, rgb, channel=(0, 2))]
    [(4, 5), (4, 5)]
    """
    if channel is None or isinstance(channel, (int, np.integer)):
        cl = cr = channel
    else:
        try:
            cl, cr = channel
        except (TypeError, ValueError):
            raise InvalidInputError(
                f"channel must be None, an int or a pair (left, right), got {shown(channel)}") from None
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
        p.update(mapping(params, "params"))
    _reg.make_params(optimizer, p)
    return p


# ----------------------------------------------------------------------------------------------
# volumes
# ----------------------------------------------------------------------------------------------

def compute_volumes(left, right, dmin: int, dmax: int, metric: str = "auto", *, window=None,
                    need_right: bool = True, cost_params: dict | None = None):
    """Left- and right-referenced cost volumes ``(C_L, C_R)`` of two 2-D images.

    Parameters
    ----------
    left, right : ndarray (H, W)
    dmin, dmax : int
        Left ``x`` is compared with right ``x - d`` for ``d = dmin..dmax``.
    metric : str
        A cost of the registry (:func:`hyperlf.costs.cost_names`) or ``"auto"``.
    window : int, optional
        The cost's window (None: its default).
    need_right : bool
        Also return ``C_R`` (else None).
    cost_params : dict, optional
        Options of the cost (:func:`hyperlf.costs.cost_volumes`).

    Returns
    -------
    (ndarray, ndarray or None)
        float32 ``(dmax - dmin + 1, H, W)`` volumes, lower is better.  Why the re-referencing
        is exact: the module docstring (step 3) and :meth:`hyperlf.costs.Cost.pair_volumes`.

    Examples
    --------
    A random texture seen 3 px further left in the right image: the cheapest label is 3, and
    the right-referenced volume is the left one read at ``x_r + d``.

    >>> import numpy as np
    >>> from hyperlf.twoview import compute_volumes
    >>> scene = np.random.default_rng(0).random((24, 48)) + 0.1
    >>> left, right = scene[:, 4:36], scene[:, 7:39]   # left x matches right x - 3
    >>> cl, cr = compute_volumes(left, right, 0, 6, "ssd")
    >>> cl.shape, float(np.median(cl.argmin(axis=0)))
    ((7, 24, 32), 3.0)
    >>> bool(np.array_equal(cr[3][:, :-3], cl[3][:, 3:]))   # C_R[d, y, x] = C_L[d, y, x + d]
    True
    """
    mapping(cost_params, "cost_params")
    return _costs.cost_volumes(left, right, dmin, dmax, metric, window=window,
                               need_right=need_right, **(cost_params or {}))


def _data_scale(cost_left: np.ndarray, dmin: int) -> float:
    Lc, H, W = cost_left.shape
    valid = _costs.candidate_validity((H, W), dmin, dmin + Lc - 1)
    vals = cost_left[valid]
    s = float(vals.std(dtype=np.float64)) if vals.size else 0.0
    return s if s > 0 and np.isfinite(s) else 1.0


def _right_volume(cost_right, shape: tuple, occlusion: str, guide_left):
    """The right-referenced volume the occlusion handling needs (None for ``"none"``),
    checked with what the fill needs before any solve starts."""
    if occlusion == "none":
        return None
    if cost_right is None:
        raise InvalidInputError(f"occlusion={occlusion!r} needs the right-referenced volume")
    if occlusion == "lr-plane" and guide_left is None:
        raise InvalidInputError("occlusion='lr-plane' needs guide_left (the left image): "
                                "pass it, or use occlusion='lr-fill'")
    cr = real_array(cost_right, "cost_right", np.float32)
    if cr.shape != shape:
        raise InvalidInputError(f"cost_right shape {cr.shape} != cost_left shape {shape}")
    return cr


def _scaled_data(cost: np.ndarray, s: float, overwrite: bool) -> np.ndarray:
    """The data term of ``cost`` divided by the volume's spread ``s``."""
    D = _reg.data_term(cost, overwrite=overwrite)
    D /= np.float32(s)  # in place: one volume-sized temporary fewer
    return D


def _optimise(D: np.ndarray, params, guide, labels, subpixel: bool, progress: bool):
    """Return (integer label map, float disparity, volume used for confidence)."""
    res = _reg.optimise(D, params, guide=guide, labels=labels, progress=progress)
    return res.labels, _label_disparity(res.volume, res.labels, labels, subpixel), res.volume


def _label_disparity(volume, f, labels, subpixel: bool) -> np.ndarray:
    """The disparity of label map ``f``, refined on ``volume`` when ``subpixel``."""
    if subpixel:
        return _reg.subpixel_refine(volume, f, labels)
    return labels[f].astype(np.float32)


def open_holes(data, label_map, params, *, data_right=None, label_map_right=None,
               guide=None, guide_right=None, labels=None, hole_params=None):
    """Step 5 of :func:`stereo` under graph cuts, when asked for: the holes that graph cuts
    filled with the foreground around them, opened from a second solve at a weaker
    smoothness.

    A hole's outline costs graph cuts more than its few pixels of background vouch for, so
    the foreground flows in.  ``data`` is solved again with ``hole_params.weight_share`` of
    ``params.weight``; where the second answer is farther,
    :func:`hyperlf.regularisers.enclosed_background` finds the components enclosed by
    ``label_map``'s foreground that the data term prefers
    (:func:`hyperlf.regularisers.label_saving` above ``min_support``), on which the second
    answer holds one depth (``coherent``: over weak or repeated texture it scatters over
    several, and that is no hole) and, with the right-referenced ``data_right`` and
    ``hole_params.consistent``, on more than half of which the two second answers pass the
    left-right check (1 px); these take the second answer's labels.  The right map
    ``label_map_right`` is opened by the same rule.  Unless ``hole_params.enabled`` (on by
    default), and for anything but graph cuts or a zero weight, the maps are returned as
    they are.

    Parameters
    ----------
    data : ndarray, float32 (L, H, W)
        The left-referenced data term graph cuts solved (module docstring, step 4).
    label_map : ndarray of int (H, W)
        Graph cuts' labels of the left view.
    params : GraphCutParams
        Graph cuts' parameters (other optimisers: nothing to open).
    data_right, label_map_right : optional
        The same for the right view (both or neither).
    guide, guide_right : ndarray (H, W) or (H, W, K), optional
        The views' images, as for the first solves.
    labels : ndarray (L,), optional
        The disparity of each label (default ``0..L-1``).
    hole_params : HoleParams, optional
        :class:`hyperlf.regularisers.HoleParams` (None: its defaults, with the step on).

    Returns
    -------
    label_map, label_map_right : ndarray of int (H, W)
        ``label_map_right`` None when not given.
    opened : ndarray of bool (H, W)
        The left view's pixels that took the second answer.

    Examples
    --------
    A wall (label 0) seen through a 6 x 6 hole in a square (label 5): the hole's 36 pixels
    save 72 at the wall's label, and its outline of 24 edges costs 96 at graph cuts' weight
    (2 per label step, truncated at 2) and 48 at half of it:

    >>> import numpy as np
    >>> from hyperlf.regularisers import GraphCutParams, HoleParams, optimise
    >>> steps = np.arange(6.0)[:, None, None]
    >>> square = np.zeros((24, 24), bool); square[4:20, 4:20] = True
    >>> hole = np.zeros((24, 24), bool); hole[9:15, 9:15] = True
    >>> want = np.where(square & ~hole, 5, 0)
    >>> data = np.minimum(abs(steps - want), 2).astype(np.float32)
    >>> params = GraphCutParams(weight=2.0, truncation=2.0, levels=0)
    >>> f = optimise(data, params).labels
    >>> int(f[hole].min())
    5
    >>> f2, _, opened = open_holes(data, f, params, hole_params=HoleParams(enabled=True))
    >>> int(f2[hole].max()), bool(opened[~hole].any())
    (0, False)
    """
    hp = params_of(hole_params, "hole_params", _reg.HoleParams)
    if (data_right is None) != (label_map_right is None):
        raise InvalidInputError("give data_right and label_map_right together, or neither")
    data = check_cost(data, "data")
    L, H, W = data.shape
    maps = [check_label_map(label_map, L, H, W, "label_map")]
    if data_right is not None:
        data_right = check_cost(data_right, "data_right")
        if data_right.shape != data.shape:
            raise InvalidInputError(f"data_right shape {data_right.shape} != data shape "
                                    f"{data.shape}")
        maps.append(check_label_map(label_map_right, L, H, W, "label_map_right"))
    labels = check_labels(labels, L)
    off = not (hp.enabled and isinstance(params, _reg.GraphCutParams) and params.weight > 0)
    if off:
        return maps[0], (maps[1] if len(maps) > 1 else None), np.zeros(maps[0].shape, bool)
    weaker = replace(params, weight=params.weight * hp.weight_share)
    volumes = [data] + ([] if data_right is None else [data_right])
    second = [_reg.optimise(v, weaker, guide=g, labels=labels).labels
              for v, g in zip(volumes, (guide, guide_right))]
    trusted = [None] * len(maps)
    if len(maps) == 2 and hp.consistent:
        dl, dr = labels[second[0]], labels[second[1]]
        trusted = [_reg.left_right_check(dl, dr),
                   _reg.left_right_check(dr[:, ::-1], dl[:, ::-1])[:, ::-1]]
    out = []
    for v, f, s2, t in zip(volumes, maps, second, trusted):
        d, p = labels[f], labels[s2]
        opened = _reg.enclosed_background(
            d, p, jump=hp.jump, touch=hp.touch, min_size=hp.min_size,
            support=_reg.label_saving(v, labels, d, p), min_support=hp.min_support,
            trusted=t, coherent=hp.coherent)
        out.append((np.where(opened, s2, f), opened))
    return out[0][0], (out[1][0] if len(out) > 1 else None), out[0][1]


def _disparity_map(value, label: str) -> np.ndarray:
    """``value`` as a 2-D real map in its own dtype (an array is used as it is)."""
    d = real_array(value, label, None)
    if d.ndim != 2 or d.dtype.kind not in "biuf":
        raise InvalidInputError(f"{label} must be a 2-D disparity map, got {shown(value)}")
    return d


def _value_range(value, label: str) -> tuple[float, float]:
    """``(low, high)``: two numbers, not NaN, ``low <= high`` (infinite ends allowed)."""
    pair = real_array(value, label)
    if pair.shape != (2,) or np.isnan(pair).any() or pair[0] > pair[1]:
        raise InvalidInputError(f"{label} must be (low, high), two numbers with low <= high "
                                f"(infinite ends allowed), got {shown(value)}")
    return value if isinstance(value, tuple) and len(value) == 2 else (pair[0], pair[1])


def fill_inconsistent(disp_l, disp_r, valid, occlusion: str, guide, plane_params=None,
                      drange=(-np.inf, np.inf)):
    """Step 6 after the left-right check (module docstring): the background fill, and for
    ``occlusion="lr-plane"`` the plane of their region for the mismatches, then the guided
    weighted median of the filled map at every inconsistent pixel.

    Parameters
    ----------
    disp_l, disp_r : ndarray (H, W)
        Left disparity (before any fill) and the right view's disparity.
    valid : ndarray of bool (H, W)
        :func:`hyperlf.regularisers.left_right_check` of the two.
    occlusion : {"lr-plane", "lr-fill"}
    guide : ndarray (H, W)
        The left image (its regions carry the planes).
    plane_params : PlaneFillParams, optional
        Constants of the planes and of the median (``"lr-plane"`` only).
    drange : (float, float)
        Plane values are clipped to it.

    Returns
    -------
    (ndarray, ndarray of bool)
        The filled map, and the pixels that got a plane value.

    Examples
    --------
    Two inconsistent pixels between a near surface (4) and a far one (1) take the far one,
    the background:

    >>> import numpy as np
    >>> from hyperlf.twoview import fill_inconsistent
    >>> d = np.array([[4.0, 4.0, 9.0, 9.0, 1.0, 1.0]] * 3)
    >>> valid = np.array([[True, True, False, False, True, True]] * 3)
    >>> filled, planes = fill_inconsistent(d, d, valid, "lr-fill", np.ones((3, 6)))
    >>> filled[0].tolist(), bool(planes.any())
    ([4.0, 4.0, 1.0, 1.0, 1.0, 1.0], False)
    """
    disp_l, disp_r = _disparity_map(disp_l, "disp_l"), _disparity_map(disp_r, "disp_r")
    if disp_r.shape != disp_l.shape:
        raise InvalidInputError(f"disp_r has shape {disp_r.shape}, disp_l {disp_l.shape}: they "
                                f"must match")
    valid = bool_mask(valid, "valid", disp_l.shape, of="disp_l")
    choice(occlusion, "occlusion", ("lr-plane", "lr-fill"))
    if plane_params is not None:
        params_of(plane_params, "plane_params", _reg.PlaneFillParams)
    drange = _value_range(drange, "drange")
    replaced = np.zeros(valid.shape, dtype=bool)
    if not valid.any():  # nothing consistent: keep the left map rather than fail
        return disp_l.copy(), replaced
    final = _reg.fill_occlusions(disp_l, valid)
    if occlusion == "lr-plane":
        mismatch = ~valid & ~_reg.left_occlusions(disp_r)
        planes, replaced = _reg.plane_fill(disp_l, valid, guide, targets=mismatch,
                                           params=plane_params)
        final = np.where(replaced, np.clip(planes, *drange), final).astype(final.dtype)
        final = _median_of_filled(final, valid, guide, plane_params)
    return final, replaced


def _median_of_filled(disp, valid, guide, params) -> np.ndarray:
    """The inconsistent pixels of a filled map take its guided weighted median
    (``params.median_radius``, 0: off; :class:`hyperlf.regularisers.PlaneFillParams`)."""
    p = params or _reg.PlaneFillParams()
    if p.median_radius == 0:
        return disp
    radius = min(p.median_radius, max(disp.shape))
    median = _reg.weighted_median(disp, guide, radius=radius, sigma=p.median_sigma, mask=~valid)
    return np.where(valid, disp, median).astype(disp.dtype)


def stereo_from_volumes(cost_left, cost_right, dmin: int, optimizer: str = "graphcut",
                        occlusion: str = DEFAULT_OCCLUSION, *, params: dict | None = None,
                        guide_left=None, guide_right=None, subpixel: bool = False,
                        metric: str = "auto", progress: bool = False,
                        plane_params: _reg.PlaneFillParams | None = None,
                        confidence_params: _reg.ConfidenceParams | None = None,
                        hole_params: _reg.HoleParams | None = None,
                        overwrite: bool = False) -> StereoResult:
    """Steps 4-7 of the pipeline on precomputed volumes (see :func:`compute_volumes`).

    Parameters
    ----------
    cost_left, cost_right : ndarray (L, H, W)
        Left- and right-referenced volumes (``cost_right`` may be None with
        ``occlusion="none"``).
    dmin : int
        Disparity of label 0.
    optimizer, occlusion, params, subpixel, progress
        As :func:`stereo`; ``params`` override :func:`default_params` of ``metric``.
    guide_left, guide_right : ndarray (H, W), optional
        The input images, for the graph-cut edge weights (``guide_left`` is required by
        ``occlusion="lr-plane"``: its regions carry the planes).
    metric : str
        Recorded, and used to look up the default parameters.
    plane_params : PlaneFillParams, optional
        Constants of the ``"lr-plane"`` fill (:class:`hyperlf.regularisers.PlaneFillParams`).
    confidence_params : ConfidenceParams, optional
        Constants of the confidence (:class:`hyperlf.regularisers.ConfidenceParams`; default
        its defaults).
    hole_params : HoleParams, optional
        Graph cuts' holes step (:func:`open_holes`; default
        :class:`hyperlf.regularisers.HoleParams`'s: on).
    overwrite : bool
        The volumes are not used again: float32 ones then hold the data terms (two
        volume-sized copies fewer; the result is the same).

    Returns
    -------
    StereoResult
        ``timings`` holds only ``optimiser``; ``extra["plane_filled"]`` the share of pixels
        the ``"lr-plane"`` fill gave a plane value, ``extra["holes_opened"]`` the share of
        the left map's pixels :func:`open_holes` opened.

    Examples
    --------
    The volumes of a pair 3 px apart (see :func:`compute_volumes`): the map is 3 px, and the
    left-right check keeps nearly every pixel but those of the 3 columns at the left edge,
    which the right image does not see.

    >>> import numpy as np
    >>> from hyperlf.twoview import compute_volumes, stereo_from_volumes
    >>> scene = np.random.default_rng(0).random((24, 48)) + 0.1
    >>> left, right = scene[:, 4:36], scene[:, 7:39]   # left x matches right x - 3
    >>> cl, cr = compute_volumes(left, right, -2, 6, "ssd")
    >>> res = stereo_from_volumes(cl, cr, -2, "wta", "lr-fill", guide_left=left)
    >>> res.disparity_range, float(np.median(res.disparity))
    ((-2, 6), 3.0)
    >>> bool(res.valid[:, 3:].mean() > 0.95), bool(res.valid[:, :3].mean() < 0.2)
    (True, True)
    """
    optimizer = _check_optimizer(optimizer)
    occlusion = _check_occlusion(occlusion)
    cp = params_of(confidence_params, "confidence_params", _reg.ConfidenceParams)
    plane_params = params_of(plane_params, "plane_params", _reg.PlaneFillParams)
    hole_params = params_of(hole_params, "hole_params", _reg.HoleParams)
    name = _costs.resolve_metric(metric)
    p = _merge_params(name, optimizer, params)
    opt = _reg.make_params(optimizer, p)
    dmin = integer(dmin, "dmin", minimum=-MAX_DISPARITY, maximum=MAX_DISPARITY)
    subpixel, overwrite = flag(subpixel, "subpixel"), flag(overwrite, "overwrite")
    progress = flag(progress, "progress")
    cl = real_array(cost_left, "cost_left", np.float32)
    if cl.ndim != 3:
        raise InvalidInputError(f"cost_left must be (L, H, W), got {cl.shape}")
    for guide, label in ((guide_left, "guide_left"), (guide_right, "guide_right")):
        if guide is not None:  # checked before any solve, and named
            check_guide(guide, *cl.shape[1:], label)
    cr = _right_volume(cost_right, cl.shape, occlusion, guide_left)
    Lc = cl.shape[0]
    labels = np.arange(dmin, dmin + Lc, dtype=np.float64)
    s = _data_scale(cl, dmin)
    t0 = time.perf_counter()
    fl, disp_l, vol_l = _optimise(_scaled_data(cl, s, overwrite), opt, guide_left, labels,
                                  subpixel, progress)
    disp_r = None
    replaced = np.zeros(disp_l.shape, dtype=bool)
    if cr is not None:
        Dr = _scaled_data(cr, s, overwrite)
        fr, _, _ = _optimise(Dr, opt, guide_right, labels, False, progress)
    else:
        Dr = fr = None
    opened = np.zeros(disp_l.shape, dtype=bool)
    if hole_params.enabled:  # off: no second look at either volume
        fl, fr, opened = open_holes(vol_l, fl, opt, data_right=Dr, label_map_right=fr,
                                    guide=guide_left, guide_right=guide_right,
                                    labels=labels, hole_params=hole_params)
        if opened.any():
            disp_l = _label_disparity(vol_l, fl, labels, subpixel)
    del Dr
    conf = _reg.confidence(vol_l, fl, floor=cp.floor)
    if cr is not None:
        disp_r = labels[fr].astype(np.float32)
        valid = _reg.left_right_check(labels[fl], disp_r, tol=1.0)
        final, replaced = fill_inconsistent(disp_l, disp_r, valid, occlusion, guide_left,
                                             plane_params, (labels[0], labels[-1]))
        conf = np.where(valid, conf, 0.0).astype(np.float32)
    else:
        valid = np.ones(disp_l.shape, dtype=bool)
        final = disp_l.copy()
    conf *= _reg.edge_confidence(final, width=cp.edge_px, jump=cp.edge_jump)
    t_opt = time.perf_counter() - t0
    return StereoResult(disparity=np.asarray(final, np.float32), raw=np.asarray(disp_l, np.float32),
                        valid=valid, confidence=conf, timings={"optimiser": t_opt}, metric=name,
                        optimizer=optimizer, params=p, occlusion=occlusion,
                        disparity_range=(int(dmin), int(dmin + Lc - 1)), right_disparity=disp_r,
                        extra={"data_scale": s, "plane_filled": float(replaced.mean()),
                               "holes_opened": float(opened.mean())})


def stereo(left, right, disparity_range, *, metric: str = "auto", optimizer: str = "graphcut",
           occlusion: str = DEFAULT_OCCLUSION, subpixel: bool = False, params: dict | None = None,
           window: int | None = None, channel=None, progress: bool = False,
           cost_params: dict | None = None,
           plane_params: _reg.PlaneFillParams | None = None,
           aggregation: _costs.AggregationParams | str | None = None,
           confidence_params: _reg.ConfidenceParams | None = None,
           hole_params: _reg.HoleParams | None = None) -> StereoResult:
    """Disparity of the left view of a rectified pair (SPEC §4; module docstring).

    Parameters
    ----------
    left, right : array_like, (H, W) or (H, W, K)
        Linear intensities (any positive scale).
    disparity_range : (int, int)
        ``(dmin, dmax)``, ``dmin < dmax``; left ``x`` matches right ``x - d``.
    metric : str
        A cost of the registry (:data:`hyperlf.costs.METRIC_NAMES`; ``"auto"`` = the library
        default).
    optimizer : {"graphcut", "sgm", "wta"}
        The names of :data:`hyperlf.regularisers.OPTIMISERS`.
    occlusion : {"lr-plane", "lr-fill", "none"}
        Left-right check, then the plane of their region for mismatches and the background
        fill for the rest (``"lr-plane"``, default), the background fill for all
        (``"lr-fill"``, the paper's protocol), or nothing (module docstring, step 6).
    subpixel : bool
        Parabola refinement of the chosen labels.
    params : dict, optional
        Optimiser parameters overriding :func:`default_params` (the fields of
        :class:`hyperlf.regularisers.SGMParams` / :class:`~hyperlf.regularisers.GraphCutParams`;
        graph cuts' ``levels`` = coarse-to-fine halvings, 0 = plain alpha-expansion), in units
        of the normalised data term.
    window : int, optional
        Cost window (odd); None uses :func:`default_window`.
    channel : None, int or (int, int)
        Channel(s) of colour inputs (:func:`select_channels`).
    progress : bool
        A progress bar during graph cuts.
    cost_params : dict, optional
        Extra options of the cost (:func:`hyperlf.costs.cost_volume`).
    plane_params : PlaneFillParams, optional
        Constants of the ``"lr-plane"`` fill (:class:`hyperlf.regularisers.PlaneFillParams`).
    aggregation : AggregationParams or str, optional
        Edge-aware aggregation of both volumes (:class:`hyperlf.costs.AggregationParams`, or a
        method name of :data:`hyperlf.costs.AGGREGATION_METHODS`); default ``"none"``.
    confidence_params : ConfidenceParams, optional
        Constants of the result's confidence (:class:`hyperlf.regularisers.ConfidenceParams`;
        default its defaults).
    hole_params : HoleParams, optional
        Graph cuts' holes step (:func:`open_holes`, :class:`hyperlf.regularisers.HoleParams`;
        ``HoleParams(enabled=False)`` turns it off); on by default.

    Returns
    -------
    StereoResult

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN, ``dmin >= dmax``, a range wider than the image, unknown names/params.

    References
    ----------
    .. [1] D. Scharstein, R. Szeliski, "A taxonomy and evaluation of dense two-frame stereo
       correspondence algorithms", IJCV 47, 2002 (the protocol and bad-pixel scores).
    .. [2] K. Zhu, Y. Xue, Q. Fu, S. B. Kang, X. Chen, J. Yu, "Hyperspectral Light Field Stereo
       Matching", IEEE TPAMI (Table 1: cross-spectral two-view stereo).

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.twoview import stereo
    >>> rng = np.random.default_rng(0)
    >>> scene = rng.random((24, 48)) + 0.1
    >>> left, right = scene[:, 4:36], scene[:, 7:39]   # left x matches right x - 3
    >>> res = stereo(left, right, (0, 6), optimizer="wta", occlusion="none")
    >>> float(np.median(res.disparity))
    3.0
    """
    t_all = time.perf_counter()
    name = _costs.resolve_metric(metric)
    optimizer = _check_optimizer(optimizer)
    occlusion = _check_occlusion(occlusion)
    L, R = select_channels(left, right, channel)
    dmin, dmax = _check_range(disparity_range, L.shape[1])
    params_of(confidence_params, "confidence_params", _reg.ConfidenceParams)
    params_of(plane_params, "plane_params", _reg.PlaneFillParams)
    params_of(hole_params, "hole_params", _reg.HoleParams)
    p = _merge_params(name, optimizer, params)
    if window is None:
        window = default_window(name, optimizer)
    if not isinstance(subpixel, (bool, np.bool_)):
        raise InvalidInputError(f"subpixel must be True or False, got {subpixel!r}")
    if L.mean() <= 0 or R.mean() <= 0:
        raise InvalidInputError("images must have a positive mean (linear intensities expected)")
    agg = _costs.AggregationParams.of(aggregation)
    t0 = time.perf_counter()
    cl, cr = compute_volumes(L, R, dmin, dmax, name, window=window,
                             need_right=(occlusion != "none"),
                             cost_params=cost_params)
    cl, cr = _costs.aggregate_pair(cl, cr, L, R, dmin, agg)
    t_cost = time.perf_counter() - t0
    res = stereo_from_volumes(cl, cr, dmin, optimizer, occlusion, params=p, guide_left=L,
                              guide_right=R, subpixel=bool(subpixel), metric=name, progress=progress,
                              plane_params=plane_params, confidence_params=confidence_params,
                              hole_params=hole_params, overwrite=True)
    res.window = window
    res.extra["aggregation"] = {"method": agg.method, "radius": agg.radius, "eps": agg.eps}
    res.timings = {"cost": t_cost, "optimiser": res.timings["optimiser"],
                   "total": time.perf_counter() - t_all}
    return res
