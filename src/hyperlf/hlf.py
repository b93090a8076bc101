"""H-LF stereo matching (SPEC §5, paper §5): correspondence + view selection + occlusion split
+ spectral-aware defocus + MRF, every cue switchable and measured.

One call::

    from hyperlf.hlf import depth
    res = depth(lf, n_labels=64)            # lf: a spectral LightField (views, wavelengths)
    res.disparity, res.confidence, res.f_c, res.f_d, res.timings, res.config

Pipeline (all shifts use view *positions*, SPEC §1)
---------------------------------------------------
Labels: ``n_labels`` disparities evenly spaced over ``[dmin, dmax]`` (argument, else
``lf.disparity_range``).  For label ``d`` and view ``v`` with offset ``o_v = pos_v - pos_ref``
the reference pixel ``p`` is compared with ``q_v = p - d o_v`` in view ``v``; the view's maps
are sampled there **bilinearly** (sub-pixel); candidates with ``q_v`` outside the image are
*masked* (excluded from every mean), never zero-filled.

**Validity masks** (``lf.valid``, SPEC §11): a view pixel without data counts exactly like a
sample outside the image, in every stage (rule: :mod:`hyperlf.costs.lightfield`; the views'
invalid pixels are filled from their nearest valid pixel and ``In`` divides by the mean over
valid pixels).  An invalid *reference* pixel, and a reference pixel that no valid sample of
any other view sees at any label, carries no information: its correspondence cost is uniform
over labels (the defocus cost too), so the MRF takes its label from the neighbours, and its
confidence is 0.  The unary normaliser ``s_X`` is the median over the informative pixels.

1. **Correspondence cost** ``C_v(p, d)`` per view ``v != ref``: the light-field form of a
   cost of the registry (:mod:`hyperlf.costs`, :func:`hyperlf.costs.view_costs`; how each is
   evaluated at sub-pixel shifts: :mod:`hyperlf.costs.lightfield`).  The default ``auto`` is
   ``census-rsncc``, ``(norm(rsncc 5x5) + norm(census 7x7)) / 2`` per view (RSNCC 3 x 3 on
   an array with at least ``params.dense_views`` other views:
   :func:`hyperlf.costs.light_field_window`; between views ``norm`` only scales, by the
   part's standard deviation over the whole view: a per-pixel minimum would depend on the
   labels at which the view sees the pixel, :attr:`hyperlf.costs.FusedCost.view_centre`);
   ``fused``, ``bwncc`` and ``bwncc-paper`` use the 612-channel descriptor and are much
   slower; ``ncc``, ``census`` and ``rsncc`` alone serve tests, quick looks and ablations.

2. **View selection** (SPEC §5.1, ``view_selection=True``; :func:`aggregate_view`): with
   ``M_v`` = gradient magnitude of ``In_v = I_v / mean(I_v)`` (central differences),
   **normalised per view by its median** (``params.selection_normalise``; fix of the prototype
   notes: gradient contrast depends on the band), ``Mbar(p, d)`` = mean of ``M_v(q_v)`` over
   the valid views, **including the reference** at ``p`` (``params.selection_include_ref``).
   If ``M_ref(p) > Mbar`` the views with ``M_v(q_v) > Mbar`` are selected, else those with
   ``M_v(q_v) <= Mbar``.  Fewer than ``params.min_selected`` selected views (default 3; never
   0) -> all valid views.  ``C(p, d)`` = mean of ``C_v`` over the chosen views.  Two passes:
   ``Mbar`` first (cheap), then the per-view costs stream into accumulators, so the memory is
   a few ``(L, H, W)`` float32 arrays whatever the number of views (no ``(n_views, L, H, W)``
   array is ever held: at 512 x 512 x 64 labels x 29 views that would be 1.9 GB).

3. **Occlusion-aware split** (SPEC §5.2, ``occlusion_split=True``): Canny edges of the
   reference (``In_ref`` scaled to 8 bits, Gaussian pre-blur ``params.canny_sigma``,
   thresholds ``params.canny_high`` / ``canny_low`` percentiles of the Sobel magnitude unless
   given), dilated by ``params.edge_dilate`` px.  The edge orientation is perpendicular to the
   Sobel gradient ``g`` of the blurred reference; the line through ``pos_ref`` along the edge
   splits the views by ``sign(g . o_v)`` (views on the line go to both halves).  ``C1, C2`` =
   means over the chosen (selected, or all on fallback) views of each half; at edge pixels
   ``C = min(C1, C2)`` over halves with at least ``params.min_half_views`` views.
   ``f*_c = argmin_d C``.

4. **Spectral-aware defocus** (SPEC §5.3, ``defocus=...``; :func:`defocus_cost`):
   profile ``P(lambda_v) = In_v(q_v)`` over all (valid) views including the reference; colour
   ``V_k = sum_v P S_k / sum_v S_k`` with the reference camera ``params.camera`` (default
   ``"CIE 1931"`` = XYZ; a named RGB camera's values are taken as linear sRGB and converted to
   XYZ before the chromaticity); ``lambda_r`` = dominant wavelength on the CIE 1931 locus,
   white E (:func:`hyperlf.spectral.dominant_wavelength_for_filters`: purples -> nearer end of
   the filter range, achromatic (``params.achromatic_radius``) -> middle, always clipped to
   the filter range); ``Pg`` Gaussian, ``sigma_d = 96.5`` nm, at the views' wavelengths,
   normalised to 1; ``P* = max(P / sum P, eps)``; ``D = sum Pg log(Pg / P*)``.

   * ``"paper"``: the Gaussian prior with ``lambda_r`` recomputed at every ``(p, d)`` (literal).
   * ``"gaussian"``: the Gaussian prior with ``lambda_r`` once per pixel, from the profile at
     ``f*_c`` (fix; ``params.lambda_r`` = ``"per_label"`` / ``"per_pixel"`` / a number in nm
     overrides either).
   * ``"flat"``: KL from a flat prior (``Pg = 1/n``).
   * ``"tv"``: total variation of ``P*`` along sorted wavelength (spectral smoothness).
   * ``"off"``: no defocus term (``f_d`` is None).

   Always (the literal formula is undefined otherwise): ``Pg`` and ``P*`` are renormalised over
   the valid (in-image) views of each ``(p, d)``, and ``P*`` is floored at ``params.p_eps``.
   ``f*_d = argmin_d D``.

5. **MRF** (SPEC §5.4): ``U = gamma_c (C - C(f*_c)) / s_C + (D - D(f*_d)) / s_D`` with
   ``s_X`` the median over pixels of the per-pixel range ``max_d X - min_d X``
   (``params.normalise_costs``; ``False`` = literal, ``s = 1``).  ``gamma_c`` default 0.45
   (synthetic; 0.6 for real captures).  Pairwise ``lambda w_pq min(|d_p - d_q|, T)``,
   ``w_pq`` contrast-sensitive on the reference ``In`` (:func:`hyperlf.regularisers.graphcut`
   guide) times ``params.occlusion_weight`` across detected occlusion boundaries (an edge
   pixel of step 3 next to a jump of ``f*_c`` larger than ``T / 2``).  ``optimizer`` =
   ``"graphcut"`` (alpha-expansion), ``"sgm"`` (8 paths, truncated linear, P1 = lambda x
   label step, P2 = lambda T) or ``"wta"``.  Sub-pixel: parabola through the optimised volume
   (``U``; the SGM-aggregated volume for SGM) around the winning label.  Confidence:
   :func:`hyperlf.regularisers.confidence` of that volume, from ``params.confidence_floor``
   up (a seen pixel whose margin is 0 still ranks above the unseen ones).

   **Textureless regions** (:func:`texture_weight`, ``params.texture_snr``): a reference pixel
   whose matching window holds less texture than ``texture_snr`` times the sensor noise
   (estimated on the reference view) has ``U`` scaled down (to 0 where the window's texture
   variance is below the noise variance), and its confidence too.  There every cost is
   noise, and a large such region (a white table) would otherwise take whichever label
   chance favours, often a range limit (fewer views see the extreme shifts); with its data
   term gone it takes its label from its surroundings through the pairwise term.  On by
   default for captures made from camera images (``hyperlf ingest``), off for rendered and
   synthetic light fields (see :class:`DepthParams`) and under ``"wta"``.
   **Coarse prior** (:func:`add_coarse_prior`, ``params.coarse_prior``): what a weakly
   textured pixel loses of its data term, ``1 - w``, it gets back as a pull towards the
   disparity of the same depth run on the light field downscaled by
   ``params.coarse_prior_scale`` (:func:`coarse_disparity`; ``params.coarse_prior_levels``
   nested levels, default 1), where that level's reference is textured: block means lower
   the noise, so a white table that holds no texture at the pixel holds some a few pixels
   wide.  Without it such a region is filled with one constant from whatever surrounds it,
   not with its own (often slanted) surface.  The confidence is then
   ``w c + (1 - w) c_s``: the pixel's own cost margin ``c`` for the share of the data term
   it kept, the coarse run's confidence ``c_s`` (itself scaled by that level's texture
   weight) for the rest, so that it is 0 where every level filled the depth in from the
   surroundings.  Under graph cuts ``c`` is measured on ``U`` with the prior's pull taken
   out (:func:`refine`'s ``prior``): the pull is the coarse run's evidence, counted once
   through ``c_s``, and would otherwise give a weakly textured pixel a clear margin at the
   coarse estimate's label however little its own window says.  (Under SGM the aggregated
   volume holds the pull spread over the paths like every neighbour's vote; its margin is
   kept as it is.)  With ``params.weak_planes`` (the default) the pull's target on pixels
   weak at every level, and on specks of texture among them (``params.plane_specks``), is a
   slanted plane that the pooled costs of such pixels choose, tile by tile, at the coarse
   prior's scale (:func:`plane_prior`).

6. **Post-filter**: the guided weighted median (:func:`post_filter`).

7. **Visibility-aware re-matching** (SPEC §5.6, ``params.visibility_rounds``; default
   :data:`DEFAULT_ROUNDS` rounds on images at least ``params.visibility_min_size`` px on
   their shorter side, none on smaller ones): the
   disparity so far is forward-warped into every view (z-buffer,
   :func:`hyperlf.warp.occlusion_zbuffer`), each view counts only at the reference pixels
   and candidate disparities at which it sees them (:class:`LabelVisibility`; with
   ``params.visibility_test="estimate"`` at the estimate's disparity only,
   :func:`visible_views`), and stages 2 and 4-6 run again on that volume; the defocus
   volume and the texture weight are kept.
   The first round starts from a quick depth run at half resolution
   (:func:`coarse_disparity`), so that one round costs about 1/8 of a pass more than none.
   A further round averages the kept per-view costs of the pass before again
   (:class:`ViewCostStore`, when they fit in ``params.reuse_memory``) and runs stages 4-6,
   its graph cut starting from the labels of the pass before (``params.round_cycles``).

8. **Thin objects** (graph cuts only, ``params.thin_objects``; :func:`thin_objects`, after
   the last round): SGM runs on the last round's unary too, and where its answer holds an
   8-connected component nearer than graph cuts' that meets graph cuts' surface at its own
   depth on under ``params.thin_touch`` of its outline and that the unary prefers
   (:func:`hyperlf.regularisers.thin_foreground`), its values replace graph cuts'.  Graph
   cuts charge a rod's whole outline against its few pixels of evidence and give rods faint
   in the reference band to the background; SGM keeps them but fattens edges elsewhere.
   With ``params.thin_holes`` the same rule, sides swapped and with its own outline share
   ``params.thin_hole_touch``, takes back the background that graph cuts filled with the
   foreground around it: a ring's hole, a gap between a rod and a box
   (:func:`hyperlf.regularisers.enclosed_background`).

9. **Confidence at depth edges** (:func:`edge_discount`, after the last round): the
   confidence is scaled by :func:`hyperlf.regularisers.edge_confidence` of the final
   disparity, 0 on an estimated depth edge and 1 from ``params.confidence_edge_px`` px away.
   The cost margin does not see the depth edges, where nearly all of the error gathers.

Defaults
--------
Every cue of 2-4 has an on/off switch, and a cue that did not lower the error on the tuning
scenes is **off by default** (SPEC §5): view selection, the occlusion split and defocus are
all off, ``occlusion_weight = 1``.  The measurements behind each default (Table 2 ablations)
are in BENCHMARKS.md.

Memory
------
The per-view volumes are streamed into a few ``(L, H, W)`` float32 accumulators (plus, for
``bwncc``, two float64 ones and one descriptor block of two views); an
``(n_views, L, H, W)`` array is never formed.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from ._kernel_args import kernel_input
from ._progress import progress_bar
from . import _options as _opt
from . import spectral as _spectral
from .costs import (DENSE_VIEWS, ROW_BLOCK, AggregationParams, aggregate_volume, cost_names,
                    fusion_weights, get_cost, light_field_window, tap_validity, view_costs)
from .imageops import fill_masked, gradient_magnitude, normalise_intensity
from .warp import shift_map
from .errors import InvalidInputError
from .tiling import check_label_volume
from . import regularisers as _reg

__all__ = [
    "DepthParams",
    "DepthResult",
    "DepthProblem",
    "depth",
    "prepare",
    "correspondence",
    "defocus_cue",
    "neutral_missing_views",
    "views_at_every_label",
    "plane_prior",
    "texture_weight",
    "coarse_prior",
    "add_coarse_prior",
    "unary",
    "regularise",
    "refine",
    "prior_free_confidence",
    "post_filter",
    "edge_discount",
    "median_passes",
    "guide_noise",
    "seen_pixels",
    "visible_views",
    "LabelVisibility",
    "visibility",
    "occluder_margins",
    "VISIBILITY_TESTS",
    "NEAREST_OCCLUDERS",
    "DEFAULT_ROUNDS",
    "make_labels",
    "with_margin",
    "range_labels",
    "view_costs",
    "shift_map",
    "selection_masks",
    "aggregate_view",
    "aggregate_view_reference",
    "half_plane_sides",
    "reference_edges",
    "defocus_cost",
    "defocus_cost_reference",
    "defocus_volume",
    "normalise_unary",
    "DEFOCUS_MODES",
    "OPTIMIZERS",
    "CORR_METRICS",
]

DEFOCUS_MODES = ("off", "paper", "gaussian", "flat", "tv")
#: How a visibility round decides which views see a reference pixel
#: (``DepthParams.visibility_test``): at every candidate disparity (:class:`LabelVisibility`)
#: or at the current estimate's only (:func:`visible_views`).
VISIBILITY_TESTS = ("hypothesis", "estimate")
#: Which visibility passes match a hypothesis that too few views see over the views with the
#: nearest occluders instead of every view (``DepthParams.nearest_occluders``): none, every
#: pass but the last, or every pass.
NEAREST_OCCLUDERS = ("never", "before-last", "always")
#: The values of ``DepthParams.missing_views``.
MISSING_VIEWS = ("average", "neutral", "common")
#: The values of ``DepthParams.unseen_labels`` (:func:`hyperlf.regularisers.fill_invalid`'s).
UNSEEN_LABELS = ("share", "worst", "median")
#: Visibility rounds when ``DepthParams.visibility_rounds`` is None, on images at least
#: ``DepthParams.visibility_min_size`` px on their shorter side whose costs can be kept
#: (:func:`_default_rounds`; BENCHMARKS.md, thirty-eighth session).
DEFAULT_ROUNDS = 3
OPTIMIZERS = tuple(_reg.OPTIMISERS)
#: The costs available for H-LF matching (those of the registry with a light-field evaluator;
#: :func:`hyperlf.costs.cost_names` with ``light_field=True`` is the live list).
CORR_METRICS = cost_names(light_field=True)
_PRIOR_CODE = {"gaussian": 0, "flat": 1, "tv": 2}
#: ``DepthParams.texture_snr`` used by default for captures made from camera images.
CAMERA_TEXTURE_SNR = 2.0


# ============================================================================================
# Parameters and result
# ============================================================================================

_rule = _opt.rule
_number, _count, _flag = _opt.number, _opt.integer, _opt.flag
_positive = _rule(_opt.number, positive=True)

#: Shortest side (px) of a guide whose noise :func:`median_passes` reads: on smaller renders
#: the aliased texture's fine scale passes for noise (procedural 40 x 48 scenes read 8-73 % of
#: their mean, 64 x 64 ones up to 1 %, 96 x 128 and larger ones 0; BENCHMARKS.md, fifty-fifth
#: session).
NOISE_MIN_SIDE = 128

#: Most passes of the guided median (``median_passes``, :func:`post_filter`): each moves an
#: edge by at most a radius; far beyond the image's size in passes the loop would only spin.
MAX_MEDIAN_PASSES = 50
#: Most labels beyond each end of the range (``DepthParams.margin_labels``).
MAX_MARGIN_LABELS = 64
#: The texture weight (:func:`texture_weight`) from which a pixel's data term counts for
#: :func:`thin_objects`: the unary's scale is taken over such pixels, and more than half of
#: a taken component must be such pixels.
TRUSTED_WEIGHT = 0.5


# ============================================================================================
# Checks of the stages' arguments (one line of InvalidInputError before any work)
# ============================================================================================

#: Widths of :func:`add_coarse_prior`'s pull (disparity px) it takes: float32 keeps their
#: quotients finite.
PULL_WIDTH = (1e-9, 1e9)
#: The range of ``sigma_d`` (nm) of the defocus prior (:class:`DepthParams`,
#: :func:`defocus_cost`): narrower, ``sigma_d ** 2`` underflows and the prior is 0 / 0.
SIGMA_D_RANGE = (1e-3, 1e6)
_sigma_d = _rule(_opt.number, positive=True, at_least=SIGMA_D_RANGE[0], at_most=SIGMA_D_RANGE[1])
#: The widest Gaussian pre-blur of the occlusion edges (px; ``DepthParams.canny_sigma``):
#: OpenCV's kernel grows with it.
MAX_CANNY_SIGMA = 100.0
_canny_sigma = _rule(_opt.number, at_most=MAX_CANNY_SIGMA)
#: Canny thresholds are on the 8-bit Sobel magnitude (at most about 1443).
_canny_threshold = _rule(_opt.number, optional=True, at_most=1e6)
#: The longest wavelength (nm) the defocus cue takes (``lambda_r``, the views'): its squares
#: stay finite (:data:`hyperlf.spectral.MAX_WAVELENGTH`).
MAX_WAVELENGTH = _spectral.MAX_WAVELENGTH
_wavelength = _rule(_opt.number, positive=True, at_most=MAX_WAVELENGTH)
_lambda_r_mode = _opt.word_or(_wavelength, ("per_label", "per_pixel"),
                              f"'per_label', 'per_pixel' or a wavelength in (0, "
                              f"{MAX_WAVELENGTH:g}] nm")


def _problem(prob) -> "DepthProblem":
    """``prob`` when it is a :class:`DepthProblem`."""
    return _opt.instance(prob, "prob", DepthProblem, "a DepthProblem (from hyperlf.hlf.prepare)")


def _depth_params(params) -> "DepthParams":
    """``params`` as :class:`DepthParams` (None: the defaults)."""
    return _opt.params_of(params, "params", DepthParams)


def _progress(value):
    """A progress switch: True, False or a bar's description."""
    if isinstance(value, str):
        return value
    return _opt.flag(value, "progress (True, False or a bar's description)")


#: The one check of an array argument (``_options.array``), by its short local name.
_array = _opt.array


def _map(value, label: str, shape, *, optional: bool = False, finite: bool = True):
    """An (H, W) map of real numbers (None where ``optional``), finite unless told."""
    if value is None and optional:
        return None
    return _array(value, label, tuple(shape), finite=finite, of=" (an H x W map)")


def _volume(value, label: str, shape=None, *, finite: bool = False) -> np.ndarray:
    """An (L, H, W) volume of real numbers (of ``shape`` where given)."""
    return _array(value, label, shape, ndim=None if shape else 3, finite=finite,
                  of=" (an L x H x W volume)")


def _mask(value, label: str, shape, *, optional: bool = True, of: str = "the image"):
    """A bool mask of ``shape`` (bools or numbers; a bool array as it is), None where
    ``optional``."""
    if value is None:
        if optional:
            return None
        raise InvalidInputError(f"{label} must be a bool mask of shape {tuple(shape)}, got None")
    return _opt.bool_mask(value, label, tuple(shape), of=of)


def _weight(value, label: str, shape):
    """None or an (H, W) map of texture weights in [0, 1] (:func:`texture_weight`)."""
    w = _map(value, label, shape, optional=True)
    if w is not None and w.size and not (w.min() >= 0 and w.max() <= 1):
        raise InvalidInputError(f"{label} must hold weights in [0, 1], got values in "
                                f"[{w.min():g}, {w.max():g}]")
    return w


def _labels(value, label: str = "labels", n: int | None = None) -> np.ndarray:
    """Finite disparities (L,), ``n`` of them where given (at least one)."""
    a = _array(value, label, ndim=1, finite=True)
    if (n is not None and a.size != n) or a.size == 0:
        want = f"{n}" if n is not None else "at least 1"
        raise InvalidInputError(f"{label} must hold {want} disparities (one per label), got "
                                f"{a.size}")
    return a


def _label_map(value, label: str, shape, n_labels: int) -> np.ndarray:
    """An (H, W) map of label indices in ``0 .. n_labels - 1``."""
    a = _array(value, label, tuple(shape), kinds="iu", of=" (an H x W map of label indices)")
    if a.size and not (a.min() >= 0 and a.max() < n_labels):
        raise InvalidInputError(f"{label} must hold label indices in 0..{n_labels - 1}, got "
                                f"values in [{a.min()}, {a.max()}]")
    return a


def _pull_width(value, label: str = "width") -> float:
    """The width of the coarse prior's pull (:data:`PULL_WIDTH`)."""
    return _opt.number(value, label, positive=True, at_least=PULL_WIDTH[0],
                       at_most=PULL_WIDTH[1])


def _prior(value, shape, sizes=(3, 4), label: str = "prior"):
    """None or :func:`coarse_prior`'s ``(coarse, strength, width[, confidence])``: finite
    (H, W) maps and a width."""
    if value is None:
        return None
    if not isinstance(value, (tuple, list)) or len(value) not in sizes:
        what = " or ".join(map(str, sizes))
        raise InvalidInputError(f"{label} must be None or the tuple of coarse_prior (coarse, "
                                f"strength, width, confidence; {what} items), got "
                                f"{_opt.shown(value)}")
    items = [_map(value[0], f"{label}'s coarse disparity", shape),
             _map(value[1], f"{label}'s strength", shape),
             _pull_width(value[2], f"{label}'s width")]
    if len(value) == 4:
        items.append(_map(value[3], f"{label}'s confidence", shape, optional=True))
    return tuple(items)


def _start(value, shape):
    """None or :func:`coarse_disparity`'s ``(disparity, confidence)``: two finite (H, W) maps."""
    if value is None:
        return None
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise InvalidInputError("start must be None or coarse_disparity's (disparity, "
                                f"confidence), got {_opt.shown(value)}")
    return (_map(value[0], "start's disparity", shape),
            _map(value[1], "start's confidence", shape))


def _image_shape(prob: "DepthProblem") -> tuple[int, int]:
    H, W = prob.lf.image_shape
    return int(H), int(W)


def _volume_shape(prob: "DepthProblem") -> tuple[int, int, int]:
    return (prob.labels.size, *_image_shape(prob))


def _texture_snr(value, label):
    """None, 0 (off) or a number > 1."""
    if value is not None and not (_number(value, label) == 0 or value > 1):
        raise InvalidInputError(f"{label} must be None, 0 (off) or > 1, got {_opt.shown(value)}")
    return None if value is None else float(value)


def _tile_rows(value, label):
    """None (chosen by the memory budget) or a multiple of :data:`hyperlf.costs.ROW_BLOCK`."""
    rows = _opt.integer(value, label, ROW_BLOCK, optional=True)
    if rows is not None and rows % ROW_BLOCK:
        raise InvalidInputError(f"{label} must be a multiple of {ROW_BLOCK}, got "
                                f"{_opt.shown(value)}")
    return rows


#: How :class:`DepthParams` checks each option, and the type it keeps (``fusion_weights``:
#: ``_check_fusion_weights``; ``aggregation*``: :class:`hyperlf.costs.AggregationParams`;
#: ``camera`` by :func:`depth` before any work, where the defocus cue reads its table).
_DEPTH_RULES = {
    "window": _opt.word_or(_opt.window, (None,), "None or an odd integer >= 1"),
    "dense_views": _rule(_opt.integer, minimum=1),
    "tau_rel": _number,
    "eps": _positive,
    "block": _rule(_opt.integer, minimum=1),
    "selection_normalise": _flag,
    "selection_include_ref": _flag,
    "min_selected": _rule(_opt.integer, minimum=1),
    "canny_sigma": _canny_sigma,
    "canny_low": _canny_threshold,
    "canny_high": _canny_threshold,
    "edge_dilate": _count,
    "min_half_views": _rule(_opt.integer, minimum=1),
    "missing_views": _rule(_opt.choice, choices=MISSING_VIEWS),
    "unseen_labels": _rule(_opt.choice, choices=UNSEEN_LABELS),
    "margin_labels": _rule(_opt.integer, maximum=MAX_MARGIN_LABELS),
    "visibility_rounds": _rule(_opt.integer, optional=True),
    "round_cycles": _rule(_opt.integer, minimum=1, optional=True),
    "visibility_scale": _rule(_opt.integer, minimum=1),
    "reuse_memory": _number,
    "visibility_min_size": _rule(_opt.integer, minimum=1),
    "visibility_margin": _number,
    "min_visible_views": _rule(_opt.integer, minimum=1),
    "visibility_test": _rule(_opt.choice, choices=VISIBILITY_TESTS),
    "nearest_occluders": _rule(_opt.choice, choices=NEAREST_OCCLUDERS),
    "nearest_occluder_max": _rule(_opt.number, positive=True, at_most=1e4),
    "nearest_occluder_min": _rule(_opt.number, at_most=1e4),
    "nearest_occluder_behind": _rule(_opt.number, at_most=1e4),
    "texture_window": _rule(_opt.integer, minimum=3, odd=True),
    "coarse_prior": _flag,
    "coarse_prior_scale": _rule(_opt.integer, minimum=2),
    "coarse_prior_width": _rule(_opt.number, positive=True, optional=True),
    "coarse_prior_levels": _rule(_opt.integer, minimum=1),
    "coarse_prior_labels": _rule(_opt.integer, minimum=2, optional=True),
    "weak_planes": _flag,
    "plane_tile": _rule(_opt.integer, minimum=8, optional=True),
    "plane_max_slope": _rule(_opt.number, positive=True, at_most=1),
    "plane_specks": _count,
    "plane_carry": _rule(_opt.number, optional=True),
    "sigma_d": _sigma_d,
    "achromatic_radius": _number,
    "p_eps": _positive,
    "gamma_c": _number,
    "normalise_costs": _flag,
    "smoothness": _number,
    "truncation": _positive,
    "occlusion_weight": _number,
    "edge_sigma": _rule(_opt.number, positive=True, optional=True),
    "max_cycles": _count,
    "mrf_levels": _rule(_opt.integer, maximum=4),
    "sgm_paths": _rule(_opt.choice, choices=_reg.SGM_PATHS),
    "refine": _flag,
    "median_radius": _count,
    "median_sigma": _positive,
    "median_blur_sharp": _number,
    "median_blur_step": _positive,
    "median_noise_step": _rule(_opt.number, positive=True, optional=True),
    "thin_objects": _flag,
    "thin_holes": _flag,
    "thin_jump": _positive,
    "thin_touch": _rule(_opt.number, positive=True, at_most=1),
    "thin_hole_touch": _rule(_opt.number, positive=True, at_most=1),
    "thin_min_size": _rule(_opt.integer, minimum=1),
    "thin_min_support": _number,
    "confidence_edge_px": _number,
    "confidence_edge_jump": _positive,
    "confidence_floor": _rule(_opt.number, below=1),
    "impl": _rule(_opt.choice, choices=("auto", "numba", "numpy")),
    "max_memory": _rule(_opt.number, positive=True, optional=True),
    "tile_rows": _tile_rows,
    "texture_snr": _texture_snr,
    "lambda_r": _opt.word_or(_lambda_r_mode, (None,), "None, 'per_label', 'per_pixel' or a "
                             f"wavelength in (0, {MAX_WAVELENGTH:g}] nm"),
    "median_passes": _opt.word_or(_rule(_opt.integer, minimum=1, maximum=MAX_MEDIAN_PASSES),
                                  ("auto",), f"'auto' or an integer in 1..{MAX_MEDIAN_PASSES}"),
}


@dataclass(frozen=True)
class DepthParams:
    """Every constant of :func:`depth` (module docstring explains each stage).

    Correspondence: ``window`` (None = the metric's default,
    :func:`hyperlf.costs.light_field_window`: ncc 5, census 7, bwncc per level / 5, rsncc and
    census-rsncc 5, or 3 with at least ``dense_views`` (12) other views), ``tau_rel`` (1e-5),
    ``eps`` (1e-3, BWNCC ``-log`` floor), ``block`` (68 descriptor
    channels per block), ``fusion_weights`` (None = the cost's own, all 1; for a fused cost,
    one weight per part in its order, e.g. ``(1, 4)`` for census-rsncc's rsncc and census:
    :func:`hyperlf.costs.fusion_weights`; census weighted 4:1 held up better on a colourful
    variant of antinous but lost on the procedural scenes, BENCHMARKS.md, thirty-second
    session).
    Selection: ``selection_normalise`` (M / median M per view), ``selection_include_ref``,
    ``min_selected``.
    Occlusion split: ``canny_sigma``, ``canny_low`` / ``canny_high`` (absolute 8-bit Canny
    thresholds; None = automatic, 0.4 x / 1 x the 90th percentile of the Sobel magnitude),
    ``edge_dilate``, ``min_half_views``.
    Views that cannot see a sample: ``missing_views`` (``"average"``, the default: average
    over the views that see it; ``"neutral"``: they count the pixel's median cost, see
    :func:`neutral_missing_views`, which removes the pull of textureless border regions to the
    range limits; ``"common"``: a view counts at a pixel only if it sees the pixel at every
    label, see :func:`views_at_every_label`, so that every label of a pixel averages the same
    views).  A label that no view sees at a pixel: ``unseen_labels`` (``"share"``, the
    default: between the pixel's median and worst cost, the nearer the worst the larger the
    share of labels its views do see; ``"worst"``: its worst cost, ruling the label out;
    ``"median"``: its median cost, so that the regulariser decides;
    :func:`hyperlf.regularisers.fill_invalid`).  Near the image edge of a reference on the
    border of the array no view may see the true depth: ruled out, the top rows of the
    synthetic imperfect 2 x 3 rig took a wrong one and spread it into rows that are seen;
    ``"median"`` lets a foreground object spread over background rows where only the
    background's depth is seen; ``"share"`` does neither (BENCHMARKS.md, thirtieth session).
    Labels beyond the range: ``margin_labels`` (0) more at the same step beyond each end
    (:func:`with_margin`), for the correspondence, the MRF and the thin-object stage of the
    full-resolution passes (the coarse runs keep the range: with the margin there too no
    figure moved); the fused costs' per-view scales, the unseen labels' fill and the
    unary's scale (:func:`normalise_unary`) are measured over the range's own labels, so
    that only a census cost's two end labels change inside the range, and the map is
    clipped back to it.  A surface on an end of the range otherwise has labels on one side
    only and wins weakly textured pixels near it; labels far from every surface that
    entered the scale would weaken the data term.  Off by default: BadPix(0.07) falls by a
    quarter where a surface lies near an end, but the tuning scenes' RMSE moved by up to
    +0.2 % (BENCHMARKS.md, sixty-sixth and sixty-seventh sessions).
    Visibility (SPEC §5.6): ``visibility_rounds`` re-matchings, each over only the views that
    see each reference pixel under the current estimate: z-test with ``visibility_margin`` px
    per baseline, asked at every candidate disparity (``visibility_test="hypothesis"``, the
    default, :class:`LabelVisibility`) or at the estimate's own (``"estimate"``,
    :func:`visible_views`); a pixel (or pixel and disparity) seen by fewer than
    ``min_visible_views`` other views keeps them all, or, in the passes that
    ``nearest_occluders`` names (``"never"``, the default; ``"before-last"``: every
    visibility pass but the last; ``"always"``), a disparity is matched there over the views
    that see it once the z-test's margin is raised, by factors of sqrt(2) from
    ``nearest_occluder_min`` (2) px per baseline (0: from the margin's first step) up to
    ``nearest_occluder_max`` (8), until ``min_visible_views`` do
    (:meth:`LabelVisibility.reach`): a band that the estimate carried into the background
    hides the background's own projections from most views, and every view counting again
    hands the band's pixels back to it.  The floor keeps every view whose occluder is less
    than 2 px nearer, the estimate's own slanted surface among them (from the margin's first
    step the views it recedes from were chosen, and Venus's light field lost 1 %).  A view
    whose occluder lies more than ``nearest_occluder_behind`` (1) px per baseline behind the
    estimate at the pixel never counts (where that leaves fewer than ``min_visible_views``,
    every view does): without it a label behind a wall was matched over the views the wall
    hides, and antinous lost 0.5 % to a fattened streak.  ``"before-last"`` lowers the
    procedural tuning scenes' error by 3-4 %, but Venus's light field's rises by 0.3 %, so it
    is not the default; its last pass keeps every view because that volume is the one the
    thin-object stage reads, and with the fallback in it that stage no longer gave a faint
    stick back (BENCHMARKS.md, sixty-third and sixty-fourth sessions).
    ``visibility_rounds`` None (the default):
    :data:`DEFAULT_ROUNDS` (3) on images at least ``visibility_min_size`` (192) px on their
    shorter side whose pass's costs fit in ``reuse_memory`` (below), 1 on larger captures,
    else 0 (on smaller images the half-resolution first estimate, under 96 px, is too rough
    near edges; until the per-hypothesis test, arrays with fewer
    than ``dense_views`` other views had none either: BENCHMARKS.md); 0 = off.
    ``round_cycles`` (1; None = afresh): the graph cut of a round after the main pass starts
    from the labels of the pass before it and runs this many cycles of alpha-expansion
    (``max_cycles`` is the main pass's), instead of starting afresh from winner-takes-all;
    only what the new visibility changes has to move (plain graph cuts, ``mrf_levels`` 0;
    SGM has no start).
    ``visibility_scale`` (2): the estimate that the first round starts from is a whole depth
    run on the light field downscaled by this factor (:func:`coarse_disparity`, about 1/8 of
    the work at 2), instead of a full-resolution pass (1); it is used where both downscaled
    sides keep at least 16 px.
    ``reuse_memory`` (3e9 bytes; 0 = never): a round after the main pass (a second one,
    or the first with ``visibility_scale=1``) needs every other view's costs of that pass
    again; when they fit in this many bytes (5 per entry: the float32 cost and its
    validity; 512 x 512, 64 labels, 30 views: 2.4 GB) and in half the ``max_memory``
    budget, they are kept and the round only averages them again over the views that now
    see each sample (:class:`ViewCostStore`), else it computes them again: the same maps,
    only slower (what a second round costs either way: BENCHMARKS.md, thirty-seventh and
    thirty-eighth sessions).  The default number of rounds follows ``reuse_memory``
    alone, so ``max_memory`` changes no map.
    Textureless regions: ``texture_snr`` (None, the default: 2 for a capture made from camera
    images by ``hyperlf ingest``, i.e. with ``"calibration"`` metadata, else off; 0 = off;
    else > 1) and ``texture_window`` (5 px):
    a reference pixel whose window holds texture ``t`` (:func:`hyperlf.imageops.texture_snr`,
    in units of the estimated sensor noise) below ``texture_snr`` has its data term scaled
    down, to 0 at ``t <= 1`` (:func:`texture_weight`), so that a white table or wall, where every
    cost is noise, follows its surroundings through the MRF instead of a cost minimum that
    chance put at a range limit.  Off by default for rendered and synthetic light fields: a
    single image cannot tell pixel-scale texture from noise (:func:`hyperlf.imageops.noise_sigma`
    separates only texture that does not halve under binning), and the benchmark scenes have
    such texture; a camera's optics blur the scene below the pixel, so there the finest
    variation is the sensor's noise.
    ``coarse_prior`` (True; acts only where the texture weight does) adds to each weakly
    textured pixel ``(1 - w) g min(|d - d_coarse|, width) / width`` (:func:`coarse_prior`,
    :func:`add_coarse_prior`), ``d_coarse`` from :func:`coarse_disparity` at
    ``coarse_prior_scale`` (2); with ``coarse_prior_levels`` > 1 (default 1) that run has a
    coarse prior of its own, and so on; a level must keep 8 texture windows on its shorter
    side (shading that spans the image, such as each camera's vignetting, must not count as
    texture).  Every nested run keeps the first coarse run's label count
    (``coarse_prior_labels``, None: ``ceil(L / coarse_prior_scale)``), so that each level's
    estimate has the same step in full-resolution px (halving it again per level left the
    true depth between two labels, and a weak pull over a large textureless region outweighs
    the one edge around it).
    ``g`` how much of ``d_coarse`` comes from textured pixels at some level; ``width``
    ``coarse_prior_width`` disparity px (None: the coarse run's label step, ``scale`` fine
    label steps).
    ``weak_planes`` (True; acts only where the coarse prior does, so by default on captures
    made from camera images only): on pixels weakly textured at full resolution and at the
    coarse levels, the pooled costs choose slanted planes, tile by tile, on the light field
    downscaled by ``coarse_prior_scale`` (:func:`plane_prior`,
    :func:`hyperlf.regularisers.cost_planes`: tiles of ``plane_tile`` px of that level,
    None: 1/8 of its shorter side, at least 48; slopes up to
    ``plane_max_slope``, 0.12 disparity px per px), and those under an accepted plane are
    pulled towards it instead of ``d_coarse`` (BENCHMARKS.md, twenty-seventh session), as
    are specks that the coarse levels saw textured in a ``plane_specks`` px square (25; 0:
    off) that is at least half pooled pixels: islands up to about 17 x 17 px, under two texture
    windows of the coarse level (twenty-eighth session).  A tile whose plane is refused takes
    an overlapping accepted tile's plane that its own pooled costs do not contradict, by more
    than ``plane_carry`` standard errors (2.0; None: off; ``cost_planes``'s ``carry``): the
    lab's textureless table corner and vignetted left border kept no plane, and so
    ``d_coarse``, in one shot and not in the other (twenty-ninth session).
    Aggregation (issue 12 item 2): ``aggregation`` (``"none"``, the default, or ``"guided"``),
    ``aggregation_radius`` (4 px), ``aggregation_eps`` (1e-3): the correspondence volume
    filtered edge-aware with the reference view as the guide before the unary
    (:mod:`hyperlf.costs.aggregation`; why not by default: BENCHMARKS.md).
    Defocus: ``camera``, ``sigma_d`` (96.5 nm), ``achromatic_radius`` (0.01), ``lambda_r``
    (None = by mode; ``"per_label"``, ``"per_pixel"`` or nm), ``p_eps`` (1e-6).
    MRF: ``gamma_c``, ``normalise_costs``, ``smoothness`` (lambda, per disparity unit on the
    normalised unary), ``truncation`` (T, disparity units), ``occlusion_weight``,
    ``edge_sigma``, ``max_cycles``, ``sgm_paths``, ``refine``; ``mrf_levels`` (graph cuts
    only; 0 = plain alpha-expansion) runs coarse to fine
    (:func:`hyperlf.regularisers.graphcut_multiscale`: halvings of the image and the label
    set, the fine moves restricted to labels near the coarse answer), as two-view stereo
    does; occlusion edge weights (``occlusion_weight != 1``) need the plain moves and take
    them whatever ``mrf_levels`` says.
    Post-filter: ``median_radius`` (px; 0 = off) and ``median_sigma`` of the guided weighted
    median (:func:`hyperlf.regularisers.weighted_median`, guide = the reference view) applied to
    the final disparity.  Default 4 / 0.05: on Table 2 it lowered the RMSE on all six runs
    (5 scenes at 128 x 128 and antinous at 512 x 512: -1 to -15 %), by moving the depth edges
    that window costs fatten back onto the image edges.  ``median_passes``: how often it is
    applied; ``"auto"`` (default) once per ``median_blur_step`` px of the reference view's edge
    blur (:func:`hyperlf.imageops.edge_blur`) above ``median_blur_sharp`` px, at least once
    (:func:`median_passes`): a blurred outline moves with its foreground in every view, so
    the window costs carry the foreground further over the background the softer the image
    is.  Default 0.8 / 0.4 px: sharp and rendered views (0.6-0.85 px) get one pass, views
    blurred by a Gaussian of 1 px two.  Noisy views add one pass per ``median_noise_step``
    (0.01; None: none) of the reference view's white noise against its mean
    (:func:`hyperlf.imageops.noise_sigma`; on views at least :data:`NOISE_MIN_SIDE` px on
    each side): at a real array's noise (1-2 % of the signal) the map's errors are blotches
    that a second pass removes, and a noise-free render reads 0-0.5 % and keeps its pass
    (BENCHMARKS.md, fifty-fifth session).
    Thin objects (graph cuts only; :func:`thin_objects`): ``thin_objects`` (on) asks SGM
    for a second opinion on graph cuts' last unary and takes its 8-connected components
    (``thin_min_size`` px or more, default 10) that are nearer by more than ``thin_jump``
    (1 disparity unit) and lie along graph cuts' surface at their own depth on under
    ``thin_touch`` (0.25) of their outline, where the unary saves more than
    ``thin_min_support`` (0.05) of its median range per pixel at SGM's disparity and the
    texture weight (if any) is at least 0.5 on more than half of the pixels: rods and
    wires faint in the reference band, that graph cuts give to the background
    (BENCHMARKS.md, fifty-seventh session).  ``thin_holes`` (on) takes, by the same rule
    and constants, the components that SGM puts *farther*, within the image and at a depth
    graph cuts' map holds elsewhere: background seen through a hole that graph cuts filled
    with the foreground around it (fifty-ninth session).  A hole's outline share is
    ``thin_hole_touch`` (0.7), not ``thin_touch``: a hole or a gap that graph cuts filled
    only in part meets the part they kept open along much of its outline.  Above 0.5 the
    share also admits a band along an edge that graph cuts widened, and there the guards
    alone decide (sixtieth session).
    Confidence: ``confidence_edge_px`` (4 px; 0 = off) and ``confidence_edge_jump`` (0.5
    disparity units): the result's confidence is scaled by
    :func:`hyperlf.regularisers.edge_confidence` of the final disparity, 0 on an estimated
    depth edge (a 3 x 3 neighbourhood spanning more than the jump) rising to 1 at that many
    px from it.  The cost margin alone does not see depth edges, where nearly all of the
    error is; with the distance the confidence orders the errors 3-58 % better on the
    tuning scenes (BENCHMARKS.md, thirty-ninth session).  ``confidence_floor`` (0.1, in
    [0, 1)): the confidence of a seen pixel whose cost margin is 0
    (:func:`hyperlf.regularisers.confidence`); a repeated or weak texture gives most of a
    scene's pixels a margin of 0, although the regulariser decides most of them right, and
    without the floor they ranked with the unseen pixels (BENCHMARKS.md, fortieth session).
    The disparity does not depend on these three.
    ``impl``: ``"auto"``/``"numba"``/``"numpy"`` for the selection and defocus kernels.
    Memory (SPEC §12; results do not depend on them): ``max_memory`` (bytes; None =
    :data:`hyperlf.tiling.DEFAULT_MAX_MEMORY`), the budget by which the correspondence stage is
    cut into strips of rows (:func:`hyperlf.tiling.plan`); ``tile_rows`` forces the strips'
    height (a multiple of :data:`hyperlf.costs.ROW_BLOCK`; None = chosen by the budget).
    """

    window: int | None = None
    dense_views: int = DENSE_VIEWS
    tau_rel: float = 1e-5
    eps: float = 1e-3
    block: int = 68
    fusion_weights: tuple | None = None
    selection_normalise: bool = True
    selection_include_ref: bool = True
    min_selected: int = 3
    canny_sigma: float = 1.0
    canny_low: float | None = None
    canny_high: float | None = None
    edge_dilate: int = 1
    min_half_views: int = 2
    missing_views: str = "average"
    unseen_labels: str = "share"
    margin_labels: int = 0
    visibility_rounds: int | None = None
    round_cycles: int | None = 1
    visibility_scale: int = 2
    reuse_memory: float = 3e9
    visibility_min_size: int = 192
    visibility_margin: float = 0.5
    min_visible_views: int = 2
    visibility_test: str = "hypothesis"
    nearest_occluders: str = "never"
    nearest_occluder_max: float = 8.0
    nearest_occluder_min: float = 2.0
    nearest_occluder_behind: float = 1.0
    texture_snr: float | None = None
    texture_window: int = 5
    coarse_prior: bool = True
    coarse_prior_scale: int = 2
    coarse_prior_width: float | None = None
    coarse_prior_levels: int = 1
    coarse_prior_labels: int | None = None
    weak_planes: bool = True
    plane_tile: int | None = None
    plane_max_slope: float = 0.12
    plane_specks: int = 25
    plane_carry: float | None = 2.0
    aggregation: str = "none"
    aggregation_radius: int = 4
    aggregation_eps: float = 1e-3
    camera: str = "CIE 1931"
    sigma_d: float = 96.5
    achromatic_radius: float = 0.01
    lambda_r: Any = None
    p_eps: float = 1e-6
    gamma_c: float = 0.45
    normalise_costs: bool = True
    smoothness: float = 1.0
    truncation: float = 1.0
    occlusion_weight: float = 1.0
    edge_sigma: float | None = None
    max_cycles: int = 3
    mrf_levels: int = 0
    sgm_paths: int = 8
    refine: bool = True
    median_radius: int = 4
    median_sigma: float = 0.05
    median_passes: int | str = "auto"
    median_blur_sharp: float = 0.8
    median_blur_step: float = 0.4
    median_noise_step: float | None = 0.01
    thin_objects: bool = True
    thin_holes: bool = True
    thin_jump: float = 1.0
    thin_touch: float = 0.25
    thin_hole_touch: float = 0.7
    thin_min_size: int = 10
    thin_min_support: float = 0.05
    confidence_edge_px: float = 4.0
    confidence_edge_jump: float = 0.5
    confidence_floor: float = 0.1
    impl: str = "auto"
    max_memory: float | None = None
    tile_rows: int | None = None

    def __post_init__(self):
        _opt.check_fields(self, _DEPTH_RULES, "params.")
        self._check_fusion_weights()
        try:
            self.aggregation_params
        except InvalidInputError as e:
            raise InvalidInputError(f"params.{e}") from None

    def _check_fusion_weights(self) -> None:
        """``fusion_weights``: None, or finite numbers >= 0, not all 0, with a finite sum, kept
        as a tuple (which cost they fit is checked by :func:`depth`)."""
        from .costs.pair import weights_tuple

        w = self.fusion_weights
        if w is None:
            return
        t = weights_tuple(w)
        if t is None:
            raise InvalidInputError("params.fusion_weights must be None or one finite number "
                                    f">= 0 per part of the fused cost, not all 0, with a "
                                    f"finite sum; got {w!r}")
        object.__setattr__(self, "fusion_weights", t)

    @property
    def aggregation_params(self) -> AggregationParams:
        """``aggregation*`` as :class:`hyperlf.costs.AggregationParams`."""
        return AggregationParams(self.aggregation, self.aggregation_radius, self.aggregation_eps)


@dataclass
class DepthResult:
    """Output of :func:`depth`.

    disparity : float32 (H, W), sub-pixel (parabola) unless ``params.refine`` is False.
    confidence : float32 (H, W) in [0, 1] (cost-margin of the optimised volume, from
        ``params.confidence_floor`` up, without the coarse prior's pull under graph cuts;
        where the texture weight discounted a pixel's data term, that share is the coarse
        prior's confidence instead, or 0 without one; scaled down within
        ``params.confidence_edge_px`` px of the depth edges,
        :func:`hyperlf.regularisers.edge_confidence`).
    f_c : float32 (H, W), correspondence-only WTA disparity (``argmin_d C``).
    f_d : float32 (H, W) defocus-only WTA disparity, or None when ``defocus="off"``.
    labels : float64 (L,) the disparity of every label.
    timings : seconds per stage.
    config : every setting used (JSON-friendly), and three summaries: ``weak_data_share`` (the
        mean share of the data term the texture weight dropped), ``coarse_prior_share``
        (the mean strength of the coarse prior that replaced it) and ``thin_object_share``
        (the share of pixels :func:`thin_objects` took from SGM).
    intermediate : with ``save_intermediate``: ``C``, ``D`` (or None), ``unary``, ``edges``,
        ``lambda_r`` (or None), ``n_selected`` (views used per (d, p) before the split),
        ``texture_weight``, ``coarse_disparity`` and ``coarse_prior_strength`` (or None),
        ``thin_objects`` (:func:`thin_objects`' mask, or None).
    """

    disparity: np.ndarray
    confidence: np.ndarray
    f_c: np.ndarray
    f_d: np.ndarray | None
    labels: np.ndarray
    timings: dict = field(default_factory=dict)
    config: dict = field(default_factory=dict)
    intermediate: dict | None = None

    def __post_init__(self):  # types and shapes only: no pass over the maps
        self.disparity = _array(self.disparity, "disparity", ndim=2, of=" (an H x W map)")
        shape = self.disparity.shape
        for name in ("confidence", "f_c", "f_d"):
            if name != "f_d" or self.f_d is not None:
                setattr(self, name, _map(getattr(self, name), name, shape, finite=False))
        self.labels = _array(self.labels, "labels", ndim=1)
        for name in ("timings", "config", "intermediate"):
            value = getattr(self, name)
            if not isinstance(value, dict) and (name != "intermediate" or value is not None):
                raise InvalidInputError(f"{name} must be a dict, got {type(value).__name__}")


def make_labels(dmin: float, dmax: float, n_labels: int) -> np.ndarray:
    """``n_labels`` disparities evenly spaced over ``[dmin, dmax]`` (float64).

    Examples
    --------
    >>> from hyperlf.hlf import make_labels
    >>> make_labels(-1, 1, 5).tolist()
    [-1.0, -0.5, 0.0, 0.5, 1.0]
    """
    from .tiling import check_memory, count_text

    n = _opt.integer(n_labels, "n_labels", 2)
    lo, hi = _opt.real(dmin, "dmin"), _opt.real(dmax, "dmax")
    if not (lo < hi and math.isfinite(hi - lo)):
        raise InvalidInputError(f"disparity range must be finite with min < max, got ({dmin}, {dmax})")
    check_memory(8.0 * n, f"{count_text(n)} labels", "use fewer labels")
    return np.linspace(lo, hi, n)


def with_margin(labels, margin: int) -> np.ndarray:
    """``labels`` (evenly spaced) with ``margin`` more at the same step beyond each end.

    The labels of :func:`depth` when ``DepthParams.margin_labels`` is set: a surface at an
    end of the range then has labels on both sides, as one inside it has, and the map is
    clipped back to the range afterwards.

    Examples
    --------
    >>> from hyperlf.hlf import make_labels, with_margin
    >>> with_margin(make_labels(-1, 1, 3), 2).tolist()
    [-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0]
    """
    labels = _labels(labels)
    k = _opt.integer(margin, "margin", maximum=MAX_MARGIN_LABELS)
    if k == 0:
        return labels
    if labels.size < 2:
        raise InvalidInputError("labels must hold at least 2 disparities to extend by a margin")
    step = (labels[-1] - labels[0]) / (labels.size - 1)
    out = labels[0] + step * np.arange(-k, labels.size + k, dtype=np.float64)
    out[k:k + labels.size] = labels  # the range's own labels to the bit
    return out


def range_labels(n: int, margin: int) -> slice:
    """The labels of the range among ``n`` made by :func:`with_margin` with ``margin``.

    Examples
    --------
    >>> from hyperlf.hlf import range_labels
    >>> range_labels(7, 2)
    slice(2, 5, None)
    """
    n = _opt.integer(n, "n", 1)
    k = _opt.integer(margin, "margin", maximum=MAX_MARGIN_LABELS)
    if n <= 2 * k:
        raise InvalidInputError(f"{n} labels hold no range inside a margin of {k} at each end")
    return slice(k, n - k)


# ============================================================================================
# View selection + occlusion split aggregation
# ============================================================================================


def selection_masks(M_ref, Mq, valid, Mbar):
    """SPEC §5.1 rule for one view: ``sel = valid & ((M_ref > Mbar) == (Mq > Mbar))``.

    All arrays broadcast to ``(L, H, W)`` (``M_ref`` (H, W)).  (Equality: ``M_ref > Mbar``
    selects ``Mq > Mbar``, otherwise ``Mq <= Mbar``.)

    References
    ----------
    .. [1] K. Zhu et al., "Hyperspectral Light Field Stereo Matching", IEEE TPAMI, §5.1.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.hlf import selection_masks
    >>> M_ref = np.array([[2.0, 0.5]])            # an edge pixel and a flat one
    >>> Mq = np.array([[[3.0, 3.0]]])             # the view sees an edge at both
    >>> selection_masks(M_ref, Mq, True, 1.0)[0].tolist()
    [[True, False]]
    """
    M_ref = _array(M_ref, "M_ref", ndim=2)
    Mq = _array(Mq, "Mq")
    Mbar = _array(Mbar, "Mbar")
    try:
        shape = np.broadcast_shapes(M_ref[None].shape, Mq.shape, Mbar.shape)
    except ValueError:
        raise InvalidInputError(f"M_ref {M_ref.shape}, Mq {Mq.shape} and Mbar {Mbar.shape} must "
                                "broadcast to one (L, H, W) shape") from None
    valid = _opt.bool_mask(valid, "valid", shape, broadcast=True, of="the volume")
    return _selection_masks(M_ref, Mq, valid, Mbar)


def _selection_masks(M_ref, Mq, valid, Mbar):
    """:func:`selection_masks` on checked arrays."""
    return np.asarray(valid) & ((np.asarray(M_ref)[None] > Mbar) == (np.asarray(Mq) > Mbar))


def aggregate_view_reference(acc: dict, Cv, valid, Mq, Mbar, M_ref, use_selection: bool,
                             edge_idx, edge_side) -> None:
    """Numpy reference of :func:`aggregate_view` (same arguments and effect)."""
    Cv, valid, Mq, Mbar, M_ref, use_selection, edge_idx, edge_side = _aggregation_args(
        acc, Cv, valid, Mq, Mbar, M_ref, use_selection, edge_idx, edge_side)
    _aggregate_view_reference(acc, Cv, valid, Mq, Mbar, M_ref, use_selection, edge_idx,
                              edge_side)


def _aggregate_view_reference(acc: dict, Cv, valid, Mq, Mbar, M_ref, use_selection: bool,
                              edge_idx, edge_side) -> None:
    """:func:`aggregate_view_reference` on checked arguments."""
    L, H, W = Cv.shape
    valid = np.asarray(valid, bool)
    separate = _separate_selection(acc, use_selection)
    sel = _selection_masks(M_ref, Mq, valid, Mbar) if use_selection else valid
    if separate:
        acc["S_sel"] += np.where(sel, Cv, 0.0).astype(np.float32)
        acc["N_sel"] += sel.astype(np.float32)
    acc["S_all"] += np.where(valid, Cv, 0.0).astype(np.float32)
    acc["N_all"] += valid.astype(np.float32)
    if edge_idx is not None and len(edge_idx):
        Cf = Cv.reshape(L, -1)[:, edge_idx]
        sf = sel.reshape(L, -1)[:, edge_idx]
        vf = valid.reshape(L, -1)[:, edge_idx]
        side = np.asarray(edge_side)
        for h, s in ((0, 1), (1, -1)):
            inh = (side == s) | (side == 0)
            m_sel = sf & inh[None]
            m_all = vf & inh[None]
            if separate:
                acc["E_S_sel"][h] += np.where(m_sel, Cf, 0.0).astype(np.float32)
                acc["E_N_sel"][h] += m_sel.astype(np.float32)
            acc["E_S_all"][h] += np.where(m_all, Cf, 0.0).astype(np.float32)
            acc["E_N_all"][h] += m_all.astype(np.float32)


#: The largest magnitude :func:`half_plane_sides` takes (squares and products stay finite).
MAX_MAGNITUDE = 1e150


def _finite_values(value, label: str, shape=None, *, ndim: int | None = None) -> np.ndarray:
    """Finite real numbers of magnitude at most :data:`MAX_MAGNITUDE` (of ``shape`` or
    ``ndim`` where given): a few, such as offsets or gradients at edge pixels."""
    return _array(value, label, shape, ndim=ndim, bound=MAX_MAGNITUDE)


def _new_accumulators(L, H, W, E, selection: bool = True):
    """Sums and counts of :func:`aggregate_view`.  Without view ``selection`` the selected
    views are all valid ones, so each ``*_sel`` entry is its ``*_all`` array itself (half the
    memory; :func:`aggregate_view` then adds to it once)."""
    z = lambda *s: np.zeros(s, np.float32)  # noqa: E731
    acc = {"S_all": z(L, H, W), "N_all": z(L, H, W), "E_S_all": z(2, L, E), "E_N_all": z(2, L, E)}
    for k in ("S", "N", "E_S", "E_N"):
        acc[f"{k}_sel"] = z(*acc[f"{k}_all"].shape) if selection else acc[f"{k}_all"]
    return acc


_ACC_KEYS = ("S_sel", "N_sel", "S_all", "N_all", "E_S_sel", "E_N_sel", "E_S_all", "E_N_all")


def _aggregation_args(acc, Cv, valid, Mq, Mbar, M_ref, use_selection, edge_idx, edge_side):
    """The arguments of :func:`aggregate_view` checked (O(1) but for the E edge pixels):
    ``(Cv, valid, Mq, Mbar, M_ref, use_selection, edge_idx, edge_side)``, the edges as empty
    arrays when there are none, ``Mq`` and ``Mbar`` as placeholders without selection."""
    use_selection = _opt.flag(use_selection, "use_selection")
    Cv = _volume(Cv, "Cv")
    L, H, W = Cv.shape
    valid = _mask(valid, "valid", Cv.shape, optional=False, of="Cv")
    M_ref = _array(M_ref, "M_ref", (H, W), of=" (Cv's H x W)")
    if use_selection:
        Mq = _array(Mq, "Mq", Cv.shape, of=" (Cv's)")
        Mbar = _array(Mbar, "Mbar", Cv.shape, of=" (Cv's)")
    else:  # the kernel never reads them
        Mq = Mbar = np.zeros((1, 1, 1), np.float32)
    if edge_idx is not None and edge_side is not None:
        edge_idx = _array(edge_idx, "edge_idx", ndim=1, kinds="biuf")
    if edge_idx is None or edge_side is None or edge_idx.size == 0:
        edge_idx = np.zeros(0, np.int64)
        edge_side = np.zeros(0, np.int8)
    else:
        edge_idx = _array(edge_idx, "edge_idx", kinds="iu")
        if not (edge_idx.min() >= 0 and edge_idx.max() < H * W):
            raise InvalidInputError(f"edge_idx must hold flat pixel indices in 0..{H * W - 1}, "
                                    f"got values in [{edge_idx.min()}, {edge_idx.max()}]")
        edge_side = _array(edge_side, "edge_side", edge_idx.shape, kinds="iu",
                           of=" (one per edge pixel)")
        if not (edge_side.min() >= -1 and edge_side.max() <= 1):
            raise InvalidInputError("edge_side must hold -1, 0 or 1 per edge pixel")
    E = edge_idx.size
    if not isinstance(acc, dict) or any(k not in acc for k in _ACC_KEYS):
        raise InvalidInputError(f"acc must be the dict of accumulators ({', '.join(_ACC_KEYS)}),"
                                f" got {_opt.shown(acc)}")
    for k in _ACC_KEYS:  # the edge sums: any count of edge pixels when none are added
        a = acc[k]
        want = (L, H, W) if not k.startswith("E_") else (2, L, E) if E else (2, L)
        if not (isinstance(a, np.ndarray) and a.dtype == np.float32 and a.ndim == 3
                and a.shape[:len(want)] == want and a.flags.c_contiguous and a.flags.writeable):
            raise InvalidInputError(f"acc[{k!r}] must be a writeable float32 array of shape "
                                    f"{want + (('E',) if len(want) == 2 else ())}, got "
                                    f"{_opt.shown(a)}")
    return Cv, valid, Mq, Mbar, M_ref, use_selection, edge_idx, edge_side


def _separate_selection(acc: dict, use_selection: bool) -> bool:
    """Whether ``acc`` keeps the selected views' sums apart from all views' (else they are the
    same arrays, which only an aggregation without view selection may use)."""
    separate = acc["S_sel"] is not acc["S_all"]
    if use_selection and not separate:
        raise InvalidInputError("view selection needs accumulators made with selection=True")
    return separate


def aggregate_view(acc: dict, Cv, valid, Mq, Mbar, M_ref, use_selection: bool,
                   edge_idx=None, edge_side=None, impl: str = "auto") -> None:
    """Add one view's costs to the selection / split accumulators (numba fast path).

    ``acc``: dict from :func:`_new_accumulators` (``S_sel, N_sel, S_all, N_all`` (L, H, W);
    ``E_*`` (2, L, E) for the two half-planes at the ``E`` edge pixels; ``*_sel`` may be the
    ``*_all`` arrays themselves when ``use_selection`` is False).  ``Cv``, ``valid``,
    ``Mq`` (M of the view at ``q_v``), ``Mbar`` (L, H, W); ``M_ref`` (H, W); ``edge_idx``
    (E,) flat pixel indices; ``edge_side`` (E,) in {-1, 0, 1} (0 = on the line: both halves).
    ``impl="numpy"`` runs :func:`aggregate_view_reference`.

    Checked at every call (one per view and strip): types, shapes and the edge pixels'
    indices and sides (O(E)); the costs' values are not scanned.
    """
    _opt.choice(impl, "impl", ("auto", "numba", "numpy"))
    Cv, valid, Mq, Mbar, M_ref, use_selection, edge_idx, edge_side = _aggregation_args(
        acc, Cv, valid, Mq, Mbar, M_ref, use_selection, edge_idx, edge_side)
    if impl == "numpy":
        return _aggregate_view_reference(acc, Cv, valid, Mq, Mbar, M_ref, use_selection,
                                         edge_idx, edge_side)
    from . import _hlf_kernels

    separate = _separate_selection(acc, use_selection)
    _hlf_kernels.aggregate(np.ascontiguousarray(Cv, np.float32),
                           np.ascontiguousarray(valid, np.bool_),
                           np.ascontiguousarray(Mq, np.float32),
                           np.ascontiguousarray(Mbar, np.float32),
                           np.ascontiguousarray(M_ref, np.float32), bool(use_selection),
                           separate,
                           acc["S_sel"], acc["N_sel"], acc["S_all"], acc["N_all"],
                           np.ascontiguousarray(edge_idx, np.int64),
                           np.ascontiguousarray(edge_side, np.int8),
                           acc["E_S_sel"], acc["E_N_sel"], acc["E_S_all"], acc["E_N_all"])



def neutral_missing_views(C: np.ndarray, n_used: np.ndarray) -> np.ndarray:
    """Count a view that cannot see a label's sample as a neutral vote, not as absent.

    The plain aggregate averages over the views that see each sample, so a label seen by few
    views (near the image border, where large shifts leave the other views' images) averages
    fewer, noisier costs, and in textureless regions its minimum wins by chance: a bias
    towards the range limits. Here every label is averaged over as many views as the best
    label of the pixel has, the missing ones counting the pixel's median cost:
    ``C' = (C n + (n_max - n) median_d C) / n_max``.

    Parameters
    ----------
    C : ndarray (L, H, W)
        Aggregated cost, NaN where no view sees the sample.
    n_used : ndarray (L, H, W)
        Number of views averaged per entry.

    Returns
    -------
    ndarray (L, H, W), float32
    """
    import warnings

    C = _volume(C, "C")
    n_used = _volume(n_used, "n_used", C.shape)
    if n_used.size and not (n_used.min() >= 0 and np.isfinite(n_used.max())):
        raise InvalidInputError("n_used must hold view counts (finite numbers >= 0)")
    n = np.asarray(n_used, np.float32)
    n_max = n.max(axis=0, keepdims=True)
    with warnings.catch_warnings():  # pixels no view sees: all-NaN, stay NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(np.where(n > 0, C, np.nan), axis=0, keepdims=True)
    out = np.where(n > 0, (np.nan_to_num(C) * n + (n_max - n) * med) / np.maximum(n_max, 1),
                   np.nan)
    return out.astype(np.float32)


def _finish_aggregation(acc, min_selected, min_half_views, edge_idx, split: bool, *,
                        consume: bool = False):
    """``C`` (L, H, W) float32 and the number of views used, from the accumulators.

    ``consume``: ``acc`` is not used again, so ``C`` and the counts may be its own arrays
    (without view selection no volume is then allocated here)."""
    shared = acc["S_sel"] is acc["S_all"]  # no view selection: the selected views are all
    use_sel = None if shared else acc["N_sel"] >= min_selected

    def pick(sel, every, mask):
        return every if mask is None else np.where(mask, sel, every)

    S = pick(acc["S_sel"], acc["S_all"], use_sel)
    N = pick(acc["N_sel"], acc["N_all"], use_sel)
    if shared and not consume:
        S, N = S.copy(), N.copy()
    seen = N > 0  # counts are whole numbers: where seen, N = max(N, 1)
    C = np.divide(S, N, out=S, where=seen)
    C[~seen] = np.nan
    del seen
    if split and edge_idx is not None and len(edge_idx):
        L = C.shape[0]
        Cf = C.reshape(L, -1)
        us = None if use_sel is None else use_sel.reshape(L, -1)[:, edge_idx]
        best = np.full((L, len(edge_idx)), np.inf, np.float32)
        for h in range(2):
            Sh = pick(acc["E_S_sel"][h], acc["E_S_all"][h], us)
            Nh = pick(acc["E_N_sel"][h], acc["E_N_all"][h], us)
            ok = Nh >= min_half_views
            Ch = np.where(ok, Sh / np.maximum(Nh, 1), np.inf)
            best = np.minimum(best, Ch)
        cur = Cf[:, edge_idx]
        Cf[:, edge_idx] = np.where(np.isfinite(best), best, cur)
    return C, N


# ============================================================================================
# Occlusion edges
# ============================================================================================


def reference_edges(ref_img, sigma: float = 1.0, low=None, high=None, dilate: int = 1):
    """Canny edges of the reference and the gradient there.

    Returns ``edges`` (H, W) bool (dilated by ``dilate`` px) and ``(gx, gy)`` float64, the
    Sobel gradient of the blurred ``In_ref`` (edge orientation is perpendicular to it).
    ``low``/``high``: 8-bit Canny thresholds; None = 0.4 x / 1 x the 90th percentile of the
    Sobel magnitude of the 8-bit image.

    Examples
    --------
    A vertical step: one column of edge (three once dilated by the default 1 px), and a
    gradient across it, none along it:

    >>> img = np.zeros((20, 30)); img[:, 15:] = 1.0
    >>> edges, (gx, gy) = reference_edges(img, dilate=0)
    >>> sorted(set(np.nonzero(edges)[1].tolist())), bool(gx[10, 14] > 0), float(abs(gy).max())
    ([14], True, 0.0)
    >>> sorted(set(np.nonzero(reference_edges(img)[0])[1].tolist()))
    [13, 14, 15]
    """
    import cv2

    ref_img = _array(ref_img, "ref_img", ndim=2, finite=True)
    if min(ref_img.shape) < 1:
        raise InvalidInputError(f"ref_img must be a non-empty image, got shape {ref_img.shape}")
    sigma = _canny_sigma(sigma, "sigma")
    low = _canny_threshold(low, "low")
    high = _canny_threshold(high, "high")
    dilate = min(_opt.integer(dilate, "dilate"), max(ref_img.shape))  # wider: every pixel
    In = normalise_intensity(ref_img)
    hi_v = float(np.percentile(In, 99.5))
    img8 = np.clip(In / (hi_v if hi_v > 0 else 1.0) * 255.0, 0, 255).astype(np.uint8)
    if sigma > 0:
        img8 = cv2.GaussianBlur(img8, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
    sx = cv2.Sobel(img8, cv2.CV_64F, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)
    sy = cv2.Sobel(img8, cv2.CV_64F, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)
    mag = np.hypot(sx, sy)
    if high is None:
        high = max(float(np.percentile(mag, 90)), 1.0)
    if low is None:
        low = 0.4 * high
    edges = cv2.Canny(img8, float(low), float(high), L2gradient=True) > 0
    if dilate > 0 and edges.any():
        k = np.ones((2 * dilate + 1, 2 * dilate + 1), np.uint8)
        edges = cv2.dilate(edges.astype(np.uint8), k) > 0
    return edges, (sx, sy)


def half_plane_sides(gx, gy, offsets) -> np.ndarray:
    """Side of every view for every pixel's edge line: ``sign(g . o_v)`` in {-1, 0, 1}.

    ``gx, gy`` (E,) gradients at the edge pixels, ``offsets`` (V, 2) view offsets ``(dx, dy)``.
    The line through ``pos_ref`` along the edge (perpendicular to ``g``) separates the
    half-planes; a view on the line (``|g . o| <= 1e-9 |g| |o|``) gets 0 (both halves).
    Returns int8 (V, E).

    Examples
    --------
    >>> from hyperlf.hlf import half_plane_sides
    >>> half_plane_sides([1.0], [0.0], [(-1, 0), (0, 1), (1, 0)])[:, 0].tolist()
    [-1, 0, 1]
    """
    gx = _finite_values(gx, "gx", ndim=1)
    gy = _finite_values(gy, "gy", gx.shape)
    o = _finite_values(offsets, "offsets")
    if o.ndim < 1 or o.shape[-1] != 2:
        raise InvalidInputError(f"offsets must be view offsets (dx, dy), shape (V, 2), got "
                                f"shape {o.shape}")
    g = np.stack([np.asarray(gx, np.float64), np.asarray(gy, np.float64)], axis=-1)  # (E, 2)
    o = np.asarray(o, np.float64).reshape(-1, 2)
    dot = o @ g.T  # (V, E)
    tol = 1e-9 * np.linalg.norm(o, axis=1)[:, None] * np.linalg.norm(g, axis=1)[None, :]
    s = np.sign(dot)
    s[np.abs(dot) <= tol] = 0
    return s.astype(np.int8)


# ============================================================================================
# Defocus cost
# ============================================================================================


def defocus_cost_reference(P, valid, wl, lam_r, prior: str = "gaussian", sigma_d: float = 96.5,
                           p_eps: float = 1e-6):
    """Numpy reference of :func:`defocus_cost`."""
    P, valid, wl, lam_r, sigma_d, p_eps = _defocus_args(P, valid, wl, lam_r, prior, sigma_d,
                                                        p_eps)
    return _defocus_cost_reference(P, valid, wl, lam_r, prior, sigma_d, p_eps)


def _defocus_args(P, valid, wl, lam_r, prior, sigma_d, p_eps):
    """The arguments of :func:`defocus_cost` checked (one call per label: types, shapes and
    the (N,) wavelengths; ``lam_r``'s values only when it is one number):
    ``(P, valid, wl, lam_r, sigma_d, p_eps)``."""
    _opt.choice(prior, "prior", tuple(_PRIOR_CODE))
    P = _array(P, "P", ndim=3, of=" (N, H, W): one profile entry per view")
    N, H, W = P.shape
    valid = _opt.bool_mask(valid, "valid", P.shape, broadcast=True, of="P")
    wl = _wavelengths(wl, "wl", (N,))
    lam = _array(lam_r, "lam_r")
    try:
        fits = np.broadcast_shapes(lam.shape, (H, W)) == (H, W)
    except ValueError:
        fits = False
    if not fits:
        raise InvalidInputError(f"lam_r must be one wavelength or an (H, W) map of them, "
                                f"{(H, W)}, got shape {lam.shape}")
    if prior == "gaussian" and lam.ndim == 0:  # a map's values are not scanned here
        _wavelength(lam_r, "lam_r")
    return P, valid, wl, lam_r, _sigma_d(sigma_d, "sigma_d"), _positive(p_eps, "p_eps")


def _wavelengths(value, label: str, shape) -> np.ndarray:
    """Wavelengths (nm) of ``shape``, each finite, > 0 and at most :data:`MAX_WAVELENGTH`."""
    wl = _array(value, label, shape, finite=True, of=" (one per view)")
    if wl.size and not (wl.min() > 0 and wl.max() <= MAX_WAVELENGTH):
        raise InvalidInputError(f"{label} must be wavelengths in (0, {MAX_WAVELENGTH:g}] nm, "
                                f"got values in [{wl.min():g}, {wl.max():g}]")
    return wl


def _defocus_cost_reference(P, valid, wl, lam_r, prior: str = "gaussian",
                            sigma_d: float = 96.5, p_eps: float = 1e-6):
    """:func:`defocus_cost_reference` on checked arguments."""
    P = np.asarray(P, np.float64)
    V = np.asarray(valid, bool)
    wl = np.asarray(wl, np.float64)
    N = P.shape[0]
    Pv = np.where(V, P, 0.0)
    nval = V.sum(axis=0)
    tot = Pv.sum(axis=0)
    Ps = np.maximum(np.where(tot > 0, Pv / np.where(tot > 0, tot, 1.0), 0.0), p_eps)
    if prior == "tv":
        order = np.argsort(wl, kind="stable")
        Pso = Ps[order]
        Vo = V[order]
        D = np.zeros(P.shape[1:])
        last = np.full(P.shape[1:], np.nan)
        for k in range(N):
            ok = Vo[k]
            D = np.where(ok & np.isfinite(last), D + np.abs(Pso[k] - last), D)
            last = np.where(ok, Pso[k], last)
        return np.where(nval > 0, D, 0.0)
    if prior == "flat":
        G = np.where(V, 1.0, 0.0)
    else:
        lr = np.broadcast_to(np.asarray(lam_r, np.float64), P.shape[1:])
        G = np.where(V, np.exp(-(wl.reshape((N,) + (1,) * (P.ndim - 1)) - lr[None]) ** 2
                                / (2 * sigma_d ** 2)), 0.0)
    gs = G.sum(axis=0)
    G = G / np.where(gs > 0, gs, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(G > 0, G * np.log(np.where(G > 0, G, 1.0) / Ps), 0.0)
    return np.where(nval > 0, terms.sum(axis=0), 0.0)


def defocus_cost(P, valid, wl, lam_r, prior: str = "gaussian", sigma_d: float = 96.5,
                 p_eps: float = 1e-6, impl: str = "auto") -> np.ndarray:
    """Defocus cost ``D`` (H, W) float64 of one profile stack (SPEC §5.3).

    ``P`` (N, H, W) the profile ``In_v(q_v)``; ``valid`` (N, H, W); ``wl`` (N,) nm; ``lam_r``
    (H, W) nm (unused for ``flat``/``tv``).  ``prior``: ``gaussian`` (KL(Pg || P*)), ``flat``
    (KL(1/n || P*)), ``tv`` (sum of |P*_k+1 - P*_k| along sorted wavelength).  Over the valid
    views only (Pg and P* renormalised), ``P*`` floored at ``p_eps``; 0 where no view is valid.
    """
    _opt.choice(impl, "impl", ("auto", "numba", "numpy"))
    P, valid, wl, lam_r, sigma_d, p_eps = _defocus_args(P, valid, wl, lam_r, prior, sigma_d,
                                                        p_eps)
    if impl == "numpy":
        return _defocus_cost_reference(P, valid, wl, lam_r, prior, sigma_d, p_eps)
    P = np.ascontiguousarray(P, np.float64)
    N, H, W = P.shape
    wl = np.asarray(wl, np.float64)
    lr = kernel_input(np.broadcast_to(np.asarray(lam_r, np.float64), (H, W)))
    out = np.empty((H, W))
    from . import _hlf_kernels

    _hlf_kernels.defocus(P, kernel_input(np.broadcast_to(valid, P.shape), np.bool_),
                         np.argsort(wl, kind="stable").astype(np.int64), wl, lr,
                         _PRIOR_CODE[prior], float(sigma_d), float(p_eps), out)
    return out


def _camera_matrix(camera, wl):
    """(N, 3) sensitivities and whether they are an RGB camera (needs RGB -> XYZ)."""
    from .spectral import camera_sensitivities
    name = str(camera).strip().lower()
    is_xyz = name in ("cie 1931", "xyz")
    S = camera_sensitivities(camera, wl)
    if np.any(S.sum(axis=0) <= 0):
        raise InvalidInputError(f"camera {camera!r} has a channel with no response at the views' wavelengths")
    return S, not is_xyz


def _lambda_r(P, valid, S, is_rgb, lo, hi, achromatic_radius):
    """Dominant wavelength (H, W) of the profile P (N, H, W) over valid views."""
    from .spectral import dominant_wavelength_for_filters, srgb_linear_to_xyz, xyz_to_xy
    Vm = np.asarray(valid, np.float64)
    num = np.einsum("vhw,vk->hwk", np.where(valid, P, 0.0), S)
    den = np.einsum("vhw,vk->hwk", Vm, S)
    col = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
    xyz = srgb_linear_to_xyz(col) if is_rgb else col
    xy = xyz_to_xy(xyz)
    return dominant_wavelength_for_filters(xy, lo, hi, achromatic_radius=achromatic_radius)


def defocus_volume(In_views, offsets, wl, labels, prior="gaussian", lambda_r="per_label",
                   f_c=None, camera="CIE 1931", sigma_d=96.5, achromatic_radius=0.01,
                   p_eps=1e-6, impl="auto", *, valid=None):
    """Defocus volume ``D[L, H, W]`` float32 and the ``lambda_r`` used ((H, W) or None).

    ``In_views`` (N, H, W) normalised views (including the reference), ``offsets`` (N, 2),
    ``wl`` (N,); ``valid`` (N, H, W) bool, optional: the views' validity masks (a sample is
    valid only where every bilinear tap it uses is, :func:`hyperlf.costs.tap_validity`).  ``lambda_r``: ``"per_label"`` (literal: from the profile at every label),
    ``"per_pixel"`` (from the profile at ``f_c``, a (H, W) disparity map) or a number (nm).
    Entries with no valid view get the pixel's worst valid value.
    """
    In_views = _array(In_views, "In_views", ndim=3, finite=True, of=" (N, H, W)")
    N, H, W = In_views.shape
    offsets = _finite_values(offsets, "offsets", (N, 2))
    wl = _wavelengths(wl, "wl", (N,))
    labels = _labels(labels)
    _opt.choice(prior, "prior", tuple(_PRIOR_CODE))
    lambda_r = _lambda_r_mode(lambda_r, "lambda_r")
    f_c = _map(f_c, "f_c", (H, W), optional=True)
    sigma_d = _sigma_d(sigma_d, "sigma_d")
    achromatic_radius = _opt.number(achromatic_radius, "achromatic_radius")
    p_eps = _positive(p_eps, "p_eps")
    _opt.choice(impl, "impl", ("auto", "numba", "numpy"))
    valid = _mask(valid, "valid", (N, H, W), of="In_views")
    In_views = np.asarray(In_views, np.float64)
    wl = np.asarray(wl, np.float64)
    lo, hi = float(wl.min()), float(wl.max())
    S = is_rgb = lam_fixed = None
    if prior == "gaussian":
        S, is_rgb = _camera_matrix(camera, wl)
        if lambda_r == "per_pixel":
            if f_c is None:
                raise InvalidInputError("lambda_r='per_pixel' needs the correspondence map f_c")
            P, V = _views_at_map(In_views, offsets, valid, f_c)
            lam_fixed = _lambda_r(P, V, S, is_rgb, lo, hi, achromatic_radius)
        elif lambda_r != "per_label":
            lam_fixed = np.full((H, W), float(lambda_r))
    D = np.empty((len(labels), H, W), np.float32)
    anyvalid = np.zeros((len(labels), H, W), bool)
    for k, d in enumerate(labels):
        P, V = _views_at_label(In_views, offsets, valid, d)
        lr = 0.0
        if prior == "gaussian":
            lr = lam_fixed if lam_fixed is not None else _lambda_r(P, V, S, is_rgb, lo, hi,
                                                                   achromatic_radius)
        D[k] = defocus_cost(P, V, wl, lr, prior, sigma_d, p_eps, impl)
        anyvalid[k] = V.any(axis=0)
    D = _reg.fill_invalid(np.where(anyvalid, D, np.nan).astype(np.float32))
    return D, lam_fixed


def _views_at_label(views: np.ndarray, offsets: np.ndarray, valid, d: float):
    """Every view (N, H, W) shifted to the reference at the plane ``d`` (edge taps 0), and
    where its samples are valid."""
    P = np.empty(views.shape)
    V = np.empty(views.shape, bool)
    for v in range(views.shape[0]):
        P[v], V[v] = _view_at_label(views[v], None if valid is None else valid[v], offsets[v], d)
    return P, V


def _view_at_label(view: np.ndarray, valid_v, offset, d: float):
    """One view shifted to the reference at the plane ``d`` (edge taps 0), and where its
    samples are valid (every bilinear tap valid in ``valid_v`` where given)."""
    sx, sy = -d * offset[0], -d * offset[1]
    out, ok = shift_map(view, sx, sy, 0)
    if valid_v is not None:
        ok = ok & tap_validity(valid_v, sx, sy)
    return out, ok


def _views_at_map(views: np.ndarray, offsets: np.ndarray, valid, f_c: np.ndarray):
    """Every view (N, H, W) warped to the reference at the disparity map ``f_c``, and where
    its samples are valid (every tap valid)."""
    from .warp import warp_to_reference

    P = np.empty(views.shape)
    V = np.empty(views.shape, bool)
    for v in range(views.shape[0]):
        P[v], V[v] = warp_to_reference(views[v], f_c, tuple(offsets[v]), fill=0.0)
        if valid is not None:
            m, _ = warp_to_reference(np.asarray(valid[v], np.float64), f_c, tuple(offsets[v]),
                                     fill=0.0)
            V[v] &= m >= 1.0 - 1e-9
    return P, V


# ============================================================================================
# MRF helpers
# ============================================================================================


def normalise_unary(X, enabled: bool = True, *, mask=None):
    """``(X - min_d X) / s`` with ``s`` = median over pixels of ``max_d X - min_d X``
    (``s = 1`` when disabled or when that median is 0).  Returns (float32 volume, s).

    ``mask`` (bool (H, W), optional): take the median over these pixels only (the
    informative ones; pixels with a uniform cost would pull it towards 0).

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.hlf import normalise_unary
    >>> U, s = normalise_unary(np.array([[[1.0]], [[5.0]]]))
    >>> U[:, 0, 0].tolist(), s
    ([0.0, 1.0], 4.0)
    """
    X = _volume(X, "X")
    enabled = _opt.flag(enabled, "enabled")
    mask = _mask(mask, "mask", X.shape[1:], of="X's pixels")
    return _normalise_unary(X, enabled, mask, "X")


def _normalise_unary(X, enabled: bool, mask, label: str, scaled: slice | None = None):
    """:func:`normalise_unary` of a checked volume, refusing non-finite costs on the way
    (their per-pixel minimum and maximum, which it needs anyway, show them); the scale is
    measured over the labels ``scaled`` (None: every label)."""
    if X.shape[0] == 0:
        raise InvalidInputError(f"{label} must hold at least one label, got shape {X.shape}")
    X = np.asarray(X, np.float32)
    low = X.min(axis=0, keepdims=True)
    high = X.max(axis=0)
    if not (np.isfinite(low).all() and np.isfinite(high).all()):
        raise InvalidInputError(f"{label} must be finite (no NaN or inf)")
    Y = X - low
    s = 1.0
    if enabled:
        # high - low = Y.max(axis=0): the rounded difference is monotonic
        rng = high - low[0] if scaled is None else \
            X[scaled].max(axis=0) - X[scaled].min(axis=0)
        if mask is not None and np.any(mask):
            rng = rng[np.asarray(mask, bool)]
        med = float(np.median(rng))
        if med > 0:
            s = med
    if s != 1.0:
        Y /= s  # in place: one volume fewer at the peak of the MRF stage
    return Y, s


def _occlusion_edge_weights(edges, f_c, threshold, factor):
    """(wx (H, W-1), wy (H-1, W)): ``factor`` where a pair touches an edge pixel and f_c jumps
    by more than ``threshold``, else 1."""
    e = edges
    jx = np.abs(np.diff(f_c, axis=1)) > threshold
    jy = np.abs(np.diff(f_c, axis=0)) > threshold
    bx = (e[:, 1:] | e[:, :-1]) & jx
    by = (e[1:, :] | e[:-1, :]) & jy
    return np.where(bx, factor, 1.0), np.where(by, factor, 1.0)


# ============================================================================================
# Public entry point
# ============================================================================================


def _mrf_params(optimizer: str, params: DepthParams, step: float):
    """The optimiser settings of :func:`depth`: ``lambda min(|Δd|, T)`` with ``lambda =
    params.smoothness`` per disparity unit and ``T = params.truncation`` (SGM: per label step
    ``p1 = lambda step``, ``p2 = lambda T``, P2 adapted to the guide; graph cuts: plain
    alpha-expansion).  ``smoothness == 0`` is WTA."""
    lam, T = params.smoothness, params.truncation
    if lam == 0:
        return _reg.WTAParams()
    settings = {
        "wta": {},
        "sgm": dict(p1=lam * step, p2=lam * T, paths=int(params.sgm_paths),
                    smoothness="truncated_linear", adaptive_p2=True),
        "graphcut": dict(smoothness="truncated_linear", weight=lam, truncation=T,
                         edge_sigma=params.edge_sigma, max_cycles=int(params.max_cycles),
                         levels=int(params.mrf_levels)),
    }
    return _reg.make_params(optimizer, settings[optimizer])


@dataclass
class DepthProblem:
    """Everything the stages of :func:`depth` share, built once by :func:`prepare`.

    Attributes
    ----------
    lf : LightField
        The input.
    metric : str
        The resolved correspondence cost name.
    view_selection, occlusion_split : bool
        The SPEC §5.1 / §5.2 switches.
    defocus, optimizer : str
        The SPEC §5.3 mode and the MRF optimiser.
    params : DepthParams
        Every constant.
    labels : ndarray, float64 (L,)
        The disparity of every label: ``n_labels`` over ``disparity_range``, and
        ``params.margin_labels`` more at the same step beyond each end.
    disparity_range : (float, float)
        The range asked for (the map is clipped to it).
    views, others : list of (r, c)
        Every view, and every view but the reference.
    reference : (r, c)
    offsets : ndarray (R, C, 2)
        ``pos_v - pos_ref`` in baselines.
    ref_img : ndarray, float64 (H, W)
        The reference view.
    In : dict
        ``I_v / mean(I_v)`` per view (float64).
    Mn : dict
        Gradient magnitude of ``In`` per view (normalised by its median when
        ``params.selection_normalise``); the reference's alone without view selection.
    M_ref : ndarray, float32 (H, W)
    Mbar : ndarray, float32 (L, H, W) or None
        Mean gradient magnitude over the valid views (view selection only).
    edges : ndarray, bool (H, W)
        Occlusion edges of the reference (all False when not needed).
    edge_idx : ndarray, int64
        Flat indices of the edge pixels used by the occlusion split.
    sides : ndarray or None
        Half-plane side of every other view at every edge pixel.
    valid : dict or None
        ``lf.valid[v]`` per view (bool (H, W)), or None when the light field has no mask.
        ``ref_img`` and the maps in ``In`` are then computed from the views with their
        invalid pixels filled (:func:`hyperlf.imageops.fill_masked`).
    window : int or None
        The correspondence window (:func:`hyperlf.costs.light_field_window`; None: the
        cost's own).
    visibility_rounds : int
        ``params.visibility_rounds`` resolved (None: :func:`_default_rounds`).
    every_label : dict or None
        With ``params.missing_views="common"``: per other view, the reference pixels where it
        counts (:func:`views_at_every_label`); else None.
    """

    lf: Any
    metric: str
    view_selection: bool
    occlusion_split: bool
    defocus: str
    optimizer: str
    params: DepthParams
    labels: np.ndarray
    disparity_range: tuple
    views: list
    others: list
    reference: tuple
    offsets: np.ndarray
    ref_img: np.ndarray
    In: dict
    Mn: dict = field(default_factory=dict)
    M_ref: np.ndarray | None = None
    Mbar: np.ndarray | None = None
    edges: np.ndarray | None = None
    edge_idx: np.ndarray | None = None
    sides: np.ndarray | None = None
    valid: dict | None = None
    window: int | None = None
    visibility_rounds: int = 0
    every_label: dict | None = None

    def __post_init__(self):  # the fields' types and shapes (prepare sets the rest later)
        from .lightfield import LightField

        _opt.check_fields(self, {"lf": _instance(LightField, "a LightField"),
                                 **_PROBLEM_RULES})
        if self.ref_img.shape != tuple(self.lf.image_shape) or self.labels.size < 2:
            raise InvalidInputError(
                f"ref_img must be the light field's {self.lf.image_shape} reference view and "
                f"labels at least 2 disparities, got shape {self.ref_img.shape} and "
                f"{self.labels.size} labels")

    @property
    def range_labels(self) -> slice:
        """The labels of ``disparity_range``: all but ``params.margin_labels`` at each end."""
        return range_labels(self.labels.size, self.params.margin_labels)

    @property
    def impl(self) -> str:
        """Kernel implementation of the selection and defocus kernels."""
        return "numpy" if self.params.impl == "numpy" else "numba"


def _instance(cls, what: str, *, optional: bool = False):
    """A rule: ``value`` when it is a ``cls`` (or None where ``optional``)."""
    return _opt.rule(_opt.instance, cls=cls, what=what, optional=optional)


def _optional(check):
    """``check`` that lets None pass."""
    return lambda value, label: None if value is None else check(value, label)


#: How :class:`DepthProblem` checks its fields (types and shapes, no pass over the arrays).
_PROBLEM_RULES = {
    "metric": _instance(str, "a cost's name"),
    "view_selection": _flag,
    "occlusion_split": _flag,
    "defocus": _rule(_opt.choice, choices=DEFOCUS_MODES),
    "optimizer": _rule(_opt.choice, choices=OPTIMIZERS),
    "params": _instance(DepthParams, "a DepthParams"),
    "labels": lambda value, label: _array(value, label, ndim=1),
    "disparity_range": _opt.real_pair,
    "views": _instance(list, "a list of views (r, c)"),
    "others": _instance(list, "a list of views (r, c)"),
    "reference": _instance(tuple, "a view (r, c)"),
    "offsets": lambda value, label: _array(value, label, ndim=3, of=" (R, C, 2)"),
    "ref_img": lambda value, label: _array(value, label, ndim=2),
    "In": _instance(dict, "a dict of images per view"),
    "Mn": _instance(dict, "a dict of images per view"),
    "M_ref": _optional(lambda value, label: _array(value, label, ndim=2)),
    "Mbar": _optional(lambda value, label: _array(value, label, ndim=3)),
    "edges": _optional(lambda value, label: _array(value, label, ndim=2)),
    "edge_idx": _optional(lambda value, label: _array(value, label, ndim=1, kinds="iu")),
    "sides": _optional(lambda value, label: _array(value, label, ndim=2, kinds="iu")),
    "valid": _instance(dict, "a dict of masks per view", optional=True),
    "window": _rule(_opt.integer, minimum=1, optional=True),
    "visibility_rounds": _count,
    "every_label": _instance(dict, "a dict of masks per view", optional=True),
}


def _check_depth_options(lf, metric, view_selection, occlusion_split, defocus, optimizer,
                         params):
    from .lightfield import check_light_field

    if check_light_field(lf).views.ndim != 4:
        raise InvalidInputError(
            "H-LF matching needs monochrome views (R, C, H, W); this light field has "
            f"{lf.channels} channels per view (an RGB light field: make an H-LF of it with "
            "'hyperlf synth hci')")
    if lf.n_views < 2:
        raise InvalidInputError("H-LF matching needs at least 2 views")
    if not np.any(np.asarray(lf.offsets, np.float64)):
        raise InvalidInputError("every view sits at the reference's position (lf.positions): "
                                "with no baseline there is no disparity to find")
    params = DepthParams() if params is None else params
    if not isinstance(params, DepthParams):
        raise InvalidInputError(f"params must be a DepthParams, got {type(params).__name__}")
    view_selection = _opt.flag(view_selection, "view_selection")
    occlusion_split = _opt.flag(occlusion_split, "occlusion_split")
    _opt.choice(defocus, "defocus", DEFOCUS_MODES)
    _opt.choice(optimizer, "optimizer", OPTIMIZERS)
    mname = get_cost(metric, light_field=True).name
    if params.fusion_weights is not None:
        try:
            fusion_weights(mname, params.fusion_weights)
        except InvalidInputError as e:
            raise InvalidInputError(f"params.fusion_weights: {e}") from None
    if defocus != "off" and not lf.is_spectral:
        raise InvalidInputError(
            "the defocus cue needs a spectral light field with one wavelength per view "
            "(lf.wavelengths); pass defocus='off' or set the wavelengths")
    if params.window is not None:
        _opt.window(params.window, "params.window", side=max(lf.image_shape), of="the views")
    if defocus in ("paper", "gaussian"):  # the camera's table, read before any long work
        _camera_matrix(params.camera, np.ravel(lf.wavelengths))
    return mname, view_selection, occlusion_split, params


def _selection_maps(In: dict, normalise: bool, masks: dict | None = None) -> dict:
    """Gradient magnitude of every view, divided by its median (over the view's valid pixels
    when ``masks``) when ``normalise``."""
    Mn = {}
    for v, img in In.items():
        M = gradient_magnitude(img)
        if normalise:
            Mv = M if masks is None or not masks[v].any() else M[masks[v]]
            med = float(np.median(Mv))
            s = med if med > 0 else float(Mv.mean())
            M = M / s if s > 0 else M
        Mn[v] = M
    return Mn


def _mean_gradient(prob: DepthProblem) -> np.ndarray:
    """``Mbar(p, d)``: mean of ``M_v(q_v)`` over the valid views (SPEC §5.1, pass 1)."""
    L = prob.labels.size
    H, W = prob.lf.image_shape
    Msum = np.zeros((L, H, W), np.float64)
    Mcnt = np.zeros((L, H, W), np.float64)
    if prob.params.selection_include_ref:
        Msum += prob.Mn[prob.reference][None]
        Mcnt += 1.0
    for v in prob.others:
        o = prob.offsets[v]
        for k, d in enumerate(prob.labels):
            m, ok = _view_at_label(prob.Mn[v], None if prob.valid is None else prob.valid[v],
                                   o, d)
            Msum[k] += np.where(ok, m, 0.0)
            Mcnt[k] += ok
    return (Msum / np.maximum(Mcnt, 1)).astype(np.float32)


def _prepare_edges(prob: DepthProblem) -> None:
    """Occlusion edges of the reference and the half-plane side of every view (SPEC §5.2)."""
    p = prob.params
    H, W = prob.lf.image_shape
    prob.edges = np.zeros((H, W), bool)
    prob.edge_idx = np.zeros(0, np.int64)
    if prob.occlusion_split or (prob.optimizer == "graphcut" and p.occlusion_weight != 1.0):
        prob.edges, (gx, gy) = reference_edges(prob.ref_img, p.canny_sigma, p.canny_low,
                                               p.canny_high, int(p.edge_dilate))
    if prob.occlusion_split:
        prob.edge_idx = np.flatnonzero(prob.edges).astype(np.int64)
        offs = np.array([prob.offsets[v] for v in prob.others])
        prob.sides = half_plane_sides(gx.ravel()[prob.edge_idx], gy.ravel()[prob.edge_idx], offs)


def _view_masks(lf, views):
    """``(masks, images)``: per view the validity mask (None without ``lf.valid``) and the
    image, with its invalid pixels filled from the nearest valid one when masked."""
    if lf.valid is None:
        return None, {v: lf.views[v] for v in views}
    if not lf.valid[lf.reference].any():
        raise InvalidInputError(
            f"the reference view {tuple(lf.reference)} has no valid pixel (lf.valid); choose "
            "a reference view that holds data")
    masks = {v: lf.valid[v] for v in views}
    return masks, {v: fill_masked(lf.views[v], masks[v]) for v in views}


def _views_with_data(views, ref, masks) -> list:
    """The views matched against the reference: all others but those without a valid pixel
    (a dead camera's view carries nothing to match)."""
    others = [v for v in views if v != ref and (masks is None or masks[v].any())]
    if not others:
        raise InvalidInputError("no view besides the reference has a valid pixel (lf.valid): "
                                "depth needs at least two views with data")
    return others


def prepare(lf, *, disparity_range=None, n_labels: int = 64, metric: str = "auto",
            view_selection: bool = False, occlusion_split: bool = False, defocus: str = "off",
            optimizer: str = "graphcut", params: DepthParams | None = None) -> DepthProblem:
    """Stage 1 of :func:`depth`: validate, make the labels and the per-view maps.

    Builds the normalised views, the selection maps (``Mn``, ``Mbar``) and the occlusion
    edges; arguments as :func:`depth`.

    Returns
    -------
    DepthProblem

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    >>> prob = prepare(lf, n_labels=16)
    >>> prob.labels[[0, -1]].tolist(), len(prob.labels), prob.reference
    ([-2.0, 2.0], 16, (1, 1))
    """
    from .lightfield import resolve_disparity_range

    mname, view_selection, occlusion_split, params = _check_depth_options(
        lf, metric, view_selection, occlusion_split, defocus, optimizer, params)
    dmin, dmax = resolve_disparity_range(lf, disparity_range)
    n_labels = _opt.integer(n_labels, "n_labels", 2)
    check_label_volume(n_labels + 2 * params.margin_labels, lf.image_shape)
    labels = with_margin(make_labels(dmin, dmax, n_labels), params.margin_labels)
    R, Cc = lf.grid_shape
    ref = lf.reference
    views = [(r, c) for r in range(R) for c in range(Cc)]
    masks, imgs = _view_masks(lf, views)
    prob = DepthProblem(
        lf=lf, metric=mname, view_selection=view_selection, occlusion_split=occlusion_split,
        defocus=defocus, optimizer=optimizer, params=params, labels=labels,
        disparity_range=(dmin, dmax), views=views, others=_views_with_data(views, ref, masks),
        reference=ref, offsets=lf.offsets, ref_img=imgs[ref].astype(np.float64),
        In={v: normalise_intensity(imgs[v], valid=None if masks is None else masks[v])
            for v in views}, valid=masks)
    prob.window = light_field_window(mname, len(prob.others), window=params.window,
                                     dense_views=params.dense_views)
    prob.visibility_rounds = _default_rounds(prob) if params.visibility_rounds is None \
        else int(params.visibility_rounds)
    # every view's map only for the selection; without it the reference's alone
    prob.Mn = _selection_maps(prob.In if view_selection else {ref: prob.In[ref]},
                              params.selection_normalise, masks)
    prob.M_ref = prob.Mn[ref].astype(np.float32)
    if view_selection:
        prob.Mbar = _mean_gradient(prob)
    _prepare_edges(prob)
    if params.missing_views == "common":
        prob.every_label = views_at_every_label(prob)
    return prob


def _default_rounds(prob: DepthProblem) -> int:
    """``params.visibility_rounds`` None: none on images under ``visibility_min_size`` px on
    their shorter side; :data:`DEFAULT_ROUNDS` where one pass's costs fit in
    ``reuse_memory`` (the later rounds then only average them again: a budget never decides
    it); else 1, as a further round would compute every cost again."""
    p = prob.params
    if min(prob.lf.image_shape) < int(p.visibility_min_size):
        return 0
    cheap = ViewCostStore.bytes_needed(prob) <= float(p.reuse_memory)
    return DEFAULT_ROUNDS if cheap else 1


def views_at_every_label(prob: DepthProblem) -> dict:
    """Per other view, the reference pixels it sees at every label (``missing_views="common"``).

    A view sees ``p`` at label ``d`` when the sample ``q_v = p - d o_v`` and its bilinear taps
    are valid (:func:`hyperlf.costs.view_validity`).  The plain aggregate averages each label
    over the views that see it there, so near a border the labels whose shifts leave some
    views' images average fewer views, and other ones: in a textureless region a label seen
    only by the views beside the reference compares the region's shading along its rows
    alone, costs less, and wins (the lab's table front went to the range limit that way;
    BENCHMARKS.md, twenty-fifth and twenty-sixth sessions).  Counting a view at ``p`` only
    where it sees ``p`` at every label gives every label the same views.  A pixel that no
    view sees at every label (a corner, when the range reaches out of the image in every
    direction) keeps every view, as the plain aggregate has it.

    Returns
    -------
    dict
        ``(r, c)`` -> bool (H, W) for every other view.
    """
    out = _seen_at_every_label(_problem(prob))
    none = np.sum(list(out.values()), axis=0) == 0
    return {v: m | none for v, m in out.items()}


def _seen_at_every_label(prob: DepthProblem) -> dict:
    """Per other view, bool (H, W): it sees the reference pixel at every label."""
    from .costs import view_shifts, view_validity

    shape = prob.lf.image_shape
    out = {}
    for v in prob.others:
        mask = None if prob.valid is None else prob.valid[v]
        every = np.ones(shape, bool)
        for shift in view_shifts(prob.offsets[v], prob.labels):
            every &= view_validity(shape, [shift], mask=mask)[0]
        out[v] = every
    return out


def _mask_args(prob: DepthProblem, v) -> dict:
    """The ``ref_valid`` / ``view_valid`` keywords of :func:`view_costs` for view ``v``."""
    if prob.valid is None:
        return {}
    return dict(ref_valid=prob.valid[prob.reference], view_valid=prob.valid[v])


def seen_pixels(prob: DepthProblem, n_used: np.ndarray) -> np.ndarray | None:
    """Reference pixels that carry information: valid, and seen by a valid sample of some
    other view at some label (bool (H, W)); None when the light field has no mask."""
    prob = _problem(prob)
    n_used = _volume(n_used, "n_used", _volume_shape(prob))
    if prob.valid is None:
        return None
    return prob.valid[prob.reference] & (np.asarray(n_used) > 0).any(axis=0)


def visible_views(prob: DepthProblem, disparity: np.ndarray) -> dict:
    """Stage 7 of :func:`depth` (SPEC §5.6 a): which other views see each reference pixel.

    :func:`hyperlf.warp.visible_in_view` of ``disparity`` for every other view (z-test,
    ``params.visibility_margin``; validity masks need nothing here, the correspondence stage
    applies them per sample).  A pixel seen by fewer than ``params.min_visible_views`` views
    keeps every view (too few votes are worse than an occluded one).

    Returns
    -------
    dict
        ``(r, c)`` -> bool (H, W) for every view but the reference.

    Examples
    --------
    A square 2 px per baseline in front of its background: the view one baseline to the
    right sees the square 2 px further left, over the background's columns 13 and 14:

    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    >>> prob = prepare(lf, n_labels=16)
    >>> disparity = np.zeros((32, 40), np.float32)
    >>> disparity[10:20, 15:25] = 2.0
    >>> hidden = ~visible_views(prob, disparity)[(1, 2)]
    >>> sorted(set(np.nonzero(hidden)[1].tolist())), int(hidden.sum())
    ([13, 14], 20)
    """
    from .warp import visible_in_view

    prob = _problem(prob)
    disparity = _map(disparity, "disparity", _image_shape(prob))
    p = prob.params
    d = np.asarray(disparity, np.float64)
    sees = {v: visible_in_view(d, tuple(prob.offsets[v]), margin=float(p.visibility_margin))
            for v in prob.others}
    count = np.sum([m for m in sees.values()], axis=0)
    few = count < int(p.min_visible_views)
    return {v: m | few for v, m in sees.items()}


class LabelVisibility:
    """Which other views see each reference pixel at each candidate disparity (SPEC §5.6 a,
    asked of every hypothesis; ``DepthParams.visibility_test="hypothesis"``, the default).

    The estimate's z-buffer in every view (:func:`hyperlf.warp.occlusion_zbuffer`) is kept;
    :meth:`mask` answers for a strip of rows with :func:`hyperlf.warp.visible_at_labels`, so
    no ``(L, H, W)`` mask per view is ever held.  A ``(d, p)`` that fewer than
    ``params.min_visible_views`` views see keeps every view (hypotheses behind the estimated
    surface, which no view sees, are matched as without visibility), or with ``nearest``
    the views whose occluders are the least nearer than ``d`` (:meth:`reach`) and not behind
    the estimate at the pixel (:meth:`nearest_views`).

    Why per hypothesis: the test of :func:`visible_views` is asked at the estimate's own
    disparity, so a background pixel that the estimate gave the foreground (a fattened edge)
    is "seen" by every view and nothing changes there; asked at the background's disparity,
    the views in which the foreground covers it drop out of that label's mean.
    """

    def __init__(self, prob: "DepthProblem", disparity: np.ndarray, *, nearest: bool = False):
        from .warp import occlusion_zbuffer

        prob = _problem(prob)
        disparity = _map(disparity, "disparity", _image_shape(prob))
        p = prob.params
        d = np.asarray(disparity, np.float64)
        self.zbuffers = {v: occlusion_zbuffer(d, tuple(prob.offsets[v])).astype(np.float32)
                         for v in prob.others}
        self.offsets = {v: tuple(float(o) for o in prob.offsets[v]) for v in prob.others}
        self.labels = np.asarray(prob.labels, np.float64)
        self.margin = float(p.visibility_margin)
        self.min_views = int(p.min_visible_views)
        self.impl = prob.impl
        self.nearest = _opt.flag(nearest, "nearest")
        self.ladder = occluder_margins(self.margin, float(p.nearest_occluder_max),
                                       smallest=float(p.nearest_occluder_min))
        self.behind = float(p.nearest_occluder_behind)
        self.estimate = d.astype(np.float32)
        self._few = self._reach = self._none = (None, None)

    def seen(self, v, rows) -> np.ndarray:
        """``(L, b - a, W)`` bool: view ``v`` sees ``(d, p)`` (before the fallback)."""
        from .warp import visible_at_labels

        return visible_at_labels(self.zbuffers[v], self.offsets[v], self.labels, rows=rows,
                                 margin=self.margin, impl=self.impl)

    def too_few(self, rows) -> np.ndarray:
        """``(L, b - a, W)`` bool: fewer than ``min_visible_views`` views see ``(d, p)``."""
        rows = (int(rows[0]), int(rows[1]))
        if self._few[0] != rows:
            count = np.zeros((self.labels.size, rows[1] - rows[0],
                              next(iter(self.zbuffers.values())).shape[1]), np.int16)
            for v in self.zbuffers:
                count += self.seen(v, rows)
            self._few = (rows, count < self.min_views)
        return self._few[1]

    def excess(self, v, rows) -> np.ndarray:
        """``(L, b - a, W)`` float32: how much nearer than ``d`` the surface is that would hide
        ``(d, p)`` from view ``v`` (:func:`hyperlf.warp.occluder_excess`)."""
        from .warp import occluder_excess

        return occluder_excess(self.zbuffers[v], self.offsets[v], self.labels, rows=rows,
                               impl=self.impl)

    def reach(self, rows) -> np.ndarray:
        """``(L, b - a, W)`` float32: where fewer than ``min_visible_views`` views see
        ``(d, p)``, the z-test's margin raised until that many do (the steps of
        :func:`occluder_margins`, from ``params.nearest_occluder_min`` up to
        ``params.nearest_occluder_max``; ``inf`` beyond it); ``-inf`` elsewhere.  With
        ``nearest`` the views whose occluder excess is within it count there, less those
        :meth:`nearest_views` leaves out."""
        rows = (int(rows[0]), int(rows[1]))
        if self._reach[0] != rows:
            few = self.too_few(rows)
            least = np.full((self.min_views,) + few.shape, np.inf, np.float32)
            for v in self.zbuffers:
                e = self.excess(v, rows)
                for j in range(self.min_views):  # e into the sorted smallest so far
                    lo = np.minimum(least[j], e)
                    np.maximum(least[j], e, out=e)
                    least[j] = lo
            reach = np.full(few.shape, np.inf, np.float32)
            for m in self.ladder[::-1]:
                reach[least[-1] <= m] = m
            reach[~few] = -np.inf
            self._reach = (rows, reach)
        return self._reach[1]

    def nearest_views(self, v, rows) -> np.ndarray:
        """``(L, b - a, W)`` bool: where too few views see ``(d, p)``, view ``v``'s occluder
        is within :meth:`reach` of ``d`` and no more than ``params.nearest_occluder_behind``
        farther than the estimate at ``p`` (a view that a farther surface than ``p``'s own
        hides says nothing of whether ``p`` is that surface or nearer)."""
        e = self.excess(v, rows)
        a, b = int(rows[0]), int(rows[1])
        occluder = e + self.labels[:, None, None].astype(np.float32)
        return (e <= self.reach(rows)) & (occluder >= self.estimate[a:b] - self.behind)

    def none_near(self, rows) -> np.ndarray:
        """``(L, b - a, W)`` bool: too few views see ``(d, p)`` even with
        :meth:`nearest_views`, so every view counts there."""
        rows = (int(rows[0]), int(rows[1]))
        if self._none[0] != rows:
            few = self.too_few(rows)
            count = np.zeros(few.shape, np.int16)
            for v in self.zbuffers:
                count += self.seen(v, rows) | (few & self.nearest_views(v, rows))
            self._none = (rows, few & (count < self.min_views))
        return self._none[1]

    def mask(self, v, rows) -> np.ndarray:
        """``(L, b - a, W)`` bool: the samples of view ``v`` that count for the strip."""
        if self.nearest:
            return (self.seen(v, rows) | (self.too_few(rows) & self.nearest_views(v, rows))
                    | self.none_near(rows))
        return self.seen(v, rows) | self.too_few(rows)


def occluder_margins(margin: float, largest: float, *, smallest: float = 0.0) -> np.ndarray:
    """The z-test's margins that :meth:`LabelVisibility.reach` tries in turn: from the larger
    of ``margin`` times sqrt(2) and ``smallest``, by factors of sqrt(2), up to ``largest``
    (float32; none when it is below the first; ``largest`` alone for a margin and a
    ``smallest`` of 0).

    Examples
    --------
    >>> [round(float(m), 2) for m in occluder_margins(0.5, 8.0)]
    [0.71, 1.0, 1.41, 2.0, 2.83, 4.0, 5.66, 8.0]
    >>> [round(float(m), 2) for m in occluder_margins(0.5, 8.0, smallest=2.0)]
    [2.0, 2.83, 4.0, 5.66, 8.0]
    """
    margin, largest = _opt.real(margin, "margin"), _opt.real(largest, "largest")
    first = max(np.sqrt(2.0) * margin, _opt.real(smallest, "smallest"))
    if first <= 0:
        return np.array([largest], np.float32)[: 1 if largest > 0 else 0]
    steps = 2 * np.log2(largest / first) if largest > 0 else -np.inf
    n = int(np.floor(steps + 1e-9)) + 1 if steps > -1e-9 else 0
    return (first * np.sqrt(2.0) ** np.arange(n)).astype(np.float32)


def visibility(prob: "DepthProblem", disparity: np.ndarray, *, last: bool = True):
    """Stage 7's visibility under ``params.visibility_test``: :class:`LabelVisibility`
    (``"hypothesis"``; with ``nearest`` as ``params.nearest_occluders`` says for the ``last``
    pass or one before it) or :func:`visible_views` (``"estimate"``)."""
    p = _problem(prob).params
    if p.visibility_test == "estimate":
        return visible_views(prob, disparity)
    nearest = p.nearest_occluders == "always" or (p.nearest_occluders == "before-last"
                                                  and not _opt.flag(last, "last"))
    return LabelVisibility(prob, disparity, nearest=nearest)


def coarse_disparity(prob: DepthProblem, *, scale: int | None = None,
                     progress: bool | str = False, return_confidence: bool = False):
    """A depth estimate made cheaply at a coarser scale: the start of the first visibility
    round (SPEC §5.6 a) and the coarse prior of weakly textured pixels.

    :func:`depth` with the same options (a coarse prior only with ``coarse_prior_levels`` > 1,
    one level fewer) and no visibility rounds on the light field downscaled by ``s = scale``
    (default ``params.visibility_scale``; :func:`hyperlf.lightfield.downscale`; ``ceil(L / s)``
    labels, or ``params.coarse_prior_labels``, over the range divided by ``s``), its disparity
    repeated over each ``s x s`` block and multiplied by ``s``.
    Visibility needs only which surface is in front where; near depth edges the z-test's
    margin errs towards "hidden".

    Returns
    -------
    ndarray, float32 (H, W) or None
        Disparity in full-resolution px; None when ``s`` is 1 or a downscaled side would be
        under 16 px (the first estimate is then the full-resolution pass).
    confidence : ndarray, float32 (H, W)
        With ``return_confidence``: the coarse run's confidence, repeated over each block
        (the pair is None where the disparity is).
    """
    s = int(prob.params.visibility_scale if scale is None else scale)
    coarse = _coarse_problem(prob, s)
    if coarse is None:
        return None
    lf_s, options = coarse
    res = depth(lf_s, **options, progress=f"views, 1/{s} resolution" if progress else False)
    disparity = _blow_up(res.disparity * s, s, prob.lf.image_shape)
    if return_confidence:
        return disparity, _blow_up(res.confidence, s, prob.lf.image_shape)
    return disparity


def _coarse_problem(prob: DepthProblem, s: int):
    """``(light field downscaled by s, depth's keyword arguments)`` for the runs of
    :func:`coarse_disparity`, or None when ``s`` is 1 or a side would be under 16 px."""
    from .lightfield import downscale

    H, W = prob.lf.image_shape
    if s == 1 or min(H, W) // s < 16:
        return None
    dmin, dmax = prob.disparity_range
    nested = int(prob.params.coarse_prior_levels) - 1
    n_range = prob.labels[prob.range_labels].size
    n = prob.params.coarse_prior_labels or max(2, math.ceil(n_range / s))
    # the coarse runs keep the range's labels: a margin there moved no figure (BENCHMARKS)
    p = replace(prob.params, margin_labels=0, visibility_rounds=0, tile_rows=None,
                thin_objects=False,
                coarse_prior=prob.params.coarse_prior and nested > 0,
                coarse_prior_levels=max(nested, 1), coarse_prior_labels=n)
    return downscale(prob.lf, s), dict(
        disparity_range=(dmin / s, dmax / s), n_labels=n,
        metric=prob.metric, view_selection=prob.view_selection,
        occlusion_split=prob.occlusion_split, defocus=prob.defocus, optimizer=prob.optimizer,
        params=p)


def _blow_up(a: np.ndarray, s: int, shape) -> np.ndarray:
    """``a`` repeated over ``s x s`` blocks and cropped to ``shape``, float32."""
    H, W = shape
    return np.repeat(np.repeat(a, s, axis=0), s, axis=1)[:H, :W].astype(np.float32)


def _strip_edges(prob: DepthProblem, rows):
    """The occlusion-split edge pixels inside the strip ``rows``: their strip-flat indices,
    and which of ``prob.edge_idx`` they are (to pick their half-plane sides)."""
    W = prob.lf.image_shape[1]
    a, b = rows
    idx = prob.edge_idx
    inside = (idx >= a * W) & (idx < b * W)
    return idx[inside] - a * W, inside


def _strip_selection(prob: DepthProblem, v, rows):
    """``Mq`` (L, h, W): the gradient magnitude of view ``v`` at ``q_v`` for the strip's
    reference pixels (SPEC §5.1), or None without view selection."""
    if not prob.view_selection:
        return None
    o = prob.offsets[v]
    a, b = rows
    return np.stack([shift_map(prob.Mn[v], -d * o[0], -d * o[1], 0)[0][a:b]
                     for d in prob.labels])


def view_scales(prob: DepthProblem, strips) -> dict | None:
    """The whole-view scales of the correspondence cost (a fusion's normalisers), measured
    strip by strip (:func:`hyperlf.costs.view_moments`): what a strip of a view cannot
    measure alone, over the range's labels (``params.margin_labels`` beyond it would
    otherwise change every cost inside it).  None for a cost without them, or a single
    strip without margin labels, which measures them itself.

    Returns
    -------
    dict or None
        ``(r, c)`` -> one standard deviation per part of the cost, for every other view.
    """
    from .costs import moments_std, view_moments

    p = prob.params
    if (len(strips) == 1 and not p.margin_labels) \
            or not get_cost(prob.metric, light_field=True).global_scales:
        return None
    out = {}
    cache: dict = {}
    labels = prob.labels[prob.range_labels]
    for v in prob.others:
        parts = [view_moments(prob.ref_img, prob.lf.views[v], prob.offsets[v], labels,
                              prob.metric, prob.window, p.tau_rel, p.eps, int(p.block), cache,
                              rows=rows, **_mask_args(prob, v)) for rows in strips]
        out[v] = [moments_std(*(np.concatenate([m[k][j] for m in parts]) for j in range(3)))
                  for k in range(len(parts[0]))]
    return out


class ViewCostStore:
    """Every other view's costs of one correspondence pass, kept for the visibility rounds
    (``DepthParams.reuse_memory``): per view and strip of rows, the cost volume and where the
    view's samples are valid, before any visibility mask.  A round then only averages them
    again (:func:`correspondence` with ``store``), with the same result as computing them
    again."""

    #: Bytes kept per (view, label, pixel): a float32 cost and a bool validity.
    BYTES_PER_ENTRY = 5

    def __init__(self):
        self._kept: dict = {}

    def get(self, v, rows):
        """``(Cv, valid)`` of view ``v`` on the strip ``rows``, or None."""
        return self._kept.get((v, tuple(rows)))

    def put(self, v, rows, Cv, valid) -> None:
        self._kept[(v, tuple(rows))] = (Cv, valid)

    def clear(self) -> None:
        """Let the kept costs go (after the last round that reads them)."""
        self._kept.clear()

    @classmethod
    def bytes_needed(cls, prob: DepthProblem) -> int:
        """Bytes that one pass's costs take."""
        H, W = prob.lf.image_shape
        return cls.BYTES_PER_ENTRY * len(prob.others) * prob.labels.size * H * W

    @classmethod
    def fits(cls, prob: DepthProblem) -> bool:
        """Whether one pass's costs fit in ``params.reuse_memory`` and in half the memory
        budget (``params.max_memory``, None: :data:`hyperlf.tiling.DEFAULT_MAX_MEMORY`).
        Only the time depends on it: costs that do not fit are computed again (SPEC §12)."""
        from .tiling import DEFAULT_MAX_MEMORY

        p = prob.params
        budget = DEFAULT_MAX_MEMORY if p.max_memory is None else p.max_memory
        return cls.bytes_needed(prob) <= min(float(p.reuse_memory), 0.5 * float(budget))


def _view_strip_costs(prob: DepthProblem, v, rows, scales, cache, store):
    """View ``v``'s costs on the strip ``rows`` and where its samples are valid, before any
    visibility mask: from ``store`` when it holds them, else computed (and put there when
    there is a store)."""
    kept = None if store is None else store.get(v, rows)
    if kept is not None:
        return kept
    p = prob.params
    a, b = rows
    whole = (a, b) == (0, prob.lf.image_shape[0])
    Cv, valid = view_costs(prob.ref_img, prob.lf.views[v], prob.offsets[v], prob.labels,
                           prob.metric, prob.window, p.tau_rel, p.eps, int(p.block), cache,
                           rows=None if whole else rows,
                           scales=None if scales is None else scales[v],
                           weights=p.fusion_weights, **_mask_args(prob, v))
    if prob.every_label is not None:
        valid &= prob.every_label[v][None, a:b]
    if store is not None:
        store.put(v, rows, Cv, valid)
    return Cv, valid


def _strip_correspondence(prob: DepthProblem, rows, scales, sees, cache, bar, clock,
                          store=None):
    """Aggregate every other view's costs over the strip ``rows``: ``(C, n_used)`` of the
    strip, (L, h, W), before the whole-volume fill."""
    p = prob.params
    a, b = rows
    W = prob.lf.image_shape[1]
    edge_idx, inside = _strip_edges(prob, rows)  # none unless the occlusion split is on
    acc = _new_accumulators(prob.labels.size, b - a, W, len(edge_idx), prob.view_selection)
    whole = (a, b) == (0, prob.lf.image_shape[0])
    M_ref = prob.M_ref if whole else np.ascontiguousarray(prob.M_ref[a:b])
    Mbar = None if prob.Mbar is None else (prob.Mbar if whole else prob.Mbar[:, a:b])
    for i, v in enumerate(prob.others):
        next(bar, None)
        clock.lap()
        Cv, valid = _view_strip_costs(prob, v, rows, scales, cache, store)
        if isinstance(sees, LabelVisibility):  # a new array: a kept validity stays as it is
            valid = valid & sees.mask(v, rows)
        elif sees is not None:
            valid = valid & sees[v][None, a:b]
        clock.lap("correspondence_s")
        sides = None if prob.sides is None else prob.sides[i][inside]
        aggregate_view(acc, Cv, valid, _strip_selection(prob, v, rows), Mbar, M_ref,
                       prob.view_selection, edge_idx, sides, prob.impl)
        del Cv, valid
        clock.lap("selection_split_s")
    C, n_used = _finish_aggregation(acc, int(p.min_selected), int(p.min_half_views),
                                    edge_idx, prob.occlusion_split, consume=True)
    del acc
    if p.missing_views == "neutral":
        C = neutral_missing_views(C, n_used)
    clock.lap("selection_split_s")
    return C, n_used


def _sees(sees, prob: DepthProblem):
    """:func:`correspondence`'s ``sees`` checked: None, a :class:`LabelVisibility` of the
    problem, or a bool (H, W) mask per other view (:func:`visible_views`)."""
    shape = _image_shape(prob)
    if sees is None:
        return None
    if isinstance(sees, LabelVisibility):
        z = next(iter(sees.zbuffers.values()), None)
        if (sees.labels.size != prob.labels.size or z is None or z.shape != shape
                or any(v not in sees.zbuffers for v in prob.others)):
            raise InvalidInputError("sees is a LabelVisibility of another problem (its "
                                    "labels, image size or views differ)")
        return sees
    if not isinstance(sees, dict) or any(v not in sees for v in prob.others):
        raise InvalidInputError("sees must be None, a LabelVisibility or a dict of bool (H, W) "
                                f"masks for every other view {prob.others}, got "
                                f"{_opt.shown(sees)}")
    return {v: _mask(sees[v], f"sees[{v}]", shape, optional=False, of="the views")
            for v in prob.others}


def correspondence(prob: DepthProblem, *, progress: bool | str = False, timings=None,
                   sees: dict | None = None, strips=None, store: ViewCostStore | None = None):
    """Stage 2 of :func:`depth`: per-view costs streamed into the aggregation (SPEC §5.1-5.2).

    ``progress``: a bar over the views on stderr (a string: the bar's label, else "views").
    ``sees`` (optional; :func:`visibility`): per other view, the reference pixels it sees
    (:func:`visible_views`), or a :class:`LabelVisibility` (those it sees at each label); a
    view counts only there (SPEC §5.6).  ``strips`` (optional; :func:`hyperlf.tiling.plan`):
    full-width strips of rows ``[(a, b), ...]`` covering the image in order, each aggregated
    alone (memory for its rows only; SPEC §12 tiles); bit for bit the result of one strip.
    A cost with whole-view scales (the fusions) then takes one more pass over the views to
    measure them (:func:`view_scales`).  ``store`` (optional): every view's costs are taken
    from it where it holds them and put into it where it does not (:class:`ViewCostStore`).

    Returns
    -------
    C : ndarray, float32 (L, H, W)
        The aggregated correspondence volume (entries no view saw: filled by
        ``params.unseen_labels``).
    n_used : ndarray
        Views used per ``(d, p)`` before the occlusion split.

    Examples
    --------
    Every other view of a 3 x 3 array adds to the volume where its sample is inside
    its image (8 at most):

    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    >>> prob = prepare(lf, n_labels=16)
    >>> C, n_used = correspondence(prob)
    >>> C.shape, C.dtype.name, int(n_used.max())
    ((16, 32, 40), 'float32', 8)
    """
    prob = _problem(prob)
    progress = _progress(progress)
    sees, strips = _correspondence_inputs(prob, timings, sees, strips, store)
    clock = _Clock({"correspondence_s": 0.0, "selection_split_s": 0.0})
    # kept costs were made with the whole-view scales already
    scales = None if store is not None and store.get(prob.others[0], strips[0]) is not None \
        else view_scales(prob, strips)
    clock.lap("scales_s")
    n = len(prob.others) * len(strips)
    desc = progress if isinstance(progress, str) else "views"
    bar = progress_bar(range(n), desc, total=n, enabled=bool(progress), unit="view")
    C, n_used = _all_strips(prob, strips, scales, sees, bar, clock, store)
    next(bar, None)  # closes the bar
    if not np.isfinite(C).any():
        dmin, dmax = prob.disparity_range
        raise InvalidInputError(
            f"no view overlaps the reference at any disparity in ({dmin:g}, {dmax:g}): "
            "narrow the disparity range")
    C = _reg.fill_invalid(C, value=prob.params.unseen_labels,
                          over=prob.range_labels if prob.params.margin_labels else None)
    clock.lap("selection_split_s")
    if prob.params.aggregation != "none":
        C = aggregate_volume(C, prob.In[prob.reference], prob.params.aggregation_params, out=C)
        clock.lap("aggregation_s")
    if timings is not None:
        timings.update(clock.timings)
        if len(strips) == 1:
            timings.pop("scales_s", None)
    return C, n_used


def _correspondence_inputs(prob: DepthProblem, timings, sees, strips, store):
    """:func:`correspondence`'s checks of its other arguments: ``(sees, strips)`` checked."""
    from .tiling import check_strips

    if timings is not None and not isinstance(timings, dict):
        raise InvalidInputError(f"timings must be None or a dict (seconds per stage are added "
                                f"to it), got {type(timings).__name__}")
    sees = _sees(sees, prob)
    if store is not None and not isinstance(store, ViewCostStore):
        raise InvalidInputError(f"store must be None or a ViewCostStore, got "
                                f"{type(store).__name__}")
    if strips is not None and not isinstance(strips, (list, tuple, np.ndarray)):
        raise InvalidInputError(f"strips must be None or a list of row ranges (a, b), got "
                                f"{_opt.shown(strips)}")
    return sees, check_strips(strips, prob.lf.image_shape[0])


def _all_strips(prob: DepthProblem, strips, scales, sees, bar, clock, store):
    """``(C, n_used)`` of every strip of rows, put together (one strip: its own arrays)."""
    cache: dict = {}
    if len(strips) == 1:
        return _strip_correspondence(prob, strips[0], scales, sees, cache, bar, clock, store)
    shape = (prob.labels.size, *prob.lf.image_shape)
    C, n_used = np.empty(shape, np.float32), np.empty(shape, np.float32)
    for a, b in strips:
        C[:, a:b], n_used[:, a:b] = _strip_correspondence(prob, (a, b), scales, sees, cache,
                                                          bar, clock, store)
    return C, n_used


def defocus_cue(prob: DepthProblem, f_c: np.ndarray):
    """Stage 3 of :func:`depth`: the spectral-aware defocus volume (SPEC §5.3).

    Returns
    -------
    D : ndarray, float32 (L, H, W) or None
        None when ``defocus="off"``.
    lambda_r : ndarray or None
        The reference wavelength(s) used.
    """
    prob = _problem(prob)
    f_c = _map(f_c, "f_c", _image_shape(prob), optional=True)
    if prob.defocus == "off":
        return None, None
    p = prob.params
    prior = "gaussian" if prob.defocus in ("paper", "gaussian") else prob.defocus
    lr_mode = p.lambda_r
    if lr_mode is None:
        lr_mode = "per_label" if prob.defocus == "paper" else "per_pixel"
    In_all = np.stack([prob.In[v] for v in prob.views])
    wl_all = np.array([prob.lf.wavelengths[v] for v in prob.views])
    off_all = np.array([prob.offsets[v] for v in prob.views])
    valid = None if prob.valid is None else np.stack([prob.valid[v] for v in prob.views])
    return defocus_volume(In_all, off_all, wl_all, prob.labels, prior, lr_mode, f_c, p.camera,
                          p.sigma_d, p.achromatic_radius, p.p_eps, prob.impl, valid=valid)


def texture_weight(prob: DepthProblem) -> np.ndarray | None:
    """Stage 4a of :func:`depth`: how much each reference pixel's data term counts.

    ``clip((t^2 - 1) / (texture_snr^2 - 1), 0, 1)`` with ``t`` the texture-to-noise ratio of
    the pixel's ``texture_window`` (:func:`hyperlf.imageops.texture_snr`; noise estimated on
    the valid pixels of the reference view): 0 while the window's texture variance is below
    one noise variance (a 5 x 5 window of pure noise has ``t`` < 1 with probability 0.996),
    rising linearly in texture variance to 1 at ``texture_snr^2`` noise variances.

    Returns
    -------
    ndarray, float32 (H, W) in [0, 1], or None
        None when the weight is off (``params.texture_snr`` 0, or None for a light field that
        does not come from cameras), every weight is 1 (a noise-free image), or the
        optimiser is ``"wta"`` (no neighbours to take a label from: the costs decide alone).
    """
    t0 = _texture_threshold(_problem(prob))
    if t0 == 0:
        return None
    ref = prob.reference
    return _weight_of(prob.In[ref], None if prob.valid is None else prob.valid[ref], t0,
                      int(prob.params.texture_window))


def _texture_threshold(prob: DepthProblem) -> float:
    """``params.texture_snr`` resolved: 0 (off) or the threshold ``T`` of :func:`texture_weight`."""
    t0 = prob.params.texture_snr
    if t0 is None:
        t0 = CAMERA_TEXTURE_SNR if "calibration" in prob.lf.metadata else 0.0
    return 0.0 if prob.optimizer == "wta" else float(t0)


def _weight_of(image: np.ndarray, valid, t0: float, window: int) -> np.ndarray | None:
    """:func:`texture_weight`'s formula on one image (None when every weight is 1)."""
    from .imageops import texture_snr

    t = texture_snr(image, window, valid=valid)
    w = np.clip((t * t - 1.0) / (t0 ** 2 - 1.0), 0.0, 1.0).astype(np.float32)
    return None if bool((w >= 1).all()) else w


def unary(C: np.ndarray, D: np.ndarray | None, params: DepthParams, *, informative=None,
          weight=None):
    """Stage 4b of :func:`depth`: ``U = w (gamma_c norm(C) + norm(D))`` (SPEC §5.4).

    ``informative`` (bool (H, W), optional; :func:`seen_pixels`): the pixels the normalisers
    are measured on; elsewhere ``U`` is 0 at every label (no information: the MRF decides).
    ``weight`` (float (H, W) in [0, 1], optional; :func:`texture_weight`): ``w``, 1 if None.

    Returns
    -------
    U : ndarray, float32 (L, H, W), C-contiguous
    scale_C, scale_D : float, float or None
        The normalisers of :func:`normalise_unary`.

    Examples
    --------
    The data term is each pixel's cost less its own minimum, so every pixel's best label
    costs nothing:

    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    >>> prob = prepare(lf, n_labels=16)
    >>> U, scale_C, scale_D = unary(correspondence(prob)[0], None, prob.params)
    >>> float(U.min(axis=0).max()), scale_D is None
    (0.0, True)
    """
    C = _volume(C, "C")
    D = None if D is None else _volume(D, "D", C.shape)
    params = _depth_params(params)
    informative = _mask(informative, "informative", C.shape[1:], of="C's pixels")
    weight = _weight(weight, "weight", C.shape[1:])
    # the labels beyond the range do not widen the scale: the data term keeps its weight
    scaled = range_labels(C.shape[0], params.margin_labels) if params.margin_labels else None
    # a new volume; C's and D's values are checked on the way (their per-pixel range)
    U, sC = _normalise_unary(C, params.normalise_costs, informative, "C", scaled)
    U *= params.gamma_c  # in place from here: the MRF stage holds as few volumes as it can
    sD = None
    if D is not None:
        Dn, sD = _normalise_unary(D, params.normalise_costs, informative, "D", scaled)
        U += Dn
        del Dn
    if informative is not None:
        U[:, ~np.asarray(informative, bool)] = 0
    if weight is not None:
        U *= np.asarray(weight, np.float32)[None]
    return np.ascontiguousarray(U, np.float32), sC, sD


def add_coarse_prior(U: np.ndarray, labels: np.ndarray, coarse: np.ndarray,
                     strength: np.ndarray, width: float) -> np.ndarray:
    """Stage 4b': ``U[l] += strength min(|labels[l] - coarse|, width) / width``, in place.

    A truncated linear pull towards the coarse estimate (:func:`coarse_disparity`); at
    ``strength`` 1 as strong as a typical normalised data term (whose median range is 1) at
    ``width`` disparity px and beyond.

    Examples
    --------
    >>> import numpy as np
    >>> U = np.zeros((3, 1, 2), np.float32)
    >>> add_coarse_prior(U, np.array([0.0, 1.0, 2.0]), np.array([[0.0, 2.0]]),
    ...                  np.array([[1.0, 0.0]]), width=1.0)[:, 0, :].tolist()
    [[0.0, 0.0], [1.0, 0.0], [1.0, 0.0]]
    """
    if not (isinstance(U, np.ndarray) and U.dtype.kind == "f" and U.ndim == 3
            and U.flags.writeable):
        raise InvalidInputError(f"U must be a writeable (L, H, W) float array (it is added to "
                                f"in place), got {_opt.shown(U)}")
    labels = _labels(labels, n=U.shape[0])
    coarse = _map(coarse, "coarse", U.shape[1:])
    strength = _map(strength, "strength", U.shape[1:])
    return _add_pull(U, labels, coarse, strength, _pull_width(width))


def _add_pull(U, labels, coarse, strength, width):
    """:func:`add_coarse_prior` on checked arguments."""
    pull = np.asarray(strength, np.float32)
    c = np.asarray(coarse, np.float32)
    for k, d in enumerate(np.asarray(labels, np.float32)):
        U[k] += pull * np.minimum(np.abs(d - c), np.float32(width)) / np.float32(width)
    return U


def coarse_prior(prob: DepthProblem, weight, start=None, *, progress: bool | str = False):
    """Stage 4b'' of :func:`depth`: ``(coarse disparity, strength, width, coarse
    confidence)``, the first three for :func:`add_coarse_prior`, or None
    (``params.coarse_prior`` off, no texture weight, or an image too small for a coarse
    level).

    The coarse disparity is :func:`coarse_disparity` at ``s = params.coarse_prior_scale``
    (with ``params.coarse_prior_levels`` > 1 itself made with a coarse prior from ``s^2``,
    and so on), for the levels that keep 8 texture windows on their shorter side (shading
    that spans the image, such as vignetting, must not count as texture).
    ``strength = (1 - w) g``: what the texture weight ``w`` took from a pixel's data term,
    given back where that estimate comes from data, ``g = w_s + (1 - w_s) g_next`` over the
    levels (``w_s`` the texture weight of the reference's block means at level ``s``), never
    where every level's MRF only filled in.  ``start``: the visibility round's coarse
    estimate, ``(disparity, confidence)`` from :func:`coarse_disparity` with
    ``return_confidence``, reused when made at the same scale.
    """
    prob = _problem(prob)
    shape = _image_shape(prob)
    weight = _weight(weight, "weight", shape)
    start = _start(start, shape)
    progress = _progress(progress)
    p = prob.params
    if weight is None or not p.coarse_prior:
        return None
    s = int(p.coarse_prior_scale)
    levels = _prior_levels(prob)
    if not levels:
        return None
    if start is not None and s == int(p.visibility_scale):
        coarse, coarse_conf = start
    else:
        coarse, coarse_conf = coarse_disparity(prob, scale=s, progress=progress,
                                               return_confidence=True)
    strength = (1.0 - np.clip(weight, 0.0, 1.0)) * _coverage(prob, levels)
    step = float(prob.labels[1] - prob.labels[0]) if prob.labels.size > 1 else 1.0
    width = s * step if p.coarse_prior_width is None else float(p.coarse_prior_width)
    return coarse, strength.astype(np.float32), width, coarse_conf


#: :func:`plane_prior` pools the pixels whose texture weight at the coarse level is below
#: this, and pulls the full-resolution pixels whose coarse coverage ``g`` is below it.
PLANE_POOL_WEIGHT = 0.5
#: The smallest automatic tile of :func:`plane_prior`, px of the coarse level: a tile must
#: pool many matching windows' worth of pixels.
PLANE_MIN_TILE = 48


def plane_prior(prob: DepthProblem, weight, prior, *, progress: bool | str = False):
    """Part of stage 4b'' of :func:`depth`, right after :func:`coarse_prior` (before
    :func:`correspondence`, whose volume it does not need): the coarse prior's target on
    weakly textured pixels replaced by slanted planes that their pooled costs choose at the
    coarse prior's scale (``params.weak_planes``).

    A weakly textured pixel's own costs hardly show their minimum, and the coarse estimate
    gives a textureless surface one constant, whichever its neighbours lend it: the lab's
    table front took the objects' disparities in one shot and the board's in the other.
    Pooled over thousands of such pixels, the costs do show where the surface is, slant
    included (BENCHMARKS.md, twenty-sixth and twenty-seventh sessions).  They are pooled on
    the light field downscaled by ``s = params.coarse_prior_scale`` (a matching window there
    covers ``s^2`` times the area, with ``1/s`` of the noise per pixel), by
    :func:`hyperlf.regularisers.cost_planes` on a volume of as many labels as the full run's
    over the range divided by ``s``, each label averaged over the views that see the pixel at
    every label (``missing_views="common"``, whatever the main pass uses: the plain average
    gives the labels that some views cannot see fewer views, a bias towards the range limits
    that pooling would turn into a plane).  Pooled are the pixels of that level whose texture
    weight is below :data:`PLANE_POOL_WEIGHT` and which some view sees at every label.  The
    planes, scaled by ``s``, then become the target of the full-resolution pixels that are
    weakly textured (``w < 1``) and were pooled (the coarse levels' ``g`` below
    :data:`PLANE_POOL_WEIGHT`: a pixel textured at a coarse level keeps ``d_coarse``, which
    that texture located), with strength ``1 - w``.  Fitting at full resolution instead left
    the lab's table front to ``d_coarse`` (BENCHMARKS.md).  Specks are the exception: a pixel
    textured at a coarse level whose ``params.plane_specks`` px square is at least half pooled
    pixels takes the plane too (on the lab's table front such specks of faint texture had
    kept the background's ``d_coarse``; BENCHMARKS.md).

    Parameters
    ----------
    prob : DepthProblem
    weight : ndarray (H, W) or None
        :func:`texture_weight`.
    prior : tuple or None
        :func:`coarse_prior`'s ``(coarse, strength, width, confidence)``.
    progress : bool or str
        A progress bar for the coarse level's costs.

    Returns
    -------
    tuple or None
        ``prior`` with ``coarse`` and ``strength`` replaced under the planes; ``prior`` itself
        when there is no prior or ``params.weak_planes`` is off.
    """
    prob = _problem(prob)
    shape = _image_shape(prob)
    weight = _weight(weight, "weight", shape)
    _prior(prior, shape, sizes=(4,))  # returned as it is where there is nothing to do
    progress = _progress(progress)
    p = prob.params
    if prior is None or weight is None or not p.weak_planes:
        return prior
    s = int(p.coarse_prior_scale)
    plane = _coarse_planes(prob, s, progress=progress)
    if plane is None:
        return prior
    w = np.clip(np.asarray(weight, np.float32), 0.0, 1.0)
    weak = _coverage(prob, _prior_levels(prob)) < PLANE_POOL_WEIGHT
    use = np.isfinite(plane) & (w < 1) & (weak | _specks(weak, int(p.plane_specks)))
    coarse, strength, width, conf = prior
    coarse = np.where(use, plane, coarse).astype(np.float32)
    strength = np.where(use, 1 - w, strength).astype(np.float32)
    return coarse, strength, width, conf


def _specks(weak: np.ndarray, window: int) -> np.ndarray:
    """The pixels of ``~weak`` whose ``window`` px square is at least half ``weak`` pixels
    (none when ``window`` is 0): specks of texture on a weakly textured surface
    (:func:`plane_prior`)."""
    if window == 0:
        return np.zeros(weak.shape, bool)
    from scipy.ndimage import uniform_filter

    share = uniform_filter(weak.astype(np.float32), window, mode="nearest")
    return ~weak & (share >= 0.5)


def _coarse_planes(prob: DepthProblem, s: int, *, progress: bool | str = False):
    """:func:`plane_prior`'s planes: full-resolution disparity px (NaN where no tile was
    accepted), or None when the image is too small for the level ``s`` or nothing there is
    weakly textured."""
    from .regularisers import cost_planes

    coarse = _coarse_problem(prob, s)
    if coarse is None:
        return None
    lf_s, options = coarse
    options.update(n_labels=prob.labels[prob.range_labels].size,
                   params=replace(options["params"], missing_views="common"))
    level = prepare(lf_s, **options)
    w = texture_weight(level)
    if w is None:
        return None
    C, _ = correspondence(level, progress=f"views, planes at 1/{s} resolution" if progress
                          else False)
    pooled = np.logical_or.reduce(list(_seen_at_every_label(level).values()))
    pooled &= w < PLANE_POOL_WEIGHT
    if level.valid is not None:
        pooled &= level.valid[level.reference]
    labels = np.asarray(level.labels, np.float64)
    step = float(labels[1] - labels[0])
    tile = prob.params.plane_tile or max(PLANE_MIN_TILE, min(lf_s.image_shape) // 8)
    carry = prob.params.plane_carry
    plane = cost_planes(C, pooled, tile=int(tile), max_slope=float(prob.params.plane_max_slope)
                        / step, period=1.0 / step, carry=None if carry is None else float(carry),
                        impl=prob.impl)
    return _blow_up(s * (labels[0] + step * plane), s, prob.lf.image_shape)


def _prior_levels(prob: DepthProblem) -> list[int]:
    """The downscaling factors of the coarse prior's levels, finest first."""
    p = prob.params
    s, H, W = int(p.coarse_prior_scale), *prob.lf.image_shape
    levels, k = [], s
    while len(levels) < int(p.coarse_prior_levels) and min(H, W) // k >= 8 * p.texture_window:
        levels.append(k)
        k *= s
    return levels


def _coverage(prob: DepthProblem, levels) -> np.ndarray:
    """``g`` of :func:`coarse_prior` at full resolution: how much of the coarse estimate at
    ``levels[0]`` comes from data, through all the levels (1 everywhere without a level:
    a prior given for an image too small for any is taken as it is)."""
    from .imageops import block_reduce

    ref, shape = prob.reference, prob.lf.image_shape
    if not levels:
        return np.ones(shape, np.float32)
    t0, window = _texture_threshold(prob), int(prob.params.texture_window)
    g = None
    for k in reversed(levels):
        valid = None if prob.valid is None else block_reduce(prob.valid[ref], k, np.all)
        w = _weight_of(block_reduce(prob.In[ref], k), valid, t0, window)
        w = np.ones(shape, np.float32) if w is None else _blow_up(w, k, shape)
        g = w if g is None else w + (1.0 - w) * g
    return g


def regularise(prob: DepthProblem, U: np.ndarray, f_c: np.ndarray, *, init=None,
               optimizer: str | None = None):
    """Stage 4c of :func:`depth`: optimise the MRF on ``U`` (SPEC §5.4).

    ``init``: the label map of the pass before, for a visibility round's plain graph cuts to
    start from (``params.round_cycles`` cycles; ignored when that is None, and by other
    optimisers).  ``optimizer``: one of :data:`OPTIMIZERS` instead of the problem's own
    (:func:`thin_objects` asks SGM for a second opinion on graph cuts' unary).

    Returns
    -------
    labels_map : ndarray, int (H, W)
        The chosen label per pixel.
    volume : ndarray, float32 (L, H, W)
        The volume refinement and confidence read (the SGM-aggregated one for SGM).

    Examples
    --------
    The MRF puts most pixels of a small procedural scene within one label step of the
    truth:

    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    >>> prob = prepare(lf, n_labels=16)
    >>> C = correspondence(prob)[0]
    >>> labels_map, volume = regularise(prob, unary(C, None, prob.params)[0],
    ...                                 prob.labels[C.argmin(axis=0)])
    >>> step = prob.labels[1] - prob.labels[0]
    >>> near = np.abs(prob.labels[labels_map] - lf.reference_gt_disparity) <= step
    >>> labels_map.shape, bool(near.mean() > 0.8)
    ((32, 40), True)
    """
    prob = _problem(prob)
    shape = _volume_shape(prob)
    U = _volume(U, "U", shape, finite=True)
    f_c = _map(f_c, "f_c", shape[1:])
    if init is not None:
        init = _label_map(init, "init", shape[1:], shape[0])
    optimizer = prob.optimizer if optimizer is None else \
        _opt.choice(optimizer, "optimizer", OPTIMIZERS)
    p = prob.params
    labels = prob.labels
    step = float(labels[1] - labels[0])
    guide = prob.In[prob.reference].astype(np.float32)
    mrf = _mrf_params(optimizer, p, step)
    ew = None
    if isinstance(mrf, _reg.GraphCutParams) and p.occlusion_weight != 1.0 and prob.edges.any():
        ew = _occlusion_edge_weights(prob.edges, f_c, p.truncation / 2.0, p.occlusion_weight)
        mrf = replace(mrf, levels=0)  # explicit edge weights need the plain moves
    warm = init is not None and p.round_cycles is not None \
        and isinstance(mrf, _reg.GraphCutParams) and mrf.levels == 0
    if warm:
        mrf = replace(mrf, max_cycles=int(p.round_cycles))
    res = _reg.optimise(U, mrf, guide=guide, labels=labels, edge_weights=ew,
                        init=init if warm else None)
    return res.labels, res.volume


def refine(volume: np.ndarray, labels_map: np.ndarray, labels: np.ndarray,
           params: DepthParams, *, informative=None, weight=None, prior=None):
    """Stage 5 of :func:`depth`: sub-pixel disparity and confidence.

    ``informative`` (bool (H, W), optional; :func:`seen_pixels`): confidence is 0 elsewhere.
    ``weight`` (optional; :func:`texture_weight`): the confidence is scaled by it (a pixel
    whose data term was discounted is as trustworthy as its neighbours' labels, no more;
    :func:`depth` adds the coarse prior's share, module docstring).
    ``prior`` (optional; :func:`coarse_prior`'s tuple): the coarse prior that ``volume``
    holds (graph cuts optimise the unary itself).  The disparity is refined on ``volume``
    as it is; the confidence is measured with the prior's pull taken out
    (:func:`prior_free_confidence`), so that it counts the pixel's own data only.

    Returns
    -------
    disparity : ndarray, float32 (H, W)
        Parabola-refined when ``params.refine``, else the label disparities.
    confidence : ndarray, float32 (H, W)

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    >>> prob = prepare(lf, n_labels=16)
    >>> C = correspondence(prob)[0]
    >>> labels_map, volume = regularise(prob, unary(C, None, prob.params)[0],
    ...                                 prob.labels[C.argmin(axis=0)])
    >>> disparity, confidence = refine(volume, labels_map, prob.labels, prob.params)
    >>> disparity.dtype.name, bool(0 <= confidence.min() <= confidence.max() <= 1)
    ('float32', True)
    """
    from .regularisers import confidence, subpixel_refine

    volume = _volume(volume, "volume", finite=True)
    shape = volume.shape[1:]
    labels_map = _label_map(labels_map, "labels_map", shape, volume.shape[0])
    labels = _labels(labels, n=volume.shape[0])
    params = _depth_params(params)
    informative = _mask(informative, "informative", shape, of="volume's pixels")
    weight = _weight(weight, "weight", shape)
    prior = _prior(prior, shape)
    if params.refine:
        disp = subpixel_refine(volume, labels_map, labels)
    else:
        disp = labels[labels_map].astype(np.float32)
    floor = params.confidence_floor
    if prior is None:
        conf = confidence(volume, labels_map, floor=floor)
    else:
        conf = _prior_free_confidence(volume, labels_map, labels, prior, 64, floor)
    if informative is not None:
        conf = np.where(np.asarray(informative, bool), conf, np.float32(0)).astype(np.float32)
    if weight is not None:
        conf = (conf * np.asarray(weight, np.float32)).astype(np.float32)
    return disp, conf


def prior_free_confidence(volume: np.ndarray, labels_map: np.ndarray, labels: np.ndarray,
                          prior, *, rows: int = 64, floor: float = 0.0) -> np.ndarray:
    """:func:`hyperlf.regularisers.confidence` (with ``floor``) of ``volume`` less the pull
    :func:`add_coarse_prior` added to it, ``rows`` rows at a time (no second volume).

    Examples
    --------
    >>> import numpy as np
    >>> labels = np.arange(5.0)
    >>> U = np.zeros((5, 1, 1), np.float32)                   # no data at all
    >>> prior = (np.full((1, 1), 2.0), np.ones((1, 1)), 1.0)
    >>> U = add_coarse_prior(U, labels, *prior)
    >>> lab = np.full((1, 1), 2)
    >>> from hyperlf.regularisers import confidence
    >>> float(confidence(U, lab)[0, 0]), float(prior_free_confidence(U, lab, labels, prior)[0, 0])
    (1.0, 0.0)
    """
    volume = _volume(volume, "volume", finite=True)
    labels_map = _label_map(labels_map, "labels_map", volume.shape[1:], volume.shape[0])
    labels = _labels(labels, n=volume.shape[0])
    prior = _prior(prior, volume.shape[1:])
    if prior is None:
        raise InvalidInputError("prior must be the tuple of coarse_prior (coarse, strength, "
                                "width[, confidence]), got None")
    rows = _opt.integer(rows, "rows", 1)
    floor = _opt.number(floor, "floor", below=1)
    return _prior_free_confidence(volume, labels_map, labels, prior, rows, floor)


def _prior_free_confidence(volume, labels_map, labels, prior, rows, floor):
    """:func:`prior_free_confidence` on checked arguments."""
    from .regularisers import confidence

    coarse, strength, width = (np.asarray(a, np.float32) for a in prior[:3])
    out = np.empty(labels_map.shape, np.float32)
    for r0 in range(0, labels_map.shape[0], int(rows)):
        rs = slice(r0, r0 + int(rows))
        strip = np.array(volume[:, rs], np.float32)  # a copy: the caller's volume stays
        _add_pull(strip, labels, coarse[rs], -strength[rs], float(width))
        out[rs] = confidence(strip, labels_map[rs], floor=floor)
    return out


def post_filter(disparity: np.ndarray, guide: np.ndarray, params: DepthParams, *,
                passes: int | None = None) -> np.ndarray:
    """Stage 6 of :func:`depth`: the guided weighted median, ``passes`` times (default
    :func:`median_passes` of ``guide``; off when ``params.median_radius == 0``). A radius
    beyond the image's longer side is taken as that side (a window over the whole image).

    Examples
    --------
    A depth edge two pixels right of the image edge is moved onto it:

    >>> guide = np.zeros((20, 40)); guide[:, 20:] = 1.0
    >>> disparity = np.zeros((20, 40)); disparity[:, 22:] = 2.0
    >>> snapped = post_filter(disparity, guide, DepthParams())
    >>> int(np.argmax(snapped[10] > 1))
    20
    """
    from .regularisers import weighted_median

    params = _depth_params(params)
    if passes is not None:
        passes = _opt.integer(passes, "passes", maximum=MAX_MEDIAN_PASSES)
    disparity = _array(disparity, "disparity", ndim=2)
    guide = _array(guide, "guide", disparity.shape, of=" (the disparity's)")
    if params.median_radius <= 0:
        return disparity
    radius = min(int(params.median_radius), max(disparity.shape))
    for _ in range(median_passes(guide, params).passes if passes is None else passes):
        disparity = weighted_median(disparity, guide, radius,
                                    params.median_sigma,
                                    impl="numpy" if params.impl == "numpy" else "numba")
    return disparity


class MedianPasses(NamedTuple):
    """What :func:`median_passes` decided, and from what.

    Attributes
    ----------
    passes : int
        Passes of the post-filter.
    edge_blur_px : float
        The guide's edge blur (:func:`hyperlf.imageops.edge_blur`), px; NaN when not measured
        or when the guide has too few edges to tell.
    noise : float
        The guide's white noise against its mean (:func:`hyperlf.imageops.noise_sigma`); NaN
        when not measured.
    noise_passes : int
        The passes the noise added.
    """

    passes: int
    edge_blur_px: float
    noise: float
    noise_passes: int


def median_passes(guide: np.ndarray, params: DepthParams, *, valid=None) -> MedianPasses:
    """Passes of the post-filter, with the guide's edge blur and noise that set them.

    ``params.median_passes`` when it is a number; with ``"auto"``, one pass per
    ``params.median_blur_step`` px of :func:`hyperlf.imageops.edge_blur` above
    ``params.median_blur_sharp``, at least one (one when the guide has too few edges to
    tell), plus one per ``params.median_noise_step`` of the guide's relative noise
    (:func:`guide_noise`; not read when the step is None or the guide is smaller than
    :data:`NOISE_MIN_SIDE` on a side), at most :data:`MAX_MEDIAN_PASSES`.

    Examples
    --------
    A sharp texture gets one pass; the same texture blurred by another 3 px gets more, since
    soft views carry the foreground further over the background:

    >>> from scipy.ndimage import gaussian_filter
    >>> rng = np.random.default_rng(0)
    >>> sharp = gaussian_filter(rng.random((64, 64)), 1.0)
    >>> soft = gaussian_filter(sharp, 3.0)
    >>> [median_passes(g, DepthParams()).passes for g in (sharp, soft)]
    [1, 4]

    White noise of 2.5 % of the mean (read as 2.2 %) adds two passes, since noise leaves
    blotches in the map:

    >>> smooth = 1.0 + gaussian_filter(rng.standard_normal((128, 128)), 2.0)
    >>> noisy = smooth + 0.025 * rng.standard_normal(smooth.shape)
    >>> got = median_passes(noisy, DepthParams())
    >>> round(got.noise, 3), got.noise_passes, got.passes
    (0.022, 2, 3)
    """
    params = _depth_params(params)
    guide = _array(guide, "guide", ndim=2)
    valid = _mask(valid, "valid", guide.shape, of="the guide")
    if params.median_passes != "auto":
        return MedianPasses(int(params.median_passes), float("nan"), float("nan"), 0)
    from .imageops import edge_blur

    blur = edge_blur(guide, valid=valid)
    base = 1
    if np.isfinite(blur):
        extra = (blur - params.median_blur_sharp) / params.median_blur_step
        base = max(1, int(np.ceil(extra - 1e-9)))
    noise, noise_passes = float("nan"), 0
    if params.median_noise_step is not None and min(guide.shape) >= NOISE_MIN_SIDE:
        noise = guide_noise(guide, valid=valid)
        with np.errstate(over="ignore"):  # a step near 0: at most MAX_MEDIAN_PASSES
            noise_passes = int(min(MAX_MEDIAN_PASSES,
                                   np.floor(noise / params.median_noise_step + 1e-9)))
    return MedianPasses(min(MAX_MEDIAN_PASSES, base + noise_passes), blur, noise, noise_passes)


def guide_noise(guide: np.ndarray, *, valid=None) -> float:
    """White noise of ``guide`` against its mean: :func:`hyperlf.imageops.noise_sigma` over
    the mean of the valid pixels (0 for a guide whose mean is not positive).

    Examples
    --------
    >>> img = 0.2 + 0.004 * np.random.default_rng(0).standard_normal((128, 128))
    >>> round(guide_noise(img), 3)
    0.02
    """
    from .imageops import noise_sigma

    guide = _array(guide, "guide", ndim=2)
    valid = _mask(valid, "valid", guide.shape, of="the guide")
    values = guide if valid is None else guide[valid]
    mean = float(np.mean(values, dtype=np.float64)) if values.size else 0.0
    if not mean > 0:
        return 0.0
    return noise_sigma(guide, valid=valid) / mean


def strips_for(prob: DepthProblem) -> list:
    """The strips of the correspondence stage under ``params.max_memory`` /
    ``params.tile_rows`` (:func:`hyperlf.tiling.plan`)."""
    from .tiling import plan

    p = prob.params
    return plan(prob.lf.image_shape, prob.labels.size, len(prob.views), p.max_memory,
                selection=prob.view_selection, tile_rows=p.tile_rows)


def _config(prob: DepthProblem, sC, sD, *, strips, start, prior, w, passes: MedianPasses,
            thin=None, kept=False) -> dict:
    """``DepthResult.config``: the problem's settings and what the run decided."""
    p = prob.params
    return dict(metric=prob.metric, n_labels=prob.labels[prob.range_labels].size,
                disparity_range=prob.disparity_range, view_selection=prob.view_selection,
                occlusion_split=prob.occlusion_split, defocus=prob.defocus,
                optimizer=prob.optimizer, params=asdict(p), window=prob.window,
                visibility_rounds=prob.visibility_rounds,
                scale_C=sC, scale_D=sD,
                n_edge_pixels=int(prob.edges.sum()), reference=tuple(prob.reference),
                strips=strips, median_passes=passes.passes, edge_blur_px=passes.edge_blur_px,
                view_noise=passes.noise, median_noise_passes=passes.noise_passes,
                visibility_estimate_scale=None if start is None else int(p.visibility_scale),
                visibility_costs_kept=bool(kept),
                coarse_prior_scale=None if prior is None else int(p.coarse_prior_scale),
                coarse_prior_levels=0 if prior is None else len(_prior_levels(prob)),
                weak_data_share=0.0 if w is None else float(np.mean(1.0 - w)),
                coarse_prior_share=0.0 if prior is None else float(np.mean(prior[1])),
                thin_object_share=0.0 if thin is None else float(np.mean(thin)))


class _Clock:
    """Records the seconds of each stage into a dict (a key lapped again adds up)."""

    def __init__(self, timings: dict):
        self.timings = timings
        self.t = time.perf_counter()

    def lap(self, key: str | None = None) -> None:
        now = time.perf_counter()
        if key is not None:
            self.timings[key] = self.timings.get(key, 0.0) + now - self.t
        self.t = now


def _solve(prob: DepthProblem, C, D, seen, f_c, w, prior, clock, passes: int,
           suffix: str = "", init=None):
    """Stages 4-6 of :func:`depth` on one correspondence volume: unary (with the coarse
    prior), MRF (from the labels ``init`` of the pass before, if any), refinement and the
    post-filter.  Returns ``(U, scale_C, scale_D, disparity, confidence, labels)``."""
    U, sC, sD = unary(C, D, prob.params, informative=seen, weight=w)
    if prior is not None:
        _add_pull(U, prob.labels, *prior[:3])
    disp, conf, lab = _solved(prob, U, f_c, seen, w, prior, passes, clock=clock,
                              suffix=suffix, init=init)
    return U, sC, sD, disp, conf, lab


def _solved(prob: DepthProblem, U, f_c, seen, w, prior, passes: int, *, clock=None,
            suffix: str = "", init=None, optimizer: str | None = None):
    """Stages 4c-6 of :func:`depth` on the unary ``U``: MRF (``optimizer``, default the
    problem's), refinement, the coarse prior's share of the confidence and the post-filter.
    Returns ``(disparity, confidence, labels)``; ``clock`` (a :class:`_Clock`, optional)
    records the stages' seconds."""
    lap = (lambda key: None) if clock is None else clock.lap
    lab, vol = regularise(prob, U, f_c, init=init, optimizer=optimizer)
    lap("mrf_s" + suffix)
    disp, conf = refine(vol, lab, prob.labels, prob.params, informative=seen, weight=w,
                        prior=prior if vol is U else None)  # graph cuts: vol is U
    if w is not None and prior is not None and len(prior) > 3 and prior[3] is not None:
        # what the weight took from a pixel came from the coarse estimate
        conf = (conf + (1.0 - np.clip(w, 0.0, 1.0)) * prior[3]).astype(np.float32)
        if seen is not None:
            conf[~seen] = 0.0
    lap("refine_s" + suffix)
    disp = post_filter(disp, prob.In[prob.reference].astype(np.float32), prob.params,
                       passes=passes)
    lap("median_s" + suffix)
    return disp, conf, lab


def thin_objects(prob: DepthProblem, U: np.ndarray, f_c: np.ndarray, disparity: np.ndarray,
                 confidence: np.ndarray, *, informative=None, weight=None, prior=None,
                 passes: int | None = None):
    """Stage 8 of :func:`depth` under graph cuts: the thin foreground that graph cuts gave to
    the background, and the holes they filled with the foreground, taken back from SGM on
    the same unary.

    Graph cuts charge a thin object's whole outline against the few pixels that vouch for
    it, and lose rods, wires and stems that are faint in the reference band to the
    background behind them; SGM, which charges along scanlines, keeps most of them, but
    fattens foreground edges elsewhere.  SGM runs on ``U`` (the unary graph cuts solved,
    coarse prior included), is refined and post-filtered like graph cuts' answer, and where
    :func:`hyperlf.regularisers.thin_foreground` (``params.thin_jump``,
    ``params.thin_touch``, ``params.thin_min_size``) finds a component it puts nearer that
    does not lie along graph cuts' surface at its depth, and that ``U`` prefers (a mean
    saving above ``params.thin_min_support`` of the unary's median range per pixel, the
    median over the pixels whose data term counts: where the data cannot tell the two
    apart, as where masks leave few views, graph cuts' answer stays) on more than half of
    whose pixels the data term counts (a texture weight of at least 0.5: SGM spreads noise
    through weak texture differently from graph cuts, and that is no object), its disparity
    and confidence replace graph cuts' (BENCHMARKS.md, fifty-sixth and fifty-seventh
    sessions).  With ``params.thin_holes``, components that SGM puts farther than graph
    cuts and that are enclosed by graph cuts' foreground
    (:func:`hyperlf.regularisers.enclosed_background`: the same constants and guards, its
    own outline share ``params.thin_hole_touch``, and two guards of its own: a hole lies
    within the image, at a depth graph cuts' map holds elsewhere) are taken too: the
    background of a hole, which the outline's cost closes the same way (fifty-ninth and
    sixtieth sessions).

    Parameters
    ----------
    prob : DepthProblem
    U : ndarray, float32 (L, H, W)
        The unary graph cuts solved (:func:`unary`, with :func:`add_coarse_prior`).
    f_c : ndarray (H, W)
        The winner-takes-all disparity of the correspondence cost (:func:`regularise`).
    disparity, confidence : ndarray (H, W)
        Graph cuts' answer after :func:`post_filter`, and its confidence.
    informative, weight, prior, passes
        As for :func:`refine` and :func:`post_filter` on graph cuts' answer.

    Returns
    -------
    disparity, confidence : ndarray, float32 (H, W)
    taken : ndarray, bool (H, W) or None
        The pixels SGM gave (thin objects and holes); None when the stage is off
        (``params.thin_objects`` False, an optimiser other than graph cuts, or
        ``params.smoothness`` 0).

    Examples
    --------
    A rod 2 px wide before a wall, whose pixels prefer its depth five times more weakly than
    the wall's prefer the wall's: graph cuts give it to the wall, and the stage takes it back
    (the post-filter is off, so that the rule alone acts):

    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    >>> prob = prepare(lf, n_labels=8, params=DepthParams(median_radius=0))
    >>> rod = np.zeros((32, 40), bool); rod[4:28, 18:20] = True
    >>> steps = np.arange(8.0)[:, None, None]
    >>> U = np.where(rod, 0.2 * np.minimum(abs(steps - 6), 3), np.minimum(abs(steps - 1), 3))
    >>> U = U.astype(np.float32)
    >>> f_c = prob.labels[U.argmin(axis=0)]
    >>> labels_map, volume = regularise(prob, U, f_c)
    >>> disparity, confidence = refine(volume, labels_map, prob.labels, prob.params)
    >>> bool((labels_map[rod] == 6).any())
    False
    >>> disparity, confidence, taken = thin_objects(prob, U, f_c, disparity, confidence)
    >>> bool(np.allclose(disparity[rod], prob.labels[6])), bool(taken[~rod].any())
    (True, False)
    """
    prob = _problem(prob)
    p = prob.params
    disparity = _map(disparity, "disparity", _image_shape(prob))
    confidence = _map(confidence, "confidence", disparity.shape)
    weight = _weight(weight, "weight", disparity.shape)
    if not p.thin_objects or prob.optimizer != "graphcut" or p.smoothness == 0:
        return disparity, confidence, None
    d2, c2, _ = _solved(prob, U, f_c, informative, weight, _prior(prior, disparity.shape),
                        passes, optimizer="sgm")
    trusted = None if weight is None else weight >= TRUSTED_WEIGHT
    rule = dict(jump=p.thin_jump, touch=p.thin_touch, min_size=p.thin_min_size,
                support=_reg.label_saving(U, prob.labels, disparity, d2, trusted=trusted),
                min_support=p.thin_min_support, trusted=trusted)
    taken = _reg.thin_foreground(disparity, d2, **rule)
    if p.thin_holes:
        taken |= _reg.enclosed_background(disparity, d2, **dict(rule, touch=p.thin_hole_touch))
    return (np.where(taken, d2, disparity).astype(np.float32),
            np.where(taken, c2, confidence).astype(np.float32), taken)


def edge_discount(conf: np.ndarray, disparity: np.ndarray, params: DepthParams) -> np.ndarray:
    """Stage 9 of :func:`depth`: the result's confidence, ``conf`` (:func:`refine`'s) scaled
    by the distance to the depth edges of the final ``disparity``
    (:func:`hyperlf.regularisers.edge_confidence` with ``params.confidence_edge_px`` and
    ``params.confidence_edge_jump``; ``conf`` as it is when the width is 0).

    Examples
    --------
    Confidence 0 on both sides of a jump, full again 4 px away (the default
    ``confidence_edge_px``):

    >>> step = np.array([[0, 0, 0, 0, 0, 3, 3, 3, 3.0]])
    >>> edge_discount(np.ones((1, 9)), step, DepthParams()).round(2).tolist()
    [[1.0, 0.75, 0.5, 0.25, 0.0, 0.0, 0.25, 0.5, 0.75]]
    """
    from .regularisers import edge_confidence

    disparity = _array(disparity, "disparity", ndim=2, finite=True)
    conf = _map(conf, "conf", disparity.shape)
    params = _depth_params(params)
    w = edge_confidence(disparity, width=params.confidence_edge_px,
                        jump=params.confidence_edge_jump)
    return np.asarray(conf, np.float32) * w


def _matched(prob: DepthProblem, keep_counts: bool, *, store: ViewCostStore | None = None,
             last: bool = False, **options):
    """:func:`correspondence` (``store`` and ``options``) and what :func:`depth` reads off it:
    ``(C, n_used or None unless kept, the pixels some view sees, the winner-takes-all map)``.
    ``last``: the kept view costs are not needed again, and are let go at once."""
    C, n_used = correspondence(prob, store=store, **options)
    if last and store is not None:
        store.clear()  # before anything else is made: the MRF's memory
    seen = seen_pixels(prob, n_used)
    f_c = prob.labels[np.argmin(C, axis=0)].astype(np.float32)
    return C, (n_used if keep_counts else None), seen, f_c


def _visibility_start(prob: DepthProblem, clock: _Clock, progress):
    """What the visibility rounds of :func:`depth` start from: ``(start, sees, first, rounds,
    store)``, the half-resolution estimate (None without one), its visibility for the main
    pass, the number of the main pass's round (1 when it is the first round, else 0), the
    rounds after it, and the :class:`ViewCostStore` that those rounds reuse (None when there
    are none, or the costs do not fit)."""
    rounds, first = prob.visibility_rounds, 0
    start = coarse_disparity(prob, progress=progress, return_confidence=True) if rounds else None
    sees = None if start is None else visibility(prob, start[0], last=rounds == 1)
    if start is not None:
        rounds, first = rounds - 1, 1
        clock.lap("visibility_estimate_s")
    store = ViewCostStore() if rounds and ViewCostStore.fits(prob) else None
    return start, sees, first, rounds, store


def depth(lf, disparity_range=None, *, n_labels: int = 64, metric: str = "auto",
          view_selection: bool = False, occlusion_split: bool = False, defocus: str = "off",
          optimizer: str = "graphcut", params: DepthParams | None = None,
          save_intermediate: bool = False, progress: bool | str = False) -> DepthResult:
    """Disparity of the reference view of an H-LF (SPEC §5).

    A list of stages, each a public function that can be run and tested alone:
    :func:`prepare` -> :func:`texture_weight` -> :func:`coarse_prior` -> :func:`plane_prior`
    -> :func:`correspondence` -> :func:`defocus_cue` -> :func:`unary` ->
    :func:`add_coarse_prior` -> :func:`regularise` -> :func:`refine` ->
    :func:`post_filter` -> :func:`thin_objects` -> :func:`edge_discount`.

    Parameters
    ----------
    lf : LightField
        Monochrome views ``(R, C, H, W)``; ``wavelengths`` are needed for the defocus cue.
    disparity_range : (dmin, dmax), optional
        Default ``lf.disparity_range``; one of the two is required.
    n_labels : int
        Labels evenly spaced over the range (>= 2).
    metric : str
        A light-field cost of :mod:`hyperlf.costs` (``"auto"`` = the library default).
    view_selection, occlusion_split : bool
        The SPEC §5.1 and §5.2 cues (off by default: BENCHMARKS.md, Table 2 ablations).
    defocus : {"off", "paper", "gaussian", "flat", "tv"}
        The SPEC §5.3 cue.
    optimizer : {"graphcut", "sgm", "wta"}
    params : DepthParams, optional
        Every constant.
    save_intermediate : bool
        Keep the volumes in ``result.intermediate``.
    progress : bool or str
        Progress bars on stderr (a string: the label of the main pass's bar).

    Returns
    -------
    DepthResult
        With ``timings`` in seconds per stage (``prepare_s``, ``correspondence_s``,
        ``selection_split_s``, ``plane_prior_s``, ``defocus_s``, ``mrf_s``, ``refine_s``,
        ``median_s``, ``thin_objects_s``, ``total_s``; ``visibility_estimate_s`` when the
        first visibility round starts from :func:`coarse_disparity` (that round is then
        the main pass above); per further visibility round ``k``:
        ``visibility_round{k}_correspondence_s``, ``mrf_s_round{k}``, ``refine_s_round{k}``,
        ``median_s_round{k}``).

    Raises
    ------
    InvalidInputError
        Not a LightField / not monochrome, no disparity range, defocus without wavelengths,
        unknown metric / optimiser / defocus mode, fewer than 2 views.

    References
    ----------
    .. [1] K. Zhu, Y. Xue, Q. Fu, S. B. Kang, X. Chen and J. Yu, "Hyperspectral Light Field
       Stereo Matching", IEEE TPAMI.

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> from hyperlf.hlf import depth
    >>> lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    >>> res = depth(lf, n_labels=16)
    >>> res.disparity.shape
    (32, 40)
    """
    timings: dict[str, float] = {}
    clock = _Clock(timings)
    t0 = clock.t
    save_intermediate = _opt.flag(save_intermediate, "save_intermediate")
    progress = _progress(progress)
    prob = prepare(lf, disparity_range=disparity_range, n_labels=n_labels, metric=metric,
                   view_selection=view_selection, occlusion_split=occlusion_split,
                   defocus=defocus, optimizer=optimizer, params=params)
    clock.lap("prepare_s")
    strips = strips_for(prob)
    start, sees, first, rounds, store = _visibility_start(prob, clock, progress)
    w = texture_weight(prob)
    prior = coarse_prior(prob, w, start, progress=progress)
    clock.lap("coarse_prior_s")
    prior = plane_prior(prob, w, prior, progress=progress)
    clock.lap("plane_prior_s")
    C, n_used, seen, f_c = _matched(prob, save_intermediate, progress=progress, timings=timings,
                                    sees=sees, strips=strips, store=store)
    clock.lap()
    D, lam_r = defocus_cue(prob, f_c)
    f_d = None if D is None else prob.labels[np.argmin(D, axis=0)].astype(np.float32)
    clock.lap("defocus_s")
    mp = median_passes(prob.In[prob.reference], prob.params,
                       valid=None if prob.valid is None else prob.valid[prob.reference])
    passes = mp.passes
    U, sC, sD, disp, conf, lab = _solve(prob, C, D, seen, f_c, w, prior, clock, passes)
    for k in range(first + 1, first + rounds + 1):
        sees = visibility(prob, disp, last=k == first + rounds)
        C = U = None  # the new round's volumes replace them: not both at once
        C, n_used, seen, f_c = _matched(
            prob, save_intermediate, last=k == first + rounds,
            progress=f"views, visibility round {k}" if progress else False, sees=sees,
            strips=strips, store=store)
        clock.lap(f"visibility_round{k}_correspondence_s")
        U, sC, sD, disp, conf, lab = _solve(prob, C, D, seen, f_c, w, prior, clock, passes,
                                            suffix=f"_round{k}", init=lab)
    if not save_intermediate:
        C = None  # not needed again: the thin-object stage's volumes in its place
    disp, conf, thin = thin_objects(prob, U, f_c, disp, conf, informative=seen, weight=w,
                                    prior=prior, passes=passes)
    clock.lap("thin_objects_s")
    conf = edge_discount(conf, disp, prob.params)
    if prob.params.margin_labels:
        disp = np.clip(disp, *prob.disparity_range)
    timings["total_s"] = time.perf_counter() - t0
    inter = None
    if save_intermediate:
        inter = dict(C=C, D=D, unary=U, edges=prob.edges, lambda_r=lam_r, n_selected=n_used,
                     texture_weight=w, coarse_disparity=None if prior is None else prior[0],
                     coarse_prior_strength=None if prior is None else prior[1],
                     thin_objects=thin)
    return DepthResult(disparity=np.asarray(disp, np.float32), confidence=conf, f_c=f_c,
                       f_d=f_d, labels=prob.labels, timings=timings,
                       config=_config(prob, sC, sD, strips=strips, start=start, prior=prior,
                                      w=w, passes=mp, thin=thin,
                                      kept=store is not None),
                       intermediate=inter)
