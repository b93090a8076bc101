"""Plenoptic cube completion (SPEC §7, paper §6).

Every view of a hyperspectral light field records one band; completion gives every view every
band, i.e. the plenoptic cube ``[R, C, B, H, W]`` with ``B = R * C`` bands sorted by wavelength,
plus a validity mask of the same shape. A light field whose filter wavelengths are unknown (a
real array's capture ingested without them) is completed too: its bands are the views in raster
order, the cube's wavelengths are NaN, and entries neither registered nor inferred stay 0
(``fill="zero"``), since interpolating over wavelength needs the wavelengths.

:func:`complete` runs the pipeline::

    res = complete(lf, disparity=ref_disp)              # in memory
    res.cube, res.mask, res.disparities, res.stats
    res = complete(lf, disparity=ref_disp, out_path="cube.h5")   # streamed to HDF5

Stages
------
1. **Disparity initialisation** (:func:`propagate_disparity`): the reference disparity is
   forward-warped to every view (z-buffer, larger disparity wins, nearest pixel; holes NaN).
2. **Pairwise cross-spectral stereo** (:func:`pairwise_disparities`): every pair of horizontal
   (``(r, c), (r, c+1)``) and vertical (``(r, c), (r+1, c)``) neighbours is matched once.  The
   pair is put in rectified form with the first view as "left" (vertical pairs: both images are
   transposed, so the epipolar line is horizontal and, with SPEC §1's sign, the lower view's pixel
   is at ``x - d``, as for a right neighbour).  Labels are integer pixel shifts ``k`` over the
   union of both views' initial disparities ``+- band`` (``band`` px, default 2), so the volume
   is small.  Data term (paper ``|C(f(p)) - C(f*(p))|``): the cost minus its per-pixel minimum,
   divided by one global scale (std of the volume), plus a **guidance term**
   ``guidance * min(|k/b - f*(p)|, band)`` where the warped initial disparity ``f*`` exists,
   and a large penalty for labels outside ``f* +- band``.  The right-referenced volume comes from
   the left one (:func:`hyperlf.regularisers.right_cost_from_left`, exact for windowed costs),
   each side is optimised with its own guidance (SGM by default, graph cuts optional), refined to
   sub-pixel by a parabola and left-right checked (tolerance 1 px).  Consistent estimates are
   merged per view as a **confidence-weighted mean** (confidence = cost margin,
   :func:`hyperlf.regularisers.confidence`); only two running sums per view are held.
   Default metric: ``"rsncc"`` (cross-spectral robust NCC of Shen et al.); it is fast, and with
   the guidance and the narrow band the choice of metric matters little.  ``metric="bwncc"``
   gives the paper's BWNCC (much slower; BENCHMARKS.md); ``"auto"`` the two-view
   default (:data:`hyperlf.costs.AUTO_METRIC`).
3. **Refinement** (:func:`refine_disparity`): a confidence-weighted, edge-aware weighted least
   squares problem (after Park et al. 2014, adapted to a single spectral image as guide)::

       min_d  sum_p c_p (d_p - z_p)^2 + lam * sum_{p~q} w_pq (d_p - d_q)^2,
       w_pq = max(exp(-(g_p - g_q)^2 / (2 sigma^2)), w_min),   g = view / mean(view)

   ``z`` is the warped initial disparity where it exists (confidence ``init_confidence``, 1);
   in its holes two data terms are combined: the **background fill** (:func:`background_fill`:
   min of the nearest valid values left/right/up/down -- holes of a forward-warped map are
   disocclusions, i.e. background; confidence ``fill_confidence``, 0.5) and the merged stereo
   estimate (confidence ``stereo_confidence * margin``, <= 0.25).  The background fill is
   trusted more than cross-spectral stereo in the holes (it measured more accurate on
   procedural scenes, BENCHMARKS.md), so stereo only nudges it; ``optimizer=None`` skips the
   stereo (used for the 512 x 512 benchmark).
   The stereo of stage 2 is guided by the background-filled map (not the raw warped map), so
   hole pixels are also band-limited around the background hypothesis.  The 5-point system
   is solved by preconditioned conjugate gradients to a relative residual of 1e-10 (a sparse
   direct solve when they do not converge, :func:`_solve_spd`).  With
   ``keep_initial=True`` (default) the warped initial disparity is kept unchanged where it
   exists and the WLS result is used only in its holes (the initial values come from the
   reference disparity, the best estimate available; smoothing them would only blur edges).
4. **Registration** (:func:`register_view`): view ``v`` receives band ``b`` of view ``u`` by
   backward warping ``u``'s image with ``v``'s disparity: ``q = p - d_v(p) (pos_u - pos_v)``,
   bilinear.  **Occlusion check**: every bilinear tap of ``q`` that carries weight must satisfy
   ``|d_u(tap) - d_v(p)| * |pos_u - pos_v| <= occlusion_tol`` (re-projection error in pixels,
   default 0.5 px) against the *source* view's disparity; a sample whose footprint touches an
   occluder (or an out-of-image position) is rejected, not copied.
   **Propagation**: entries still missing in a view are taken from its 4-neighbours that have
   them (registered in an earlier pass), with the same warp and check (offset = neighbour
   minus view), averaging the neighbours that pass; views are visited in raster order and
   updated in place (Gauss-Seidel), until a pass changes nothing or ``max_iter`` passes.  With
   exact geometry every band is seen by exactly one view, so propagation can only add what the
   direct check rejected for numerical reasons (e.g. a bilinear footprint at the image border,
   disparity interpolation across a slanted surface); its count is reported in ``stats``.
   **Validity masks** (``lf.valid``, SPEC §11): a pixel without data is never a source.  A
   view's own band is registered only at its valid pixels, a warped sample only where every
   bilinear tap that carries weight is valid in the source view, and propagation only moves
   registered entries; the rest stay missing and are inferred / filled like any missing
   entry.  The images every stage reads (stereo, refinement guide, registration, inference
   guide) are the views with their invalid pixels filled from the nearest valid pixel
   (:func:`hyperlf.imageops.fill_masked`), so not even a tap below the weight threshold
   carries an invalid pixel's value.
5. **Inference and output**: an entry still missing is a point hidden in (or outside) the one
   view that records its band: no view observed it.  :func:`infer_missing` (``infer=True``,
   default) gives it the joint-bilateral mean of the same band at nearby pixels of the same
   view with a similar disparity (same surface: the hidden point is background, so the
   foreground that hid it is excluded) and a similar recorded intensity; such entries are
   flagged in a separate ``inferred`` mask, not in the registration mask.  Entries that are
   still missing keep mask False and are filled (``fill``): ``"spectral"`` (default) linear
   interpolation over wavelength between the nearest valid bands of the same pixel (constant
   beyond the ends; the view's own band is always valid), or ``"zero"`` (the default when the
   wavelengths are unknown).  "% completed" counts
   registered and inferred entries; metrics "on valid entries" use the registration mask;
   metrics "on all entries" use every value.

Memory model (``out_path``)
---------------------------
Held in memory throughout: the views ``(R, C, H, W)`` and the per-view disparities
``(R, C, H, W)`` (float32), plus two ``(R, C, H, W)`` running sums during stage 2 and one pair's
cost volume at a time.  Cube entries are computed one view at a time, each view's ``(B, H, W)``
cube and mask being written to an uncompressed **scratch HDF5 file** beside ``out_path``
(chunks of one band image).  Propagation reads single neighbour bands back from the scratch
file and updates views in place.  Finally every view is filled and written through
:class:`hyperlf.formats.hdf5.CubeWriter` (atomic: nothing appears at ``out_path`` unless every
view was written), the scratch file is deleted.  The per-entry registration mask
``/band_mask`` and the inference mask ``/inferred_mask`` (bool, ``(R, C, B, H, W)``,
:func:`read_band_mask`) are written view by view into the same atomic file.  The writer's own
``/mask`` (``(R, C, H, W)``) is True where *every* band of a pixel holds data, registered or
inferred (renderers leave the other pixels out; a pixel whose bands were only filled across
the spectrum is not in it).  A 5 x 6 x 30
cube at 1200 x 900 thus never sits in memory.  The peak is one pair's stage 2 (its float32
cost volumes; the costs compute their float64 scores a few labels at a time), or a view's
stage 3 when its WLS falls back to the direct solve (sparse factors); BENCHMARKS.md measures
it.
The in-memory path (``out_path=None``) runs the very same code on numpy arrays, so both give
identical results.

Baseline: :func:`naive_completion` warps every band with the forward-warped reference disparity
only (no stereo, no refinement, no occlusion check, no propagation); holes stay invalid.
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ._atomic import temporary_beside
from ._options import (bool_mask, check_values, choice, flag, index, integer, mapping, number,
                       path_like, real_array, real_pair, rule, shown, word_or)
from ._parallel import map_threads
from ._progress import grid_views, progress_bar
from .errors import DataNotFoundError, FormatError, InvalidInputError
from .warp import bilinear_taps, forward_warp_disparity, gather_taps

__all__ = [
    "CompletionResult",
    "complete",
    "naive_completion",
    "propagate_disparity",
    "pairwise_disparities",
    "refine_disparity",
    "register_view",
    "band_order",
    "background_fill",
    "fill_missing",
    "infer_missing",
    "read_band_mask",
]

_W_EPS = 1e-3  # bilinear taps with less weight do not count for the checks


# ----------------------------------------------------------------------------- result
@dataclass
class CompletionResult:
    """Output of :func:`complete` / :func:`naive_completion`.

    Attributes
    ----------
    cube : float32 (R, C, B, H, W) or None
        The completed plenoptic cube (invalid entries filled, see ``fill``); None when streamed.
    path : Path or None
        The HDF5 file when streamed (``/cube``, ``/wavelengths``, ``/mask``, ``/band_mask``).
    mask : bool (R, C, B, H, W) or None
        True where an entry was registered (not filled); None when streamed (read it with
        :func:`read_band_mask`).
    wavelengths : float64 (B,)
        Band centres, ascending (all NaN when the views had no wavelengths).
    band_index : int (R, C)
        The band each view records.
    disparities : float32 (R, C, H, W)
        Per-view disparities used for registration (NaN = none, naive baseline only).
    stats : dict
        ``completed_pct`` (% of entries registered or inferred), ``registered_pct``,
        ``inferred_pct``, ``direct`` / ``propagated`` / ``own`` entry counts,
        ``propagation_passes``, ``timings`` (s per stage), ``config``.
    inferred : bool (R, C, B, H, W) or None
        True where stage 5 inferred an entry (:func:`infer_missing`); None when streamed
        (dataset ``/inferred_mask``) or when inference was off.
    """

    cube: np.ndarray | None
    path: Path | None
    mask: np.ndarray | None
    wavelengths: np.ndarray
    band_index: np.ndarray
    disparities: np.ndarray
    stats: dict = field(default_factory=dict)
    inferred: np.ndarray | None = None

    @property
    def completed_pct(self) -> float:
        return float(self.stats.get("completed_pct", float("nan")))


# ----------------------------------------------------------------------------- helpers
def _light_field(lf):
    """``lf`` when it is a :class:`~hyperlf.lightfield.LightField`."""
    from .lightfield import check_light_field

    return check_light_field(lf)


def _check_lf(lf):
    if _light_field(lf).views.ndim != 4:
        raise InvalidInputError("cube completion needs a spectral capture, one band per view "
                                "(R, C, H, W); from an RGB light field make one with "
                                "'hyperlf synth hci'")
    return lf


def _fill_mode(fill, wavelengths: np.ndarray) -> str:
    """``fill`` checked; None picks "spectral", or "zero" when the wavelengths are unknown."""
    known = bool(np.isfinite(wavelengths).all())
    if fill is None:
        return "spectral" if known else "zero"
    choice(fill, "fill", ("spectral", "zero"))
    if fill == "spectral" and not known:
        raise InvalidInputError("fill='spectral' interpolates over wavelength, and the views' "
                                "wavelengths are unknown: use fill='zero', or give the capture "
                                "its wavelengths ('hyperlf ingest --wavelengths')")
    return fill


def band_order(lf) -> tuple[np.ndarray, np.ndarray]:
    """The cube's bands: the views' wavelengths sorted, and each view's band index.

    Parameters
    ----------
    lf : LightField

    Returns
    -------
    wavelengths : ndarray (B,)
        Sorted band centres in nm, ``B = R * C``; all NaN when the light field has no
        wavelengths, whose bands are then the views in raster order.
    band_index : ndarray of intp (R, C)
        Index in ``wavelengths`` of each view's band.

    Raises
    ------
    InvalidInputError
        When two views share a wavelength (the cube needs distinct bands).

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=2, cols=2, height=8, width=8)
    >>> band_order(lf.replace(wavelengths=None))[1].tolist()
    [[0, 1], [2, 3]]
    """
    if _light_field(lf).wavelengths is None:
        R, C = lf.grid_shape
        return np.full(R * C, np.nan), np.arange(R * C, dtype=np.intp).reshape(R, C)
    wl = np.asarray(lf.wavelengths, dtype=np.float64)
    flat = wl.ravel()
    if np.unique(flat).size != flat.size:
        values, counts = np.unique(flat, return_counts=True)
        twice = values[counts > 1][0]
        views = [f"({r},{c})" for r, c in zip(*np.nonzero(wl == twice))]
        raise InvalidInputError(
            f"cube completion needs a distinct wavelength per view; views {', '.join(views)} "
            f"all have {twice:g} nm (an array with two equal filters cannot be completed; "
            "give their real centre wavelengths, or leave one camera out)")
    order = np.argsort(flat, kind="stable")
    idx = np.empty(flat.size, dtype=np.intp)
    idx[order] = np.arange(flat.size)
    return flat[order], idx.reshape(wl.shape)


def _filled(lf):
    """``lf`` with every view's invalid pixels filled from its nearest valid pixel (the mask
    kept); ``lf`` itself when it has no mask."""
    if lf.valid is None:
        return lf
    from .imageops import fill_masked

    R, C = lf.grid_shape
    views = np.stack([np.stack([fill_masked(lf.views[r, c], lf.valid[r, c]) for c in range(C)])
                      for r in range(R)]).astype(np.float32)
    return lf.replace(views=views)


def _offset(lf, src, dst) -> tuple[float, float]:
    p = lf.positions
    return (float(p[src][0] - p[dst][0]), float(p[src][1] - p[dst][1]))


def _as_ref_disparity(lf, d) -> np.ndarray:
    a = real_array(d, "ref_disparity", np.float32)
    if a.shape != lf.image_shape:
        raise InvalidInputError(f"reference disparity must have shape {lf.image_shape}, got {a.shape}")
    return a


def _footprint_ok(flat_bool_or_disp, idx, wts, d=None, scale=1.0, tol=None):
    """All weighted taps valid (bool map) or disparity-consistent with ``d``."""
    ok = None
    for i, w in zip(idx, wts):
        v = flat_bool_or_disp[i]
        if d is None:
            t = v
        else:
            with np.errstate(invalid="ignore"):
                t = np.abs(v - d) * scale <= tol
        t = t | (w < _W_EPS)
        ok = t if ok is None else (ok & t)
    return ok


# ----------------------------------------------------------------------------- stage 1
def propagate_disparity(lf, ref_disparity) -> np.ndarray:
    """Forward-warp the reference disparity to every view (SPEC §7.1).

    z-buffer (larger disparity wins), nearest pixel, holes NaN
    (:func:`hyperlf.warp.forward_warp_disparity`); the reference view gets ``ref_disparity``
    itself.

    Parameters
    ----------
    lf : LightField
    ref_disparity : array_like (H, W)
        The reference view's disparity (px per baseline).

    Returns
    -------
    ndarray of float32, shape (R, C, H, W)

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> propagate_disparity(lf, lf.gt_disparity[lf.reference]).shape
    (3, 3, 24, 32)
    """
    lf = _check_lf(lf)
    d = _as_ref_disparity(lf, ref_disparity)
    R, C = lf.grid_shape
    out = np.empty((R, C) + lf.image_shape, dtype=np.float32)
    for r in range(R):
        for c in range(C):
            if (r, c) == lf.reference:
                out[r, c] = d
            else:
                out[r, c] = forward_warp_disparity(d, tuple(lf.offsets[r, c]))
    return out


# ----------------------------------------------------------------------------- stage 2
def background_fill(disparity: np.ndarray) -> np.ndarray:
    """Fill NaN holes of a disparity map from the background side.

    Each hole pixel takes the minimum (= farthest surface) of the nearest valid values to its
    left, right, top and bottom: holes of a forward-warped map are disocclusions, which belong to
    the background.  A map without any valid pixel is returned unchanged (all NaN).

    Parameters
    ----------
    disparity : ndarray (H, W)
        NaN = hole.

    Returns
    -------
    ndarray, shape (H, W)

    Examples
    --------
    >>> background_fill(np.array([[1.0, np.nan, 3.0]])).tolist()
    [[1.0, 1.0, 3.0]]
    """
    d = real_array(disparity, "disparity", np.float32)
    if d.ndim != 2:
        raise InvalidInputError(f"disparity must be a 2-D map, got shape {d.shape}")
    v = np.isfinite(d)
    if v.all() or not v.any():
        return d.copy()
    H, W = d.shape

    def rows(a, ok):
        n = a.shape[1]
        idx = np.broadcast_to(np.arange(n), a.shape)
        li = np.maximum.accumulate(np.where(ok, idx, -1), axis=1)
        ri = np.minimum.accumulate(np.where(ok, idx, n)[:, ::-1], axis=1)[:, ::-1]
        lv = np.where(li >= 0, np.take_along_axis(a, np.clip(li, 0, n - 1), axis=1), np.inf)
        rv = np.where(ri < n, np.take_along_axis(a, np.clip(ri, 0, n - 1), axis=1), np.inf)
        return np.minimum(lv, rv)

    m = np.minimum(rows(d, v), rows(d.T, v.T).T)
    m = np.where(np.isfinite(m), m, np.nanmin(d))
    return np.where(v, d, m).astype(np.float32)


def _add_guided_term(D: np.ndarray, kmin: int, base: float, init: np.ndarray, guidance: float,
                     band: float, outside: float) -> np.ndarray:
    """Add the guidance penalty (units of the normalised data term) to ``D`` (L, H, W) in
    place, label by label, and return it."""
    has = np.isfinite(init)
    if not has.any():
        return D
    z = np.where(has, init, 0.0).astype(np.float32)
    for i in range(D.shape[0]):
        dev = np.abs((kmin + i) / base - z)
        pen = guidance * np.minimum(dev, band) + np.where(dev > band, outside, 0.0)
        D[i] += np.where(has, pen, 0.0).astype(np.float32)  # as a float32 term is added
    return D


def _side_disparity(vol, scale, kmin, base, init, img, labels, opt, guidance, band):
    """Sub-pixel disparity and confidence of one side of a guided pair: the data term of
    ``vol`` over ``scale`` plus the guidance, optimised. ``vol`` is overwritten by the term."""
    from . import regularisers as _reg

    D = _reg.data_term(vol, overwrite=True)
    D /= np.float32(scale)
    _add_guided_term(D, kmin, base, init, guidance, band, outside=10.0)
    return _optimise(D, opt, img, labels)


def _volume_std(vol: np.ndarray) -> float:
    """The standard deviation of a cost volume's finite entries (1 when there is none or it is
    0), without a copy when all are finite."""
    finite = np.isfinite(vol)
    vals = vol if finite.all() else vol[finite]
    s = float(vals.std()) if vals.size else 1.0
    return s if s > 0 else 1.0


#: Completion's optimiser settings per name, in units of the normalised data term: plain
#: alpha-expansion (no coarse to fine) and SGM without a guide; ``params`` override them.
_OPTIMISER_DEFAULTS: dict[str, dict[str, Any]] = {
    "wta": {},
    "sgm": {"p1": 0.5, "p2": 2.0, "paths": 8, "smoothness": "p1p2", "adaptive_p2": False},
    "graphcut": {"smoothness": "truncated_linear", "weight": 1.0, "truncation": 2.0,
                 "edge_sigma": None, "max_cycles": 3, "levels": 0},
}


#: Largest weight of the refinement and of the guidance (``wls_lambda`` / ``lam``,
#: ``guidance``, the confidences): the data and smoothness terms are of order 1, so far beyond
#: it the float32 result no longer changes, and near 1e300 the solver overflows.
MAX_WEIGHT = 1e6
#: Bounds of ``edge_sigma``: the guide is divided by its mean, so its steps are of order 1;
#: below the lower bound every edge weight is the floor, above the upper one none differs.
EDGE_SIGMA_RANGE = (1e-6, 1e6)

_weight = rule(number, at_most=MAX_WEIGHT)

#: How :func:`complete`, :func:`pairwise_disparities` and :func:`refine_disparity` check their
#: options before any work.
_COMPLETE_RULES = {
    "out_path": word_or(path_like, (None,), "a file to write (or None)"),
    "optimizer": rule(choice, choices=(None, *_OPTIMISER_DEFAULTS)),
    "band": rule(number, positive=True), "guidance": _weight,
    "window": rule(integer, minimum=1, odd=True, optional=True), "params": mapping,
    "wls_lambda": _weight, "lam": _weight,
    "edge_sigma": rule(number, at_least=EDGE_SIGMA_RANGE[0], at_most=EDGE_SIGMA_RANGE[1]),
    "min_weight": rule(number, at_most=1.0),
    "init_confidence": _weight, "stereo_confidence": _weight, "fill_confidence": _weight,
    "keep_initial": flag, "occlusion_tol": number, "max_iter": integer,
    "disparity_range": word_or(real_pair, (None,), "two finite numbers (low, high) or None"),
    "progress": flag,
    "compression": rule(choice, choices=(None, "none", False, "gzip", "lzf")),
}


def _check_band(band: float, lf) -> None:
    """A band no wider than the views (labels beyond any view's reach, and memory for them)."""
    if band > max(lf.image_shape):
        raise InvalidInputError(f"band {band} px is wider than the {lf.image_shape[1]} x "
                                f"{lf.image_shape[0]} px views; use at most "
                                f"{max(lf.image_shape)}")


def _optimiser_params(optimizer, params):
    """The typed parameters of ``optimizer``: completion's defaults updated with ``params``."""
    from . import regularisers as _reg

    return _reg.make_params(optimizer, {**_OPTIMISER_DEFAULTS.get(optimizer, {}),
                                        **(params or {})})


def _optimise(D, opt, guide, labels):
    """Sub-pixel disparity and confidence of one reference's data term ``D``."""
    from . import regularisers as _reg

    res = _reg.optimise(D, opt, guide=guide, labels=labels)
    disp = _reg.subpixel_refine(res.volume, res.labels, labels)
    conf = _reg.confidence(res.volume, res.labels)
    return disp, conf


def pairwise_disparities(lf, initial: np.ndarray, *, metric: str = "rsncc", optimizer: str = "sgm",
                         band: float = 2.0, guidance: float = 0.5, window: int | None = None,
                         params: dict | None = None, disparity_range=None,
                         progress: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Guided cross-spectral stereo between all horizontal and vertical neighbours (SPEC §7.2).

    See the module docstring, stage 2.  ``initial`` is the ``(R, C, H, W)`` warped initial
    disparity (NaN holes).  ``band`` (px per baseline) limits the labels around it; pixels
    without an initial value may take any label of the pair's range (the union of both views'
    initial ranges +- band, or ``disparity_range`` / ``lf.disparity_range`` when no view has an
    initial value).

    Returns
    -------
    merged : ndarray of float32 (R, C, H, W)
        Confidence-weighted mean of the consistent estimates; NaN where there is none.
    confidence : ndarray of float32 (R, C, H, W)

    Examples
    --------
    Nine views of one random texture, each shifted by 2 px per baseline (a plane at
    disparity 2), and an initial guess of 1.5 everywhere: the stereo finds the plane
    within a tenth of a pixel.

    >>> from hyperlf.lightfield import LightField, raster_wavelengths
    >>> tex = np.random.default_rng(0).random((40, 48)) + 0.1
    >>> views = np.array([[tex[6 + 2 * r:30 + 2 * r, 6 + 2 * c:38 + 2 * c] for c in range(3)]
    ...                   for r in range(3)], np.float32)
    >>> lf = LightField(views, wavelengths=raster_wavelengths(3, 3))
    >>> merged, confidence = pairwise_disparities(lf, np.full((3, 3, 24, 32), 1.5))
    >>> merged.shape, round(float(np.nanmedian(merged)), 1)
    ((3, 3, 24, 32), 2.0)
    """
    from . import costs as _costs

    lf = _check_lf(lf)
    R, C = lf.grid_shape
    H, W = lf.image_shape
    o = check_values(dict(band=band, guidance=guidance, window=window, params=params,
                          disparity_range=disparity_range, progress=progress), _COMPLETE_RULES)
    band, guidance, window, drange = o["band"], o["guidance"], o["window"], o["disparity_range"]
    _check_band(band, lf)
    choice(optimizer, "optimizer", tuple(_OPTIMISER_DEFAULTS))
    _costs.get_cost(metric)  # a known name, before any matching
    init = real_array(initial, "initial", np.float32)
    if init.shape != (R, C, H, W):
        raise InvalidInputError(f"initial must have shape {(R, C, H, W)}, got {init.shape}")
    opt = _optimiser_params(optimizer, params)
    drange = drange if drange is not None else lf.disparity_range
    merge = _PairMerge((R, C, H, W))
    pairs = _neighbour_pairs(lf)
    for a, b, kind, base in progress_bar(pairs, "pairwise stereo", total=len(pairs),
                                         enabled=progress):
        tr = (lambda x: x) if kind == "h" else (lambda x: np.ascontiguousarray(x.T))
        L_img, R_img = tr(lf.views[a]), tr(lf.views[b])
        ia, ib = tr(init[a]), tr(init[b])
        kmin, kmax = _pair_labels(ia, ib, band, drange, base)
        if L_img.mean() <= 0 or R_img.mean() <= 0:
            continue
        sides = _match_pair(L_img, R_img, ia, ib, kmin, kmax, base, metric=metric, window=window,
                            opt=opt, guidance=guidance, band=band)
        back = (lambda x: x) if kind == "h" else (lambda x: x.T)
        for v, (d_, c_, ok) in zip((a, b), sides):
            merge.add(v, back(d_ / base), back(c_), back(ok))
    return merge.result()


def _neighbour_pairs(lf) -> list:
    """Every horizontal and vertical pair of neighbouring views as ``(a, b, kind, base)``,
    ordered so that the baseline ``base`` (px per unit of disparity) from ``a`` to ``b`` is
    positive; pairs at the same position are left out."""
    R, C = lf.grid_shape
    pairs = [((r, c), (r, c + 1), "h") for r in range(R) for c in range(C - 1)]
    pairs += [((r, c), (r + 1, c), "v") for r in range(R - 1) for c in range(C)]
    out = []
    for a, b, kind in pairs:
        off = _offset(lf, b, a)
        base = off[0] if kind == "h" else off[1]
        if abs(base) < 1e-9:
            continue
        out.append((a, b, kind, base) if base > 0 else (b, a, kind, -base))
    return out


def _pair_labels(ia, ib, band: float, drange, base: float) -> tuple[int, int]:
    """The pair's integer label range: both views' initial disparities +- ``band``, else
    ``drange``, in px of this pair's baseline (at least 3 labels)."""
    vals = np.concatenate([ia[np.isfinite(ia)], ib[np.isfinite(ib)]])
    if vals.size:
        lo, hi = float(vals.min()) - band, float(vals.max()) + band
    elif drange is not None:
        lo, hi = float(drange[0]), float(drange[1])
    else:
        raise InvalidInputError("no initial disparity and no disparity_range for the stereo")
    kmin, kmax = int(np.floor(lo * base)), int(np.ceil(hi * base))
    return (kmin - 1, kmax + 1) if kmax - kmin < 2 else (kmin, kmax)


def _match_pair(L_img, R_img, ia, ib, kmin, kmax, base, *, metric, window, opt, guidance, band):
    """Guided stereo of one rectified pair: for each side its disparity (px), confidence and
    left-right consistency."""
    from . import regularisers as _reg
    from . import twoview as _stereo

    cl, cr = _stereo.compute_volumes(L_img, R_img, kmin, kmax, metric, window=window,
                                     need_right=True)
    labels = np.arange(kmin, kmax + 1, dtype=np.float64)
    s = _volume_std(cl)
    side = dict(kmin=kmin, base=base, labels=labels, opt=opt, guidance=guidance, band=band)
    dL, cL = _side_disparity(cl, s, init=ia, img=L_img, **side)
    del cl  # each side's volume goes as soon as it is used
    dR, cR = _side_disparity(cr, s, init=ib, img=R_img, **side)
    del cr
    okL = _reg.left_right_check(dL, dR, tol=1.0)
    okR = _reg.left_right_check(dR[:, ::-1], dL[:, ::-1], tol=1.0)[:, ::-1]
    return (dL, cL, okL), (dR, cR, okR)


class _PairMerge:
    """The confidence-weighted mean of every pair's consistent estimates, view by view."""

    def __init__(self, shape):
        self.sum_wd = np.zeros(shape, dtype=np.float32)
        self.sum_w = np.zeros(shape, dtype=np.float32)
        self.count = np.zeros(shape, dtype=np.uint8)

    def add(self, v, d, c, ok) -> None:
        """One pair's estimate ``d`` (disparity per baseline) of view ``v``, its confidence
        ``c`` and where it is consistent ``ok``."""
        w = np.where(ok, c + 1e-3, 0.0).astype(np.float32)
        self.sum_wd[v] += w * np.where(ok, d, 0.0)
        self.sum_w[v] += w
        self.count[v] += ok.astype(np.uint8)

    def result(self) -> tuple[np.ndarray, np.ndarray]:
        """``(merged, confidence)``: NaN / 0 where no pair was consistent."""
        sum_w, cnt = self.sum_w, self.count
        with np.errstate(invalid="ignore", divide="ignore"):
            merged = np.where(sum_w > 0, self.sum_wd / np.maximum(sum_w, 1e-12),
                              np.nan).astype(np.float32)
            conf = np.where(cnt > 0, sum_w / np.maximum(cnt, 1), 0.0).astype(np.float32)
        return merged, np.clip(conf, 0.0, 1.0)


# ----------------------------------------------------------------------------- stage 3
def refine_disparity(image, z, c, *, lam: float = 1.0, edge_sigma: float = 0.1,
                     min_weight: float = 1e-3) -> np.ndarray:
    """Confidence-weighted edge-aware WLS (module docstring, stage 3); fills every hole.

    Solved by :func:`_solve_spd` (preconditioned conjugate gradients, a direct solve when
    they do not converge).

    Parameters
    ----------
    image : ndarray (H, W)
        The guide (the view's own spectral image).
    z : ndarray (H, W)
        Data term (NaN = none).
    c : ndarray (H, W)
        Confidences in ``[0, MAX_WEIGHT ** 2]`` where ``z`` has data.
    lam, edge_sigma, min_weight : float
        Smoothness weight (at most :data:`MAX_WEIGHT`), edge sigma (within
        :data:`EDGE_SIGMA_RANGE`) and weight floor (in (0, 1]) (module docstring, stage 3).

    Returns
    -------
    ndarray of float32 (H, W)
        All finite (a map without any data gets the constant 0).

    References
    ----------
    .. [1] J. Park, H. Kim, Y.-W. Tai, M. S. Brown, I. S. Kweon, "High-quality depth map
       upsampling and completion for RGB-D cameras", IEEE Trans. Image Processing, 2014.

    Examples
    --------
    Disparity 1 on the left half, 3 on the right, and a hole over columns 12..19 across the
    boundary. A guide with an edge at the boundary (column 16) keeps the two sides apart
    inside the hole; a flat guide spreads a ramp across it instead.

    >>> z = np.where(np.arange(32) < 16, 1.0, 3.0) * np.ones((12, 1))
    >>> z[:, 12:20] = np.nan
    >>> guide = np.where(np.arange(32) < 16, 1.0, 2.0) * np.ones((12, 1))
    >>> d = refine_disparity(guide, z, np.ones((12, 32)))
    >>> d[6, 14:18].astype(float).round(1).tolist()
    [1.0, 1.0, 3.0, 3.0]
    >>> flat = refine_disparity(np.ones((12, 32)), z, np.ones((12, 32)))
    >>> flat[6, 14:18].astype(float).round(1).tolist()
    [1.7, 1.9, 2.1, 2.3]
    """
    import scipy.sparse as sp

    o = check_values(dict(lam=lam, edge_sigma=edge_sigma, min_weight=min_weight),
                     _COMPLETE_RULES)
    lam, edge_sigma, min_weight = o["lam"], o["edge_sigma"], o["min_weight"]
    g, z, c = _same_shape_maps(image=image, z=z, c=c)
    H, W = g.shape
    c = np.where(np.isfinite(z), c, 0.0)
    if not np.isfinite(g).all() or not (np.isfinite(c) & (c >= 0) & (c <= MAX_WEIGHT ** 2)).all():
        raise InvalidInputError(f"image must be finite and c in [0, {MAX_WEIGHT ** 2:g}] where z "
                                "has data (NaN in z marks none)")
    z = np.where(np.isfinite(z), z, 0.0)
    if not (c > 0).any():
        return np.zeros((H, W), dtype=np.float32)
    # weak prior towards the median of the data so that isolated components stay defined
    zmed = float(np.median(z[c > 0]))
    c_all = c + 1e-6
    rhs = c * z + 1e-6 * zmed
    m = g.mean()
    gn = g / m if m > 0 else g
    s2 = 2.0 * float(edge_sigma) ** 2
    wx = np.maximum(np.exp(-(gn[:, 1:] - gn[:, :-1]) ** 2 / s2), min_weight) * lam
    wy = np.maximum(np.exp(-(gn[1:, :] - gn[:-1, :]) ** 2 / s2), min_weight) * lam
    N = H * W
    idx = np.arange(N).reshape(H, W)
    diag = c_all.copy()
    diag[:, 1:] += wx
    diag[:, :-1] += wx
    diag[1:, :] += wy
    diag[:-1, :] += wy
    rows = np.concatenate([idx[:, :-1].ravel(), idx[:, 1:].ravel(),
                           idx[:-1, :].ravel(), idx[1:, :].ravel(), idx.ravel()])
    cols = np.concatenate([idx[:, 1:].ravel(), idx[:, :-1].ravel(),
                           idx[1:, :].ravel(), idx[:-1, :].ravel(), idx.ravel()])
    vals = np.concatenate([-wx.ravel(), -wx.ravel(), -wy.ravel(), -wy.ravel(), diag.ravel()])
    A = sp.csr_matrix((vals, (rows, cols)), shape=(N, N))
    return np.asarray(_solve_spd(A, rhs.ravel()), dtype=np.float32).reshape(H, W)


def _same_shape_maps(**maps) -> list[np.ndarray]:
    """The 2-D float64 maps ``maps`` (name -> array), all of one shape."""
    out = [real_array(a, name) for name, a in maps.items()]
    if out[0].ndim != 2 or any(a.shape != out[0].shape for a in out):
        shapes = ", ".join(f"{name} {a.shape}" for name, a in zip(maps, out))
        raise InvalidInputError(f"{', '.join(maps)} must be 2-D maps of one shape, got {shapes}")
    return out


def _solve_spd(A, b, *, rtol: float = 1e-10, maxiter: int = 1000) -> np.ndarray:
    """Solve a sparse symmetric positive definite system ``A x = b`` (stage 3's WLS).

    Conjugate gradients with a Jacobi preconditioner, started from ``b / diag(A)``: where
    every pixel has some confidence (the background fill gives the holes one) the system is
    well conditioned and a few dozen iterations reach ``rtol``, in the memory of a few
    vectors.  When they do not converge within ``maxiter`` (confidence near 0 over wide
    regions), the sparse direct solve (SuperLU; a minimum-degree ordering of ``A + A^T``
    fills its factors least) gives the exact answer.

    Parameters
    ----------
    A : scipy.sparse matrix, shape (N, N)
        Symmetric positive definite.
    b : ndarray, shape (N,)
    rtol : float
        Relative residual ``|b - A x| / |b|`` at which the iterations stop.
    maxiter : int
        Iterations before the direct solve takes over.

    Returns
    -------
    ndarray of float64, shape (N,)
    """
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    A = sp.csr_matrix(A)
    b = np.asarray(b, dtype=np.float64)
    diag = A.diagonal()
    if np.all(diag > 0):
        x, info = spla.cg(A, b, x0=b / diag, rtol=rtol, atol=0.0, maxiter=int(maxiter),
                          M=sp.diags(1.0 / diag))
        if info == 0:
            return x
    return spla.spsolve(A.tocsc(), b, permc_spec="MMD_AT_PLUS_A")


# ----------------------------------------------------------------------------- stage 4
def register_view(lf, disparities: np.ndarray, view, band_index: np.ndarray,
                  occlusion_tol: float | None = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Direct registration of every band into ``view`` (module docstring, stage 4).

    Parameters
    ----------
    lf : LightField
        With ``lf.valid``, invalid source pixels are never registered (module docstring).
    disparities : ndarray (R, C, H, W)
        Per-view maps (NaN = unknown -> invalid).
    view : (int, int)
        The receiving view.
    band_index : ndarray (R, C)
        From :func:`band_order`.
    occlusion_tol : float or None
        Re-projection tolerance in px; None = no occlusion check (naive baseline).

    Returns
    -------
    cube : ndarray of float32 (B, H, W)
        NaN where invalid.
    mask : ndarray of bool (B, H, W)

    Examples
    --------
    Nine views of one random texture at disparity 2, registered into the centre view with the
    true disparity: every band that arrives is the centre view's own image, and it arrives
    wherever its source view saw the point. A view one baseline away along x misses the
    2 columns its shift moves out of the image (24 x 30 px), a diagonal one also 2 rows
    (22 x 30 px).

    >>> from hyperlf.lightfield import LightField, raster_wavelengths
    >>> tex = np.random.default_rng(0).random((40, 48)) + 0.1
    >>> views = np.array([[tex[6 + 2 * r:30 + 2 * r, 6 + 2 * c:38 + 2 * c] for c in range(3)]
    ...                   for r in range(3)], np.float32)
    >>> lf = LightField(views, wavelengths=raster_wavelengths(3, 3))
    >>> wl, band_index = band_order(lf)
    >>> cube, mask = register_view(lf, np.full((3, 3, 24, 32), 2.0), (1, 1), band_index)
    >>> mask.sum(axis=(1, 2)).tolist()
    [660, 704, 660, 720, 768, 720, 660, 704, 660]
    >>> bool(np.array_equal(cube[mask], np.broadcast_to(lf.views[1, 1], cube.shape)[mask]))
    True
    """
    R, C = _light_field(lf).grid_shape
    H, W = lf.image_shape
    B = R * C
    v = index(view, "view", (R, C))
    occlusion_tol = number(occlusion_tol, "occlusion_tol", optional=True)
    disparities = _float_maps(disparities, "disparities", (R, C, H, W))
    band_index = _band_index(band_index, (R, C))
    cube = np.full((B, H, W), np.nan, dtype=np.float32)
    mask = np.zeros((B, H, W), dtype=bool)
    dv = np.asarray(disparities[v], dtype=np.float64)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)

    def one(src):
        """Warp source view ``src``'s band into ``cube`` and ``mask`` (its own band)."""
        b = int(band_index[src])
        if src == v:
            mask[b] = True if lf.valid is None else lf.valid[v]
            cube[b] = np.where(mask[b], lf.views[v], np.nan)
            return
        ox, oy = _offset(lf, src, v)
        inside, idx, wts = bilinear_taps(xx - dv * ox, yy - dv * oy, (H, W))
        ok = inside & np.isfinite(dv)
        if occlusion_tol is not None:
            du = np.asarray(disparities[src], dtype=np.float64).ravel()
            ok &= _footprint_ok(du, idx, wts, d=dv, scale=max(np.hypot(ox, oy), 1.0),
                                tol=float(occlusion_tol))
        if lf.valid is not None:
            ok &= _footprint_ok(lf.valid[src].ravel(), idx, wts)
        val = gather_taps(lf.views[src].ravel(), idx, wts)
        cube[b] = np.where(ok, val, np.nan)
        mask[b] = ok

    # each source writes only its own band; numpy releases the GIL
    map_threads(one, [(r, c) for r in range(R) for c in range(C)], cap=REGISTER_THREADS)
    return cube, mask


def _float_maps(value, label: str, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a real array of ``shape``: a numeric array as it is (no copy), anything
    else as float64."""
    a = value if isinstance(value, np.ndarray) and value.dtype.kind in "fiu" else real_array(
        value, label)
    if a.shape != shape:
        raise InvalidInputError(f"{label} must have shape {shape}, got {a.shape}")
    return a


def _band_index(value, grid: tuple[int, int]) -> np.ndarray:
    """``value`` as the ``(R, C)`` band indices of :func:`band_order`, each in ``0..R C-1``."""
    b = real_array(value, "band_index")
    n = grid[0] * grid[1]
    ok = b.shape == grid and bool(np.all(np.isfinite(b)))
    if not (ok and np.all((b == np.round(b)) & (b >= 0) & (b < n))):
        raise InvalidInputError(f"band_index must be {grid[0]} x {grid[1]} integers in "
                                f"0..{n - 1} (from band_order), got {shown(value)}")
    return b.astype(np.intp)


#: The most threads :func:`register_view` warps source views on (each holds about a dozen
#: image-sized float64 temporaries; numpy's Python-side work caps the gain anyway).
REGISTER_THREADS = 4


class _MemStore:
    def __init__(self, shape):
        self.cube = np.zeros(shape, dtype=np.float32)
        self.mask = np.zeros(shape, dtype=bool)

    def put(self, v, cube, mask):
        self.cube[v] = np.where(mask, cube, 0.0)
        self.mask[v] = mask

    def get(self, v):
        return self.cube[v], self.mask[v]

    def get_band(self, v, b):
        return self.cube[v][b], self.mask[v][b]

    def put_band(self, v, b, img, m):
        self.cube[v][b] = img
        self.mask[v][b] = m

    def close(self):
        pass


class _H5Store:
    """Uncompressed scratch HDF5 with the working cube and mask, one chunk per band image.

    Every read and write moves whole chunks (``read_direct_chunk`` / ``write_direct_chunk``):
    the chunks are uncompressed, so a chunk's bytes are its band image, and this skips h5py's
    selection machinery, which costs more than the copy on small images (propagation reads
    one neighbour band at a time)."""

    def __init__(self, path: Path, shape):
        import h5py

        self.path = path
        self.f = h5py.File(path, "w")
        R, C, B, H, W = shape
        self.image_shape = (H, W)
        self.n_bands = B
        self.cube = self.f.create_dataset("cube", shape=shape, dtype=np.float32,
                                          chunks=(1, 1, 1, H, W))
        self.mask = self.f.create_dataset("mask", shape=shape, dtype=np.uint8,
                                          chunks=(1, 1, 1, H, W))

    def put(self, v, cube, mask):
        cube = np.where(mask, cube, 0.0)
        for b in range(self.n_bands):
            self.put_band(v, b, cube[b], mask[b])

    def get(self, v):
        cube = np.empty((self.n_bands, *self.image_shape), np.float32)
        mask = np.empty(cube.shape, bool)
        for b in range(self.n_bands):
            cube[b], mask[b] = self.get_band(v, b)
        return cube, mask

    def get_band(self, v, b):
        at = (v[0], v[1], b, 0, 0)
        cube = np.frombuffer(self.cube.id.read_direct_chunk(at)[1], np.float32)
        mask = np.frombuffer(self.mask.id.read_direct_chunk(at)[1], np.uint8)
        return cube.reshape(self.image_shape).copy(), mask.reshape(self.image_shape) != 0

    def put_band(self, v, b, img, m):
        at = (v[0], v[1], b, 0, 0)
        self.cube.id.write_direct_chunk(at, np.ascontiguousarray(img, np.float32).tobytes())
        self.mask.id.write_direct_chunk(at, np.ascontiguousarray(m, np.uint8).tobytes())

    def close(self):
        try:
            self.f.close()
        finally:
            with contextlib.suppress(FileNotFoundError):
                self.path.unlink()


def _propagate(lf, store, disparities, occlusion_tol, max_iter, progress=False) -> tuple[int, int]:
    """Fill missing entries from 4-neighbours (Gauss-Seidel passes). Returns (filled, passes)."""
    R, C = lf.grid_shape
    total = 0
    passes = 0
    for it in range(int(max_iter)):
        passes += 1
        changed = sum(_propagate_view(lf, store, disparities, v, occlusion_tol)
                      for v in grid_views(R, C, f"propagation, pass {it + 1}", enabled=progress))
        total += changed
        if changed == 0:
            break
    return total, passes


def _propagate_view(lf, store, disparities, v, occlusion_tol) -> int:
    """One view's missing entries that a 4-neighbour observes, each the mean of the
    neighbours' bilinear samples whose footprints pass the occlusion check; the count set."""
    H, W = lf.image_shape
    cube_v, mask_v = store.get(v)
    missing = ~mask_v
    if not missing.any():
        return 0
    dv = np.asarray(disparities[v], dtype=np.float64)
    todo = np.flatnonzero(missing.any(axis=0).ravel() & np.isfinite(dv).ravel())
    if todo.size == 0:
        return 0
    geom = _neighbour_taps(lf, disparities, v, todo, dv.ravel()[todo], occlusion_tol)
    pos = np.full(H * W, -1, dtype=np.intp)
    pos[todo] = np.arange(todo.size)
    changed = 0
    for b in np.nonzero(missing.reshape(missing.shape[0], -1).any(axis=1))[0]:
        pix = np.flatnonzero(missing[b].ravel() & (pos >= 0))
        if pix.size == 0:
            continue
        acc, n = _neighbour_mean(store, b, pos[pix], geom)
        got = n > 0
        if got.any():
            img = cube_v[b].copy()
            m = mask_v[b].copy()
            img.ravel()[pix[got]] = (acc[got] / n[got]).astype(np.float32)
            m.ravel()[pix[got]] = True
            store.put_band(v, b, img, m)
            changed += int(got.sum())
    return changed


def _neighbour_taps(lf, disparities, v, todo, dt, occlusion_tol) -> list:
    """For each 4-neighbour ``w`` of view ``v``: where the pixels ``todo`` (disparities
    ``dt``) land in it, as ``(w, inside, idx, wts)`` bilinear taps.  They depend on the view
    pair only, not on the band, so they are computed once per view and pass."""
    R, C = lf.grid_shape
    H, W = lf.image_shape
    r, c = v
    ty, tx = np.divmod(todo, W)
    geom = []
    for w in [(r + dr, c + dc) for dr, dc in ((0, 1), (0, -1), (1, 0), (-1, 0))
              if 0 <= r + dr < R and 0 <= c + dc < C]:
        ox, oy = _offset(lf, w, v)
        inside, idx, wts = bilinear_taps(tx - dt * ox, ty - dt * oy, (H, W))
        if occlusion_tol is not None:
            inside = inside & _footprint_ok(
                np.asarray(disparities[w], np.float64).ravel(), idx, wts, d=dt,
                scale=max(np.hypot(ox, oy), 1.0), tol=float(occlusion_tol))
        geom.append((w, inside, idx, wts))
    return geom


def _neighbour_mean(store, b: int, sel: np.ndarray, geom: list) -> tuple:
    """Band ``b``'s sum and count over the neighbours that observe the taps ``sel`` of
    ``geom`` (:func:`_neighbour_taps`) with their whole footprint."""
    acc = np.zeros(sel.size)
    n = np.zeros(sel.size)
    for w, inside, idx_all, wts_all in geom:
        img_w, m_w = store.get_band(w, b)
        if not m_w.any():
            continue
        idx = tuple(i[sel] for i in idx_all)
        wts = tuple(x[sel] for x in wts_all)
        ok = inside[sel] & _footprint_ok(m_w.ravel(), idx, wts)
        if not ok.any():
            continue
        val = gather_taps(img_w.ravel(), idx, wts)
        acc[ok] += val[ok]
        n[ok] += 1
    return acc, n


# ----------------------------------------------------------------------------- stage 5
def fill_missing(cube: np.ndarray, mask: np.ndarray, wavelengths, mode: str = "spectral", *,
                 impl: str = "auto") -> np.ndarray:
    """Fill invalid entries of one view's ``(B, H, W)`` cube (module docstring, stage 5).

    ``"spectral"``: per pixel, linear interpolation over wavelength between the nearest valid
    bands (nearest valid band beyond the ends; 0 where no band is valid); ``"zero"``: 0.

    Parameters
    ----------
    cube : ndarray (B, H, W)
    mask : ndarray of bool (B, H, W)
        True = valid.
    wavelengths : array_like (B,)
    mode : {"spectral", "zero"}
    impl : {"auto", "numpy", "numba"}
        ``"numpy"``: the reference, a few rows at a time; ``"numba"`` / ``"auto"``: the kernel
        (the same numbers, bit for bit).

    Returns
    -------
    ndarray of float32 (B, H, W)
        A new array.

    Examples
    --------
    Bands at 400, 450, 600 and 650 nm, the second and the last missing: the second lies a
    quarter of the way from 400 to 600 nm, so it gets ``1 + (3 - 1) / 4``; the last, beyond
    the valid ones, copies the nearest.

    >>> cube = np.array([1.0, 9.0, 3.0, 9.0])[:, None, None] * np.ones((4, 1, 2))
    >>> mask = np.array([True, False, True, False])[:, None, None] & np.ones((4, 1, 2), bool)
    >>> fill_missing(cube, mask, [400, 450, 600, 650])[:, 0, 0].tolist()
    [1.0, 1.5, 3.0, 3.0]
    >>> fill_missing(cube, mask, [400, 450, 600, 650], "zero")[:, 0, 0].tolist()
    [1.0, 0.0, 3.0, 0.0]
    """
    choice(impl, "impl", _IMPLS)
    choice(mode, "mode", ("spectral", "zero"))
    cube = real_array(cube, "cube", np.float32)
    if cube.ndim != 3:
        raise InvalidInputError(f"cube must be (B, H, W), got shape {cube.shape}")
    m = bool_mask(mask, "mask", cube.shape, of="the cube")
    if mode == "zero":
        return np.where(m, cube, 0.0).astype(np.float32)
    B = cube.shape[0]
    wl = _float_maps(wavelengths, "wavelengths", (B,)).astype(np.float64, copy=False)
    _fill_mode(mode, wl)
    out = np.where(m, cube, 0.0).astype(np.float32)
    if m.all():
        return out
    if impl != "numpy":
        from . import _completion_kernels

        _completion_kernels.fill_bands(out, np.ascontiguousarray(m), np.ascontiguousarray(wl))
        return out
    step = max(1, FILL_BLOCK_ENTRIES // max(B * cube.shape[2], 1))
    for y in range(0, cube.shape[1], step):  # pixels are independent: a few rows at a time
        rows = slice(y, y + step)
        out[:, rows] = _interpolate_bands(out[:, rows], m[:, rows], wl)
    return out


#: ``(B, rows, W)`` entries that :func:`fill_missing` interpolates at a time: its int64 and
#: float64 temporaries stay a few tens of MB whatever the view's size.
FILL_BLOCK_ENTRIES = 2**21


def _interpolate_bands(out: np.ndarray, m: np.ndarray, wl: np.ndarray) -> np.ndarray:
    """The spectral fill of one block ``(B, h, W)``: invalid entries linearly interpolated
    over wavelength between the nearest valid bands (module docstring, stage 5)."""
    B = out.shape[0]
    bi = np.arange(B)[:, None, None]
    lo = np.maximum.accumulate(np.where(m, bi, -1), axis=0)
    hi = np.minimum.accumulate(np.where(m, bi, B)[::-1], axis=0)[::-1]
    has_lo, has_hi = lo >= 0, hi < B
    lo_c, hi_c = np.clip(lo, 0, B - 1), np.clip(hi, 0, B - 1)
    v_lo = np.take_along_axis(out, lo_c, axis=0)
    v_hi = np.take_along_axis(out, hi_c, axis=0)
    wl_b = wl[:, None, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (wl_b - wl[lo_c]) / (wl[hi_c] - wl[lo_c])
    interp = np.where(has_lo & has_hi, v_lo + np.nan_to_num(t) * (v_hi - v_lo),
                      np.where(has_lo, v_lo, np.where(has_hi, v_hi, 0.0)))
    return np.where(m, out, interp).astype(np.float32)


#: The implementations of :func:`fill_missing` and :func:`infer_missing`.
_IMPLS = ("auto", "numpy", "numba")
#: Bounds of :func:`infer_missing`'s ``sigma_d`` and ``sigma_g``: below, ``2 sigma**2``
#: underflows to 0 (a division by zero); above, the term no longer changes any weight.
INFER_SIGMA_RANGE = (1e-6, 1e6)


def _infer_params(radius, sigma_d, sigma_g, min_weight, rounds):
    low, high = INFER_SIGMA_RANGE
    return (integer(radius, "infer radius", 1),
            *(number(v, f"infer {name}", at_least=low, at_most=high) for v, name in
              ((sigma_d, "sigma_d"), (sigma_g, "sigma_g"))),
            number(min_weight, "infer min_weight", positive=True),
            integer(rounds, "infer rounds"))


def _infer_round_numpy(cube, src, disp, guide, radius, sigma_d, sigma_g, min_weight):
    """One round of :func:`infer_missing`, written over whole arrays (the reference)."""
    B, H, W = cube.shape
    r = radius
    sig_s = max(radius / 2.0, 0.5)
    pad = ((r, r), (r, r))
    dpad = np.pad(disp, pad, constant_values=np.nan)
    gpad = np.pad(guide, pad, constant_values=np.nan)
    cpad = np.pad(cube, ((0, 0),) + pad)
    spad = np.pad(src, ((0, 0),) + pad)
    acc = np.zeros((B, H, W))
    wsum = np.zeros((B, H, W))
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            dq = dpad[r + dy:r + dy + H, r + dx:r + dx + W]
            gq = gpad[r + dy:r + dy + H, r + dx:r + dx + W]
            with np.errstate(invalid="ignore"):
                w = np.exp(-(dy * dy + dx * dx) / (2 * sig_s ** 2)
                           - (disp - dq) ** 2 / (2 * sigma_d ** 2)
                           - (guide - gq) ** 2 / (2 * sigma_g ** 2))
            w = np.nan_to_num(w)
            sq = spad[:, r + dy:r + dy + H, r + dx:r + dx + W]
            cq = cpad[:, r + dy:r + dy + H, r + dx:r + dx + W]
            acc += np.where(sq, w * cq, 0.0)
            wsum += np.where(sq, w, 0.0)
    got = (~src) & (wsum >= min_weight)
    out = np.where(got, acc / np.maximum(wsum, 1e-300), cube).astype(np.float32)
    return out, got


def infer_missing(cube, mask, disparity, guide, *, radius: int = 6, sigma_d: float = 0.5,
                  sigma_g: float = 0.1, min_weight: float = 0.05, rounds: int = 3,
                  impl: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Infer the entries no view observed from the same band at nearby pixels of the same
    surface (module docstring, stage 5).

    An entry ``(b, p)`` of a view is missing after registration when the point ``p`` is hidden
    in the view that records band ``b`` (or falls outside it).  It gets the joint-bilateral
    mean of the band's valid entries ``q`` within ``radius`` pixels::

        w_pq = exp(-|p - q|^2 / (2 (radius/2)^2) - (d_p - d_q)^2 / (2 sigma_d^2)
                   - (g_p - g_q)^2 / (2 sigma_g^2))

    where ``d`` is the view's disparity (px; a hidden point is background, so the disparity
    term keeps the foreground that hid it out of the mean) and ``g`` the view's own recorded
    image divided by its mean (valid everywhere; separates materials on the same surface).
    An entry is inferred only when ``sum_q w_pq >= min_weight``; otherwise it stays missing.
    ``rounds`` passes let inferred entries feed the next pass (holes wider than ``radius``).

    Parameters
    ----------
    cube : (B, H, W) float; mask : (B, H, W) bool (True = registered);
    disparity : (H, W) float, px (NaN: no inference at / from that pixel);
    guide : (H, W) float, the view's own image (any positive scale).
    impl : ``"numpy"`` (reference), ``"numba"`` or ``"auto"`` (numba).

    Returns
    -------
    (cube, inferred) : float32 ``(B, H, W)`` with inferred entries filled (others unchanged),
    and the bool map of inferred entries.

    Examples
    --------
    A foreground (value 0.9, disparity 3) on columns 0..2, background (0.3, disparity 1)
    elsewhere, and columns 3 and 4 of the background missing. The disparity term keeps the
    foreground out, so the hole gets the background's 0.3; without it (a huge ``sigma_d``)
    the foreground bleeds in.

    >>> cube = np.full((1, 9, 9), 0.3)
    >>> cube[:, :, :3] = 0.9
    >>> disparity = np.where(np.arange(9) < 3, 3.0, 1.0) * np.ones((9, 1))
    >>> mask = np.ones((1, 9, 9), bool)
    >>> mask[:, :, 3:5] = False
    >>> out, inferred = infer_missing(cube, mask, disparity, np.ones((9, 9)))
    >>> int(inferred.sum()), out[0, 4, 2:6].astype(float).round(3).tolist()
    (18, [0.9, 0.3, 0.3, 0.3])
    >>> blind, _ = infer_missing(cube, mask, disparity, np.ones((9, 9)), sigma_d=1e3)
    >>> bool(blind[0, 4, 3] > 0.5)
    True
    """
    radius, sigma_d, sigma_g, min_weight, rounds = _infer_params(radius, sigma_d, sigma_g,
                                                                 min_weight, rounds)
    choice(impl, "impl", _IMPLS)
    c = real_array(cube, "cube", np.float32)
    d = real_array(disparity, "disparity")
    g = real_array(guide, "guide")
    if c.ndim != 3 or d.shape != c.shape[1:] or g.shape != c.shape[1:]:
        raise InvalidInputError(
            f"infer_missing needs cube/mask (B, H, W) and disparity/guide (H, W); got "
            f"{c.shape}, {d.shape}, {g.shape}")
    m = bool_mask(mask, "mask", c.shape, of="the cube")
    limit = max(c.shape[1], c.shape[2], 6)  # the default radius 6 on any view
    if radius > limit:
        raise InvalidInputError(f"infer radius {radius} px reaches past the {c.shape[2]} x "
                                f"{c.shape[1]} px view; use at most {limit}")
    gm = float(np.nanmean(np.abs(g))) if np.isfinite(g).any() else 0.0
    g = g / gm if gm > 0 else g
    inferred = np.zeros(c.shape, dtype=bool)
    out = c.copy()
    src = m.copy()
    for _ in range(rounds):
        if src.all():
            break
        if impl == "numpy":
            out, got = _infer_round_numpy(out, src, d, g, radius, sigma_d, sigma_g, min_weight)
        else:
            nxt = np.empty_like(out)
            got = np.empty(out.shape, dtype=bool)
            from . import _completion_kernels

            _completion_kernels.infer_round(out, src, d, g, radius, sigma_d, sigma_g, min_weight,
                                            nxt, got)
            out = nxt
        if not got.any():
            break
        inferred |= got
        src |= got
    return out, inferred


def read_band_mask(path, view=None, *, name: str = "band_mask") -> np.ndarray:
    """A per-entry mask of a streamed completion file.

    Parameters
    ----------
    path : path-like
        File written by :func:`complete` with ``out_path``.
    view : (int, int), optional
        One view; default all.
    name : {"band_mask", "inferred_mask"}
        Registered or inferred entries.

    Returns
    -------
    ndarray of bool, shape (R, C, B, H, W) or (B, H, W)

    Examples
    --------
    A completion streamed to a file records the same registration mask as one kept in
    memory, and every view has its own band:

    >>> import pathlib, tempfile
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "cube.h5"
    >>> streamed = complete(lf, lf.gt_disparity, path)
    >>> mask = read_band_mask(path)
    >>> mask.shape, read_band_mask(path, (1, 1)).shape
    ((3, 3, 9, 24, 32), (9, 24, 32))
    >>> bool(np.array_equal(mask, complete(lf, lf.gt_disparity).mask))
    True
    >>> all(mask[r, c, streamed.band_index[r, c]].all() for r in range(3) for c in range(3))
    True
    """
    import h5py

    path_like(path)
    choice(name, "name", ("band_mask", "inferred_mask"))
    if not os.path.isfile(path):
        raise DataNotFoundError(f"{path} does not exist")
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise FormatError(f"{path} is not an HDF5 file") from None
    with f:
        if name not in f:
            raise InvalidInputError(f"{path} has no /{name} (not written by hyperlf.completion"
                                    f"{', or inference was off' if name == 'inferred_mask' else ''})")
        ds = f[name]
        if view is not None:
            view = index(view, "view", ds.shape[:2])
        return np.asarray(ds[view[0], view[1]] if view is not None else ds[()], dtype=bool)


# ----------------------------------------------------------------------------- pipeline
def _check_infer(infer) -> dict | None:
    """``complete``'s ``infer`` argument as keyword arguments of :func:`infer_missing`."""
    if infer is False or infer is None:
        return None
    if infer is True:
        return {}
    if not isinstance(infer, dict):
        raise InvalidInputError(f"infer must be True, False or a dict of options, got "
                                f"{shown(infer)}")
    mapping(infer, "infer", keys=("radius", "sigma_d", "sigma_g", "min_weight", "rounds",
                                  "impl"))
    kw = dict(infer)
    _infer_params(kw.get("radius", 6), kw.get("sigma_d", 0.5), kw.get("sigma_g", 0.1),
                  kw.get("min_weight", 0.05), kw.get("rounds", 3))
    return kw


def _view_disparities(lf, disparity, *, metric, optimizer, band, guidance, window, params,
                      wls_lambda, edge_sigma, init_confidence, stereo_confidence, keep_initial,
                      progress, timings, cfg, fill_confidence=0.5):
    """Stages 1-3 of :func:`complete`: every view's initial disparity, its background fill,
    pairwise stereo and the refinement; ``(initial, refined)``, each ``(R, C, H, W)``."""
    R, C = lf.grid_shape
    init, per_view = _initial_disparities(lf, disparity, progress, timings, cfg)
    if per_view and np.isfinite(init).all():  # nothing to estimate
        timings["stereo"] = timings["refinement"] = 0.0
        return init, init
    t0 = time.perf_counter()
    bg = np.empty_like(init)
    for r in range(R):
        for c in range(C):
            bg[r, c] = background_fill(init[r, c])
    timings["background_fill"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if optimizer is None:
        merged, conf = np.full_like(init, np.nan), np.zeros_like(init)
    else:
        merged, conf = pairwise_disparities(lf, bg, metric=metric, optimizer=optimizer,
                                            band=band, guidance=guidance, window=window,
                                            params=params, progress=progress)
    timings["stereo"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = np.empty_like(init)
    for v in grid_views(R, C, "refinement (WLS)", enabled=progress):
        out[v] = _refined_view(lf.views[v], init[v], bg[v], merged[v], conf[v],
                               init_confidence=init_confidence,
                               fill_confidence=fill_confidence,
                               stereo_confidence=stereo_confidence, wls_lambda=wls_lambda,
                               edge_sigma=edge_sigma, keep_initial=keep_initial)
    timings["refinement"] = time.perf_counter() - t0
    return init, out


def _initial_disparities(lf, disparity, progress, timings, cfg) -> tuple[np.ndarray, bool]:
    """Stage 1: the views' initial disparities ``(R, C, H, W)`` (NaN holes) from per-view maps,
    a reference map warped to every view, or hlf depth's reference map where none is given;
    and whether per-view maps were given."""
    R, C = lf.grid_shape
    H, W = lf.image_shape
    if disparity is None:
        from .hlf import depth as _depth

        t0 = time.perf_counter()
        disparity = _depth(lf, progress=progress).disparity
        timings["depth"] = time.perf_counter() - t0
        cfg["disparity_source"] = "hyperlf.hlf.depth (estimated reference disparity)"
    d = np.asarray(disparity, dtype=np.float32)
    if d.shape == (R, C, H, W):
        cfg["disparity_source"] = cfg.get("disparity_source", "per-view maps given")
        timings["initialisation"] = 0.0
        return d.copy(), True
    if d.shape != (H, W):
        raise InvalidInputError(
            f"disparity must be None, the reference map {(H, W)} or per-view maps "
            f"{(R, C, H, W)}; got shape {d.shape}")
    cfg.setdefault("disparity_source", "reference map given")
    t0 = time.perf_counter()
    init = propagate_disparity(lf, d)
    timings["initialisation"] = time.perf_counter() - t0
    return init, False


def _refined_view(image, init, bg, merged, conf, *, init_confidence, fill_confidence,
                  stereo_confidence, wls_lambda, edge_sigma, keep_initial) -> np.ndarray:
    """Stage 3 for one view: the WLS refinement of two data terms in the holes of ``init``,
    its background fill and the stereo estimate (the ``c1 z1 + c2 z2`` form)."""
    has = np.isfinite(init)
    if has.all():
        return init
    c1 = np.where(has, init_confidence, np.where(np.isfinite(bg), fill_confidence, 0.0))
    z1 = np.where(has, init, bg)
    okm = np.isfinite(merged) & ~has
    c2 = np.where(okm, stereo_confidence * conf, 0.0)
    z2 = np.where(okm, merged, 0.0)
    cw = c1 + c2
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(cw > 0, (c1 * np.nan_to_num(z1) + c2 * z2) / np.maximum(cw, 1e-12), np.nan)
    ref = refine_disparity(image, z, cw, lam=wls_lambda, edge_sigma=edge_sigma)
    return np.where(has, init, ref) if keep_initial else ref


def complete(lf, disparity=None, out_path=None, *, metric: str = "rsncc",
             optimizer: str | None = "sgm", band: float = 2.0, guidance: float = 0.5,
             window: int | None = None, params: dict | None = None, wls_lambda: float = 1.0,
             edge_sigma: float = 0.1, init_confidence: float = 1.0,
             stereo_confidence: float = 0.25, fill_confidence: float = 0.5,
             keep_initial: bool = True, occlusion_tol: float = 0.5, max_iter: int = 10,
             infer: bool | dict = True, fill: str | None = None,
             compression: str | None = "gzip", progress: bool = False) -> CompletionResult:
    """Complete the plenoptic cube of an H-LF (SPEC §7; module docstring for every stage).

    Parameters
    ----------
    lf : LightField
        Monochrome views with distinct wavelengths, or with none (unknown: the bands are the
        views in raster order and the cube's wavelengths NaN).
    disparity : None, (H, W) or (R, C, H, W)
        The reference view's disparity (forward-warped, then stereo + refinement), per-view
        maps (NaN holes are estimated and refined; complete maps are used as they are), or
        None: estimate the reference disparity with :func:`hyperlf.hlf.depth` first.
    out_path : path-like, optional
        Stream the cube to this HDF5 file instead of returning it (memory model in the module
        docstring).
    metric, optimizer, band, guidance, window, params :
        Pairwise stereo (stage 2).  ``optimizer``: ``"sgm"`` (default), ``"graphcut"``,
        ``"wta"`` or None (skip the stereo; holes are filled by the WLS from the initial
        disparity alone).
    wls_lambda, edge_sigma, init_confidence, stereo_confidence, fill_confidence, keep_initial :
        Refinement (stage 3). The weights (and ``guidance``) are at most :data:`MAX_WEIGHT`,
        ``edge_sigma`` within :data:`EDGE_SIGMA_RANGE`.
    occlusion_tol : float
        Re-projection tolerance in px of the occlusion check (stage 4).
    max_iter : int
        Maximum propagation passes (0 = none).
    infer : bool or dict
        Stage 5 inference of entries no view observed (:func:`infer_missing`); a dict gives
        its keyword arguments (``radius``, ``sigma_d``, ``sigma_g``, ``min_weight``,
        ``rounds``, ``impl``).  False: leave them to ``fill``.
    fill : {"spectral", "zero"}, optional
        Value of entries that stay missing (neither registered nor inferred). Default
        "spectral", or "zero" when the wavelengths are unknown ("spectral" needs them).
    compression : str or None
        HDF5 compression of the output file.

    Returns
    -------
    CompletionResult
        ``cube`` / ``mask`` ``(R, C, B, H, W)`` (None when streamed to ``out_path``), the
        per-view ``disparities`` and ``stats`` (see :class:`CompletionResult`).

    Raises
    ------
    InvalidInputError
        For views sharing a wavelength, or invalid options.

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> res = complete(lf, lf.gt_disparity[lf.reference])
    >>> res.cube.shape, res.mask.shape
    ((3, 3, 9, 24, 32), (3, 3, 9, 24, 32))
    """
    lf = _filled(_check_lf(lf))
    o = check_values(dict(out_path=out_path, optimizer=optimizer, band=band, guidance=guidance,
                          window=window, params=params, wls_lambda=wls_lambda,
                          edge_sigma=edge_sigma, init_confidence=init_confidence,
                          stereo_confidence=stereo_confidence, fill_confidence=fill_confidence,
                          keep_initial=keep_initial, occlusion_tol=occlusion_tol,
                          max_iter=max_iter, compression=compression), _COMPLETE_RULES)
    window, keep_initial, max_iter = o["window"], o["keep_initial"], o["max_iter"]
    _check_band(band, lf)
    if optimizer is not None:  # its params and metric, before a depth run that may take minutes
        from . import costs as _costs

        _optimiser_params(optimizer, params)
        _costs.get_cost(metric)
    if disparity is not None:
        disparity = real_array(disparity, "disparity", np.float32)
    wl, bidx = band_order(lf)
    fill = _fill_mode(fill, wl)
    infer_kw = _check_infer(infer)
    t_all = time.perf_counter()
    timings: dict[str, float] = {}
    cfg: dict[str, Any] = dict(metric=metric, optimizer=optimizer, band=band, guidance=guidance,
                               window=window, params=params, wls_lambda=wls_lambda,
                               edge_sigma=edge_sigma, init_confidence=init_confidence,
                               stereo_confidence=stereo_confidence, fill_confidence=fill_confidence,
                               keep_initial=keep_initial, occlusion_tol=occlusion_tol,
                               max_iter=max_iter, infer=infer_kw, fill=fill)
    _, disp = _view_disparities(lf, disparity, metric=metric, optimizer=optimizer, band=band,
                                guidance=guidance, window=window, params=params,
                                wls_lambda=wls_lambda, edge_sigma=edge_sigma,
                                init_confidence=init_confidence,
                                stereo_confidence=stereo_confidence, keep_initial=keep_initial,
                                progress=progress, timings=timings, cfg=cfg,
                                fill_confidence=fill_confidence)
    return _register_all(lf, disp, wl, bidx, out_path, occlusion_tol, max_iter, fill,
                         compression, progress, timings, cfg, t_all, name="completion",
                         infer=infer_kw)


def naive_completion(lf, ref_disparity, out_path=None, *, fill: str | None = None,
                     compression: str | None = "gzip") -> CompletionResult:
    """Naive baseline: warp every band with the forward-warped reference disparity only.

    No pairwise stereo, no refinement (holes of the warped disparity stay invalid), no
    occlusion check, no propagation.

    Parameters
    ----------
    lf : LightField
    ref_disparity : array_like (H, W)
    out_path, fill, compression
        As :func:`complete`.

    Returns
    -------
    CompletionResult
        Same format as :func:`complete`.

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> naive_completion(lf, lf.gt_disparity[lf.reference]).cube.shape
    (3, 3, 9, 24, 32)
    """
    lf = _filled(_check_lf(lf))
    out_path = check_values(dict(out_path=out_path, compression=compression),
                            _COMPLETE_RULES)["out_path"]
    t_all = time.perf_counter()
    wl, bidx = band_order(lf)
    fill = _fill_mode(fill, wl)
    t0 = time.perf_counter()
    disp = propagate_disparity(lf, ref_disparity)
    timings = {"initialisation": time.perf_counter() - t0}
    cfg = {"method": "naive", "fill": fill, "disparity_source": "reference map given"}
    return _register_all(lf, disp, wl, bidx, out_path, None, 0, fill, compression, False,
                         timings, cfg, t_all, name="naive")


def _scratch_store(out_path: Path, shape) -> "_H5Store":
    """The scratch HDF5 store beside ``out_path``; removed again if making it fails or is
    interrupted (the caller's ``finally`` closes, and so removes, the store it got)."""
    out_path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temporary_beside(out_path, ".h5", tag="scratch")
    try:
        os.close(fd)
        return _H5Store(Path(tmp), shape)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _register_all(lf, disp, wl, bidx, out_path, occlusion_tol, max_iter, fill, compression,
                  progress, timings, cfg, t_all, name, infer=None):
    """Stages 4 and 5 of :func:`complete` (and the naive baseline): registration,
    propagation, then inference and fill view by view, in memory or streamed to
    ``out_path`` through a scratch store."""
    R, C = lf.grid_shape
    H, W = lf.image_shape
    shape = (R, C, R * C, H, W)
    out_path = None if out_path is None else Path(out_path)
    store = _MemStore(shape) if out_path is None else _scratch_store(out_path, shape)
    finish = _Finish(lf, disp, wl, fill, infer)
    try:
        t0 = time.perf_counter()
        direct = _register_views(lf, store, disp, bidx, occlusion_tol, progress)
        timings["registration"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        propagated, passes = (_propagate(lf, store, disp, occlusion_tol, max_iter, progress)
                              if max_iter > 0 else (0, 0))
        timings["propagation"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        if out_path is None:
            cube, mask, inferred = _finish_in_memory(store, finish)
        else:
            _finish_to_file(out_path, store, finish, wl, compression,
                            _cube_metadata(lf, cfg, name), progress)
            cube, mask, inferred = None, None, None
        timings["inference"] = finish.seconds
        timings["output"] = time.perf_counter() - t0 - finish.seconds
    except BaseException:
        # the scratch file goes either way; a close that fails too (HDF5 cannot flush to a
        # full disk) must not hide why the run failed
        with contextlib.suppress(Exception):
            store.close()
        raise
    store.close()
    timings["total"] = time.perf_counter() - t_all
    total = R * C * R * C * H * W
    stats = {
        "completed_pct": 100.0 * (finish.n_valid + finish.n_inferred) / total,
        "registered_pct": 100.0 * finish.n_valid / total,
        "inferred_pct": 100.0 * finish.n_inferred / total,
        "own": R * C * H * W,
        "direct": direct - R * C * H * W,
        "propagated": propagated,
        "propagation_passes": passes,
        "timings": timings,
        "config": cfg,
    }
    return CompletionResult(cube=cube, path=out_path, mask=mask, wavelengths=wl, band_index=bidx,
                            disparities=disp, stats=stats, inferred=inferred)


def _register_views(lf, store, disp, bidx, occlusion_tol, progress) -> int:
    """Stage 4: every view's registered bands into ``store``; the count of entries set."""
    direct = 0
    for v in grid_views(*lf.grid_shape, "registration", enabled=progress):
        cube_v, mask_v = register_view(lf, disp, v, bidx, occlusion_tol)
        store.put(v, cube_v, mask_v)
        direct += int(mask_v.sum())
    return direct


class _Finish:
    """Stage 5 for one view: inference of the entries no view observed (where ``infer`` is
    given), then the fill of what is still missing; counts the registered and inferred
    entries and the inference's time."""

    def __init__(self, lf, disp, wl, fill, infer):
        self.lf, self.disp, self.wl, self.fill, self.infer = lf, disp, wl, fill, infer
        self.n_valid = self.n_inferred = 0
        self.seconds = 0.0

    def __call__(self, v, cv, mv):
        """The filled cube of view ``v`` and its inferred entries."""
        self.n_valid += int(mv.sum())
        iv = np.zeros(mv.shape, dtype=bool)
        if self.infer is not None and not mv.all():
            t1 = time.perf_counter()
            cv, iv = infer_missing(cv, mv, self.disp[v], self.lf.views[v], **self.infer)
            self.seconds += time.perf_counter() - t1
            self.n_inferred += int(iv.sum())
        return fill_missing(cv, mv | iv, self.wl, self.fill), iv


def _finish_in_memory(store: "_MemStore", finish: _Finish):
    """Stage 5 in place in the in-memory store: ``(cube, mask, inferred or None)``."""
    R, C = store.cube.shape[:2]
    inferred = np.zeros(store.cube.shape, dtype=bool) if finish.infer is not None else None
    for v in ((r, c) for r in range(R) for c in range(C)):
        store.cube[v], iv = finish(v, store.cube[v], store.mask[v])
        if inferred is not None:
            inferred[v] = iv
    return store.cube, store.mask, inferred


def _finish_to_file(out_path, store, finish: _Finish, wl, compression, metadata, progress):
    """Stage 5 view by view from the scratch store into the cube file at ``out_path``."""
    from .formats.hdf5 import CubeWriter

    R, C = finish.lf.grid_shape
    H, W = finish.lf.image_shape
    with CubeWriter(out_path, (R, C, R * C, H, W), wl, compression=compression,
                    metadata=metadata) as wr:
        for v in grid_views(R, C, "inference and output", enabled=progress):
            cv, mv = store.get(v)
            filled, iv = finish(v, cv, mv)
            # a pixel renders when each band holds data: registered or inferred
            wr.write_view(v[0], v[1], filled, (mv | iv).all(axis=0))
            wr.write_view_extra("band_mask", v[0], v[1], mv)
            if finish.infer is not None:
                wr.write_view_extra("inferred_mask", v[0], v[1], iv)


def _cube_metadata(lf, cfg: dict, name: str) -> dict:
    """What a cube file records of its making: the settings, the method, the geometry (so
    that renderers can refocus non-uniform arrays from the file alone) and the downscale
    (1/N resolution, :func:`hyperlf.lightfield.downscale`, so that a copied file says so)."""
    downscale = lf.metadata.get("downscale", 1)
    return {"completion": {k: (v if isinstance(v, (int, float, str, bool, type(None)))
                               else repr(v)) for k, v in cfg.items()},
            "method": name, "positions": np.asarray(lf.positions).tolist(),
            "reference": list(lf.reference),
            "downscale": int(downscale) if isinstance(downscale, int) else 1}
