"""Synthetic hyperspectral light fields with ground truth (SPEC §6).

Two generators, both returning a :class:`hyperlf.LightField` with

* ``views`` ``(R, C, H, W)`` float32 in [0, 1]: view ``(r, c)`` sees band ``layout[r, c]``;
* ``wavelengths`` ``(R, C)``: the centre wavelength of every view's filter;
* ``gt_cube`` ``(R, C, B, H, W)`` and ``cube_wavelengths`` ``(B,)``: every band seen from every
  view, noise-free (``B = R * C``, the sorted filter wavelengths, equal steps from
  ``lambda_min`` to ``lambda_max``); ``views[r, c] == gt_cube[r, c, layout[r, c]]`` + noise;
* ``gt_disparity``: ``(R, C, H, W)`` (every view; NaN where unknown);
* ``disparity_range`` and ``metadata`` recording every synthesis parameter.

:func:`from_rgb_lightfield` / :func:`from_hci_scene` turn an RGB light field (the HCI 4D
benchmark) into an H-LF; :func:`procedural_scene` ray-casts analytic scenes (planes, boxes,
spheres) textured with real reflectance spectra; :data:`SCENES` names a few fixed ones.

Camera model of the procedural renderer (SPEC §1 sign convention)
-----------------------------------------------------------------
Pinhole cameras with focal length ``f`` (pixels), principal point at the image centre
``(cx, cy) = ((W-1)/2, (H-1)/2)``, centres at ``(dx, dy, 0)`` baselines for the view offset
``(dx, dy) = pos[r, c] - pos[ref]`` and a sensor shift of ``d0 * (dx, dy)`` pixels, so that a point
at depth ``Z`` (baselines) has disparity ``d = f / Z - d0`` (``d0 > -dmin`` lets disparities be
negative, as in HCI's converged set-up). A point seen by the reference at ``(x, y)`` then appears
in view ``(r, c)`` at ``(x - d dx, y - d dy)``. Surfaces given in disparity space as
``d(x, y) = a (x - cx) + b (y - cy) + c`` are the 3-D planes ``a X + b Y + (c + d0)/f Z = 1``.
"""

from __future__ import annotations

import math
import time
from typing import Any, Mapping, Sequence

import numpy as np

from . import _options as _opt
from . import tiling
from ._progress import grid_views
from .errors import InvalidInputError
from .lightfield import (LightField, centre_view, check_disparity_range, filter_layout,
                         grid_positions, view_offsets)
from .spectral import FILTER_SHAPES, MAX_FWHM, MIN_FWHM
from .warp import forward_warp_disparity

__all__ = [
    "from_rgb_lightfield",
    "from_hci_scene",
    "procedural_scene",
    "add_noise",
    "band_grid",
    "view_disparity_from_reference",
    "SCENES",
    "named_scene",
    "MAX_OBJECTS",
    "MAX_OBJECT_VALUE",
    "MAX_SUPERSAMPLE",
]


# ----------------------------------------------------------------------------- helpers
def add_noise(views: np.ndarray, sigma: float, seed: Any = 0) -> np.ndarray:
    """Add zero-mean Gaussian noise of standard deviation ``sigma`` and clip to [0, 1].

    Parameters
    ----------
    views : ndarray
        Intensities in [0, 1] (any shape).
    sigma : float
        Noise standard deviation on the [0, 1] scale, at most 1e6; ``0`` returns a float32
        copy.
    seed : int or sequence of int
        Anything :func:`numpy.random.default_rng` accepts; the same seed gives the same noise.

    Returns
    -------
    ndarray of float32, same shape, in [0, 1].

    Examples
    --------
    On mid-grey nothing is clipped, and the noise's spread is measured back:

    >>> grey = np.full((3, 200, 200), 0.5, np.float32)
    >>> noisy = add_noise(grey, 0.05, seed=3)
    >>> noisy.dtype, round(float(noisy.std()), 3), round(float(noisy.mean()), 3)
    (dtype('float32'), 0.05, 0.5)
    >>> bool(np.array_equal(noisy, add_noise(grey, 0.05, seed=3)))  # same seed, same noise
    True

    On black the negative half is clipped to 0, so the mean becomes
    ``sigma / sqrt(2 pi)`` (0.0399 for ``sigma = 0.1``):

    >>> dark = add_noise(np.zeros(100_000), 0.1, seed=0)
    >>> float(dark.min()), round(float(dark.mean()), 3)
    (0.0, 0.04)
    """
    v = _opt.real_array(views, "views", np.float32)
    if v.ndim == 0:
        raise InvalidInputError(f"views must be an array of intensities, got {_opt.shown(views)}")
    sigma = _opt.number(sigma, "noise sigma", at_most=1e6)  # float32 noise stays finite
    if sigma == 0:
        return v.copy()
    try:
        rng = np.random.default_rng(seed)
    except (TypeError, ValueError):
        raise InvalidInputError(f"seed must be an integer >= 0 (or a sequence of them), got "
                                f"{_opt.shown(seed)}") from None
    noisy = v + rng.normal(0.0, sigma, size=v.shape).astype(np.float32)
    return np.clip(noisy, 0.0, 1.0, out=noisy)


def _observe(cube: np.ndarray, kmap: np.ndarray, noise_sigma: float, seed) -> np.ndarray:
    """The captured views: view ``(r, c)`` records band ``kmap[r, c]`` of its cube, plus sensor
    noise (seeded by ``[seed, 1]``) when ``noise_sigma > 0``."""
    R, C = kmap.shape
    clean = cube[np.arange(R)[:, None], np.arange(C)[None, :], kmap]
    return add_noise(clean, noise_sigma, seed=[int(seed), 1]) if noise_sigma > 0 else clean


def band_grid(rows: int, cols: int, lambda_min: float = 410.0,
              lambda_max: float = 700.0) -> np.ndarray:
    """The ``rows * cols`` band centres (nm), equal steps from ``lambda_min`` to ``lambda_max``.

    Parameters
    ----------
    rows, cols : int
        Grid of views (one band per view).
    lambda_min, lambda_max : float
        Band range in nm.

    Returns
    -------
    ndarray of float64, shape (rows * cols,)

    Examples
    --------
    >>> band_grid(1, 3, 400.0, 600.0).tolist()
    [400.0, 500.0, 600.0]
    """
    rows, cols = _opt.integer(rows, "rows", 1), _opt.integer(cols, "cols", 1)
    lambda_min = _opt.number(lambda_min, "lambda_min", positive=True)
    lambda_max = _opt.number(lambda_max, "lambda_max", positive=True)
    tiling.check_memory(8 * rows * cols, f"a {rows} x {cols} grid of bands", "use a smaller grid")
    if not lambda_min <= lambda_max:
        raise InvalidInputError(
            f"band range must satisfy 0 < lambda_min <= lambda_max, got {lambda_min}..{lambda_max}"
        )
    n = rows * cols
    if n > 1 and lambda_min == lambda_max:
        raise InvalidInputError("lambda_min == lambda_max gives identical bands; widen the range")
    return np.linspace(float(lambda_min), float(lambda_max), n) if n > 1 else np.array(
        [float(lambda_min)])


#: Largest view offset (baselines) :func:`view_disparity_from_reference` takes: its sampling
#: grids are float32, and no array is a million baselines wide.
_MAX_OFFSET = 1e6


def view_disparity_from_reference(gt_ref: np.ndarray, offset: tuple[float, float],
                                  *, tol: float = 0.05, iterations: int = 2) -> np.ndarray:
    """Ground-truth disparity of another view from the reference's ground truth.

    A pixel ``p`` of the view with disparity ``d`` shows the reference pixel
    ``q = p + d * (dx, dy)`` (SPEC §1), and must satisfy ``gt_ref(q) = d``. Candidates for ``d``
    come from :func:`hyperlf.warp.forward_warp_disparity` (z-buffer, nearest pixel) and the
    largest / smallest forward-warped value in the 3 x 3 neighbourhood (filling the one-pixel
    cracks that rounding leaves on slanted surfaces); each candidate is refined by
    ``iterations`` fixed-point steps ``d <- gt_ref(p + d * offset)`` (bilinear) and kept if
    ``|gt_ref(p + d * offset) - d| < tol``. The largest consistent candidate (nearest surface)
    wins; pixels with none (disoccluded: not seen by the reference) are NaN.

    Parameters
    ----------
    gt_ref : ndarray (H, W)
        Reference ground truth (NaN allowed).
    offset : (dx, dy)
        View position minus reference position (baselines).
    tol : float
        Largest ``|gt_ref(p + d * offset) - d|`` of a consistent candidate (px per baseline).
    iterations : int
        Fixed-point steps per candidate, at most 100.

    Returns
    -------
    ndarray of float32 (H, W)

    Examples
    --------
    A background at disparity 2 and, in front of it, a square at disparity 4 spanning
    reference columns 10..19. In the view one baseline to the right the square moves 4 px to
    the left (columns 6..15) and the background 2 px, which uncovers the background of
    columns 16 and 17: the reference never saw it, so those pixels are NaN.

    >>> gt = np.full((24, 32), 2.0, np.float32)
    >>> gt[8:16, 10:20] = 4.0
    >>> d = view_disparity_from_reference(gt, (1.0, 0.0))
    >>> d[12, 4:20].tolist()
    [2.0, 2.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0, nan, nan, 2.0, 2.0]
    """
    import cv2
    from scipy import ndimage

    g = np.ascontiguousarray(_opt.real_array(gt_ref, "gt_ref", np.float32))
    if g.ndim != 2:
        raise InvalidInputError(f"gt_ref must be an (H, W) map, got shape {g.shape}")
    H, W = g.shape
    dx, dy = _opt.real_pair(offset, "offset", "two finite numbers (dx, dy)")
    if max(abs(dx), abs(dy)) > _MAX_OFFSET:
        raise InvalidInputError(f"offset must be at most {_MAX_OFFSET:g} baselines in size, got "
                                f"{_opt.shown(offset)}")
    tol = _opt.number(tol, "tol", at_most=1e6)  # px; compared with float32 maps
    iterations = _opt.integer(iterations, "iterations", maximum=100)
    fw = forward_warp_disparity(g, (dx, dy))
    if dx == 0 and dy == 0:
        return g.copy()
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)

    def sample(d: np.ndarray) -> np.ndarray:
        mx = xx + d * np.float32(dx)
        my = yy + d * np.float32(dy)
        # replicated, not NaN, beyond the border: a sample exactly on the last row or column
        # has a zero-weight tap outside, and a NaN there made it NaN (0 * NaN); what lies
        # beyond the image is masked just below
        out = cv2.remap(g, np.nan_to_num(mx, nan=-10.0), np.nan_to_num(my, nan=-10.0),
                        cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        out[~np.isfinite(d) | (mx < 0) | (mx > W - 1) | (my < 0) | (my > H - 1)] = np.nan
        return out

    hi = ndimage.maximum_filter(np.where(np.isnan(fw), -np.inf, fw), size=3)
    lo = ndimage.minimum_filter(np.where(np.isnan(fw), np.inf, fw), size=3)
    best = np.full((H, W), np.nan, dtype=np.float32)
    for cand in (fw, hi, lo):
        d = np.where(np.isfinite(cand), cand, np.nan).astype(np.float32)
        for _ in range(int(iterations)):
            d = sample(d)
        chk = sample(d)
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(d) & (np.abs(chk - d) < tol) & ~(best >= d)
        best[ok] = d[ok]
    return best


def _layout_meta(layout: Any) -> Any:
    return layout if isinstance(layout, str) else [int(v) for v in np.asarray(layout).ravel()]


def _qe_on(quantum_efficiency: Any, wl: np.ndarray, cube_wl: np.ndarray) -> np.ndarray:
    """Quantum efficiency evaluated on ``wl`` (ones when None)."""
    if quantum_efficiency is None:
        return np.ones_like(wl)
    if callable(quantum_efficiency):
        q = _opt.real_array(quantum_efficiency(wl), "quantum_efficiency(wavelengths)")
    elif (isinstance(quantum_efficiency, (tuple, list)) and len(quantum_efficiency) == 2
          and np.ndim(quantum_efficiency[0]) == 1 and np.ndim(quantum_efficiency[1]) == 1):
        qw = _opt.real_array(quantum_efficiency[0], "quantum_efficiency's wavelengths")
        qv = _opt.real_array(quantum_efficiency[1], "quantum_efficiency's values")
        if qw.shape != qv.shape or qw.size < 2:
            raise InvalidInputError(
                "quantum_efficiency as (wavelengths, values) needs two 1-D arrays of equal length"
            )
        order = np.argsort(qw)
        q = np.interp(wl, qw[order], qv[order])
    else:
        qv = _opt.real_array(quantum_efficiency, "quantum_efficiency").ravel()
        if qv.size != cube_wl.size:
            raise InvalidInputError(
                f"quantum_efficiency must be a callable, a (wavelengths, values) pair or one "
                f"value per band ({cube_wl.size}); got {qv.size} values"
            )
        q = np.interp(wl, cube_wl, qv)
    if q.shape != wl.shape or not np.all(np.isfinite(q)) or np.any(q < 0):
        raise InvalidInputError("quantum efficiency must be finite and >= 0 at every wavelength")
    if q.max() > 1.0 + 1e-9:
        raise InvalidInputError(
            f"quantum efficiency must be a fraction in [0, 1] (max here {q.max():g}); "
            "divide percentages by 100"
        )
    return q


def _qe_meta(quantum_efficiency: Any) -> Any:
    if quantum_efficiency is None:
        return None
    if callable(quantum_efficiency):
        return getattr(quantum_efficiency, "__name__", "callable")
    if isinstance(quantum_efficiency, (tuple, list)) and len(quantum_efficiency) == 2 and \
            np.ndim(quantum_efficiency[0]) == 1:
        return {"wavelengths": [float(v) for v in quantum_efficiency[0]],
                "values": [float(v) for v in quantum_efficiency[1]]}
    return [float(v) for v in np.asarray(quantum_efficiency).ravel()]


def _band_weights(cube_wl: np.ndarray, filter_shape: str, fwhm: float,
                  quantum_efficiency: Any, illuminant: str | None,
                  spectral_range: tuple[float, float] = (380.0, 780.0)
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Spectral sampling grid ``wl`` and weights ``Wt (len(wl), B)`` of every band.

    ``band_b = sum_k radiance(wl_k) * Wt[k, b]`` where the weights hold the filter transmission
    (normalised to unit sum, so a flat unit spectrum gives 1 before illuminant and QE), the
    illuminant SPD (normalised to max 1 on ``wl``) and the quantum efficiency. Dirac filters
    sample the spectrum at the band centres; other shapes integrate on a 1 nm grid.
    ``filter_shape`` and ``fwhm`` are checked by the callers' rules (:data:`_SCENE_RULES`).
    """
    from . import spectral

    if filter_shape == "dirac":
        wl = cube_wl.astype(np.float64)
        Wt = np.eye(wl.size)
    else:
        lo = max(spectral_range[0], math.floor(cube_wl.min() - 3 * fwhm))
        hi = min(spectral_range[1], math.ceil(cube_wl.max() + 3 * fwhm))
        wl = np.arange(lo, hi + 0.5, 1.0)
        Wt = np.empty((wl.size, cube_wl.size))
        for b, c in enumerate(cube_wl):
            t = np.asarray(spectral.filter_response(float(c), wl, shape=filter_shape, fwhm=fwhm),
                           dtype=np.float64)
            t = np.clip(t, 0.0, None)
            s = t.sum()
            if not np.isfinite(s) or s <= 0:
                raise InvalidInputError(
                    f"the {filter_shape} filter at {c:g} nm has no transmission on "
                    f"{lo:g}..{hi:g} nm; use a narrower band range"
                )
            Wt[:, b] = t / s
    if illuminant is not None:
        e = np.asarray(spectral.illuminant_spd(illuminant, wl), dtype=np.float64)
        if e.shape != wl.shape or not np.all(np.isfinite(e)) or e.max() <= 0:
            raise InvalidInputError(f"illuminant {illuminant!r} has no usable SPD on the bands")
        Wt = Wt * (np.clip(e, 0, None) / e.max())[:, None]
    Wt = Wt * _qe_on(quantum_efficiency, wl, cube_wl)[:, None]
    return wl, Wt


def _subgrid_start(src_shape: tuple[int, int], src_ref: tuple[int, int], rows: int,
                   cols: int) -> tuple[int, int]:
    R0, C0 = src_shape
    if rows > R0 or cols > C0:
        raise InvalidInputError(
            f"cannot take a {rows} x {cols} sub-grid from a {R0} x {C0} light field; "
            f"ask for at most {R0} x {C0} views"
        )
    r0, c0 = centre_view(rows, cols)
    sr, sc = src_ref[0] - r0, src_ref[1] - c0
    if sr < 0 or sc < 0 or sr + rows > R0 or sc + cols > C0:
        raise InvalidInputError(
            f"a {rows} x {cols} sub-grid with the source reference {src_ref} at ({r0}, {c0}) "
            f"does not fit in the {R0} x {C0} grid; choose a smaller grid"
        )
    return sr, sc


def _simple(v: Any) -> bool:
    return isinstance(v, (str, int, float, bool)) or v is None


# ----------------------------------------------------------------------------- from RGB
def _check_rgb_args(lf_rgb: Any, view_disparity: str, normalization: str) -> None:
    if not isinstance(lf_rgb, LightField):
        raise InvalidInputError(
            f"from_rgb_lightfield needs a LightField, got {type(lf_rgb).__name__}; "
            "read one with hyperlf.formats.read_hci_scene"
        )
    if lf_rgb.views.ndim != 5 or lf_rgb.views.shape[4] != 3:
        raise InvalidInputError(
            f"from_rgb_lightfield needs RGB views (R, C, H, W, 3); got {lf_rgb.views.shape}"
        )
    _opt.choice(view_disparity, "view_disparity", ("warp", "reference"))
    _opt.choice(normalization, "normalization", ("white", "max"))


class _RGBToBands:
    """Linear RGB -> band values through ``spectral.rgb_to_spectrum`` and the band weights.

    When the spectral map is linear (checked numerically on random probes) and non-negative it
    is folded once into a 3 x B matrix; otherwise spectra are computed per pixel, clipped at 0.
    """

    def __init__(self, wl: np.ndarray, Wt: np.ndarray):
        from . import spectral

        self._spectral = spectral
        self.wl, self.Wt, self.B = wl, Wt, Wt.shape[1]
        basis = np.asarray(spectral.rgb_to_spectrum(np.eye(3), wl), dtype=np.float64)
        probe = np.random.default_rng(1).random((8, 3))
        self.linear = bool(
            basis.shape == (3, wl.size) and np.all(np.isfinite(basis))
            and np.allclose(np.asarray(spectral.rgb_to_spectrum(probe, wl), dtype=np.float64),
                            probe @ basis, atol=1e-6)
            and basis.min() >= 0)
        self.M = basis @ Wt if self.linear else None  # (3, B)
        self.M32 = np.ascontiguousarray(self.M.T, dtype=np.float32) if self.linear else None

    def __call__(self, rgb_lin: np.ndarray) -> np.ndarray:
        """(H, W, 3) linear RGB -> (B, H, W) float32."""
        h, w = rgb_lin.shape[:2]
        B, wl = self.B, self.wl
        if self.linear:
            planes = np.ascontiguousarray(np.moveaxis(rgb_lin, -1, 0).reshape(3, -1),
                                          dtype=np.float32)
            return (self.M32 @ planes).reshape(B, h, w)
        flat = rgb_lin.reshape(-1, 3)
        out = np.empty((flat.shape[0], B))
        step = max(1, 2_000_000 // max(wl.size, 1))
        for i in range(0, flat.shape[0], step):
            sp = np.asarray(self._spectral.rgb_to_spectrum(flat[i:i + step], wl),
                            dtype=np.float64)
            out[i:i + step] = np.clip(sp, 0.0, None) @ self.Wt
        return out.T.reshape(B, h, w).astype(np.float32)

    def white(self) -> np.ndarray:
        """Band values of a perfect white (linear RGB 1, 1, 1)."""
        if self.linear:
            return np.ones(3) @ self.M
        sp = np.asarray(self._spectral.rgb_to_spectrum(np.ones((1, 3)), self.wl),
                        dtype=np.float64)
        return np.clip(sp, 0.0, None) @ self.Wt


def _rgb_cube(lf_rgb: LightField, start: tuple[int, int], rows: int, cols: int,
              to_bands: _RGBToBands, progress: bool) -> np.ndarray:
    """Every band of every view of the sub-grid starting at ``start``: (R, C, B, H, W)."""
    from . import spectral

    sr, sc = start
    H, W = lf_rgb.image_shape
    cube = np.empty((rows, cols, to_bands.B, H, W), dtype=np.float32)
    for r, c in grid_views(rows, cols, "spectra per view", progress):
        srgb = np.asarray(lf_rgb.views[sr + r, sc + c], dtype=np.float32)
        lin = np.asarray(spectral.srgb_to_linear(srgb), dtype=np.float32)
        np.maximum(lin, 0.0, out=lin)
        cube[r, c] = to_bands(lin)
    return cube


def _normalise_cube(cube: np.ndarray, white: np.ndarray, normalization: str) -> float:
    """Scale ``cube`` in place (``"white"`` or ``"max"``; see :func:`from_rgb_lightfield`)."""
    cmax = float(cube.max())
    if normalization == "white" and float(np.max(white)) > 0:
        scale = 1.0 / float(np.max(white))
        if cmax * scale > 1.0:
            scale = 1.0 / cmax
    else:
        scale = 1.0 / cmax if cmax > 0 else 1.0
    if scale != 1.0:
        cube *= np.float32(scale)
    np.clip(cube, 0.0, 1.0, out=cube)  # rounding only; the scale already keeps it <= 1
    return scale


def _subgrid_gt_disparity(lf_rgb: LightField, start: tuple[int, int], rows: int, cols: int,
                          view_disparity: str) -> tuple[np.ndarray | None, str | None]:
    """Ground-truth disparity of the sub-grid and how it was obtained."""
    gt = lf_rgb.gt_disparity
    if gt is None:
        return None, None
    sr, sc = start
    if gt.ndim == 4:
        return gt[sr:sr + rows, sc:sc + cols].copy(), "source, every view"
    if view_disparity == "reference":
        return gt.copy(), "source reference view only"
    H, W = lf_rgb.image_shape
    offsets = lf_rgb.offsets[sr:sr + rows, sc:sc + cols]
    ref = centre_view(rows, cols)
    gt_out = np.empty((rows, cols, H, W), dtype=np.float32)
    for r in range(rows):
        for c in range(cols):
            if (r, c) == ref:
                gt_out[r, c] = gt
            else:
                gt_out[r, c] = view_disparity_from_reference(gt, tuple(offsets[r, c]))
    return gt_out, ("reference: source; other views: forward-warped reference "
                    "(z-buffer), refined and crack-filled by a consistency check "
                    "against the reference ground truth; unknown pixels NaN")


def _source_disparity_range(lf_rgb: LightField) -> tuple[float, float] | None:
    gt = lf_rgb.gt_disparity
    if lf_rgb.disparity_range is not None:
        return lf_rgb.disparity_range
    if gt is not None and np.isfinite(gt).any():
        lo, hi = float(np.nanmin(gt)), float(np.nanmax(gt))
        return (lo, hi) if hi > lo else (lo - 0.5, hi + 0.5)
    return None


def _rgb_metadata(lf_rgb: LightField, start: tuple[int, int], origin: np.ndarray,
                  opts: dict, kmap: np.ndarray, linear: bool, scale: float,
                  disp_method: str | None) -> dict:
    sr, sc = start
    rows, cols, filter_shape = opts["rows"], opts["cols"], opts["filter_shape"]
    src_meta = {k: v for k, v in lf_rgb.metadata.items() if _simple(v)}
    return {
        "synthesis": "from_rgb_lightfield",
        "source": src_meta.get("source", src_meta.get("path", "rgb light field")),
        "source_metadata": src_meta,
        "source_grid": list(lf_rgb.grid_shape),
        "source_reference": list(lf_rgb.reference),
        "subgrid_rows": [sr, sr + rows - 1],
        "subgrid_cols": [sc, sc + cols - 1],
        "source_position_origin": [float(v) for v in origin],
        "licence": src_meta.get("licence"),
        "rows": rows, "cols": cols,
        "lambda_min": float(opts["lambda_min"]), "lambda_max": float(opts["lambda_max"]),
        "layout": _layout_meta(opts["layout"]),
        "band_index": kmap.tolist(),
        "filter_shape": filter_shape,
        "fwhm": float(opts["fwhm"]) if filter_shape != "dirac" else None,
        "quantum_efficiency": _qe_meta(opts["quantum_efficiency"]),
        "illuminant": opts["illuminant"],
        "spectral_basis": "hyperlf.spectral.rgb_to_spectrum (Mallett & Yuksel 2019)",
        "spectral_path": "linear 3xB matrix" if linear else "per-pixel spectra clipped at 0",
        "normalization": opts["normalization"],
        "intensity_scale": float(scale),
        "noise_sigma": float(opts["noise_sigma"]),
        "seed": int(opts["seed"]),
        "gt_disparity": disp_method,
    }


def from_rgb_lightfield(lf_rgb: LightField, *, rows: int = 5, cols: int = 6,
                        lambda_min: float = 410.0, lambda_max: float = 700.0,
                        layout: str | Sequence[int] = "raster", filter_shape: str = "dirac",
                        quantum_efficiency: Any = None, noise_sigma: float = 0.0,
                        seed: int = 0, illuminant: str | None = None, fwhm: float = 10.0,
                        view_disparity: str = "warp", normalization: str = "white",
                        progress: bool = False) -> LightField:
    """Synthesise an H-LF (with its ground-truth cube) from an RGB light field (SPEC §6).

    Steps
    -----
    1. Take the ``rows x cols`` sub-grid whose reference ``((rows-1)//2, (cols-1)//2)`` is the
       source's reference view (HCI 9 x 9 -> 5 x 6: rows 2..6, columns 2..7, reference = Cam040).
       Positions are the source positions of the sub-grid minus that of its first view.
    2. sRGB -> linear RGB (``hyperlf.spectral.srgb_to_linear``); negative values are set to 0.
    3. Every pixel becomes a spectrum through ``hyperlf.spectral.rgb_to_spectrum`` (Mallett 2019
       basis). Because that map is linear, it is evaluated once on the RGB unit vectors and
       folded with the filters, illuminant and QE into a 3 x B matrix (checked numerically; a
       non-linear or negative-valued map falls back to per-pixel spectra, clipped at 0), so the
       cube is built view by view without holding per-pixel fine spectra.
    4. Band ``b`` of view ``(r, c)``: the spectrum sampled at ``cube_wavelengths[b]`` (Dirac
       filter) or integrated against the unit-sum filter transmission on a 1 nm grid
       (``filter_shape`` "gaussian" / "thorlabs" with ``fwhm``), times the illuminant SPD
       (``illuminant`` name, normalised to max 1; ``None``: the recovered spectrum is the
       radiance itself, i.e. equal-energy light) and the quantum efficiency (fraction in [0,1]:
       callable of wavelength, ``(wavelengths, values)`` pair or one value per band).
    5. Normalisation (``normalization``): ``"white"`` (default) scales so that a perfect white
       (linear RGB 1, 1, 1) reads 1 in its brightest band -- a fixed, scene-independent exposure
       (scale 1 for the Mallett basis, Dirac filters and no illuminant); if anything still
       exceeds 1 the whole cube is divided by its maximum. ``"max"`` divides the whole cube by
       its global maximum. A single global factor preserves relative spectra; it is recorded in
       ``metadata["intensity_scale"]``.
    6. ``views[r, c] = gt_cube[r, c, layout[r, c]]`` plus Gaussian noise (``noise_sigma``,
       seeded by ``seed``), clipped to [0, 1].

    Ground-truth disparity: a source with per-view ground truth keeps it; one with only the
    reference's (HCI) gets, with ``view_disparity="warp"`` (default), every other view's by
    forward-warping the reference ground truth (z-buffer, nearest pixel; holes NaN), or with
    ``view_disparity="reference"`` only the reference map ``(H, W)``.

    Parameters
    ----------
    lf_rgb : LightField
        Colour light field, views ``(R0, C0, H, W, 3)`` sRGB-encoded in [0, 1].
    rows, cols : int
        Grid of the H-LF (paper: 5 x 6).
    lambda_min, lambda_max : float
        Band range in nm; ``rows * cols`` bands in equal steps.
    layout : {"raster", "serpentine", "random"} or sequence of int
        Filter layout (:func:`hyperlf.filter_layout`; "random" drawn from ``seed``).
    seed : int
        Seed of the noise (and of a random layout).
    progress : bool
        Show a progress bar over the views.

    Returns
    -------
    LightField

    Raises
    ------
    InvalidInputError
        For a non-RGB input, a sub-grid that does not fit, or bad parameters.

    References
    ----------
    I. Mallett, C. Yuksel, "Spectral primary decomposition for rendering with sRGB
    reflectance", Eurographics Symposium on Rendering 2019 (the RGB -> spectrum basis).

    Examples
    --------
    >>> rgb = LightField(np.full((3, 3, 8, 8, 3), 0.5, np.float32))
    >>> H = from_rgb_lightfield(rgb, rows=3, cols=3)
    >>> H.views.shape, float(H.wavelengths[1, 1])
    ((3, 3, 8, 8), 555.0)
    """
    _check_rgb_args(lf_rgb, view_disparity, normalization)
    # the options it shares with procedural_scene, by the same rules (values kept as given)
    _opt.check_values(dict(rows=rows, cols=cols, lambda_min=lambda_min, lambda_max=lambda_max,
                           filter_shape=filter_shape, fwhm=fwhm, noise_sigma=noise_sigma,
                           seed=seed, progress=progress), _SCENE_RULES)
    rows, cols = int(rows), int(cols)
    t_start = time.perf_counter()
    cube_wl = band_grid(rows, cols, lambda_min, lambda_max)
    kmap = filter_layout(rows, cols, layout, seed=seed)
    wavelengths = cube_wl[kmap]
    start = _subgrid_start(lf_rgb.grid_shape, lf_rgb.reference, rows, cols)

    wl, Wt = _band_weights(cube_wl, filter_shape, float(fwhm), quantum_efficiency, illuminant)
    to_bands = _RGBToBands(wl, Wt)
    cube = _rgb_cube(lf_rgb, start, rows, cols, to_bands, progress)
    scale = _normalise_cube(cube, to_bands.white(), normalization)

    views = _observe(cube, kmap, noise_sigma, seed)  # (R, C, H, W)

    gt_out, disp_method = _subgrid_gt_disparity(lf_rgb, start, rows, cols, view_disparity)
    drange = _source_disparity_range(lf_rgb)
    ref = centre_view(rows, cols)

    sr, sc = start
    positions = lf_rgb.positions[sr:sr + rows, sc:sc + cols]
    origin = positions[0, 0].copy()
    positions = positions - origin[None, None, :]
    opts = dict(rows=rows, cols=cols, lambda_min=lambda_min, lambda_max=lambda_max,
                layout=layout, filter_shape=filter_shape, fwhm=fwhm,
                quantum_efficiency=quantum_efficiency, illuminant=illuminant,
                normalization=normalization, noise_sigma=noise_sigma, seed=seed)
    metadata = _rgb_metadata(lf_rgb, start, origin, opts, kmap, to_bands.linear, scale,
                             disp_method)
    metadata["runtime_s"] = round(time.perf_counter() - t_start, 3)
    return LightField(views=views, wavelengths=wavelengths, positions=positions,
                      reference=ref, disparity_range=drange, gt_disparity=gt_out,
                      gt_cube=cube, cube_wavelengths=cube_wl, metadata=metadata)


def from_hci_scene(folder: Any, **kw: Any) -> LightField:
    """Read an HCI 4D light field scene folder and synthesise an H-LF from it.

    ``hyperlf.formats.read_hci_scene(folder)`` followed by :func:`from_rgb_lightfield` with the
    keyword arguments ``kw`` (rows, cols, lambda_min, ..., see there). For ``antinous`` and the
    default 5 x 6 grid the reference view is the centre camera ``input_Cam040``. The scene is
    CC BY-NC-SA 4.0 (Honauer et al. 2016), recorded in the metadata.

    Parameters
    ----------
    folder : path-like
        HCI scene folder (``input_Cam###.png``, ``gt_disp_lowres.pfm``).
    **kw
        Keyword arguments of :func:`from_rgb_lightfield`.

    Returns
    -------
    LightField
        The H-LF with its ground-truth cube and disparity.

    References
    ----------
    K. Honauer, O. Johannsen, D. Kondermann, B. Goldluecke, "A dataset and evaluation
    methodology for depth estimation on 4D light fields", ACCV 2016.

    Examples
    --------
    A stand-in scene (the real ones come from the benchmark): a 3 x 3 grid of uniform
    mid-grey 8-bit views and a ground truth of 1.5 px everywhere. Grey has a flat
    spectrum, so every band of every view holds the linear value of the stored sRGB
    ``128 / 255``, which is ``((128 / 255 + 0.055) / 1.055) ** 2.4``:

    >>> import pathlib, tempfile
    >>> from hyperlf.formats import write_image, write_pfm
    >>> scene = pathlib.Path(tempfile.mkdtemp()) / "grey"
    >>> scene.mkdir()
    >>> for i in range(9):
    ...     _ = write_image(scene / f"input_Cam{i:03d}.png", np.full((24, 32, 3), 0.5), 8)
    >>> _ = write_pfm(scene / "gt_disp_lowres.pfm", np.full((24, 32), 1.5, np.float32))
    >>> lf = from_hci_scene(scene, rows=3, cols=3)
    >>> lf.views.shape, lf.reference, float(lf.wavelengths[lf.reference])
    ((3, 3, 24, 32), (1, 1), 555.0)
    >>> round(float(lf.views.mean()), 4), round(((128 / 255 + 0.055) / 1.055) ** 2.4, 4)
    (0.2159, 0.2159)
    >>> float(lf.reference_gt_disparity.mean())
    1.5
    """
    from .formats import read_hci_scene

    rows, cols = int(kw.get("rows", 5)), int(kw.get("cols", 6))
    # Read only the needed sub-grid around the centre camera (the full grid size comes from a
    # one-view read); fall back to reading everything.
    sub = None
    try:
        probe = read_hci_scene(folder, rows=[0], cols=[0])
        R0, C0 = (int(v) for v in probe.metadata["full_grid"])
        sr, sc = _subgrid_start((R0, C0), ((R0 - 1) // 2, (C0 - 1) // 2), rows, cols)
        sub = (sr, sc)
    except (KeyError, TypeError, ValueError):
        sub = None
    if sub is not None:
        lf = read_hci_scene(folder, rows=range(sub[0], sub[0] + rows),
                            cols=range(sub[1], sub[1] + cols))
        if lf.reference != centre_view(rows, cols) or lf.gt_disparity is None:
            lf = read_hci_scene(folder)
            sub = None
    else:
        lf = read_hci_scene(folder)
    out = from_rgb_lightfield(lf, **kw)
    md = out.metadata
    md["synthesis"] = "from_hci_scene"
    md["source_folder"] = str(folder)
    if sub is not None:
        md["source_grid"] = [R0, C0]
        md["source_reference"] = [(R0 - 1) // 2, (C0 - 1) // 2]
        md["subgrid_rows"] = [sub[0], sub[0] + rows - 1]
        md["subgrid_cols"] = [sub[1], sub[1] + cols - 1]
    if not md.get("licence"):
        md["licence"] = lf.metadata.get("licence") or (
            "HCI 4D light field benchmark, CC BY-NC-SA 4.0, cite Honauer et al. 2016")
    return out


# ----------------------------------------------------------------------------- procedural
_EPS = 1e-9


def _hash2(ix: np.ndarray, iy: np.ndarray, salt: int) -> np.ndarray:
    """Deterministic integer hash of two integer arrays (uint64)."""
    with np.errstate(over="ignore"):
        h = (ix.astype(np.int64).astype(np.uint64) * np.uint64(0x9E3779B1)
             ^ iy.astype(np.int64).astype(np.uint64) * np.uint64(0x85EBCA77)
             ^ np.uint64(salt & 0xFFFFFFFF) * np.uint64(0xC2B2AE3D))
        h ^= h >> np.uint64(15)
        h *= np.uint64(0x2C1B3C6D)
        h ^= h >> np.uint64(12)
        h *= np.uint64(0x297A2D39)
        h ^= h >> np.uint64(15)
    return h


def _texture(tex: Mapping[str, Any], u: np.ndarray, v: np.ndarray, period_px: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Texture lookup in an object's own 2-D coordinates ``(u, v)`` (pixels at the object).

    Returns local palette indices ``(i1, i2)`` and the weight ``w`` of ``i1`` (the rest goes to
    ``i2``).
    """
    pattern = tex["pattern"]
    n = len(tex["chips"])
    p = max(period_px, 1e-3)
    ones = np.ones(u.shape)
    if pattern == "checker":
        k = (np.floor(u / p) + np.floor(v / p)).astype(np.int64) % 2
        return k % n, k % n, ones
    if pattern == "stripes":
        a = math.radians(tex.get("angle", 0.0))
        k = np.floor((u * math.cos(a) + v * math.sin(a)) / p).astype(np.int64) % n
        return k, k, ones
    if pattern == "patches":
        jit = tex.get("jitter", [0.0, 0.0])
        uu = u + 0.35 * p * np.sin(2 * np.pi * v / (1.7 * p) + jit[0])
        vv = v + 0.35 * p * np.sin(2 * np.pi * u / (1.9 * p) + jit[1])
        h = _hash2(np.floor(uu / p), np.floor(vv / p), int(tex.get("salt", 0)))
        k = (h % np.uint64(n)).astype(np.int64)
        return k, k, ones
    if pattern == "noise":
        field = np.zeros(u.shape)
        waves = tex["waves"]
        for fx, fy, ph in waves:
            field += np.sin(2 * np.pi * (fx * u + fy * v) / p + ph)
        field /= math.sqrt(len(waves) / 2.0)
        w = np.clip(0.5 + 0.5 * field, 0.0, 1.0)
        i1 = np.zeros(u.shape, np.int64)
        i2 = np.full(u.shape, 1 % n, np.int64)
        return i1, i2, w
    raise InvalidInputError(
        f"unknown texture pattern {pattern!r}; use 'checker', 'stripes', 'noise' or 'patches'"
    )


class _Surface:
    """An analytic surface: intersect rays, then give texture coordinates and normals."""

    def __init__(self, spec: dict, geom: dict):
        self.spec = spec
        self.g = geom

    # each returns t (N,) with inf for misses, and aux (face index) or None
    def intersect(self, C: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, Any]:
        raise NotImplementedError

    def surface(self, P: np.ndarray, aux: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        raise NotImplementedError


class _Plane(_Surface):
    # plane n . P = 1, optional rect bound in reference-image pixel coordinates
    def intersect(self, C, D):
        n = self.g["n"]
        denom = D @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (1.0 - n @ C) / denom
        t = np.where(np.isfinite(t) & (t > _EPS), t, np.inf)
        rect = self.g["rect_px"]
        if rect is not None:
            f, cx, cy = self.g["f"], self.g["cx"], self.g["cy"]
            tt = np.where(np.isfinite(t), t, 1.0)
            P = C[None, :] + tt[:, None] * D
            xr = cx + f * P[:, 0] / P[:, 2]
            yr = cy + f * P[:, 1] / P[:, 2]
            inside = (xr >= rect[0]) & (xr < rect[2]) & (yr >= rect[1]) & (yr < rect[3])
            if self.g.get("shape") is not None:
                inside &= _shape_inside(self.g["shape"], xr, yr)
            t = np.where(inside, t, np.inf)
        return t, None

    def surface(self, P, aux):
        f, cx, cy = self.g["f"], self.g["cx"], self.g["cy"]
        u = cx + f * P[:, 0] / P[:, 2]
        v = cy + f * P[:, 1] / P[:, 2]
        nrm = -self.g["n"] / np.linalg.norm(self.g["n"])
        return u, v, np.broadcast_to(nrm, P.shape)


class _Sphere(_Surface):
    def intersect(self, C, D):
        P0, rho = self.g["center"], self.g["radius"]
        oc = C - P0
        a = np.einsum("ij,ij->i", D, D)
        b = D @ oc
        cq = oc @ oc - rho * rho
        disc = b * b - a * cq
        ok = disc >= 0
        sq = np.sqrt(np.where(ok, disc, 0.0))
        t = (-b - sq) / a
        t = np.where(ok & (t > _EPS), t, np.inf)
        return t, None

    def surface(self, P, aux):
        nrm = (P - self.g["center"]) / self.g["radius"]
        rpx = self.g["radius_px"]
        u = rpx * np.arctan2(nrm[:, 0], -nrm[:, 2])
        v = rpx * np.arcsin(np.clip(nrm[:, 1], -1.0, 1.0))
        return u, v, nrm


class _Box(_Surface):
    def intersect(self, C, D):
        lo, hi = self.g["lo"], self.g["hi"]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / D
            t1 = (lo - C)[None, :] * inv
            t2 = (hi - C)[None, :] * inv
        tmin = np.where(np.isnan(t1) | np.isnan(t2), -np.inf, np.minimum(t1, t2))
        tmax = np.where(np.isnan(t1) | np.isnan(t2), np.inf, np.maximum(t1, t2))
        face = np.argmax(tmin, axis=1)
        tnear = tmin[np.arange(tmin.shape[0]), face]
        tfar = tmax.min(axis=1)
        hit = (tnear <= tfar) & (tnear > _EPS) & np.isfinite(tnear)
        sign = np.sign(D[np.arange(D.shape[0]), face])  # >0: entered through the lo face
        return np.where(hit, tnear, np.inf), (face, sign)

    def surface(self, P, aux):
        face, sign = aux
        f, cx, cy, z0 = self.g["f"], self.g["cx"], self.g["cy"], self.g["lo"][2]
        s = f / z0
        u = np.where(face == 1, cx + s * P[:, 0], np.where(face == 0, s * P[:, 2], cx + s * P[:, 0]))
        v = np.where(face == 0, cy + s * P[:, 1], np.where(face == 1, s * P[:, 2], cy + s * P[:, 1]))
        nrm = np.zeros(P.shape)
        nrm[np.arange(P.shape[0]), face] = -sign
        return u, v, nrm


_PATTERNS = ("checker", "stripes", "noise", "patches")
_KINDS = ("fronto", "slanted", "box", "sphere")
#: Shapes a plane may take (its ``"shape"``): a ring, whose hole shows what lies behind it,
#: and a thin stick at any angle.
_SHAPES = ("ring", "stick")
#: Object kinds with thin parts and holes (``procedural_scene(kinds=...)``), each a
#: fronto-parallel plane of that shape (:func:`_thin_object`); not in the default
#: :data:`_KINDS`, so the default scenes stay what they were.
_THIN_KINDS = _SHAPES
_ALL_KINDS = _KINDS + _THIN_KINDS


def _shape_inside(shape: dict, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Inside a plane's shape, in reference-image pixel coordinates (``shape`` in pixels as
    :func:`_shape_px` makes it): a ring (elliptic annulus) or a stick (a segment's
    neighbourhood of half its width)."""
    if shape["kind"] == "ring":
        (xc, yc), (a, b) = shape["centre"], shape["axes"]
        q = ((x - xc) / a) ** 2 + ((y - yc) / b) ** 2
        return (q < 1.0) & (q >= shape["hole"] ** 2)
    (x0, y0), (x1, y1) = shape["ends"]
    dx, dy = x1 - x0, y1 - y0
    t = np.clip(((x - x0) * dx + (y - y0) * dy) / max(dx * dx + dy * dy, _EPS), 0.0, 1.0)
    return np.hypot(x - x0 - t * dx, y - y0 - t * dy) <= shape["width"] / 2.0


def _rect_px(rect, H: int, W: int) -> list[float]:
    """A rect ``[u0, v0, u1, v1]`` in fractions of the image as pixel coordinates (pixel
    centres at integers)."""
    return [rect[0] * W - 0.5, rect[1] * H - 0.5, rect[2] * W - 0.5, rect[3] * H - 0.5]


def _plane_shape_px(o: Mapping[str, Any], H: int, W: int) -> dict | None:
    """The pixel shape (:func:`_shape_px`) of plane object ``o``, None without one."""
    if o.get("shape") is None:
        return None
    rect = o.get("rect")
    return _shape_px(o["shape"], None if rect is None else _rect_px(rect, H, W), H, W)


def _shape_px(shape: Mapping[str, Any], rect_px: list, H: int, W: int) -> dict:
    """A plane's ``shape`` (fractions of the image, checked by :func:`_check_shape`) in pixels:
    ``{"kind": "ring", "hole": h}`` is the ellipse inscribed in the plane's rect with a hole of
    ``h`` (0-1, default 0.6) times its size; ``{"kind": "stick", "ends": [[u0, v0], [u1, v1]],
    "width": w}`` the points within ``w / 2`` (a fraction of ``min(H, W)``, default 0.02) of
    the segment between the two ends."""
    if shape["kind"] == "ring":
        x0, y0, x1, y1 = rect_px
        return {"kind": "ring", "hole": float(shape.get("hole", 0.6)),
                "centre": ((x0 + x1) / 2, (y0 + y1) / 2), "axes": ((x1 - x0) / 2, (y1 - y0) / 2)}
    (u0, v0), (u1, v1) = np.asarray(shape["ends"], dtype=np.float64)
    return {"kind": "stick", "width": float(shape.get("width", 0.02)) * min(H, W),
            "ends": ((u0 * W - 0.5, v0 * H - 0.5), (u1 * W - 0.5, v1 * H - 0.5))}


def _check_shape(shape, label: str, rect) -> None:
    """A plane's ``shape`` (:func:`_shape_px`): a ring or a stick, inside the plane's ``rect``."""
    if not isinstance(shape, Mapping):
        raise InvalidInputError(f"{label} must be a dict whose 'kind' is one of "
                                f"{', '.join(_SHAPES)}, got {_opt.shown(shape)}")
    kind = _opt.choice(shape.get("kind"), f"{label}['kind'] (a plane's shape)", _SHAPES)
    if rect is None:
        raise InvalidInputError(f"a {kind} plane needs a rect")
    if kind == "ring":
        _opt.mapping(shape, label, keys=("kind", "hole"), taker="a ring")
        _opt.number(shape.get("hole", 0.6), f"{label}['hole'] (a ring's hole)", below=1.0)
        return
    _opt.mapping(shape, label, keys=("kind", "ends", "width"), taker="a stick")
    ends = _opt.real_array(shape.get("ends", ()), f"{label}['ends']")
    if ends.shape != (2, 2) or not (np.abs(ends) <= MAX_OBJECT_VALUE).all():
        raise InvalidInputError(f"a stick needs 'ends': [[u0, v0], [u1, v1]], finite and at "
                                f"most {MAX_OBJECT_VALUE:g} in size, got "
                                f"{_opt.shown(shape.get('ends'))}")
    _opt.number(shape.get("width", 0.02), f"{label}['width'] (a stick's width)", positive=True,
                at_most=MAX_OBJECT_VALUE)


def _pick_chips(rng: np.random.Generator, refl_mean: np.ndarray, k: int) -> list[int]:
    """k library indices with clearly different mean reflectance (contrast for matching)."""
    n = refl_mean.size
    chips = [int(rng.integers(n))]
    for _ in range(k - 1):
        far = np.flatnonzero(np.min(np.abs(refl_mean[:, None] - refl_mean[chips][None, :]),
                                    axis=1) > 0.12)
        chips.append(int(rng.choice(far)) if far.size else int(rng.integers(n)))
    return chips


def _complete_texture(tex: Mapping[str, Any] | None, rng: np.random.Generator,
                      refl_mean: np.ndarray) -> dict:
    """Fill every missing texture parameter from ``rng`` (deterministic)."""
    t = dict(tex or {})
    if "pattern" not in t:
        t["pattern"] = str(rng.choice(_PATTERNS))
    pat = t["pattern"]
    if pat not in _PATTERNS:
        raise InvalidInputError(
            f"unknown texture pattern {pat!r}; use one of {', '.join(_PATTERNS)}"
        )
    t.setdefault("period", float(rng.uniform(0.05, 0.10)))
    ncol = {"checker": 2, "noise": 2, "stripes": int(rng.integers(2, 4)),
            "patches": int(rng.integers(4, 8))}[pat]
    if "chips" not in t:
        t["chips"] = _pick_chips(rng, refl_mean, int(t.get("colors", ncol)))
    t["chips"] = [int(c) % refl_mean.size for c in t["chips"]]
    if pat == "stripes":
        t.setdefault("angle", float(rng.uniform(0, 180)))
    if pat == "patches":
        t.setdefault("salt", int(rng.integers(2**31)))
        t.setdefault("jitter", [float(v) for v in rng.uniform(0, 2 * np.pi, 2)])
    if pat == "noise":
        if "waves" not in t:
            waves = []
            for _ in range(6):
                ang = rng.uniform(0, np.pi)
                fr = rng.uniform(0.5, 1.5)
                waves.append([float(fr * math.cos(ang)), float(fr * math.sin(ang)),
                              float(rng.uniform(0, 2 * np.pi))])
            t["waves"] = waves
    return t


def _random_objects(rng: np.random.Generator, n_objects: int, kinds: Sequence[str],
                    drange: tuple[float, float]) -> list[dict]:
    dmin, dmax = drange
    span = dmax - dmin
    objs: list[dict] = [{"kind": "plane", "disparity": dmin + 0.05 * span, "name": "background"}]
    if n_objects <= 0:
        return objs
    order = list(rng.permutation(len(kinds)))
    ds = np.sort(rng.uniform(dmin + 0.35 * span, dmax - 0.05 * span, n_objects))
    for i in range(n_objects):
        kind = kinds[order[i % len(kinds)]]
        d = float(ds[i])
        cu, cv = (float(x) for x in rng.uniform(0.2, 0.8, 2))
        if kind in ("fronto", "slanted"):
            w, h = (float(x) for x in rng.uniform(0.18, 0.4, 2))
            o = {"kind": "plane", "rect": [cu - w / 2, cv - h / 2, cu + w / 2, cv + h / 2],
                 "disparity": d}
            if kind == "slanted":
                g = rng.normal(size=2)
                room = min(d - (dmin + 0.2 * span), dmax - d)
                dev = abs(g[0]) * w / 2 + abs(g[1]) * h / 2
                g = g * (0.9 * room / dev if dev > 0 else 0.0)
                o["gradient"] = [float(g[0]), float(g[1])]
            objs.append(o)
        elif kind == "box":
            w, h = (float(x) for x in rng.uniform(0.15, 0.3, 2))
            depth = float(rng.uniform(0.3, 0.6) * min(0.4 * span, d - dmin - 0.15 * span))
            objs.append({"kind": "box", "rect": [cu - w / 2, cv - h / 2, cu + w / 2, cv + h / 2],
                         "disparity": d, "depth": max(depth, 0.05 * span)})
        elif kind == "sphere":
            objs.append({"kind": "sphere", "center": [cu, cv],
                         "radius": float(rng.uniform(0.1, 0.18)), "disparity": d})
        elif kind in _THIN_KINDS:
            objs.append(_thin_object(rng, kind, cu, cv, d))
        else:
            raise InvalidInputError(
                f"unknown object kind {kind!r}; use one of {', '.join(_ALL_KINDS)}"
            )
    return objs


def _thin_object(rng: np.random.Generator, kind: str, cu: float, cv: float, d: float) -> dict:
    """A random ring (outer size 0.2-0.4 of the image, hole 0.5-0.8 of that) or stick
    (length 0.3-0.6, width 0.01-0.03 of the image, any angle) centred at ``(cu, cv)``."""
    if kind == "ring":
        size = float(rng.uniform(0.2, 0.4))
        return {"kind": "plane", "disparity": d,
                "rect": [cu - size / 2, cv - size / 2, cu + size / 2, cv + size / 2],
                "shape": {"kind": "ring", "hole": float(rng.uniform(0.5, 0.8))}}
    half = float(rng.uniform(0.15, 0.3))
    ang = float(rng.uniform(0.0, np.pi))
    du, dv = half * math.cos(ang), half * math.sin(ang)
    width = float(rng.uniform(0.01, 0.03))
    eu, ev = abs(du) + width, abs(dv) + width  # the rect bounds the stick with room to spare
    return {"kind": "plane", "disparity": d, "rect": [cu - eu, cv - ev, cu + eu, cv + ev],
            "shape": {"kind": "stick", "ends": [[cu - du, cv - dv], [cu + du, cv + dv]],
                      "width": width}}


def _check_inverse_depth(inverse_depth: float, what: str) -> None:
    """Refuse an object whose nearest point is at or beyond infinity (``d + d0`` below
    :data:`_MIN_INVERSE_DEPTH`)."""
    if inverse_depth < _MIN_INVERSE_DEPTH:
        raise InvalidInputError(f"{what} is below the scene's disparity range; widen "
                                f"disparity_range")


def _build_surface(o: dict, H: int, W: int, f: float, d0: float) -> _Surface:
    cx, cy = (W - 1) / 2.0, (H - 1) / 2.0
    kind = o["kind"]
    base = {"f": f, "cx": cx, "cy": cy}
    if kind in ("plane", "fronto", "slanted"):
        rect = o.get("rect")
        gx, gy = o.get("gradient", (0.0, 0.0))
        d = float(o["disparity"])
        if rect is not None:
            xr, yr = (rect[0] + rect[2]) / 2 * W - 0.5, (rect[1] + rect[3]) / 2 * H - 0.5
            rect_px = _rect_px(rect, H, W)
        else:
            xr, yr, rect_px = cx, cy, None
        a, b = gx / W, gy / H
        c = d - a * (xr - cx) - b * (yr - cy)
        _check_inverse_depth(c + d0, f"plane disparity {d}")
        return _Plane(o, dict(base, n=np.array([a, b, (c + d0) / f]), rect_px=rect_px,
                              shape=_plane_shape_px(o, H, W)))
    if kind == "sphere":
        u, v = o["center"]
        rpx = float(o["radius"]) * min(H, W)
        d = float(o["disparity"])
        _check_inverse_depth(d + d0, f"sphere disparity {d}")
        zf = f / (d + d0)                                # depth of the front point
        rho = rpx * zf / f
        zc = zf + rho
        X = (u * W - 0.5 - cx) * zc / f
        Y = (v * H - 0.5 - cy) * zc / f
        return _Sphere(o, dict(base, center=np.array([X, Y, zc]), radius=rho,
                               radius_px=rpx))
    if kind == "box":
        rect = o["rect"]
        d = float(o["disparity"])
        back = d - float(o.get("depth", 0.5))
        if back + d0 < _MIN_INVERSE_DEPTH:
            raise InvalidInputError("box depth reaches behind infinity; reduce 'depth'")
        z0, z1 = f / (d + d0), f / (back + d0)
        x0, x1 = (rect[0] * W - 0.5 - cx) * z0 / f, (rect[2] * W - 0.5 - cx) * z0 / f
        y0, y1 = (rect[1] * H - 0.5 - cy) * z0 / f, (rect[3] * H - 0.5 - cy) * z0 / f
        return _Box(o, dict(base, lo=np.array([x0, y0, z0]), hi=np.array([x1, y1, z1])))
    raise InvalidInputError(f"unknown object kind {kind!r}; use plane, fronto, slanted, box, sphere")


def _kinds(value, label: str) -> tuple[str, ...]:
    """A non-empty sequence of object kinds (:data:`_ALL_KINDS`)."""
    kinds = tuple(value) if isinstance(value, (list, tuple)) else None
    if not kinds or not all(isinstance(k, str) and k in _ALL_KINDS for k in kinds):
        raise InvalidInputError(f"{label} must be a non-empty list of object kinds out of "
                                f"{', '.join(_ALL_KINDS)}, got {_opt.shown(value)}")
    return kinds


def _objects(value, label: str):
    """None, or a sequence of object descriptions (mappings), each checked
    (:func:`_check_object`)."""
    if value is not None and not (isinstance(value, (list, tuple))
                                  and all(isinstance(o, Mapping) for o in value)):
        raise InvalidInputError(f"{label} must be None or a list of object descriptions "
                                f"(dicts), got {_opt.shown(value)}")
    for i, o in enumerate(value or ()):
        _check_object(o, f"{label}[{i}]")
    return value


def _text_or_none(value, label: str):
    return _opt.text(value, label, optional=True)


#: The most random objects :func:`procedural_scene` places (each is ray-cast in every view):
#: far more than a scene of the image's size can show apart.
MAX_OBJECTS = 256
#: The most rays per pixel side :func:`procedural_scene` casts: 16 x 16 rays already average
#: any texture period the generator draws.
MAX_SUPERSAMPLE = 16

#: The options of :func:`procedural_scene` that take one value, checked before any work
#: (:mod:`hyperlf._options`, by :func:`_check_scene`); the others (layout, disparity range,
#: reflectances, illuminant, quantum efficiency) are checked where they are read.
_SCENE_RULES = {
    "seed": _opt.integer, "rows": _opt.rule(_opt.integer, minimum=1),
    "cols": _opt.rule(_opt.integer, minimum=1), "height": _opt.rule(_opt.integer, minimum=2),
    "width": _opt.rule(_opt.integer, minimum=2),
    "lambda_min": _opt.rule(_opt.number, positive=True),
    "lambda_max": _opt.rule(_opt.number, positive=True),
    "n_objects": _opt.rule(_opt.integer, maximum=MAX_OBJECTS), "kinds": _kinds,
    "noise_sigma": _opt.rule(_opt.number, at_most=1e6),  # as add_noise takes it
    "texture_scale": _opt.rule(_opt.number, positive=True),
    "supersample": _opt.rule(_opt.integer, minimum=1, maximum=MAX_SUPERSAMPLE),
    "objects": _objects,
    "filter_shape": _opt.rule(_opt.choice, choices=tuple(FILTER_SHAPES)),
    "fwhm": _opt.rule(_opt.number, at_least=MIN_FWHM, at_most=MAX_FWHM),
    # px; within 1e-6..1e12 the projections stay finite (1e300 overflowed them)
    "focal_length": _opt.rule(_opt.number, positive=True, at_least=1e-6, at_most=1e12,
                              optional=True),
    "shading": _opt.flag, "name": _text_or_none, "progress": _opt.flag,
}


def _check_scene(given: dict) -> tuple[float, float]:
    """:func:`procedural_scene`'s arguments ``given`` checked by :data:`_SCENE_RULES` and
    against the memory available, before any work; returns the disparity range."""
    _opt.check_values(given, _SCENE_RULES)
    R, C, H, W = (int(given[k]) for k in ("rows", "cols", "height", "width"))
    tiling.check_memory(4 * (R * C) ** 2 * H * W, f"a {R} x {C} scene of {W} x {H} px with "
                        f"{R * C} bands", "use a smaller grid or image")
    return check_disparity_range(given["disparity_range"])


def _focal_length(focal_length: float | None, H: int, W: int) -> float:
    f = float(focal_length) if focal_length is not None else float(max(H, W))
    if not (np.isfinite(f) and f > 0):
        raise InvalidInputError(f"focal_length must be > 0 pixels, got {focal_length}")
    return f


def _reflectances(reflectance_source: str) -> tuple[np.ndarray, np.ndarray]:
    """The reflectance library as float64, reflectances clipped to [0, 1]."""
    from . import spectral

    lib_wl, lib_refl = spectral.reflectance_library(reflectance_source)
    lib_wl = np.asarray(lib_wl, dtype=np.float64)
    return lib_wl, np.clip(np.asarray(lib_refl, dtype=np.float64), 0.0, 1.0)


#: Largest size of an explicit object's numbers (disparities, gradients, rects and centres in
#: fractions of the image, radii, depths, texture periods): far beyond any scene, and the ray
#: casting stays finite.
MAX_OBJECT_VALUE = 1e6
#: Smallest inverse depth ``d + d0`` (px per baseline) of an object's nearest point: nearer to
#: infinity than this, the ray casting overflows.
_MIN_INVERSE_DEPTH = 1e-6
#: Most colours a texture may ask for (``"colors"``): each is a chip of the library.
_MAX_TEXTURE_COLOURS = 64

#: The keys of an explicit object, per kind (every kind also takes kind, disparity, texture,
#: name).
_OBJECT_KEYS = {"plane": ("rect", "gradient", "shape"), "fronto": ("rect", "gradient", "shape"),
                "slanted": ("rect", "gradient", "shape"), "box": ("rect", "depth"),
                "sphere": ("center", "radius")}


def _bounded(value, label: str) -> float:
    """A finite number within +-:data:`MAX_OBJECT_VALUE`."""
    v = _opt.real(value, label)
    if abs(v) > MAX_OBJECT_VALUE:
        raise InvalidInputError(f"{label} must be at most {MAX_OBJECT_VALUE:g} in size, got "
                                f"{_opt.shown(value)}")
    return v


def _bounded_list(value, label: str, n: int, what: str) -> list[float]:
    """``n`` finite numbers within +-:data:`MAX_OBJECT_VALUE` (``what`` names them)."""
    a = _opt.real_array(value, label) if isinstance(value, (list, tuple, np.ndarray)) else None
    if a is None or a.shape != (n,) or not (np.abs(a) <= MAX_OBJECT_VALUE).all():
        raise InvalidInputError(f"{label} must be {what}, finite and at most "
                                f"{MAX_OBJECT_VALUE:g} in size, got {_opt.shown(value)}")
    return [float(v) for v in a]


def _entries(value, label: str, what: str, each) -> None:
    """A non-empty list of ``what``, each entry passing the rule ``each``."""
    if not isinstance(value, (list, tuple)) or not value:
        raise InvalidInputError(f"{label} must be a non-empty list of {what}, got "
                                f"{_opt.shown(value)}")
    for entry in value:
        each(entry, f"{label} entries")


#: The rule of each texture key (:func:`_complete_texture` fills the missing ones).
_TEXTURE_RULES = {
    "pattern": _opt.rule(_opt.choice, choices=_PATTERNS),
    "period": _opt.rule(_opt.number, positive=True, at_most=MAX_OBJECT_VALUE),
    "chips": _opt.rule(_entries, what="reflectance library indices", each=_opt.integer),
    "colors": _opt.rule(_opt.integer, minimum=1, maximum=_MAX_TEXTURE_COLOURS),
    "angle": _bounded,
    "salt": _opt.integer,
    "jitter": _opt.rule(_bounded_list, n=2, what="two phases"),
    "waves": _opt.rule(_entries, what="[fx, fy, phase]",
                       each=_opt.rule(_bounded_list, n=3, what="[fx, fy, phase]")),
}


def _check_texture(t, label: str) -> None:
    """An object's ``texture``: None or a mapping of :data:`_TEXTURE_RULES`' keys."""
    if t is None:
        return
    if not isinstance(t, Mapping):
        raise InvalidInputError(f"{label} must be None or a dict, got {_opt.shown(t)}")
    _opt.mapping(t, label, keys=tuple(_TEXTURE_RULES), taker="a texture")
    for key, value in t.items():
        _TEXTURE_RULES[key](value, f"{label}[{key!r}]")


def _check_object(o: Mapping, label: str) -> None:
    """One explicit object description (:func:`procedural_scene`'s ``objects``), refused in
    one line before any work: its kind, its keys, and each value's type and range."""
    kind = _opt.choice(o.get("kind"), f"{label}['kind']", tuple(_OBJECT_KEYS))
    _opt.mapping(o, label, keys=("kind", "disparity", "texture", "name") + _OBJECT_KEYS[kind],
                 taker=f"a {kind}")
    needs = ("disparity",) + {"box": ("rect",), "sphere": ("center", "radius")}.get(kind, ())
    for key in needs:
        if o.get(key) is None:
            raise InvalidInputError(f"{label} needs {key!r}: a {kind} is given by "
                                    f"{', '.join(needs)}")
    _bounded(o["disparity"], f"{label}['disparity']")
    if o.get("rect") is not None:
        u0, v0, u1, v1 = _bounded_list(o["rect"], f"{label}['rect']", 4, "[u0, v0, u1, v1]")
        if not (u0 < u1 and v0 < v1):
            raise InvalidInputError(f"{label}['rect'] must have u0 < u1 and v0 < v1, got "
                                    f"{_opt.shown(o['rect'])}")
    if "gradient" in o:
        _bounded_list(o["gradient"], f"{label}['gradient']", 2, "(gx, gy)")
    if o.get("shape") is not None:
        _check_shape(o["shape"], f"{label}['shape']", o.get("rect"))
    if "depth" in o:
        _opt.number(o["depth"], f"{label}['depth']", at_most=MAX_OBJECT_VALUE)
    if kind == "sphere":
        _bounded_list(o["center"], f"{label}['center']", 2, "(u, v)")
        _opt.number(o["radius"], f"{label}['radius']", positive=True, at_most=MAX_OBJECT_VALUE)
    _opt.text(o.get("name"), f"{label}['name']", optional=True)
    _check_texture(o.get("texture"), f"{label}['texture']")


def _scene_objects(objects: Sequence[Mapping[str, Any]] | None, scene_rng: np.random.Generator,
                   tex_rng: np.random.Generator, n_objects: int, kinds: Sequence[str],
                   drange: tuple[float, float], refl_mean: np.ndarray) -> list[dict]:
    """The scene description: random or explicit objects, textures completed from the seed."""
    if objects is None:
        objs = _random_objects(scene_rng, int(n_objects), list(kinds), drange)
    else:
        objs = [dict(o) for o in objects]
        if not objs:
            raise InvalidInputError("objects is empty; give at least a background plane")
    for o in objs:
        o["texture"] = _complete_texture(o.get("texture"), tex_rng, refl_mean)
    return objs


def _chip_palette(objs: list[dict], lib_wl: np.ndarray, lib_refl: np.ndarray,
                  cube_wl: np.ndarray, filter_shape: str, fwhm: float, quantum_efficiency: Any,
                  illuminant: str | None) -> tuple[np.ndarray, dict, float]:
    """Every chip used, as band values (filters, illuminant, QE folded in), scaled to <= 1."""
    wl, Wt = _band_weights(cube_wl, filter_shape, float(fwhm), quantum_efficiency, illuminant,
                           spectral_range=(max(380.0, lib_wl.min()), min(780.0, lib_wl.max())))
    chips = sorted({c for o in objs for c in o["texture"]["chips"]})
    chip_index = {c: i for i, c in enumerate(chips)}
    refl_wl = np.stack([np.interp(wl, lib_wl, lib_refl[c]) for c in chips])
    palette = (refl_wl @ Wt).astype(np.float64)  # (n_chips, B)
    pal_max = float(palette.max()) if palette.size else 0.0
    pscale = 1.0 / pal_max if pal_max > 1.0 else 1.0
    palette *= pscale
    return palette, chip_index, pscale


class _RayCaster:
    """Pinhole-array ray caster of the procedural renderer (camera model: module docstring)."""

    #: Fixed light direction and ambient term of the Lambertian shading.
    AMBIENT = 0.35

    def __init__(self, surfaces: list[_Surface], H: int, W: int, f: float, d0: float,
                 palette: np.ndarray, chip_index: dict, base_period: float, shading: bool,
                 supersample: int):
        self.surfaces, self.f, self.d0 = surfaces, f, d0
        self.palette, self.chip_index, self.base_period = palette, chip_index, base_period
        self.shading, self.supersample = shading, supersample
        self.H, self.W = H, W
        light = np.array([-0.35, -0.55, -1.0])
        light /= np.linalg.norm(light)
        self.light = light
        self.cx, self.cy = (W - 1) / 2.0, (H - 1) / 2.0
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
        self.xx, self.yy = xx.ravel(), yy.ravel()
        self.sub = (np.arange(supersample) + 0.5) / supersample - 0.5

    def cast(self, dx: float, dy: float, sx: float, sy: float):
        """Nearest hit of every pixel's ray (sub-pixel offset ``sx, sy``) from view ``dx, dy``."""
        xx, yy, f, d0 = self.xx, self.yy, self.f, self.d0
        C = np.array([dx, dy, 0.0])
        D = np.stack([(xx + sx - self.cx - d0 * dx) / f, (yy + sy - self.cy - d0 * dy) / f,
                      np.ones_like(xx)], axis=1)
        best_t = np.full(xx.size, np.inf)
        best_i = np.full(xx.size, -1, np.int64)
        auxs = []
        for i, s in enumerate(self.surfaces):
            t, aux = s.intersect(C, D)
            auxs.append(aux)
            closer = t < best_t
            best_t = np.where(closer, t, best_t)
            best_i = np.where(closer, i, best_i)
        return C, D, best_t, best_i, auxs

    def radiance(self, hits, acc: np.ndarray) -> None:
        """Add the band values of every hit (textured, shaded) to ``acc (n_pixels, B)``."""
        C, D, t, idx, auxs = hits
        palette, ambient = self.palette, self.AMBIENT
        for i, s in enumerate(self.surfaces):
            sel = np.flatnonzero(idx == i)
            if sel.size == 0:
                continue
            P = C[None, :] + t[sel, None] * D[sel]
            aux = auxs[i]
            if aux is not None:
                aux = tuple(a[sel] for a in aux)
            u, v, nrm = s.surface(P, aux)
            tex = s.spec["texture"]
            i1, i2, w = _texture(tex, u, v, tex["period"] * self.base_period)
            gidx = np.array([self.chip_index[ch] for ch in tex["chips"]])
            rad = (w[:, None] * palette[gidx[i1]]
                   + (1.0 - w)[:, None] * palette[gidx[i2]])
            if self.shading:
                lam = np.clip(nrm @ self.light, 0.0, None)
                rad *= (ambient + (1.0 - ambient) * lam)[:, None]
            acc[sel] += rad

    def render_view(self, dx: float, dy: float) -> tuple[np.ndarray, np.ndarray, int]:
        """Exact disparity ``(H, W)``, bands ``(B, H, W)`` and missed pixels of one view."""
        H, W, f, d0 = self.H, self.W, self.f, self.d0
        n = self.xx.size
        # exact disparity at pixel centres (the centre sample when supersample is odd)
        centre = self.cast(dx, dy, 0.0, 0.0)
        t0 = centre[2]
        hit0 = np.isfinite(t0)
        disp = np.full(n, np.nan)
        disp[hit0] = f / t0[hit0] - d0  # t is the depth Z since D_z = 1, C_z = 0
        acc = np.zeros((n, self.palette.shape[1]))
        for sy in self.sub:
            for sx in self.sub:
                hits = centre if sx == 0.0 and sy == 0.0 else self.cast(dx, dy, sx, sy)
                self.radiance(hits, acc)
        acc /= self.supersample * self.supersample
        bands = acc.T.reshape(-1, H, W).astype(np.float32)
        return disp.reshape(H, W), bands, int((~hit0).sum())

    def render_grid(self, offsets: np.ndarray, progress: bool = False):
        """Ground truth ``(R, C, H, W)``, cube ``(R, C, B, H, W)`` (clipped to [0, 1]) and
        missed-pixel count of every view at ``offsets (R, C, 2)``."""
        rows, cols = offsets.shape[:2]
        cube = np.zeros((rows, cols, self.palette.shape[1], self.H, self.W), dtype=np.float32)
        gt = np.full((rows, cols, self.H, self.W), np.nan, dtype=np.float32)
        missed = 0
        for r, c in grid_views(rows, cols, "rendering views", progress):
            dx, dy = offsets[r, c]
            gt[r, c], cube[r, c], n_missed = self.render_view(dx, dy)
            missed += n_missed
        np.clip(cube, 0.0, 1.0, out=cube)
        return gt, cube, missed


def _finite_range(values: np.ndarray, default: tuple[float, float]) -> tuple[float, float]:
    """``(min, max)`` of the finite ``values``; ``default`` when none is finite."""
    finite = np.isfinite(values)
    if not finite.any():
        return default
    return float(values[finite].min()), float(values[finite].max())


def _procedural_metadata(opts: dict, objs: list[dict], kmap: np.ndarray, dmin: float,
                         dmax: float, gmin: float, gmax: float, n_library: int, f: float,
                         d0: float, pscale: float, missed: int) -> dict:
    name, filter_shape = opts["name"], opts["filter_shape"]
    return {
        "synthesis": "procedural_scene",
        "source": f"procedural:{name}" if name else "procedural",
        "scene": name,
        "seed": int(opts["seed"]),
        "rows": opts["rows"], "cols": opts["cols"],
        "height": opts["height"], "width": opts["width"],
        "lambda_min": float(opts["lambda_min"]), "lambda_max": float(opts["lambda_max"]),
        "layout": _layout_meta(opts["layout"]),
        "band_index": kmap.tolist(),
        "n_objects": len(objs) - (1 if opts["objects"] is None else 0),
        "kinds": list(opts["kinds"]),
        "objects": objs,
        "disparity_range_requested": [dmin, dmax],
        "gt_disparity_min": gmin, "gt_disparity_max": gmax,
        "reflectance_source": opts["reflectance_source"],
        "reflectance_library_size": n_library,
        "illuminant": opts["illuminant"],
        "filter_shape": filter_shape,
        "fwhm": float(opts["fwhm"]) if filter_shape != "dirac" else None,
        "quantum_efficiency": _qe_meta(opts["quantum_efficiency"]),
        "noise_sigma": float(opts["noise_sigma"]),
        "texture_scale": float(opts["texture_scale"]),
        "supersample": opts["supersample"],
        "shading": bool(opts["shading"]),
        "focal_length_px": f,
        "disparity_offset_d0": d0,
        "palette_scale": pscale,
        "camera_model": "pinhole array, d = f/Z - d0, baseline 1, sensor shift d0*(dx, dy)",
        "gt_disparity": "exact ray casting at pixel centres, every view",
        "missed_pixels": missed,
        "runtime_s": 0.0,
    }


def procedural_scene(seed: int = 0, *, rows: int = 5, cols: int = 6, height: int = 128,
                     width: int = 160, lambda_min: float = 410.0, lambda_max: float = 700.0,
                     layout: str | Sequence[int] = "raster", n_objects: int = 4,
                     kinds: Sequence[str] = _KINDS,
                     disparity_range: tuple[float, float] = (-2.0, 2.0),
                     reflectance_source: str = "auto", illuminant: str | None = "D65",
                     noise_sigma: float = 0.0, texture_scale: float = 1.0, supersample: int = 1,
                     objects: Sequence[Mapping[str, Any]] | None = None,
                     filter_shape: str = "dirac", fwhm: float = 10.0,
                     quantum_efficiency: Any = None, focal_length: float | None = None,
                     shading: bool = True, name: str | None = None,
                     progress: bool = False) -> LightField:
    """Render a procedural H-LF with exact ground truth by ray casting (SPEC §6).

    The scene is a background plane plus objects -- fronto-parallel and slanted rectangles,
    axis-aligned boxes, spheres -- at several depths, each textured (checker, stripes, smooth
    noise blend, random patches) with real reflectance spectra from
    ``hyperlf.spectral.reflectance_library(reflectance_source)`` (Munsell, else ColorChecker)
    under ``illuminant`` (SPD normalised to max 1 on the band range; ``None`` = equal energy).
    Every pixel of every view casts a ray (camera model in the module docstring) against the
    analytic surfaces; the nearest hit (largest disparity) wins. Texture is looked up in each
    surface's own 2-D parametrisation (planes: reference-image coordinates of the hit point;
    sphere: longitude/latitude; box: per-face coordinates), so a surface point looks the same
    from every view; optional Lambertian shading (``shading``, fixed light, ambient 0.35)
    depends only on the normal, so it is view-independent too.

    Ground truth: ``gt_disparity (R, C, H, W)`` is the exact disparity of the surface hit at
    every pixel centre of every view; ``gt_cube (R, C, B, H, W)`` every band of every view
    (radiance = shading x reflectance x illuminant, filtered, x QE: in [0, 1] by construction,
    no further normalisation). With ``supersample = s > 1`` each pixel averages s x s rays
    (anti-aliased cube and views; disparity stays the pixel-centre value), ``s`` at most
    :data:`MAX_SUPERSAMPLE`.

    Parameters
    ----------
    seed : int
        Everything random (object placement, textures, chips, noise) derives from it.
    rows, cols, height, width : int
        Grid and image size; the layout is given in fractions of the image, so any
        resolution shows the same scene. A scene whose cubes (``4 (R C)² H W`` bytes) exceed
        the memory available is refused before any work.
    n_objects, kinds :
        Random objects (at most :data:`MAX_OBJECTS`) in front of the background, cycling
        through ``kinds`` (default fronto, slanted, box, sphere; also ring, stick: planes of
        that shape). Ignored with ``objects``.
    disparity_range : (float, float)
        Disparities (px per baseline) of the scene; random objects stay inside. The returned
        ``disparity_range`` is this, widened if explicit objects go beyond it.
    texture_scale : float
        Multiplies every texture period (periods are fractions of ``min(H, W)``).
    objects : list of dict, optional
        Explicit scene (overrides ``n_objects``/``kinds``; include a background). Entries:
        ``{"kind": "plane", "disparity": d, "gradient": (gx, gy), "rect": (x0, y0, x1, y1),
        "texture": {...}}`` (``gradient``: disparity change across the full image width/height,
        relative to the rect centre; no ``rect``: infinite plane; optional ``"shape"``, a ring
        ``{"kind": "ring", "hole": h}`` or a stick ``{"kind": "stick", "ends": [[u0, v0], [u1,
        v1]], "width": w}`` inside the rect, as :func:`_shape_px`), ``{"kind": "box", "rect":
        ..., "disparity": front-face d, "depth": disparity drop to the back face}``,
        ``{"kind": "sphere", "center": (u, v), "radius": fraction of min(H, W), "disparity":
        d of the nearest point}``; rect/centre in fractions of the image. ``texture``:
        ``{"pattern": "checker"|"stripes"|"noise"|"patches", "period": fraction,
        "chips": [library indices], "angle": deg, ...}``; missing values come from ``seed``.
        The completed description is stored in ``metadata["objects"]``. Every object is
        checked before any work: a key its kind does not take (``"centre"`` for
        ``"center"``) is refused, and numbers may be at most :data:`MAX_OBJECT_VALUE` in size.
    filter_shape, fwhm, quantum_efficiency :
        As in :func:`from_rgb_lightfield`.
    focal_length : float, optional
        Pixels; default ``max(H, W)``.
    name : str, optional
        Scene name recorded in the metadata (set by :data:`SCENES`).
    progress : bool
        Show a progress bar over the views.

    Returns
    -------
    LightField

    Examples
    --------
    >>> lf = procedural_scene(**dict(SCENES["planes"], rows=3, cols=3, height=24, width=32,
    ...                              reflectance_source="colorchecker"))
    >>> lf.views.shape, lf.gt_cube.shape
    ((3, 3, 24, 32), (3, 3, 9, 24, 32))
    """
    given = dict(locals())  # the arguments, as given
    dmin, dmax = _check_scene(given)
    t_start = time.perf_counter()
    rows, cols, H, W, supersample = (int(v) for v in (rows, cols, height, width, supersample))

    cube_wl = band_grid(rows, cols, lambda_min, lambda_max)
    kmap = filter_layout(rows, cols, layout, seed=seed)
    wavelengths = cube_wl[kmap]
    f = _focal_length(focal_length, H, W)
    d0 = -dmin + 0.5 * (dmax - dmin)  # inverse-depth offset: f / Z = d + d0 > 0 on the range

    ss = np.random.SeedSequence(int(seed))
    scene_rng, tex_rng = (np.random.default_rng(s) for s in ss.spawn(2))
    lib_wl, lib_refl = _reflectances(reflectance_source)
    objs = _scene_objects(objects, scene_rng, tex_rng, n_objects, kinds, (dmin, dmax),
                          lib_refl.mean(axis=1))
    palette, chip_index, pscale = _chip_palette(objs, lib_wl, lib_refl, cube_wl, filter_shape,
                                                fwhm, quantum_efficiency, illuminant)
    caster = _RayCaster([_build_surface(o, H, W, f, d0) for o in objs], H, W, f, d0, palette,
                        chip_index, min(H, W) * float(texture_scale), shading, supersample)

    positions, ref = grid_positions(rows, cols), centre_view(rows, cols)
    gt, cube, missed = caster.render_grid(view_offsets(positions, ref), progress)
    views = _observe(cube, kmap, noise_sigma, seed)
    gmin, gmax = _finite_range(gt, default=(dmin, dmax))

    opts = {**given, "rows": rows, "cols": cols, "height": H, "width": W,
            "supersample": supersample}
    metadata = _procedural_metadata(opts, objs, kmap, dmin, dmax, gmin, gmax,
                                    int(lib_refl.shape[0]), f, d0, pscale, missed)
    metadata["runtime_s"] = round(time.perf_counter() - t_start, 3)
    return LightField(views=views, wavelengths=wavelengths, positions=positions,
                      reference=ref, disparity_range=(min(dmin, gmin), max(dmax, gmax)),
                      gt_disparity=gt, gt_cube=cube, cube_wavelengths=cube_wl,
                      metadata=metadata)


# ----------------------------------------------------------------------------- named scenes
def _textured(kind: str, pattern: str, period: float, angle: float | None = None,
              **geometry) -> dict[str, Any]:
    """One object of a scene description: ``kind``, its geometry keys (in the order given) and
    its texture (``pattern``, ``period``, ``angle`` when given)."""
    texture = {"pattern": pattern, "period": period}
    if angle is not None:
        texture["angle"] = angle
    return {"kind": kind, **geometry, "texture": texture}


def _scene(name: str, seed: int, *objects: dict[str, Any]) -> dict[str, Any]:
    """A named scene: its own seed, the disparity range every named scene shares, its objects."""
    return dict(name=name, seed=seed, disparity_range=(-2.0, 2.0), objects=list(objects))


#: Named deterministic scenes: ``procedural_scene(**SCENES[name])`` (any size via height/width).
SCENES: dict[str, dict[str, Any]] = {scene["name"]: scene for scene in (
    _scene("planes", 101,
           _textured("plane", "patches", 0.08, disparity=-1.5, name="background"),
           _textured("plane", "stripes", 0.06, 30.0, disparity=0.0, rect=[0.08, 0.12, 0.5, 0.88]),
           _textured("plane", "checker", 0.07, disparity=1.5, rect=[0.48, 0.3, 0.88, 0.72])),
    _scene("slanted", 202,
           _textured("plane", "patches", 0.07, disparity=-0.8, gradient=[1.6, 0.4],
                     name="slanted"),
           _textured("plane", "noise", 0.1, disparity=1.2, rect=[0.55, 0.25, 0.85, 0.65])),
    _scene("occlusion", 303,
           _textured("plane", "patches", 0.06, disparity=-1.2, name="background"),
           _textured("plane", "stripes", 0.05, 90.0, disparity=1.6, rect=[0.15, 0.05, 0.19, 0.95]),
           _textured("plane", "checker", 0.04, disparity=1.3, rect=[0.42, 0.05, 0.47, 0.95]),
           _textured("plane", "noise", 0.05, disparity=1.0, rect=[0.70, 0.05, 0.73, 0.95]),
           _textured("plane", "stripes", 0.05, 0.0, disparity=0.6, rect=[0.05, 0.58, 0.95, 0.62])),
    _scene("solids", 404,
           _textured("plane", "checker", 0.09, disparity=-1.5, name="background"),
           _textured("box", "patches", 0.06, rect=[0.12, 0.2, 0.42, 0.6], disparity=0.8,
                     depth=1.0),
           _textured("sphere", "stripes", 0.06, 60.0, center=[0.68, 0.55], radius=0.2,
                     disparity=1.4)),
    # Thin structures and holes (issue 12's held-out risk): one ring's hole shows the
    # background, the other's a plane between; two sticks, one of them in front of everything.
    _scene("rings", 505,
           _textured("plane", "patches", 0.07, disparity=-1.5, name="background"),
           _textured("plane", "noise", 0.08, disparity=-0.3, rect=[0.52, 0.08, 0.96, 0.62]),
           _textured("plane", "checker", 0.05, disparity=1.4, rect=[0.06, 0.12, 0.46, 0.66],
                     shape={"kind": "ring", "hole": 0.6}),
           _textured("plane", "stripes", 0.05, 45.0, disparity=0.9, rect=[0.58, 0.16, 0.90, 0.52],
                     shape={"kind": "ring", "hole": 0.55}),
           _textured("plane", "noise", 0.08, disparity=1.8, rect=[0.10, 0.55, 0.95, 0.80],
                     shape={"kind": "stick", "ends": [[0.12, 0.78], [0.92, 0.58]], "width": 0.03}),
           _textured("plane", "stripes", 0.04, 0.0, disparity=0.5, rect=[0.30, 0.02, 0.40, 0.98],
                     shape={"kind": "stick", "ends": [[0.36, 0.04], [0.33, 0.96]],
                            "width": 0.025})),
)}


def named_scene(name: str) -> dict[str, Any]:
    """The parameters of the named scene ``name`` (a copy of ``SCENES[name]``).

    Raises
    ------
    InvalidInputError
        For a name that is not in :data:`SCENES`; the message lists the names.

    Examples
    --------
    >>> named_scene("planes")["seed"]
    101
    """
    if not isinstance(name, str) or name not in SCENES:
        raise InvalidInputError(f"unknown scene {_opt.shown(name)}; the named scenes are "
                                f"{', '.join(SCENES)}")
    return dict(SCENES[name])
