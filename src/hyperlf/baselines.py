"""Light-field depth baselines of the paper's Table 2 (SPEC §5 "Baselines").

Three classic light-field depth methods, re-implemented from their papers (and, where the notes
in ``notes/baselines-and-formats.md`` checked them, from the authors' released code; no code was
copied). As in the paper, they see the H-LF views as **plain intensities**: they know nothing
about the filters, so on a hyperspectral light field they compare different bands as if they
were the same; on a same-spectrum light field they are ordinary light-field depth methods.

Public API
----------
``tao2013(lf, n_labels=64, disparity_range=None, progress=False, **params)``,
``wang2015(...)``, ``lin2015(...)`` return a :class:`BaselineResult`; :data:`METHODS` maps the
names to the functions; :data:`DEFAULTS` holds each method's parameters (``**params`` overrides
them; an unknown name raises :class:`~hyperlf.errors.InvalidInputError`).

Examples
--------
>>> from hyperlf import synthesis
>>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
>>> {name: method(lf, n_labels=8).disparity.shape for name, method in METHODS.items()}
{'tao2013': (24, 32), 'wang2015': (24, 32), 'lin2015': (24, 32)}

Common conventions (all three)
------------------------------
* **Input.** A :class:`~hyperlf.lightfield.LightField`. Monochrome views ``(R, C, H, W)`` are
  used as they are. Colour views ``(R, C, H, W, 3)`` are reduced to their Rec. 709 luma
  ``0.2126 R + 0.7152 G + 0.0722 B`` of the stored values (no linearisation); other channel
  counts to the channel mean. Tao's and Wang's codes work on RGB and sum/RMS over channels;
  using one luminance channel is our simplification (the H-LF case is monochrome anyway).
* **Labels.** ``n_labels`` disparities evenly spaced over ``disparity_range`` (default
  ``lf.disparity_range``). The papers' own parametrisations (Tao's shear ``alpha`` with
  ``1 - 1/alpha``, Wang's ``[-d_max, d_max]`` in 0.01 px steps) are replaced by these disparities.
* **Geometry.** Every shift uses ``lf.offsets`` (SPEC §1): the reference pixel ``(x, y)`` at
  disparity ``d`` is sampled in the view with offset ``(dx, dy)`` at ``(x - d dx, y - d dy)``,
  bilinearly. Samples beyond the image are **clamped to the border** (as in Tao's and Wang's
  released code) rather than masked, so every label has a finite cost at every pixel. All
  sampling goes through :mod:`hyperlf.warp` with ``edge="clamp"``; a constant shift is
  separable (:func:`hyperlf.warp.shift_map`, float32 weights, x then y).
* **Streaming.** Pixels are vectorised, labels are looped over (a progress bar with
  ``progress=True``), and for each label the views are accumulated one at a time (sums and sums
  of squares), so memory is a few ``(L, H, W)`` float32 volumes, never ``(L, R, C, H, W)``.
* **Sub-pixel.** A parabola through the cost at the winning label
  (:func:`hyperlf.regularisers.subpixel_refine`); details per method below.

Tao et al. 2013 (ICCV), "Depth from combining defocus and correspondence" -- :func:`tao2013`
-----------------------------------------------------------------------------------------
Faithful points: for each label the light field is sheared (refocused); **defocus response**
``D_d(p)`` = mean over a ``window x window`` box (paper ``W_D`` = 9x9) of ``|Laplacian(Lbar_d)|``
where ``Lbar_d`` is the refocused image (mean over views) -- the paper's Eq. 2-3 (the released
code uses ``|d/dx|`` instead; ``defocus_operator="gradient_x"`` selects that);
**correspondence response** ``C_d(p)`` = angular standard deviation averaged over the same
window (Eq. 4-5); ``depth_D = argmax_d D``, ``depth_C = argmin_d C``; **confidence** = peak
ratio (Eq. 7): defocus = highest / second-highest local maximum, correspondence = second-lowest /
lowest local minimum (fallback to the second-best value when there is no other local extremum),
both normalised jointly; **fusion** (Eq. 9-11): minimise
``sum_src W_src (Z - Z_src)^2 + lambda_flat |grad Z|^2 + lambda_smooth |Laplacian Z|^2`` with
``W_C = conf_C ** 0.2``, ``W_D = conf_D ** 0.6``, ``lambda_flat = lambda_smooth = 2`` (code
values), then reweighted (IRLS) towards the paper's L1 data term.
Simplifications: the two cue depths are refined by a parabola before fusion (sub-pixel
``Z_src``), the fusion is one sparse linear solve (``scipy.sparse``) per IRLS step (default 2
steps, as the code effectively does), without the code's edge masks; confidences are
normalised by the 99th percentile of the pooled peak ratios instead of the global maximum (a
noise-free pixel has an infinite ratio and would zero every other weight); the IRLS softness
``irls_epsilon`` is in label steps (so the result scales exactly with the baselines); luminance
instead of RMS over RGB. ``confidence`` of the result = the larger of the two normalised
confidences. ``irls_iterations`` defaults to the code's 2 reweighting steps, even though plain
least squares (``0``) measured better on grey procedural scenes (BENCHMARKS.md): the baseline
follows the code.

Wang et al. 2015 (ICCV), "Occlusion-aware depth estimation using light-field cameras" -- :func:`wang2015`
------------------------------------------------------------------------------------------------------
Faithful points: Canny edges of the reference view (Gaussian sigma sqrt(2), thresholds as
MATLAB's defaults: high = 70th percentile of the gradient magnitude, low = 0.4 high); edge
orientation = orientation of the second moments of the edge pixels in a 5x5 window (the code's
``regionprops`` orientation); orientations spread to pixels within ``band_radius`` = 4 px of an
edge (the code dilates the orientation map with a disk of radius 4). At those pixels the views
are split into two half-planes by the line through the reference position along the edge
orientation (views within ``split_margin`` baselines of the line belong to neither half); per
half the sample variance (N - 1) and mean; **colour-consistency check**: with ``px+``/``px-``
the reference intensities 2 px either side of the edge along the normal,
``dif1 = (mean+ - px+)^2 + (mean- - px-)^2`` and ``dif2`` the swapped pairing; if
``dif1 < dif2 + 0.05`` the cost is ``min(std+, std-)``, else 1 (the code's constant). The pairing
follows from SPEC §1: the views on the ``+n`` side of the line are the ones in which an occluder
on the ``+n`` side of the pixel covers it. Elsewhere the cost is the full angular standard
deviation. **Refocus cost** ``|mean - I_ref(p)|`` (mean of the chosen half at split pixels).
Both costs are cross-bilateral filtered (5x5, range sigma 0.01 on the reference; filtering is
linear so the sum is filtered once), total = corr + 1 * refocus; initial depth = argmin.
**Occlusion map** at the initial depth: ``occ_v = max(var+/var-, var-/var+)`` clipped to 100
and ``occ_f = (mean+ - mean-)^2`` clipped to 0.01, each z-scored over the edge band,
``occ = (occ_v > 0) & (occ_f > 0) & (occ_v occ_f > 1)``, components smaller than 2 px removed.
**Confidence** = peak ratio - 1 (second-lowest / lowest local minimum), 0 where not finite, and 0
where the initial label is in the outer 10 % of the range. **MRF** (alpha-expansion,
:func:`hyperlf.regularisers.graphcut`): unary ``1 - exp(-(l - l0)^2 / (2 s^2))`` with
``s = 0.1 L clip(1 - conf, 0.01, 1)`` (labels); pairwise weight per 4-neighbour pair
``1 / (0.2 (|dSobel| + canny_w |dCanny| + 1e5 |dOcc| + 0.1))`` (passed as ``edge_weights``);
**3x3 median** post-filter.
Simplifications: orientation spread to the band by nearest edge pixel (the code's grey-scale
dilation takes the maximum angle); ``split_margin`` default 0.5 baseline (the code drops about
one angular unit, which on a 3x3 grid would leave diagonal edges with two views per half); a
half with fewer than 2 views disables the split there; the code's label cost
``min(0.3, 1 - Gaussian(sigma = 0.05 L))`` is not a metric, so it is replaced by the truncated
linear ``0.3 min(|dd|, T) / T`` with ``T`` where the Gaussian reaches 0.3
(``T = 0.845 * 0.05 * span``); ``|dSobel|`` is the difference of the Sobel gradient magnitude of
the reference (per-pixel derivative units) and ``|dCanny|``, ``|dOcc|`` of the binary maps,
``canny_w = 1`` (not found in the notes); ``occEdge`` (body not found) is omitted; the
bilateral filter has uniform spatial weights. Sub-pixel: parabola through the filtered cost at
the MRF label, before the median filter. **Tuned:** the code's relative scale of unary and
pairwise terms is not known; with the code's pairwise constants and ``smooth_weight = 1`` the
MRF over-smooths on grey procedural scenes, so the default is ``smooth_weight = 0.1``
(BENCHMARKS.md). Known weakness (faithful behaviour, not a bug): on densely textured scenes the
Canny band covers almost every pixel, and at a *texture* edge the half whose samples stay on the
pixel's own side has near-zero variance at every depth behind the true one, so the split raises
the interior error while only slightly helping at true occlusions (BENCHMARKS.md).

Lin et al. 2015 (ICCV), "Depth recovery from light field using focal stack symmetry" -- :func:`lin2015`
---------------------------------------------------------------------------------------------------
Faithful points: a focal stack ``F(p, d)`` by shift-and-add refocusing; **focal-stack symmetry
cost** ``S(p, d) = sum_{window} mean_{k=1..K} rho(F(p, d + k) - F(p, d - k))`` with the
truncated L1 ``rho(v) = min(|v|, tau)``, ``K`` labels covering ``symmetry_span`` px of disparity
(the in-focus slice is the centre of symmetry of the focal profile of a non-occluding pixel);
**data consistency** ``sum_{window} |Fall(p, d) - I_ref(p)|``; both normalised (by their
median per-pixel range), combined ``S + data_weight * D`` and regularised by graph cuts
(alpha-expansion, truncated-linear smoothness, contrast-sensitive weights from the reference).
Simplifications: the paper's data consistency is an analysis-by-synthesis comparison of the
focal stack re-rendered from the current depth and all-in-focus image with the captured one,
iterated with the depth estimate, and occlusion-aware; here it is the plain (non-iterative)
difference between the refocused image and the reference view. The symmetry of the focal
profile needs a centrally symmetric aperture, so ``F`` for the symmetry cost is built from the
views whose mirror position about the reference exists (e.g. the 5x5 centred sub-grid of a 5x6
array; all views if fewer than 2 such views); ``Fall`` (data term) uses all views. At the first
and last labels (no symmetric pair) the symmetry cost is the pixel's worst value.
``rho``, ``tau``, ``K`` and the weights are our choices (no released code; ``symmetry_span = 1``
and ``smooth_weight = 1`` picked on grey procedural scenes, BENCHMARKS.md). Sub-pixel: parabola
through the combined cost at the graph-cut label. The symmetry cost alone is a poor cue: two
slices far from focus are both blurred and nearly equal, so the cost is also near zero at
strongly defocused labels; the data term resolves that ambiguity and the graph cut does the
rest (figures in BENCHMARKS.md).
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from . import regularisers as _reg
from ._options import check_values, choice, flag, integer, mapping, number, rule, word_or
from ._progress import progress_bar
from .errors import InvalidInputError
from .lightfield import LightField, resolve_disparity_range
from .warp import sample_bilinear, shift_map

__all__ = ["BaselineResult", "tao2013", "wang2015", "lin2015", "METHODS", "DEFAULTS",
           "prepare_views", "label_disparities"]


@dataclass
class BaselineResult:
    """Output of a baseline method.

    Attributes
    ----------
    disparity : float32 (H, W)
        Reference-view disparity (px per baseline, SPEC §1 sign).
    confidence : float32 (H, W)
        Method-specific confidence in [0, 1] (module docstring).
    timings : dict
        Seconds per stage plus ``total``.
    maps : dict
        Intermediate maps (per-cue depths, confidences, edges, occlusion, ...), (H, W) arrays
        (plus a few scalars, e.g. ``n_symmetric_views``).
    method : str
    labels : float64 (L,)
        The label disparities.
    params : dict
        The parameters actually used.
    """

    disparity: np.ndarray
    confidence: np.ndarray
    timings: dict
    maps: dict = field(default_factory=dict)
    method: str = ""
    labels: np.ndarray | None = None
    params: dict = field(default_factory=dict)


#: Default parameters per method (module docstring says where each value comes from).
DEFAULTS: dict[str, dict[str, Any]] = {
    "tao2013": dict(window=9, defocus_operator="laplacian", conf_exponent_corr=0.2,
                    conf_exponent_defocus=0.6, lambda_flat=2.0, lambda_smooth=2.0,
                    irls_iterations=2, irls_epsilon=1.0, conf_percentile=99.0),
    "wang2015": dict(band_radius=4, orientation_window=5, split_margin=0.5, consistency_offset=2.0,
                     consistency_threshold=0.05, inconsistent_cost=1.0, refocus_weight=1.0,
                     bilateral_radius=2, bilateral_sigma=0.01, canny_sigma=float(np.sqrt(2.0)),
                     canny_non_edge=0.7, canny_low_ratio=0.4, canny_weight=1.0,
                     occlusion_weight=1e5, smooth_weight=0.1, max_cycles=3, median=3),
    "lin2015": dict(window=5, symmetry_span=1.0, tau=0.1, data_weight=1.0, smooth_weight=1.0,
                    truncation=None, edge_sigma=None, max_cycles=3),
}

_LUMA = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)

#: Largest window, radius, offset or sigma in px; largest weight, threshold or exponent; most
#: iterations or cycles. Beyond them nothing changes that the result can show, and near the
#: largest floats the arithmetic overflows or the loops never end.
MAX_PX, MAX_CONSTANT, MAX_ITERATIONS = 1000, 1e6, 100

_px = rule(number, at_most=MAX_PX)
_weight = rule(number, at_most=MAX_CONSTANT)
_sigma = rule(number, at_least=1e-6, at_most=MAX_CONSTANT)
_window = rule(integer, minimum=1, maximum=MAX_PX, odd=True)
_count = rule(integer, minimum=0, maximum=MAX_ITERATIONS)

#: Every parameter's rule per method, checked by :func:`_merge` before any work.
_RULES: dict[str, dict[str, Callable]] = {
    "tao2013": dict(window=_window, defocus_operator=rule(choice, choices=("laplacian",
                                                                           "gradient_x")),
                    conf_exponent_corr=_weight, conf_exponent_defocus=_weight,
                    lambda_flat=_weight, lambda_smooth=_weight, irls_iterations=_count,
                    irls_epsilon=rule(number, positive=True, at_most=MAX_CONSTANT),
                    conf_percentile=rule(number, positive=True, at_most=100)),
    "wang2015": dict(band_radius=_px, orientation_window=_window, split_margin=_weight,
                     consistency_offset=_px, consistency_threshold=_weight,
                     inconsistent_cost=_weight, refocus_weight=_weight,
                     bilateral_radius=rule(integer, maximum=MAX_PX), bilateral_sigma=_sigma,
                     canny_sigma=_px, canny_non_edge=rule(number, positive=True, below=1),
                     canny_low_ratio=rule(number, positive=True, at_most=1),
                     canny_weight=_weight, occlusion_weight=_weight, smooth_weight=_weight,
                     max_cycles=_count, median=rule(integer, maximum=MAX_PX)),
    "lin2015": dict(window=_window, symmetry_span=rule(number, positive=True, at_most=MAX_PX),
                    tau=rule(number, positive=True, at_most=MAX_CONSTANT),
                    data_weight=_weight, smooth_weight=_weight,
                    truncation=word_or(rule(number, positive=True, at_most=MAX_CONSTANT),
                                       (None,), f"None or a number in (0, {MAX_CONSTANT:g}]"),
                    edge_sigma=word_or(_sigma, (None,),
                                       f"None or a number in [1e-06, {MAX_CONSTANT:g}]"),
                    max_cycles=_count),
}


# ----------------------------------------------------------------------------------------------
# shared helpers
# ----------------------------------------------------------------------------------------------

def _check_lf(lf) -> LightField:
    if not isinstance(lf, LightField):
        raise InvalidInputError(
            f"expected a hyperlf.LightField, got {type(lf).__name__}; build one with "
            "hyperlf.LightField(views=...) or load it with hyperlf.load(path)")
    if lf.n_views < 2:
        raise InvalidInputError("depth from a light field needs at least 2 views, got 1")
    H, W = lf.image_shape
    if H < 3 or W < 3:
        raise InvalidInputError(f"views must be at least 3 x 3 pixels, got {H} x {W}")
    return lf


def prepare_views(lf: LightField) -> np.ndarray:
    """The views as plain intensities (module docstring, "Input").

    Parameters
    ----------
    lf : LightField

    Returns
    -------
    ndarray, shape (R, C, H, W)
        Monochrome views as they are; Rec. 709 luma (float32) of 3-channel views, the channel
        mean (float32) of others.

    Examples
    --------
    Pure red weighs 0.2126 in Rec. 709 luma:

    >>> red = LightField(np.zeros((1, 2, 4, 4, 3), np.float32) + np.float32([1, 0, 0]))
    >>> grey = prepare_views(red)
    >>> grey.shape, round(float(grey[0, 0, 0, 0]), 4)
    ((1, 2, 4, 4), 0.2126)
    >>> mono = LightField(np.ones((1, 2, 4, 4), np.float32))
    >>> prepare_views(mono) is mono.views
    True
    """
    if not isinstance(lf, LightField):
        raise InvalidInputError(f"expected a hyperlf.LightField, got {type(lf).__name__}")
    v = lf.views
    if v.ndim == 4:
        return v
    if v.shape[-1] == 3:
        return np.tensordot(v, _LUMA, axes=([4], [0])).astype(np.float32)
    return v.mean(axis=-1, dtype=np.float32)


def label_disparities(lf: LightField, n_labels, disparity_range=None) -> np.ndarray:
    """``n_labels`` disparities evenly spaced over ``disparity_range``.

    Parameters
    ----------
    lf : LightField
    n_labels : int
        Number of labels (>= 3).
    disparity_range : (float, float), optional
        Default ``lf.disparity_range``.

    Returns
    -------
    ndarray of float64 (n_labels,)

    Raises
    ------
    InvalidInputError
        When ``n_labels`` is not an integer >= 3.

    Examples
    --------
    >>> lf = LightField(np.ones((3, 3, 24, 32), np.float32), disparity_range=(-3, 3))
    >>> label_disparities(lf, 7).tolist()
    [-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0]
    >>> label_disparities(lf, 3, (0, 1)).tolist()
    [0.0, 0.5, 1.0]
    """
    from .tiling import check_label_volume

    lf = _check_lf(lf)
    n_labels = integer(n_labels, "n_labels", 3)
    check_label_volume(n_labels, lf.image_shape)
    dmin, dmax = resolve_disparity_range(lf, disparity_range)
    return np.linspace(dmin, dmax, n_labels)


def _merge(method: str, params: dict) -> dict:
    """``params`` over :data:`DEFAULTS` of ``method``, every value checked by :data:`_RULES`."""
    p = dict(DEFAULTS[method])
    mapping(params, "params", keys=sorted(p), taker=method)
    p.update(params)
    checked = check_values(p, _RULES[method])
    # integers in their canonical type (a window of 9.0 is 9); numbers stay as given
    p.update({k: v for k, v in checked.items() if type(v) is int})
    return p


def _shift(img: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """``img`` sampled at ``(x + sx, y + sy)``: the baselines' separable shift (module docstring:
    replicated border, float32 weights, x then y)."""
    return shift_map(img, sx, sy, edge="clamp", dtype=np.float32, order="xy")[0]


def _warp_clamped(img: np.ndarray, disp: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``img`` at ``(x - disp dx, y - disp dy)`` per pixel, bilinear, clamped (SPEC §1 sign)."""
    H, W = img.shape
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    out, _ = sample_bilinear(img, xx - disp * dx, yy - disp * dy, edge="clamp")
    return out.astype(np.float32)


def _view_list(lf: LightField, views: np.ndarray):
    R, C = lf.grid_shape
    off = lf.offsets
    return [(views[r, c], float(off[r, c, 0]), float(off[r, c, 1]))
            for r in range(R) for c in range(C)]


def _box(a: np.ndarray, w: int) -> np.ndarray:
    from scipy import ndimage
    return ndimage.uniform_filter(a, size=w, mode="nearest") if w > 1 else a


def _peak_ratio(cost: np.ndarray, maximise: bool = False, eps: float = 1e-9) -> np.ndarray:
    """Hirschmüller's peak ratio along axis 0 (>= 1; larger = more confident).

    Minimise: second-lowest local minimum / lowest value; maximise: highest value /
    second-highest local maximum. Local extrema include the end labels; with no second local
    extremum the second-best value overall is used (the code's sorted-values fallback).
    """
    c = np.asarray(cost, dtype=np.float64)
    if maximise:
        c = -c
    L = c.shape[0]
    loc = np.ones(c.shape, dtype=bool)
    loc[1:] &= c[1:] <= c[:-1]
    loc[:-1] &= c[:-1] <= c[1:]
    best = np.argmin(c, axis=0)
    lab = np.arange(L)[:, None, None]
    others = loc & (lab != best[None])
    second = np.where(others, c, np.inf).min(axis=0)
    srt = np.partition(c, 1, axis=0)[1]
    second = np.where(np.isfinite(second), second, srt)
    first = np.take_along_axis(c, best[None], axis=0)[0]
    if maximise:
        num, den = -first, -second
    else:
        num, den = second, first
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.maximum(num, 0.0) / np.maximum(den, eps)
    return np.where(np.isfinite(ratio), np.maximum(ratio, 1.0), 1.0)


def _shifted_views(vl, d: float):
    """Each view of ``vl`` as ``(img, shifted)``, ``shifted`` sampled at disparity ``d``."""
    for img, dx, dy in vl:
        yield img, _shift(img, -d * dx, -d * dy)


@dataclass
class _Run:
    """One baseline run: the stages every method shares (checked input, labels, parameters,
    intensity views) and the bookkeeping of its stage timings."""

    method: str
    labels: np.ndarray
    p: dict
    vl: list
    ref: np.ndarray
    progress: bool
    t0: float
    timings: dict = field(default_factory=dict)

    @contextmanager
    def stage(self, name: str):
        """Time the block as stage ``name``."""
        t = time.perf_counter()
        yield
        self.timings[name] = time.perf_counter() - t

    def each_label(self, what: str = "labels"):
        """``(index, disparity)`` of every label, with a progress bar when asked for."""
        L = self.labels.size
        return progress_bar(enumerate(self.labels), f"{self.method}: {what}", total=L,
                            enabled=self.progress, unit="label")

    def finish(self, disparity, confidence, maps) -> BaselineResult:
        """The result; floating-point maps become float32, confidence is clipped to [0, 1]."""
        self.timings["total"] = time.perf_counter() - self.t0
        maps = {k: v.astype(np.float32) if isinstance(v, np.ndarray) and v.dtype.kind == "f"
                else v for k, v in maps.items()}
        return BaselineResult(disparity=np.asarray(disparity, dtype=np.float32),
                              confidence=np.clip(np.asarray(confidence, dtype=np.float32), 0, 1),
                              timings=self.timings, maps=maps, method=self.method,
                              labels=np.asarray(self.labels, dtype=np.float64), params=self.p)


def _start(method: str, lf, n_labels, disparity_range, params: dict, progress: bool) -> _Run:
    """Check the light field, make the labels, merge and check the parameters, and reduce the
    views to intensities (module docstring, "Common conventions")."""
    t0 = time.perf_counter()
    lf = _check_lf(lf)
    progress = flag(progress, "progress")
    labels = label_disparities(lf, n_labels, disparity_range)
    p = _merge(method, params)
    views = prepare_views(lf)
    return _Run(method=method, labels=labels, p=p, vl=_view_list(lf, views),
                ref=views[lf.reference].astype(np.float32), progress=progress, t0=t0)


# ----------------------------------------------------------------------------------------------
# Tao et al. 2013
# ----------------------------------------------------------------------------------------------

def _grid_operators(H: int, W: int):
    from scipy import sparse

    def d1(n):
        if n < 2:
            return sparse.csr_matrix((0, n))
        return sparse.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n))

    def d2(n):
        if n < 3:
            return sparse.csr_matrix((0, n))
        return sparse.diags([np.ones(n - 2), -2 * np.ones(n - 2), np.ones(n - 2)], [0, 1, 2],
                            shape=(n - 2, n))

    Iw, Ih = sparse.identity(W), sparse.identity(H)
    Dx = sparse.kron(Ih, d1(W))
    Dy = sparse.kron(d1(H), Iw)
    Lxx = sparse.kron(Ih, d2(W))
    Lyy = sparse.kron(d2(H), Iw)
    return Dx, Dy, Lxx, Lyy


def _tao_fuse(z_src, w_src, lam_flat, lam_smooth, n_irls, eps):
    """Weighted least squares fusion of the cue depths with flatness + smoothness terms."""
    from scipy import sparse
    from scipy.sparse.linalg import spsolve

    H, W = z_src[0].shape
    Dx, Dy, Lxx, Lyy = _grid_operators(H, W)
    # |Laplacian Z|^2 with the Laplacian split as the two second differences on the interior
    P = lam_flat * (Dx.T @ Dx + Dy.T @ Dy) + lam_smooth * (Lxx.T @ Lxx + Lyy.T @ Lyy)
    zs = [z.ravel().astype(np.float64) for z in z_src]
    ws = [np.maximum(w.ravel().astype(np.float64), 0.0) for w in w_src]
    wsum = sum(ws)
    z = sum(w * s for w, s in zip(ws, zs)) / np.maximum(wsum, 1e-12)
    floor = 1e-6  # keeps the system positive definite where both confidences are 0
    for it in range(max(int(n_irls), 0) + 1):
        if it == 0:
            wi = ws
        else:
            wi = [w / np.sqrt((z - s) ** 2 + eps ** 2) * eps for w, s in zip(ws, zs)]
        A = sparse.diags(sum(wi) + floor) + P
        b = sum(w * s for w, s in zip(wi, zs)) + floor * z
        z = spsolve(A.tocsc(), b)
    return z.reshape(H, W)


def _tao_responses(run: _Run):
    """Defocus response (contrast of the refocused image) and correspondence response (angular
    standard deviation) per label, both box-averaged over the window."""
    from scipy import ndimage
    w = int(run.p["window"])
    laplacian = run.p["defocus_operator"] == "laplacian"
    n = len(run.vl)
    H, W = run.ref.shape
    Dvol = np.empty((run.labels.size, H, W), dtype=np.float32)
    Cvol = np.empty((run.labels.size, H, W), dtype=np.float32)
    for li, d in run.each_label():
        s = np.zeros((H, W), dtype=np.float32)
        q = np.zeros((H, W), dtype=np.float32)
        for _, v in _shifted_views(run.vl, d):
            s += v
            q += v * v
        mean = s / n
        var = np.maximum(q / n - mean * mean, 0.0)
        if laplacian:
            contrast = np.abs(ndimage.laplace(mean, mode="nearest"))
        else:
            contrast = np.abs(np.gradient(mean, axis=1))
        Dvol[li] = _box(contrast, w)
        Cvol[li] = _box(np.sqrt(var), w)
    return Dvol, Cvol


def _tao_cues(Dvol: np.ndarray, Cvol: np.ndarray, labels: np.ndarray, pct: float):
    """Sub-pixel cue depths and their peak-ratio confidences, normalised jointly by the
    ``pct`` percentile of the pooled ratios."""
    depth_d = _reg.subpixel_refine(-Dvol, np.argmax(Dvol, axis=0), labels)
    depth_c = _reg.subpixel_refine(Cvol, np.argmin(Cvol, axis=0), labels)
    ratio_d = _peak_ratio(Dvol, maximise=True)
    ratio_c = _peak_ratio(Cvol)
    norm = float(np.percentile(np.concatenate([ratio_d.ravel(), ratio_c.ravel()]), pct))
    norm = norm if norm > 0 else 1.0
    return depth_d, depth_c, np.clip(ratio_d / norm, 0, 1), np.clip(ratio_c / norm, 0, 1)


def tao2013(lf: LightField, *, n_labels: int = 64, disparity_range=None,
            progress: bool = False, **params) -> BaselineResult:
    """Tao et al. 2013: defocus + correspondence cues, peak-ratio confidences, global fusion.

    The module docstring ("Tao et al. 2013") says which steps follow the paper's equations or
    the released code and which are simplified; its Examples run all three baselines.

    Parameters
    ----------
    lf : LightField
        At least 2 views of at least 3 x 3 px (module docstring, "Input").
    n_labels : int, optional
        Number of label disparities (>= 3).
    disparity_range : (float, float), optional
        Label range in px per baseline (default ``lf.disparity_range``).
    progress : bool, optional
        Show a progress bar over the labels.
    **params
        ``window`` (9), ``defocus_operator`` (``"laplacian"`` | ``"gradient_x"``),
        ``conf_exponent_corr`` (0.2), ``conf_exponent_defocus`` (0.6), ``lambda_flat`` (2),
        ``lambda_smooth`` (2), ``irls_iterations`` (2), ``irls_epsilon`` (1, in label steps),
        ``conf_percentile`` (99).

    Returns
    -------
    BaselineResult
        ``maps``: ``depth_defocus``, ``depth_correspondence`` (px), ``conf_defocus``,
        ``conf_correspondence`` (normalised), ``weight_defocus``, ``weight_correspondence``.

    Raises
    ------
    InvalidInputError
        For an unknown or out-of-range parameter, ``n_labels`` < 3, or a light field with a
        single view or views smaller than 3 x 3 px.

    References
    ----------
    .. [1] M. W. Tao, S. Hadap, J. Malik, R. Ramamoorthi, "Depth from combining defocus and
       correspondence using light-field cameras", ICCV 2013.
    """
    run = _start("tao2013", lf, n_labels, disparity_range, params, progress)
    p, labels = run.p, run.labels
    with run.stage("responses"):
        Dvol, Cvol = _tao_responses(run)
    with run.stage("confidence"):
        depth_d, depth_c, conf_d, conf_c = _tao_cues(Dvol, Cvol, labels,
                                                     float(p["conf_percentile"]))
        w_d = conf_d ** p["conf_exponent_defocus"]
        w_c = conf_c ** p["conf_exponent_corr"]
    with run.stage("fusion"):
        step = float(labels[1] - labels[0])
        z = _tao_fuse([depth_c, depth_d], [w_c, w_d], p["lambda_flat"], p["lambda_smooth"],
                      p["irls_iterations"], float(p["irls_epsilon"]) * step)
        disp = np.clip(z, labels[0], labels[-1])
    maps = {"depth_defocus": depth_d, "depth_correspondence": depth_c, "conf_defocus": conf_d,
            "conf_correspondence": conf_c, "weight_defocus": w_d, "weight_correspondence": w_c}
    return run.finish(disp, np.maximum(conf_d, conf_c), maps)


# ----------------------------------------------------------------------------------------------
# Wang et al. 2015
# ----------------------------------------------------------------------------------------------

def _canny(ref: np.ndarray, sigma: float, non_edge: float, low_ratio: float):
    """Canny edges (MATLAB-style automatic thresholds) and the Sobel gradients of ``ref``."""
    from scipy import ndimage
    import cv2

    g = ndimage.gaussian_filter(ref.astype(np.float64), sigma, mode="nearest") if sigma > 0 else ref
    gx = ndimage.sobel(g, axis=1, mode="nearest")
    gy = ndimage.sobel(g, axis=0, mode="nearest")
    mag = np.hypot(gx, gy)
    mmax = float(mag.max())
    if mmax <= 0:
        return np.zeros(ref.shape, dtype=bool), gx, gy
    scale = 8000.0 / mmax
    dx16 = np.round(gx * scale).astype(np.int16)
    dy16 = np.round(gy * scale).astype(np.int16)
    high = float(np.quantile(mag, non_edge)) * scale
    high = max(high, 1.0)
    edges = cv2.Canny(dx16, dy16, low_ratio * high, high, L2gradient=True) > 0
    return edges, gx, gy


def _edge_orientation(edges: np.ndarray, gx: np.ndarray, gy: np.ndarray, win: int) -> np.ndarray:
    """Tangent angle (rad, image coords x right / y down) of the edge through each edge pixel.

    Second moments of the edge pixels in a ``win x win`` window (regionprops orientation);
    where they are degenerate, the gradient direction + 90 degrees.
    """
    e = edges.astype(np.float64)
    H, W = e.shape
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    m0 = _box(e, win)
    mx = _box(e * xx, win)
    my = _box(e * yy, win)
    mxx = _box(e * xx * xx, win)
    myy = _box(e * yy * yy, win)
    mxy = _box(e * xx * yy, win)
    with np.errstate(divide="ignore", invalid="ignore"):
        cx, cy = mx / m0, my / m0
        mu20 = mxx / m0 - cx * cx
        mu02 = myy / m0 - cy * cy
        mu11 = mxy / m0 - cx * cy
        theta = 0.5 * np.arctan2(2 * mu11, mu20 - mu02)
        aniso = np.hypot(mu20 - mu02, 2 * mu11)
    fallback = np.arctan2(gy, gx) + np.pi / 2
    ok = np.isfinite(theta) & (m0 * win * win >= 2.5) & (aniso > 1e-3)
    return np.where(ok, theta, fallback)


def _bilateral_weights(guide: np.ndarray, radius: int, sigma: float):
    """Normalised cross-bilateral weights (uniform spatial, Gaussian range) per window offset."""
    H, W = guide.shape
    pad = np.pad(guide, radius, mode="edge")
    offs, ws = [], []
    for oy in range(-radius, radius + 1):
        for ox in range(-radius, radius + 1):
            nb = pad[radius + oy:radius + oy + H, radius + ox:radius + ox + W]
            ws.append(np.exp(-((nb - guide) ** 2) / (2 * sigma * sigma)).astype(np.float32))
            offs.append((oy, ox))
    tot = np.sum(ws, axis=0)
    return offs, [w / tot for w in ws]


def _bilateral_apply(a: np.ndarray, offs, ws, radius: int) -> np.ndarray:
    H, W = a.shape
    pad = np.pad(a, radius, mode="edge")
    out = np.zeros_like(a)
    for (oy, ox), w in zip(offs, ws):
        out += w * pad[radius + oy:radius + oy + H, radius + ox:radius + ox + W]
    return out


@dataclass
class _WangSplit:
    """Edges, orientations and the per-view half-plane split (module docstring)."""

    edges: np.ndarray
    theta: np.ndarray
    split: np.ndarray                 # pixels where the views are split
    side_p: list                      # per view: float32 (H, W), 1 on the +n side
    side_m: list
    n_p: np.ndarray                   # views per half (>= 1), float32
    n_m: np.ndarray
    px_p: np.ndarray                  # reference intensity consistency_offset px along +n
    px_m: np.ndarray


def _wang_split(ref: np.ndarray, vl, p: dict) -> _WangSplit:
    """Canny edges, their orientation spread to a band, the two half-planes of views."""
    from scipy import ndimage
    H, W = ref.shape
    edges, gx, gy = _canny(ref, float(p["canny_sigma"]), float(p["canny_non_edge"]),
                           float(p["canny_low_ratio"]))
    theta_e = _edge_orientation(edges, gx, gy, int(p["orientation_window"]))
    if edges.any():
        dist, (iy, ix) = ndimage.distance_transform_edt(~edges, return_indices=True)
        band = dist <= float(p["band_radius"])
        theta = theta_e[iy, ix]
    else:
        band = np.zeros((H, W), dtype=bool)
        theta = np.zeros((H, W))
    nx, ny = -np.sin(theta), np.cos(theta)           # normal of the edge line
    margin = float(p["split_margin"])
    side_p, side_m = [], []
    for _, dx, dy in vl:
        s = nx * dx + ny * dy
        side_p.append((s > margin) & band)
        side_m.append((s < -margin) & band)
    n_p = np.sum(side_p, axis=0)
    n_m = np.sum(side_m, axis=0)
    split = band & (n_p >= 2) & (n_m >= 2)
    off = float(p["consistency_offset"])
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    return _WangSplit(
        edges=edges, theta=theta, split=split,
        side_p=[(m & split).astype(np.float32) for m in side_p],
        side_m=[(m & split).astype(np.float32) for m in side_m],
        n_p=np.maximum(n_p * split, 1).astype(np.float32),
        n_m=np.maximum(n_m * split, 1).astype(np.float32),
        px_p=sample_bilinear(ref, xx + off * nx, yy + off * ny, edge="clamp")[0],
        px_m=sample_bilinear(ref, xx - off * nx, yy - off * ny, edge="clamp")[0])


def _angular_stats(samples, n: int, sp: _WangSplit):
    """Mean and variance over all ``n`` views and over each half, from ``(v, mp, mm)``."""
    H, W = sp.split.shape
    s = np.zeros((H, W), np.float32)
    q = np.zeros((H, W), np.float32)
    s_p = np.zeros((H, W), np.float32)
    q_p = np.zeros((H, W), np.float32)
    s_m = np.zeros((H, W), np.float32)
    q_m = np.zeros((H, W), np.float32)
    for v, mp, mm in samples:
        vv = v * v
        s += v
        q += vv
        s_p += mp * v
        q_p += mp * vv
        s_m += mm * v
        q_m += mm * vv
    n_p, n_m = sp.n_p, sp.n_m
    mean = s / n
    var = np.maximum(q - n * mean * mean, 0.0) / max(n - 1, 1)
    mean_p, mean_m = s_p / n_p, s_m / n_m
    var_p = np.maximum(q_p - n_p * mean_p ** 2, 0.0) / np.maximum(n_p - 1, 1)
    var_m = np.maximum(q_m - n_m * mean_m ** 2, 0.0) / np.maximum(n_m - 1, 1)
    return mean, var, mean_p, var_p, mean_m, var_m


def _wang_cost(run: _Run, sp: _WangSplit) -> np.ndarray:
    """Occlusion-aware correspondence + refocus cost per label, bilateral filtered."""
    p, ref = run.p, run.ref
    H, W = ref.shape
    L, n = run.labels.size, len(run.vl)
    thr = float(p["consistency_threshold"])
    bad = float(p["inconsistent_cost"])
    br = int(p["bilateral_radius"])
    offs, bw = _bilateral_weights(ref, br, float(p["bilateral_sigma"]))
    cost = np.empty((L, H, W), dtype=np.float32)
    for li, d in run.each_label():
        mean, var, mean_p, var_p, mean_m, var_m = _angular_stats(
            ((v, mp, mm) for (_, v), mp, mm in zip(_shifted_views(run.vl, d), sp.side_p, sp.side_m)),
            n, sp)
        dif1 = (mean_p - sp.px_p) ** 2 + (mean_m - sp.px_m) ** 2
        dif2 = (mean_p - sp.px_m) ** 2 + (mean_m - sp.px_p) ** 2
        consistent = dif1 < dif2 + thr
        sd_p, sd_m = np.sqrt(var_p), np.sqrt(var_m)
        pick_p = sd_p <= sd_m
        corr_split = np.where(consistent, np.minimum(sd_p, sd_m), bad)
        mean_split = np.where(pick_p, mean_p, mean_m)
        corr = np.where(sp.split, corr_split, np.sqrt(var))
        mref = np.where(sp.split, mean_split, mean)
        total = corr + float(p["refocus_weight"]) * np.abs(mref - ref)
        cost[li] = _bilateral_apply(total.astype(np.float32), offs, bw, br) if br > 0 else total
    return cost


def _wang_confidence(cost: np.ndarray, labels: np.ndarray):
    """Initial label, depth, peak ratio and confidence (0 in the outer 10 % of the range)."""
    L = labels.size
    l0 = np.argmin(cost, axis=0)
    ratio = _peak_ratio(cost)
    conf = ratio - 1.0
    conf = np.where(np.isfinite(conf), conf, 0.0)
    outer = (l0 < 0.1 * L) | (l0 > 0.9 * L)
    conf = np.where(outer, 0.0, conf)
    return l0, labels[l0], ratio, conf


def _wang_occlusion(vl, initial: np.ndarray, sp: _WangSplit) -> np.ndarray:
    """Occlusion map from the two halves' statistics at the initial depth."""
    from scipy import ndimage
    _, _, mean_p, var_p, mean_m, var_m = _angular_stats(
        ((_warp_clamped(img, initial, dx, dy), mp, mm)
         for (img, dx, dy), mp, mm in zip(vl, sp.side_p, sp.side_m)), len(vl), sp)
    split = sp.split
    occ = np.zeros(split.shape, dtype=bool)
    if split.sum() > 1:
        e = 1e-12
        occ_v = np.minimum(np.maximum((var_p + e) / (var_m + e), (var_m + e) / (var_p + e)), 100.0)
        occ_f = np.minimum((mean_p - mean_m) ** 2, 0.01)

        def z(a):
            sd = float(a[split].std())
            return (a - float(a[split].mean())) / (sd if sd > 0 else 1.0)

        zv, zf = z(occ_v), z(occ_f)
        occ = split & (zv > 0) & (zf > 0) & (zv * zf > 1)
        lab, nlab = ndimage.label(occ)
        if nlab:
            sizes = ndimage.sum(occ, lab, index=np.arange(1, nlab + 1))
            occ = np.isin(lab, 1 + np.flatnonzero(sizes >= 2))
    return occ


def _wang_mrf(l0, conf, ref, edges, occ, labels: np.ndarray, p: dict) -> np.ndarray:
    """Alpha-expansion with the Gaussian-shaped unary and edge/occlusion-aware pairwise terms."""
    from scipy import ndimage
    L = labels.size
    lab_idx = np.arange(L, dtype=np.float64)[:, None, None]
    sig = 0.1 * L * np.clip(1.0 - conf, 0.01, 1.0)
    unary = (1.0 - np.exp(-((lab_idx - l0[None]) ** 2) / (2 * sig[None] ** 2))).astype(np.float32)
    sob = np.hypot(ndimage.sobel(ref, axis=1, mode="nearest"),
                   ndimage.sobel(ref, axis=0, mode="nearest")) / 8.0
    cw, owt = float(p["canny_weight"]), float(p["occlusion_weight"])
    ed, oc = edges.astype(np.float64), occ.astype(np.float64)

    def pair(a, b, c, d_, e_, f_):
        return 1.0 / (0.2 * (np.abs(a - b) + cw * np.abs(c - d_) + owt * np.abs(e_ - f_) + 0.1))

    wx = pair(sob[:, 1:], sob[:, :-1], ed[:, 1:], ed[:, :-1], oc[:, 1:], oc[:, :-1])
    wy = pair(sob[1:], sob[:-1], ed[1:], ed[:-1], oc[1:], oc[:-1])
    span = float(labels[-1] - labels[0])
    T = 0.845 * 0.05 * span
    return _reg.graphcut(unary, smoothness="truncated_linear",
                         weight=float(p["smooth_weight"]) * 0.3 / T, truncation=T,
                         init=l0, max_cycles=int(p["max_cycles"]), labels=labels,
                         edge_weights=(wx, wy))


def wang2015(lf: LightField, *, n_labels: int = 64, disparity_range=None,
             progress: bool = False, **params) -> BaselineResult:
    """Wang et al. 2015: occlusion-aware angular-patch split, occlusion map, edge-aware MRF.

    The module docstring ("Wang et al. 2015") says which steps follow the paper and the
    released code, which are simplified and which default was tuned.

    Parameters
    ----------
    lf, n_labels, disparity_range, progress
        As in :func:`tao2013`, which also lists the errors raised.
    **params
        ``band_radius`` (4), ``orientation_window`` (5), ``split_margin`` (0.5 baseline),
        ``consistency_offset`` (2 px), ``consistency_threshold`` (0.05), ``inconsistent_cost``
        (1), ``refocus_weight`` (1), ``bilateral_radius`` (2), ``bilateral_sigma`` (0.01),
        ``canny_sigma`` (sqrt 2), ``canny_non_edge`` (0.7), ``canny_low_ratio`` (0.4),
        ``canny_weight`` (1), ``occlusion_weight`` (1e5), ``smooth_weight`` (0.1, multiplies the
        pairwise term; module docstring), ``max_cycles`` (3), ``median`` (3; 0 or 1 = off).

    Returns
    -------
    BaselineResult
        ``maps``: ``initial`` (px, argmin of the filtered cost), ``mrf`` (px, before the
        median), ``edges``, ``band`` (split pixels), ``orientation`` (rad), ``occlusion``,
        ``peak_ratio``.

    References
    ----------
    .. [1] T.-C. Wang, A. A. Efros, R. Ramamoorthi, "Occlusion-aware depth estimation using
       light-field cameras", ICCV 2015.

    Examples
    --------
    Nine views of one random texture, each shifted by 2 px per baseline (a plane at
    disparity 2), with labels every 0.5 px from -3 to 3:

    >>> tex = np.random.default_rng(0).random((40, 48)) + 0.1
    >>> views = np.array([[tex[6 + 2 * r:30 + 2 * r, 6 + 2 * c:38 + 2 * c] for c in range(3)]
    ...                   for r in range(3)], np.float32)
    >>> res = wang2015(LightField(views, disparity_range=(-3, 3)), n_labels=13)
    >>> float(np.median(res.disparity)), bool(np.mean(np.abs(res.disparity - 2) < 0.25) > 0.9)
    (2.0, True)
    """
    from scipy import ndimage
    run = _start("wang2015", lf, n_labels, disparity_range, params, progress)
    p, labels, ref = run.p, run.labels, run.ref
    with run.stage("edges"):
        sp = _wang_split(ref, run.vl, p)
    with run.stage("cost"):
        cost = _wang_cost(run, sp)
    with run.stage("occlusion"):
        l0, initial, ratio, conf = _wang_confidence(cost, labels)
        occ = _wang_occlusion(run.vl, initial, sp)
    with run.stage("mrf"):
        lab_mrf = _wang_mrf(l0, conf, ref, sp.edges, occ, labels, p)
    with run.stage("post"):
        med = int(p["median"])
        mrf = _reg.subpixel_refine(cost, lab_mrf, labels)
        disp = ndimage.median_filter(mrf, size=med, mode="nearest") if med > 1 else mrf
    conf_out = np.clip(conf, 0, None)
    maps = {"initial": initial, "mrf": mrf, "edges": sp.edges, "band": sp.split,
            "orientation": sp.theta, "occlusion": occ, "peak_ratio": ratio}
    return run.finish(disp, conf_out / (1.0 + conf_out), maps)


# ----------------------------------------------------------------------------------------------
# Lin et al. 2015
# ----------------------------------------------------------------------------------------------

def _symmetric_views(vl, tol: float = 1e-6):
    """The views whose mirror position about the reference also exists."""
    offs = np.array([[dx, dy] for _, dx, dy in vl])
    scale = max(float(np.abs(offs).max()), 1.0)
    keep = []
    for i, (_, dx, dy) in enumerate(vl):
        dist = np.hypot(offs[:, 0] + dx, offs[:, 1] + dy)
        if dist.min() <= tol * scale:
            keep.append(vl[i])
    return keep


def _robust_range(vol: np.ndarray) -> float:
    r = np.median(vol.max(axis=0) - vol.min(axis=0))
    return float(r) if r > 0 else 1.0


def _lin_focal_stack(run: _Run, sym) -> tuple[np.ndarray, np.ndarray]:
    """Focal stack ``F`` of the symmetric views and the data term ``|Fall - I_ref|`` (boxed)."""
    w = int(run.p["window"])
    H, W = run.ref.shape
    F = np.empty((run.labels.size, H, W), dtype=np.float32)
    Dvol = np.empty((run.labels.size, H, W), dtype=np.float32)
    sym_ids = {id(x[0]) for x in sym}
    for li, d in run.each_label("focal stack"):
        s_all = np.zeros((H, W), np.float32)
        s_sym = np.zeros((H, W), np.float32)
        for img, v in _shifted_views(run.vl, d):
            s_all += v
            if id(img) in sym_ids:
                s_sym += v
        F[li] = s_sym / len(sym)
        Dvol[li] = _box(np.abs(s_all / len(run.vl) - run.ref), w)
    return F, Dvol


def _lin_symmetry(F: np.ndarray, K: int, tau: float, w: int) -> np.ndarray:
    """Focal-stack symmetry cost over ``K`` label pairs; the end labels get the worst value."""
    L, H, W = F.shape
    S = np.full((L, H, W), np.nan, dtype=np.float32)
    for li in range(1, L - 1):
        kmax = min(K, li, L - 1 - li)
        acc = np.zeros((H, W), np.float32)
        for k in range(1, kmax + 1):
            acc += np.minimum(np.abs(F[li + k] - F[li - k]), tau)
        S[li] = _box(acc / kmax, w)
    return _reg.fill_invalid(S)


def _lin_graphcut(run: _Run, S: np.ndarray, Dvol: np.ndarray):
    """The combined normalised cost ``S + data_weight D`` and its graph-cut labels."""
    p, labels = run.p, run.labels
    Sn = (S - S.min(axis=0, keepdims=True)) / _robust_range(S)
    Dn = (Dvol - Dvol.min(axis=0, keepdims=True)) / _robust_range(Dvol)
    E = (Sn + float(p["data_weight"]) * Dn).astype(np.float32)
    T = p["truncation"] if p["truncation"] is not None else 0.25 * float(labels[-1] - labels[0])
    lab = _reg.graphcut(E, smoothness="truncated_linear", weight=float(p["smooth_weight"]),
                        truncation=float(T), guide=run.ref, edge_sigma=p["edge_sigma"],
                        max_cycles=int(p["max_cycles"]), labels=labels)
    return E, lab


def lin2015(lf: LightField, *, n_labels: int = 64, disparity_range=None,
            progress: bool = False, **params) -> BaselineResult:
    """Lin et al. 2015: focal-stack symmetry + data consistency, graph cuts.

    The module docstring ("Lin et al. 2015") says which steps follow the paper and which are
    our own choices (no code was released); its Examples run all three baselines.

    Parameters
    ----------
    lf, n_labels, disparity_range, progress
        As in :func:`tao2013`, which also lists the errors raised.
    **params
        ``window`` (5), ``symmetry_span`` (1 px of disparity on each side), ``tau`` (0.1,
        truncation of the L1 symmetry penalty), ``data_weight`` (1), ``smooth_weight`` (1),
        ``truncation`` (None = 1/4 of the disparity span), ``edge_sigma`` (None = automatic),
        ``max_cycles`` (3).

    Returns
    -------
    BaselineResult
        ``maps``: ``depth_symmetry``, ``depth_data`` (px, WTA of each cost), ``wta`` (combined),
        ``graphcut`` (px, integer labels), ``n_symmetric_views``.

    References
    ----------
    .. [1] H. Lin, C. Chen, S. B. Kang, J. Yu, "Depth recovery from light field using focal
       stack symmetry", ICCV 2015.
    """
    run = _start("lin2015", lf, n_labels, disparity_range, params, progress)
    p, labels = run.p, run.labels
    sym = _symmetric_views(run.vl)
    if len(sym) < 2:
        sym = run.vl
    with run.stage("focal_stack"):
        F, Dvol = _lin_focal_stack(run, sym)
    with run.stage("symmetry"):
        step = float(labels[1] - labels[0])
        K = int(max(1, np.ceil(float(p["symmetry_span"]) / step - 1e-9)))
        S = _lin_symmetry(F, K, float(p["tau"]), int(p["window"]))
    with run.stage("graphcut"):
        E, lab = _lin_graphcut(run, S, Dvol)
        disp = _reg.subpixel_refine(E, lab, labels)
    maps = {"depth_symmetry": labels[np.argmin(S, axis=0)],
            "depth_data": labels[np.argmin(Dvol, axis=0)],
            "wta": labels[np.argmin(E, axis=0)], "graphcut": labels[lab],
            "n_symmetric_views": len(sym)}
    return run.finish(disp, _reg.confidence(E, lab), maps)


METHODS: dict[str, Callable[..., BaselineResult]] = {
    "tao2013": tao2013,
    "wang2015": wang2015,
    "lin2015": lin2015,
}

