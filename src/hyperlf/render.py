"""Rendering from hyperspectral light fields (SPEC §8, paper §7.4-7.5).

Colour sensor emulation, spectral refocusing, all-focus images, focal sweeps and spectral
profiles, from a plenoptic cube ``[R, C, B, H, W]`` (every band seen from every view: the
output of cube completion or a synthetic ground truth) or from the raw H-LF views
``[R, C, H, W]`` (one band per view) with their filter wavelengths.

Everything is linear until the very end
---------------------------------------
A *spectral profile* turns the bands of a pixel into ``K`` channels with a linear map:

* a **camera** (a name from :func:`hyperlf.spectral.list_cameras`, ``"CIE 1931"``, a CSV file
  ``wavelength_nm, r, g, b``, or sensitivities ``(B, 3)`` sampled at the band wavelengths):
  ``RGB_k = sum_b cube_b S_k(λ_b)`` (a plain sum over bands, SPEC §8), white-balanced so that a
  flat spectrum is grey;
* a **single band**: a number, the wavelength in nm (the nearest band; it must lie within half a
  band step);
* a **weight vector** over the bands, shape ``(B,)``: ``sum_b w_b cube_b / sum_b w_b`` (so a flat
  spectrum gives 1; weights summing to zero are used as they are);
* ``None`` (or ``"bands"``): every band, i.e. the cube itself (output ``(B, H, W)``).

Refocusing shifts and adds these channel images; only then come the per-channel gain (undoing
white balance when ``white_balance=False``), the 3 x 3 colour matrix to sRGB (``output="srgb"``),
the exposure, and the sRGB transfer function. Because every stage before the transfer function
is linear, refocusing a camera rendering equals rendering the refocused cube.

Output spaces
-------------
``output="camera"``: linear, unclipped camera RGB (for ``"CIE 1931"``: CIE XYZ), white-balanced
so that a flat spectrum gives ``(1, 1, 1)``.

``output="srgb"``: display sRGB, encoded with the sRGB transfer function and clipped to [0, 1].

* ``"CIE 1931"`` (or any sensitivities equal to the CIE 1931 CMFs): the XYZ of the spectra are
  normalised so that the white (a flat spectrum, times ``illuminant``; or ``white``) has
  ``Y = 1``, adapted from the white's chromaticity to D65 with the Bradford transform and
  converted with the IEC 61966-2-1 matrix (:func:`hyperlf.spectral.xyz_to_srgb_linear`).
  The white therefore maps to sRGB (1, 1, 1). This is what
  ``spectral.xyz_to_srgb(spectral.spectrum_to_xyz(s, wl), white=xy_of_white)`` computes.
* An RGB camera: its white-balanced RGB is mapped to linear sRGB by a 3 x 3 colour-correction
  matrix (CCM) fitted by least squares on real reflectance spectra
  (:func:`hyperlf.spectral.reflectance_library`: the 1269 Munsell chips with ``HYPERLF_DATA``,
  else the 24 ColorChecker patches), lit by the white, so that the emulated images are
  comparable with sRGB renderings (:func:`fit_ccm`). The fit is constrained to map the white
  to (1, 1, 1) (``white_preserving``), so a flat spectrum stays grey. ``ccm=None`` shows the
  camera RGB as if it were linear sRGB; a ``(3, 3)`` array is used as given
  (``srgb_linear = rgb @ ccm``).
* A single band or weight vector: a grey image, only encoded.

Exposure (``exposure``): ``"white"`` (default) scales so that the white's largest output channel
is 1 (with white balance this changes nothing); ``"none"`` leaves the values; ``"percentile"``
divides by the ``exposure_percentile``-th percentile (default 99.5) of all finite output values
(over every view, or every frame of a sweep, so that the brightness does not flicker); a number
is a gain.

Illuminant and white
--------------------
``illuminant`` multiplies the spectra and the white, as in
:func:`hyperlf.spectral.spectrum_to_rgb` (use it for reflectance cubes). ``white`` names the
spectrum that should come out neutral for a *radiance* cube that already contains the light
(e.g. ``white="D65"`` for :func:`hyperlf.synthesis.procedural_scene`, whose cube is
reflectance x D65): a name for :func:`hyperlf.spectral.illuminant_spd` or an array ``(B,)``.
Default: a flat spectrum.

Sampling
--------
Shift-and-add follows SPEC §1: the reference pixel ``p = (x, y)`` with disparity ``d`` is seen
by view ``v`` at ``q_v = p - d (pos_v - pos_ref)``. Views are sampled bilinearly by
:mod:`hyperlf.warp` (``edge="mask"``, float32 weights, x before y); a sample whose
footprint leaves the view, touches an invalid (masked or non-finite) pixel, or fails the
occlusion check is *excluded*: each output pixel is the (weight-)normalised average of its
valid samples, never a zero-filled one. Pixels without any valid sample get ``fill``.

Raw H-LF views (one band per view): the profile weights every view by its band's weight --
``out_k(p) = sum_v a_vk I_v(q_v) / sum_v a_vk [valid]`` with ``a_vk`` = camera sensitivity
``S_k(λ_v)`` (so white balance is automatic), the view's entry of a weight vector, or 1 for the
views of a single band. A weight vector for views is either ``(R, C)`` (one weight per view) or
``(B,)`` over the distinct view wavelengths in increasing order. Refocusing the raw views of a
5 x 6 H-LF with a camera profile therefore combines 30 differently-filtered images into one
colour image focused at ``d`` (paper Fig. "H-LF refocusing").

Memory
------
Cubes may be on disk (a :class:`hyperlf.formats.hdf5.CubeFile` from ``open_cube_h5`` or an
``h5py`` dataset ``(R, C, B, H, W)``): every function iterates over views and reads one view (or
only the bands the profile needs) at a time; a full ``[R, C, B, H, W]`` is never loaded.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from . import _options as _opt
from . import spectral
from ._atomic import atomic_path, atomic_write_text
from ._progress import progress_bar
from .errors import InvalidInputError
from .lightfield import centre_view, grid_positions
from .warp import coordinate_taps, forward_warp_disparity, sample_bilinear, shift_map

__all__ = [
    "emulate_camera",
    "camera_matrix",
    "fit_ccm",
    "refocus",
    "focal_stack",
    "all_focus",
    "focal_sweep",
    "spectrum_at",
    "band_index",
    "save_spectrum_figure",
]

_OUTPUTS = ("camera", "srgb")
#: The farthest (nm) a ``band:NM`` profile may be from the band it picks: about half a narrow
#: band-pass filter's width (and never more than half the spacing of the bands).
BAND_TOLERANCE_NM = 5.0


# ============================================================================ data sources

def _is_h5_dataset(obj) -> bool:
    try:
        import h5py
    except ImportError:  # pragma: no cover - h5py is a dependency
        return False
    return isinstance(obj, h5py.Dataset)


def _is_cubefile(obj) -> bool:
    return hasattr(obj, "cube") and hasattr(obj, "wavelengths") and hasattr(obj, "view") \
        and not isinstance(obj, np.ndarray)


def _is_lightfield(obj) -> bool:
    from .lightfield import LightField

    return isinstance(obj, LightField)


class _Source:
    """Uniform, lazy access to a cube ``(R, C, B, H, W)`` or to H-LF views ``(R, C, H, W)``.

    ``kind`` is ``"cube"`` or ``"views"``. Data may be a numpy array or an h5py dataset.
    """

    def __init__(self, data, kind: str, wavelengths: np.ndarray, mask=None,
                 offsets: np.ndarray | None = None, reference: tuple[int, int] | None = None):
        self.data = data
        self.kind = kind
        self.wavelengths = wavelengths
        self.mask = mask
        shape = tuple(int(s) for s in data.shape)
        if kind == "cube":
            self.R, self.C, self.B, self.H, self.W = shape
        else:
            self.R, self.C, self.H, self.W = shape
            self.B = int(np.unique(wavelengths).size)
        self.offsets = offsets
        self.reference = reference

    def read_bands(self, r: int, c: int, idx: np.ndarray | None = None) -> np.ndarray:
        """``(k, H, W)`` float32 bands ``idx`` (all when None) of view (r, c) of a cube."""
        if idx is None or idx.size == self.B:
            a = self.data[r, c]
        elif idx.size == 1:
            a = self.data[r, c, int(idx[0])][None]
        elif _is_h5_dataset(self.data):
            # h5py needs increasing indices; read one band (= one chunk) at a time
            a = np.stack([np.asarray(self.data[r, c, int(b)]) for b in idx])
        else:
            a = self.data[r, c, idx]
        return np.asarray(a, dtype=np.float32)

    def read_view(self, r: int, c: int) -> np.ndarray:
        """``(H, W)`` float32 image of view (r, c) of an H-LF."""
        return np.asarray(self.data[r, c], dtype=np.float32)

    def view_mask(self, r: int, c: int) -> np.ndarray | None:
        if self.mask is None:
            return None
        return np.asarray(self.mask[r, c], dtype=bool)


#: The keyword options of this module's functions that take one value, checked before any
#: work (:mod:`hyperlf._options`); ``exposure`` and ``profile``, which take words or numbers,
#: are checked where they are read.
_RULES = {
    "output": _opt.rule(_opt.choice, choices=_OUTPUTS),
    "white_balance": _opt.flag, "white_preserving": _opt.flag, "return_counts": _opt.flag,
    "progress": _opt.flag, "annotate": _opt.flag,
    "exposure_percentile": _opt.rule(_opt.number, positive=True, at_most=100),
    "fill": lambda value, label: _float32_value(_opt.real(value, label, nan=True), label),
    "tol": _opt.number,
    "fps": _opt.rule(_opt.number, positive=True),
    "bit_depth": _opt.rule(_opt.choice, choices=(8, 16)),
}


def _float32_value(value: float, label: str) -> float:
    """``value`` (a number or NaN) when float32, the type of the images made, holds it."""
    if abs(value) > float(np.finfo(np.float32).max):
        raise InvalidInputError(f"{label} must be a number float32 holds (at most 3.4e+38 in "
                                f"size) or NaN, got {value:g}")
    return value


def _checked(**options) -> None:
    """Refuse any of ``options`` that :data:`_RULES` does not take."""
    _opt.check_values(options, _RULES)


def _check_mask(mask, shape: tuple[int, ...], name: str = "mask"):
    if mask is None:
        return None
    if _is_h5_dataset(mask):
        if tuple(mask.shape) != shape:
            raise InvalidInputError(f"{name} must have shape {shape}, got {tuple(mask.shape)}")
        return mask
    m = np.asarray(mask)
    if m.shape != shape:
        raise InvalidInputError(f"{name} must have shape {shape} (True = valid), got {m.shape}")
    return m.astype(bool, copy=False)


def _default_offsets(R: int, C: int, reference=None) -> tuple[np.ndarray, tuple[int, int]]:
    ref = centre_view(R, C) if reference is None else _opt.index(reference, "reference", (R, C))
    pos = grid_positions(R, C)
    return pos - pos[ref][None, None, :], ref


def _make_source(obj, wavelengths=None, offsets=None, mask=None, reference=None) -> _Source:
    """Resolve the input of refocus / all_focus / focal_stack into a :class:`_Source`: a
    spectral light field, a cube file, or a cube / views array with its wavelengths."""
    if _is_lightfield(obj):
        data, wl, offsets, reference = _lightfield_input(obj, wavelengths, offsets, reference)
        kind = "views"
    elif _is_cubefile(obj):
        data, kind = obj.cube, "cube"
        wl = _opt.real_array(obj.wavelengths if wavelengths is None else wavelengths,
                             "wavelengths")
        mask = obj.mask if mask is None else mask
    else:
        data, kind = _array_input(obj)
        if wavelengths is None:
            raise InvalidInputError(
                "wavelengths are required: (B,) band centres for a cube, (R, C) filter "
                "wavelengths for H-LF views")
        wl = _opt.real_array(wavelengths, "wavelengths")
    shape = tuple(int(s) for s in data.shape)
    wl, mask_shape = _source_wavelengths(kind, wl, shape)
    mask = _check_mask(None if mask is False else mask, mask_shape)
    offsets, reference = _source_geometry(offsets, reference, *shape[:2])
    return _Source(data, kind, wl, mask=mask, offsets=offsets, reference=reference)


def _lightfield_input(lf, wavelengths, offsets, reference):
    """A spectral light field's views, and its wavelengths, offsets and reference where the
    call gives none."""
    if not lf.is_spectral:
        raise InvalidInputError(
            "the LightField is not spectral (views must be (R, C, H, W) with wavelengths); "
            "pass lf.gt_cube with lf.cube_wavelengths to refocus a cube")
    wl = (np.asarray(lf.wavelengths, dtype=np.float64) if wavelengths is None
          else _opt.real_array(wavelengths, "wavelengths"))
    return (lf.views, wl, lf.offsets if offsets is None else offsets,
            lf.reference if reference is None else reference)


def _array_input(obj):
    """A numeric array (or HDF5 dataset) and its kind: ``"cube"`` (5-D) or ``"views"``
    (4-D)."""
    data = obj if _is_h5_dataset(obj) else np.asarray(obj)
    if not _is_h5_dataset(data) and (data.dtype == object
                                     or not np.issubdtype(data.dtype, np.number)):
        raise InvalidInputError(f"expected a numeric cube or views array, got dtype {data.dtype}")
    if data.ndim not in (4, 5):
        raise InvalidInputError(
            "expected a cube (R, C, B, H, W) or H-LF views (R, C, H, W), got shape "
            f"{tuple(data.shape)}")
    return data, "cube" if data.ndim == 5 else "views"


def _source_wavelengths(kind: str, wl: np.ndarray, shape: tuple) -> tuple:
    """The wavelengths checked against the data's ``shape`` (a cube's band centres, all NaN
    where unknown, which the profiles that need none allow; one finite filter wavelength per
    view), and the shape of a mask of the data."""
    if kind == "cube":
        wl = wl.ravel() if spectral.wavelengths_unknown(wl) else spectral.as_wavelengths(wl)
        if wl.size != shape[2]:
            raise InvalidInputError(
                f"the cube has {shape[2]} bands but {wl.size} wavelengths were given")
        return wl, shape[:2] + shape[3:]
    if wl.shape != shape[:2]:
        raise InvalidInputError(
            f"H-LF views {shape} need one filter wavelength per view, shape {shape[:2]}; "
            f"got {wl.shape} (for a cube pass an (R, C, B, H, W) array)")
    if not np.all(np.isfinite(wl)):
        raise InvalidInputError("view wavelengths contain NaN or inf")
    return wl, shape


def _source_geometry(offsets, reference, R: int, C: int) -> tuple:
    """The views' ``(R, C, 2)`` offsets (default: a regular grid) and the reference (default:
    the view at offset 0, else the grid's default centre)."""
    if offsets is None:
        return _default_offsets(R, C, reference)
    offsets = _opt.real_array(offsets, "offsets")
    if offsets.shape != (R, C, 2):
        raise InvalidInputError(
            f"offsets must have shape ({R}, {C}, 2) as (dx, dy) per view, got {offsets.shape}")
    if not np.all(np.isfinite(offsets)):
        raise InvalidInputError("offsets contain NaN or inf")
    if reference is None:
        zero = np.argwhere(np.all(np.abs(offsets) < 1e-9, axis=-1))
        reference = tuple(int(v) for v in zero[0]) if len(zero) else _default_offsets(R, C)[1]
    return offsets, _opt.index(reference, "reference", (R, C))


# ============================================================================ profiles

@dataclass
class _Plan:
    """How a profile turns bands into output channels (see the module docstring)."""

    K: int
    band_matrix: np.ndarray | None  # (B, K) cube: per-view projection, channel-normalised
    view_weights: np.ndarray | None  # (R, C, K) views: per-view channel weights
    view_scale: np.ndarray | None  # (R, C) views: image multiplier (1 / white at the band)
    gain: np.ndarray  # (K,) applied after averaging
    post: np.ndarray | None  # (K, K2) colour matrix (row vectors: out = x @ post)
    white_out: np.ndarray  # (K2,) output of the white before exposure
    encode: bool
    layout: str  # "hwk" (H, W, K), "hw" (K = 1 squeezed), "khw" (bands first)
    description: str


def _is_number(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


def _white_spd(white, wl: np.ndarray) -> np.ndarray:
    if white is None:
        return np.ones(wl.size)
    if isinstance(white, str):
        return spectral.illuminant_spd(white, wl)
    w = _opt.real_array(white, "white")
    if w.shape != wl.shape or not np.all(np.isfinite(w)):
        raise InvalidInputError(
            f"white must be an illuminant name or a finite array of shape {wl.shape} (one "
            f"value per band), got shape {w.shape}")
    return spectral.check_magnitude(w, "white")


def _camera_S(camera, wl: np.ndarray) -> np.ndarray:
    if isinstance(camera, (str, os.PathLike)):
        return np.asarray(spectral.camera_sensitivities(camera, wl), dtype=np.float64)
    S = _opt.real_array(camera, "camera sensitivities")
    if S.shape != (wl.size, 3):
        raise InvalidInputError(
            f"camera sensitivities must have shape ({wl.size}, 3) (one row per band), "
            f"got {S.shape}")
    if not np.all(np.isfinite(S)):
        raise InvalidInputError("camera sensitivities contain NaN or inf")
    return spectral.check_magnitude(S, "camera sensitivities")


def _is_xyz(S: np.ndarray, wl: np.ndarray) -> bool:
    ref = spectral.cmfs(wl)
    scale = max(float(np.abs(ref).max()), 1e-12)
    return bool(np.allclose(S, ref, rtol=1e-6, atol=1e-9 * scale))


def _camera_stage(camera, wl: np.ndarray, white_balance: bool, illuminant, white):
    """Sensitivities (incl. illuminant), the white's raw response, XYZ flag."""
    S = _camera_S(camera, wl)
    xyz = _is_xyz(S, wl)
    ill = spectral.illuminant_values(illuminant, wl)
    if ill is not None:
        S = S * ill[:, None]
    Wraw = (_white_spd(white, wl)[:, None] * S).sum(axis=0)  # (3,)
    if np.any(Wraw <= 0):
        dead = [ch for ch, v in zip("RGB", Wraw) if v <= 0]
        raise InvalidInputError(
            f"camera channel(s) {', '.join(dead)} have no response at {wl.min():g}-{wl.max():g} "
            "nm; cannot emulate this camera on these bands")
    return S, Wraw, xyz


def fit_ccm(camera, wavelengths, *, illuminant=None, white=None, source: str = "auto",
            white_preserving: bool = True) -> np.ndarray:
    """Least-squares colour-correction matrix from white-balanced camera RGB to linear sRGB.

    Training data: the reflectances of :func:`hyperlf.spectral.reflectance_library` (``source``)
    at ``wavelengths``, lit by ``white`` (default flat) and ``illuminant``. Camera side:
    ``rgb_k = sum_b s_b S_k(λ_b) / sum_b white_b S_k(λ_b)``. Target: the spectra's XYZ
    (:func:`hyperlf.spectral.cmfs`, same bands, white has Y = 1), Bradford-adapted from the
    white's chromaticity to D65, in linear sRGB. Solves ``min ||rgb @ M - srgb||²``, with
    ``white_preserving`` subject to ``(1, 1, 1) @ M = (1, 1, 1)`` (the white stays white).

    Parameters
    ----------
    camera : str, path-like or array_like (B, 3)
    wavelengths : array_like (B,)
    illuminant, white : see :func:`emulate_camera`
    source : {"auto", "munsell", "colorchecker"}
    white_preserving : bool

    Returns
    -------
    ndarray, shape (3, 3)
        ``srgb_linear = rgb @ M``.

    Examples
    --------
    A "camera" whose sensitivities are the CIE 1931 colour-matching functions sees XYZ, so
    the least-squares fit must find the exact matrix: scale the white-balanced XYZ back by
    the white's ``(X, Y, Z) / Y``, then convert with
    :func:`hyperlf.spectral.xyz_to_srgb_linear`. The columns sum to 1 (white stays white),
    and swapping the camera's channels swaps the rows of the matrix.

    >>> wl = np.arange(410.0, 701.0, 10.0)
    >>> S = spectral.cmfs(wl)
    >>> M = fit_ccm(S, wl, source="colorchecker")
    >>> white = S.sum(axis=0)  # XYZ of the flat white
    >>> direct = np.diag(white / white[1]) @ spectral.xyz_to_srgb_linear(
    ...     np.eye(3), white=tuple(spectral.xyz_to_xy(white)))
    >>> bool(np.allclose(M, direct)), M.sum(axis=0).round(6).tolist()
    (True, [1.0, 1.0, 1.0])
    >>> bool(np.allclose(fit_ccm(S[:, ::-1], wl, source="colorchecker"), M[::-1]))
    True
    """
    _checked(white_preserving=white_preserving)
    wl = spectral.as_wavelengths(wavelengths)
    S, Wraw, _ = _camera_stage(camera, wl, True, illuminant, white)
    _, refl = spectral.reflectance_library(source, wl)
    spectra = np.clip(refl, 0.0, None) * _white_spd(white, wl)[None, :]
    A = spectra @ (S / Wraw)  # (n, 3) camera, white-balanced
    X, Wxyz = _xyz_of(spectra, wl, illuminant, white)
    T = spectral.xyz_to_srgb_linear(X / Wxyz[1], white=tuple(spectral.xyz_to_xy(Wxyz)))
    if not white_preserving:
        M, *_ = np.linalg.lstsq(A, T, rcond=None)
        return M
    # KKT system per output column: [[A^T A, 1], [1^T, 0]] [m; mu] = [A^T t; 1]
    G = A.T @ A
    K = np.zeros((4, 4))
    K[:3, :3] = G
    K[:3, 3] = 1.0
    K[3, :3] = 1.0
    M = np.empty((3, 3))
    for j in range(3):
        rhs = np.concatenate([A.T @ T[:, j], [1.0]])
        M[:, j] = np.linalg.lstsq(K, rhs, rcond=None)[0][:3]
    return M


def _xyz_of(spectra: np.ndarray, wl: np.ndarray, illuminant, white):
    """Plain-sum XYZ of ``spectra`` (n, B) (times the illuminant) and of the white."""
    cmf = spectral.cmfs(wl)
    ill = spectral.illuminant_values(illuminant, wl)
    if ill is not None:
        cmf = cmf * ill[:, None]
    return spectra @ cmf, (_white_spd(white, wl)[:, None] * cmf).sum(axis=0)


def camera_matrix(camera, wavelengths, *, white_balance: bool = True, illuminant=None, white=None,
                  output: str = "camera", ccm="fit", ccm_source: str = "auto") -> np.ndarray:
    """The ``(B, 3)`` matrix ``M`` of a camera emulation: ``linear_output = spectrum @ M``.

    Before exposure and the sRGB transfer function, :func:`emulate_camera` is exactly this
    linear map.

    Parameters
    ----------
    camera, white_balance, illuminant, white, output, ccm, ccm_source
        As :func:`emulate_camera`.
    wavelengths : array_like (B,)
        Band centres in nm.

    Returns
    -------
    ndarray of float64, shape (B, 3)

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> camera_matrix("CIE 1931", lf.cube_wavelengths).shape
    (9, 3)
    """
    _checked(white_balance=white_balance, output=output)
    wl = spectral.as_wavelengths(wavelengths)
    plan = _camera_plan(camera, wl, white_balance, illuminant, white, output, ccm, ccm_source,
                        kind="cube")
    M = plan.band_matrix * plan.gain[None, :]
    return M @ plan.post if plan.post is not None else M


def _camera_plan(camera, wl_bands: np.ndarray, white_balance: bool, illuminant, white,
                 output: str, ccm, ccm_source: str, kind: str,
                 view_wl: np.ndarray | None = None) -> _Plan:
    if output not in _OUTPUTS:
        raise InvalidInputError(f"output must be 'camera' or 'srgb', got {output!r}")
    wl_bands = spectral.as_wavelengths(wl_bands, "the cube's wavelengths")  # known ones
    S, Wraw, xyz = _camera_stage(camera, wl_bands, white_balance, illuminant, white)
    post = None
    if output == "camera":
        gain = np.ones(3) if white_balance else Wraw.copy()
        desc = "camera XYZ" if xyz else "camera RGB"
    elif xyz:
        gain = Wraw / Wraw[1]
        post = spectral.xyz_to_srgb_linear(
            np.eye(3), white=tuple(spectral.xyz_to_xy(Wraw)) if white_balance else None)
        desc = "sRGB from CIE 1931 XYZ"
    else:
        gain = np.ones(3) if white_balance else Wraw / Wraw[1]
        if ccm is None or (isinstance(ccm, str) and ccm.lower() == "none"):
            post = np.eye(3)
        elif isinstance(ccm, str) and ccm.lower() == "fit":
            post = fit_ccm(camera, wl_bands, illuminant=illuminant, white=white,
                           source=ccm_source)
        else:
            post = _opt.real_array(ccm, "ccm")
            if post.shape != (3, 3) or not np.all(np.isfinite(post)):
                raise InvalidInputError(
                    f"ccm must be 'fit', None or a finite (3, 3) array, got {ccm!r}")
        desc = "sRGB via CCM"
    white_out = gain if post is None else gain @ post
    if kind == "cube":
        return _Plan(3, S / Wraw[None, :], None, None, gain, post, white_out, output == "srgb",
                     "hwk", desc)
    # views: weight of each view = white x sensitivity at its wavelength; the image is divided
    # by the white there, so sum_v a_vk I_v / white_v / sum_v a_vk = sum I S / sum white S.
    idx = np.searchsorted(wl_bands, view_wl)
    wspd = _white_spd(white, wl_bands)
    if np.any(wspd[idx] <= 0):
        raise InvalidInputError("the white spectrum must be > 0 at every view's wavelength")
    return _Plan(3, None, S[idx] * wspd[idx][..., None], 1.0 / wspd[idx], gain, post, white_out,
                 output == "srgb", "hwk", desc)


def band_index(wavelengths, lam: float) -> int:
    """Index of the band at ``lam`` nm: the nearest, if it lies within
    :data:`BAND_TOLERANCE_NM` and within half the bands' smallest spacing.

    Raises
    ------
    InvalidInputError
        ``lam`` is not finite, or no band is that near.

    Examples
    --------
    >>> band_index([410.0, 548.7, 700.0], 550)
    1
    """
    wl_bands = spectral.as_wavelengths(_opt.real_array(wavelengths, "wavelengths").ravel(),
                                       "the cube's wavelengths")  # known ones
    try:
        lam = _opt.real(lam, "lam")
    except InvalidInputError:
        raise InvalidInputError(f"a band profile needs a finite wavelength in nm, got "
                                f"{_opt.shown(lam)}") from None
    b = int(np.argmin(np.abs(wl_bands - lam)))
    tol = BAND_TOLERANCE_NM
    if wl_bands.size > 1:
        step = float(np.min(np.diff(np.unique(wl_bands)), initial=np.inf))
        tol = min(tol, 0.5 * step)
    if abs(wl_bands[b] - lam) > tol + 1e-9:
        raise InvalidInputError(
            f"no band at {lam:g} nm: the bands are {wl_bands.min():g}-{wl_bands.max():g} nm, "
            f"the nearest {wl_bands[b]:g} nm; name a band within {tol:g} nm of it")
    return b


def _make_plan(profile, src: _Source, white_balance: bool = True, illuminant=None, white=None,
               output: str = "camera", ccm="fit", ccm_source: str = "auto") -> _Plan:
    """How ``profile`` turns the bands of ``src`` into output channels: all bands, one band,
    a camera (a name, a CSV path or ``(B, 3)`` sensitivities), or weights."""
    if output not in _OUTPUTS:
        raise InvalidInputError(f"output must be 'camera' or 'srgb', got {output!r}")
    encode = output == "srgb"
    view_wl = None if src.kind == "cube" else src.wavelengths
    wl_bands = src.wavelengths if view_wl is None else np.unique(view_wl)
    if _all_bands(profile):
        return _all_bands_plan(src, wl_bands, view_wl, encode)
    if _is_number(profile):
        return _band_plan(src, wl_bands, view_wl, profile, encode)
    arr = None if isinstance(profile, (str, os.PathLike)) else _opt.real_array(profile, "profile")
    if arr is None or arr.shape == (wl_bands.size, 3):
        return _camera_plan(profile if arr is None else arr, wl_bands, white_balance,
                            illuminant, white, output, ccm, ccm_source, src.kind, view_wl)
    return _weights_plan(src, wl_bands, view_wl, arr, encode)


def _all_bands(profile) -> bool:
    """Whether ``profile`` asks for every band (None or ``"bands"``), not one image."""
    return profile is None or (isinstance(profile, str) and profile.lower() == "bands")


def _linear_plan(K: int, band_matrix, view_weights, encode: bool, layout: str,
                 description: str) -> _Plan:
    """A plan without colour stages: unit gain, no colour matrix, a white of ones."""
    ones = np.ones(K)
    return _Plan(K, band_matrix, view_weights, None, ones, None, ones, encode, layout,
                 description)


def _view_bands(wl_bands: np.ndarray, view_wl: np.ndarray) -> np.ndarray:
    """The index in ``wl_bands`` of each view's band ``(R, C)``."""
    return np.searchsorted(wl_bands, view_wl)


def _all_bands_plan(src: _Source, wl_bands, view_wl, encode: bool) -> _Plan:
    """Every band as its own channel, bands first."""
    B = wl_bands.size
    if src.kind == "cube":
        return _linear_plan(B, np.eye(B, dtype=np.float32), None, encode, "khw", "all bands")
    vw = np.zeros((src.R, src.C, B))
    vw[np.arange(src.R)[:, None], np.arange(src.C)[None, :], _view_bands(wl_bands, view_wl)] = 1
    return _linear_plan(B, None, vw, encode, "khw", "all bands")


def _band_plan(src: _Source, wl_bands, view_wl, profile, encode: bool) -> _Plan:
    """The one band nearest the wavelength ``profile`` (nm), within the bands' spacing."""
    b = band_index(wl_bands, _opt.real(profile, "a band profile's wavelength (nm)"))
    label = f"band {wl_bands[b]:g} nm"
    if src.kind == "cube":
        M = np.zeros((wl_bands.size, 1))
        M[b, 0] = 1.0
        return _linear_plan(1, M, None, encode, "hw", label)
    vw = (np.abs(view_wl - wl_bands[b]) < 1e-9).astype(np.float64)[..., None]
    return _linear_plan(1, None, vw, encode, "hw", label)


def _weights_plan(src: _Source, wl_bands, view_wl, arr: np.ndarray, encode: bool) -> _Plan:
    """One channel weighted over the bands ``(B,)`` (normalised to sum 1 for a cube), or over
    the views ``(R, C)``."""
    B = wl_bands.size
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError("profile weights contain NaN or inf")
    if src.kind == "cube" and arr.shape == (B,):
        s = float(arr.sum())
        w = arr / s if abs(s) > 1e-12 else arr
        return _linear_plan(1, w[:, None], None, encode, "hw", "weighted bands")
    if src.kind == "views" and arr.shape in ((B,), (src.R, src.C)):
        if np.any(arr < 0):
            raise InvalidInputError("per-view weights must be non-negative for H-LF views")
        if arr.shape == (B,):
            return _linear_plan(1, None, arr[_view_bands(wl_bands, view_wl)][..., None],
                                encode, "hw", "weighted bands")
        return _linear_plan(1, None, arr[..., None], encode, "hw", "weighted views")
    expected = f"({B},) over the bands" + (f" or ({src.R}, {src.C}) per view"
                                            if src.kind == "views" else "")
    raise InvalidInputError(
        f"profile must be a camera (name, CSV path or ({B}, 3) sensitivities), a wavelength in "
        f"nm, None (all bands) or weights {expected}; got "
        f"{arr.size if arr.ndim == 1 else arr.shape} values")


# ============================================================================ finishing

def _apply_post(x: np.ndarray, plan: _Plan, channel_axis: int = -1) -> np.ndarray:
    """Gain and colour matrix on the channel axis (last)."""
    out = x * plan.gain.astype(np.float32)
    if plan.post is not None:
        out = out @ plan.post.astype(np.float32)
    return out.astype(np.float32, copy=False)


def _exposure_scale(values: Iterable[np.ndarray], plan: _Plan, exposure, percentile: float
                    ) -> float:
    if _is_number(exposure):
        # at most 1e30: the float32 images it scales stay finite
        return _opt.number(exposure, "an exposure gain", positive=True, at_most=1e30)
    e = str(exposure).lower() if exposure is not None else "none"
    if e == "none":
        return 1.0
    if e == "white":
        m = float(np.max(plan.white_out))
        return 1.0 / m if m > 0 else 1.0
    if e == "percentile":
        if not (0 < percentile <= 100):
            raise InvalidInputError(f"exposure_percentile must be in (0, 100], got {percentile}")
        finite = [v[np.isfinite(v)].ravel() for v in values]
        allv = np.concatenate(finite) if finite else np.zeros(0)
        if allv.size == 0:
            return 1.0
        p = float(np.percentile(allv, percentile))
        return 1.0 / p if p > 0 else 1.0
    raise InvalidInputError(
        f"exposure must be 'none', 'white', 'percentile' or a gain, got {exposure!r}")


def _encode(x: np.ndarray, plan: _Plan, scale: float) -> np.ndarray:
    if scale != 1.0:
        x = x * np.float32(scale)
    if plan.encode:
        x = spectral.linear_to_srgb(np.clip(x, 0.0, 1.0).astype(np.float32))
    return x.astype(np.float32, copy=False)


def _layout(x: np.ndarray, plan: _Plan) -> np.ndarray:
    """(..., H, W, K) -> the plan's output layout."""
    if plan.layout == "hw":
        return x[..., 0]
    if plan.layout == "khw":
        return np.moveaxis(x, -1, -3)
    return x


# ============================================================================ emulation

def _project(bands: np.ndarray, M: np.ndarray) -> np.ndarray:
    """(k, H, W) bands x (k, K) matrix -> (H, W, K) float32."""
    k, H, W = bands.shape
    out = M.astype(np.float32).T @ bands.reshape(k, H * W)  # (K, HW)
    return np.ascontiguousarray(out.T).reshape(H, W, M.shape[1])


def _used_bands(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    idx = np.flatnonzero(np.any(M != 0, axis=1))
    return idx, M[idx]


def _select_views(views, lead: tuple[int, ...]) -> tuple[list[tuple[int, ...]], bool]:
    """The leading indices ``emulate_camera(views=...)`` renders, and whether it is one view."""
    if views is None or (isinstance(views, str) and views.lower() == "all"):
        return (list(np.ndindex(*lead)) if lead else [()]), False
    if isinstance(views, str) and views.lower() in ("reference", "ref"):
        if len(lead) != 2:
            raise InvalidInputError("views='reference' needs a 5-D cube (R, C, B, H, W)")
        return [((lead[0] - 1) // 2, (lead[1] - 1) // 2)], True
    if isinstance(views, tuple) and all(_is_number(i) for i in views):
        return [_opt.index(views, "views", lead)], True
    try:
        several = None if isinstance(views, (str, dict)) else list(views)
    except TypeError:  # not iterable
        several = None
    if not several:
        raise InvalidInputError("views must be None, 'all', 'reference', one index (i, j) or a "
                                f"list of them, got {_opt.shown(views)}")
    return [_opt.index(t, "views", lead) for t in several], False


def _emulate_views(data, sel, idx: np.ndarray, B: int, M: np.ndarray, plan: _Plan, mask,
                   progress: bool) -> tuple[np.ndarray, np.ndarray]:
    """Linear camera values ``(n, H, W, 3)`` of the selected views (NaN where invalid) and the
    invalid pixels ``(n, H, W)``."""
    H, W = (int(s) for s in data.shape[-2:])
    out = np.empty((len(sel), H, W, 3), dtype=np.float32)
    bad_px = np.zeros((len(sel), H, W), dtype=bool)
    h5 = _is_h5_dataset(data)
    for n, t in enumerate(progress_bar(sel, "emulating camera", total=len(sel), enabled=progress,
                                       unit="view")):
        if idx.size == B:
            bands = data[t] if t else data[()] if h5 else data
        elif h5:
            bands = np.stack([np.asarray(data[t + (int(b),)]) for b in idx])
        else:
            bands = data[t][idx] if t else data[idx]
        bands = np.asarray(bands, dtype=np.float32)
        out[n] = _apply_post(_project(bands, M), plan)
        bad = ~np.isfinite(out[n]).all(axis=-1)  # a NaN in any used band propagates
        if mask is not None:
            bad |= ~np.asarray(mask[t] if t else mask, dtype=bool)
        bad_px[n] = bad
        if bad.any():
            out[n][bad] = np.nan
    return out, bad_px


def emulate_camera(cube, wavelengths=None, camera="CIE 1931", *, white_balance: bool = True,
                   illuminant=None, output: str = "camera", mask=None, exposure="white",
                   exposure_percentile: float = 99.5, white=None, views=None, ccm="fit",
                   ccm_source: str = "auto", fill: float = 0.0,
                   progress: bool = False) -> np.ndarray:
    """Colour sensor emulation (SPEC §8): the image a colour camera would record.

    ``RGB_k(x) = sum_b cube_b(x) S_k(λ_b)``, white-balanced so that a flat spectrum is grey,
    then optionally mapped to display sRGB (module docstring: "Output spaces").

    Parameters
    ----------
    cube : array_like (..., B, H, W), h5py dataset, or CubeFile
        A cube of one view ``(B, H, W)``, a plenoptic cube ``(R, C, B, H, W)`` or any stack
        whose third-last axis is the band axis. On-disk data is read one view at a time.
    wavelengths : array_like (B,)
        Band centres in nm (taken from a CubeFile when omitted).
    camera : str, path-like or array_like (B, 3)
        ``"CIE 1931"``, a name from :func:`hyperlf.spectral.list_cameras` (colour-science's
        and, with ``HYPERLF_DATA``, the camspec database, Jiang et al. 2013), a CSV file
        ``wavelength_nm, r, g, b``, or sensitivities sampled at ``wavelengths``.
    white_balance : bool
        Divide channel k by the white's response ``sum_b white_b S_k(λ_b)``.
    illuminant : str or array_like (B,), optional
        Multiplies the spectra and the white (for reflectance cubes).
    output : {"camera", "srgb"}
        Linear camera RGB (XYZ for CIE 1931), or encoded display sRGB in [0, 1].
    mask : array_like of bool (..., H, W), optional
        True = valid; invalid pixels get ``fill``. With a CubeFile, ``None`` uses the file's
        mask and ``False`` ignores it.
    exposure : {"white", "none", "percentile"} or float
        See the module docstring. ``"percentile"`` uses all rendered views together.
    exposure_percentile : float
    white : str or array_like (B,), optional
        The spectrum rendered neutral (default flat); e.g. ``"D65"`` for a D65-lit radiance cube.
    views : None, "all", "reference", (i, j) or list of (i, j)
        Which leading indices to render: all (default), the reference view
        ``((R-1)//2, (C-1)//2)`` of a 5-D cube, one index (output without the leading axes)
        or several (stacked on a new first axis).
    ccm : "fit", None or array_like (3, 3)
        Colour correction of an RGB camera for ``output="srgb"`` (see :func:`fit_ccm`).
    ccm_source : {"auto", "munsell", "colorchecker"}
        Reflectances for the CCM fit.
    fill : float
        Value of masked pixels.
    progress : bool

    Returns
    -------
    ndarray of float32, shape (..., H, W, 3)

    Raises
    ------
    InvalidInputError
        For a cube that is not ``(..., B, H, W)``, a band count that differs from the
        wavelengths, or a view index outside the cube.

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> emulate_camera(lf.gt_cube[lf.reference], lf.cube_wavelengths).shape
    (24, 32, 3)
    """
    _checked(white_balance=white_balance, output=output, exposure_percentile=exposure_percentile,
             fill=fill, progress=progress)
    if _is_cubefile(cube):
        data = cube.cube
        if wavelengths is None:
            wavelengths = cube.wavelengths
        if mask is None:
            mask = cube.mask
    else:
        data = cube if _is_h5_dataset(cube) else np.asarray(cube)
    if mask is False:
        mask = None
    if wavelengths is None:
        raise InvalidInputError("wavelengths (B,) are required for an array cube")
    wl = spectral.as_wavelengths(wavelengths)
    shape = tuple(int(s) for s in data.shape)
    if len(shape) < 3:
        raise InvalidInputError(f"cube must be (..., B, H, W), got shape {shape}")
    if shape[-3] != wl.size:
        raise InvalidInputError(
            f"the cube's band axis (third from last) has {shape[-3]} samples but {wl.size} "
            "wavelengths were given; the layout is (..., B, H, W)")
    lead, (B, H, W) = shape[:-3], shape[-3:]
    mask = _check_mask(mask, lead + (H, W))
    plan = _camera_plan(camera, wl, white_balance, illuminant, white, output, ccm, ccm_source,
                        kind="cube")
    idx, M = _used_bands(plan.band_matrix)

    sel, single = _select_views(views, lead)
    out, bad_px = _emulate_views(data, sel, idx, B, M, plan, mask, progress)
    scale = _exposure_scale([out], plan, exposure, exposure_percentile)
    for n in range(len(sel)):  # view by view: no full-size temporaries
        out[n] = _encode(out[n], plan, scale)
        out[n][bad_px[n]] = fill
    if single:
        return out[0]
    if views is None or (isinstance(views, str) and views.lower() == "all"):
        return out.reshape(lead + (H, W, 3))
    return out


# ============================================================================ shift and add

def _aperture_weights(aperture, src: _Source) -> np.ndarray:
    R, C = src.R, src.C
    if aperture is None:
        return np.ones((R, C))
    if _is_number(aperture):
        rad = _opt.number(aperture, "aperture radius (baselines)")
        return (np.hypot(src.offsets[..., 0], src.offsets[..., 1]) <= rad + 1e-9).astype(float)
    a = _opt.real_array(aperture, "aperture")
    if a.shape != (R, C):
        raise InvalidInputError(
            f"aperture must be a radius (baselines), or a ({R}, {C}) mask/weights, got {a.shape}")
    if not np.all(np.isfinite(a)) or np.any(a < 0):
        raise InvalidInputError("aperture weights must be finite and non-negative")
    if not np.any(a > 0):
        raise InvalidInputError("the aperture selects no view")
    return a


def _as_disparity(d, H: int, W: int, name: str = "disparity") -> np.ndarray | float:
    a = _opt.real_array(d, name)
    if a.ndim == 0:
        return _opt.real(a.item(), name)
    if a.shape != (H, W):
        raise InvalidInputError(f"{name} must be a scalar or an ({H}, {W}) map, got {a.shape}")
    return a


#: How refocusing samples the views (module docstring): invalid samples are 0 (with weight 0),
#: float32 weights, x interpolated before y.
_SAMPLING = {"fill": 0.0, "edge": "mask", "dtype": np.float32}


def _sample_shift(img: np.ndarray, sx: float, sy: float) -> tuple[np.ndarray, np.ndarray]:
    """``img`` (H, W, K) sampled at ``(x + sx, y + sy)``: a separable bilinear translation."""
    out, valid = shift_map(img, sx, sy, order="xy", channel_axis=-1, skip_zero=True, **_SAMPLING)
    return out.astype(np.float32, copy=False), valid


def _sample_map(img: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``img`` (H, W, K) sampled bilinearly at float coordinates ``(qx, qy)`` (H, W), float32."""
    out, valid = sample_bilinear(img, qx, qy, **_SAMPLING)
    return out.astype(np.float32, copy=False), valid


def _accumulate(src: _Source, plan: _Plan, disparities: Sequence, aperture=None,
                occlusion: str = "none", view_disparities=None, tol: float = 0.5,
                progress: bool = False, desc: str = "refocusing"):
    """Shift-and-add for several disparities at once (each view is read once).

    Returns lists of ``num (H, W, K)``, ``den (H, W, K or 1)`` and ``count (H, W)``.
    """
    H, W, K = src.H, src.W, plan.K
    ds = [_as_disparity(d, H, W) for d in disparities]
    ap = _aperture_weights(aperture, src)
    Kd = 1 if src.kind == "cube" else K
    num = [np.zeros((H, W, K), np.float32) for _ in ds]
    den = [np.zeros((H, W, Kd), np.float32) for _ in ds]
    cnt = [np.zeros((H, W), np.int32) for _ in ds]
    grid = np.mgrid[0:H, 0:W].astype(np.float64)
    bands = _profile_bands(plan)
    todo = _contributing_views(src, plan, ap)
    for r, c in progress_bar(todo, desc, total=len(todo), enabled=progress, unit="view"):
        img, wv = _view_channels(src, plan, r, c, ap[r, c], bands)
        img, good, goodf = _valid_pixels(src, img, r, c)
        offset = tuple(float(v) for v in src.offsets[r, c])
        vd = None
        if occlusion == "views":
            vd = np.asarray(view_disparities[r, c], dtype=np.float64)
        for i, d in enumerate(ds):
            samp, valid, q = _sample_view(img, good, goodf, d, offset, grid)
            if np.ndim(d) != 0:
                valid &= np.isfinite(d)
                if occlusion in ("views", "zbuffer") and q is not None:
                    other = vd if occlusion == "views" else forward_warp_disparity(d, offset)
                    valid &= _agrees(other, d, q, tol)
            _add_samples(num[i], den[i], cnt[i], samp, valid, wv, cube=src.kind == "cube")
    return num, den, cnt


def _contributing_views(src: _Source, plan: _Plan, ap: np.ndarray) -> list[tuple[int, int]]:
    """The views with a non-zero aperture weight and, for views, a non-zero profile weight."""
    todo = [(r, c) for r in range(src.R) for c in range(src.C) if ap[r, c] > 0]
    if plan.view_weights is not None:
        todo = [(r, c) for r, c in todo if np.any(plan.view_weights[r, c] != 0)]
    if not todo:
        raise InvalidInputError("no view contributes to this profile (check the wavelength, "
                                "weights and aperture)")
    return todo


def _profile_bands(plan: _Plan):
    """``(bands read, their matrix, whether it is the identity)`` of a cube's profile, or None."""
    if plan.band_matrix is None:
        return None
    idx, M = _used_bands(plan.band_matrix)
    return idx, M, idx.size == plan.K and np.array_equal(M, np.eye(plan.K))


def _view_channels(src: _Source, plan: _Plan, r: int, c: int, ap_rc, bands):
    """View ``(r, c)`` as the profile's channels ``(H, W, K)`` (a cube) or its one band
    ``(H, W, 1)`` (views), and the weight of its samples."""
    if src.kind == "cube":
        idx, M, identity = bands
        b = src.read_bands(r, c, idx)
        img = np.ascontiguousarray(np.moveaxis(b, 0, -1)) if identity else _project(b, M)
        return img, np.float32(ap_rc)
    im = src.read_view(r, c)
    if plan.view_scale is not None:
        im = im * np.float32(plan.view_scale[r, c])
    return im[..., None], (plan.view_weights[r, c] * ap_rc).astype(np.float32)


def _valid_pixels(src: _Source, img: np.ndarray, r: int, c: int):
    """``img`` with its non-finite samples zeroed, the pixels valid in every channel and in
    the view's mask, and those as float weights ``(H, W, 1)`` (None where all are valid)."""
    finite = np.isfinite(img)
    good = finite.all(axis=-1)  # a NaN in any used band invalidates the pixel
    if not good.all():
        img = np.where(finite, img, np.float32(0))
    vm = src.view_mask(r, c)
    if vm is not None:
        good &= vm
    return img, good, None if good.all() else good.astype(np.float32)[..., None]


def _sample_view(img, good, goodf, d, offset: tuple, grid: np.ndarray):
    """The view sampled at ``p - d (dx, dy)``: samples, their validity, and the sample
    positions ``(qx, qy)`` where ``d`` is a map (None for a plane or the reference)."""
    dx, dy = offset
    if dx == 0.0 and dy == 0.0:
        return img, good.copy(), None
    if np.ndim(d) == 0:
        return (*_sample_masked(_sample_shift, img, goodf, -d * dx, -d * dy), None)
    yy, xx = grid
    dd = np.where(np.isfinite(d), d, 0.0)
    q = (xx - dd * dx, yy - dd * dy)
    return (*_sample_masked(_sample_map, img, goodf, *q), q)


def _sample_masked(sample, img: np.ndarray, goodf, *where):
    """``sample(img, *where)``, its validity narrowed to samples of valid pixels only."""
    samp, valid = sample(img, *where)
    if goodf is not None:
        gs, _ = sample(goodf, *where)
        valid &= gs[..., 0] > 1.0 - 1e-4
    return samp, valid


def _agrees(other: np.ndarray, d: np.ndarray, q: tuple, tol: float) -> np.ndarray:
    """Whether the view's own disparity ``other`` at the nearest pixel of ``q`` agrees with
    ``d`` within ``tol`` (the view sees the surface, not a nearer one)."""
    H, W = d.shape
    ix = np.clip(np.rint(q[0]), 0, W - 1).astype(np.intp)
    iy = np.clip(np.rint(q[1]), 0, H - 1).astype(np.intp)
    with np.errstate(invalid="ignore"):
        return np.abs(other[iy, ix] - np.where(np.isfinite(d), d, np.nan)) <= tol


def _add_samples(num, den, cnt, samp, valid, wv, *, cube: bool) -> None:
    """Add the valid samples, weighted by ``wv``, to ``num``, ``den`` and ``cnt`` in place
    (samples outside a view are 0 and have weight 0)."""
    if not cube:
        w = valid[..., None].astype(np.float32) * wv
        num += samp * w
        den += w
    elif valid.all() and wv == 1:
        num += samp
        den += 1.0
    else:
        wmap = (valid * wv).astype(np.float32)[..., None]
        num += samp * wmap
        den += wmap
    cnt += valid


def _average(num: np.ndarray, den: np.ndarray, plan: _Plan) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        avg = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan).astype(np.float32)
    # a pixel is defined when every channel has a sample; channels with no weight -> NaN
    return _apply_post(avg, plan)


def _finish_frames(frames: list[np.ndarray], plan: _Plan, exposure, percentile: float,
                   fill: float) -> list[np.ndarray]:
    scale = _exposure_scale(frames, plan, exposure, percentile)
    out = []
    for f in frames:
        bad = ~np.isfinite(f).all(axis=-1)
        g = _encode(np.where(np.isfinite(f), f, 0.0), plan, scale)
        g[bad] = fill
        out.append(_layout(g, plan))
    return out


def _check_occlusion(occlusion, view_disparities, src: _Source):
    occ = "none" if occlusion is None or occlusion is False else str(occlusion).lower()
    if occ == "auto":
        occ = "views" if view_disparities is not None else "zbuffer"
    if occ not in ("none", "views", "zbuffer"):
        raise InvalidInputError(
            f"occlusion must be 'auto', 'views', 'zbuffer' or 'none', got {occlusion!r}")
    vd = None
    if occ == "views":
        if view_disparities is None:
            raise InvalidInputError("occlusion='views' needs view_disparities (R, C, H, W)")
        vd = view_disparities
        if tuple(np.shape(vd)) != (src.R, src.C, src.H, src.W):
            raise InvalidInputError(
                f"view_disparities must have shape {(src.R, src.C, src.H, src.W)}, got "
                f"{tuple(np.shape(vd))}")
    return occ, vd


def focal_stack(views_or_cube, offsets=None, disparities=(0.0,), profile="CIE 1931",
                *, wavelengths=None, output: str = "camera", exposure="white",
                exposure_percentile: float = 99.5, white_balance: bool = True, illuminant=None,
                white=None, ccm="fit", ccm_source: str = "auto", aperture=None, mask=None,
                reference=None, fill: float = 0.0, return_counts: bool = False,
                progress: bool = False):
    """Refocused images at several disparities, reading every view once.

    Same parameters as :func:`refocus`, with ``disparities`` a sequence of scalars or
    ``(H, W)`` maps. ``exposure="percentile"`` uses one scale for the whole stack.

    Parameters
    ----------
    disparities : sequence of float or array_like (H, W)
        One refocusing disparity (px per baseline) or map per output image.

    Other parameters are those of :func:`refocus`.

    Returns
    -------
    list of ndarray
        One image per disparity, laid out as in :func:`refocus`.
    counts : list of ndarray (H, W) int, only with ``return_counts``
        Number of views that contributed to each pixel.

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> [im.shape for im in focal_stack(lf, disparities=(0.0, 1.0))]
    [(24, 32, 3), (24, 32, 3)]
    """
    _checked(output=output, exposure_percentile=exposure_percentile,
             white_balance=white_balance, fill=fill, return_counts=return_counts,
             progress=progress)
    src = _make_source(views_or_cube, wavelengths, offsets, mask, reference)
    plan = _make_plan(profile, src, white_balance, illuminant, white, output, ccm, ccm_source)
    try:
        ds = [disparities] if np.ndim(disparities) == 2 else list(disparities)
    except (TypeError, ValueError):  # not a sequence, or a ragged one
        ds = None
    if not ds:
        raise InvalidInputError("disparities must be a non-empty sequence of disparities "
                                f"(scalars or (H, W) maps), got {_opt.shown(disparities)}")
    num, den, cnt = _accumulate(src, plan, ds, aperture=aperture, progress=progress)
    frames = [_average(n, d, plan) for n, d in zip(num, den)]
    out = _finish_frames(frames, plan, exposure, exposure_percentile, fill)
    return (out, cnt) if return_counts else out


def refocus(views_or_cube, offsets=None, disparity=0.0, profile="CIE 1931", *, wavelengths=None,
            output: str = "camera", exposure="white", exposure_percentile: float = 99.5,
            white_balance: bool = True, illuminant=None, white=None, ccm="fit",
            ccm_source: str = "auto", aperture=None, mask=None, reference=None,
            fill: float = 0.0, return_counts: bool = False, progress: bool = False):
    """Spectral refocusing (SPEC §8): shift-and-add over the views at a disparity.

    Every view ``v`` is sampled at ``q_v = p - d (pos_v - pos_ref)`` (SPEC §1) and the valid
    samples are averaged (count-normalised: samples outside a view or masked are excluded, never
    zero-filled). The spectral profile (a camera, a single band, a weight vector, or all bands)
    is applied per view before averaging; see the module docstring.

    Parameters
    ----------
    views_or_cube : cube (R, C, B, H, W) (array, h5py dataset or CubeFile), H-LF views
        (R, C, H, W), or a spectral LightField (its views, wavelengths and offsets)
    offsets : array_like (R, C, 2), optional
        ``pos[r, c] - pos[ref]`` as ``(dx, dy)`` in baselines (``LightField.offsets``).
        Default: the regular grid ``(c, r)`` around ``reference``.
    disparity : float or array_like (H, W)
        Focus disparity (px per baseline): a plane, or a map of the reference view.
    profile : camera name / CSV path / (B, 3) array, wavelength (nm), weights (B,) or (R, C)
        for views, or None (all bands)
    wavelengths : array_like
        ``(B,)`` for a cube, ``(R, C)`` for views (from a CubeFile / LightField when omitted).
        A cube's may be all NaN (unknown, :func:`hyperlf.spectral.wavelengths_unknown`): then
        only weights and None (all bands) work.
    output : {"camera", "srgb"}
    exposure, exposure_percentile, white_balance, illuminant, white, ccm, ccm_source :
        As in :func:`emulate_camera`.
    aperture : float or array_like (R, C), optional
        A radius in baselines around the reference (views farther away are left out), or a
        mask/weights per view. Default: every view.
    mask : array_like of bool, optional
        ``(R, C, H, W)``, True = valid sample (a CubeFile's mask by default).
    reference : (int, int), optional
        Reference view for the default offsets.
    fill : float
        Value of pixels with no valid sample.
    return_counts : bool
        Also return the number of views averaged at each pixel.
    progress : bool

    Returns
    -------
    ndarray of float32
        ``(H, W, 3)`` for a camera, ``(H, W)`` for a band or weights, ``(B, H, W)`` for all
        bands. With ``return_counts``: ``(image, counts)``.

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> refocus(lf, None, 0.5).shape
    (24, 32, 3)
    """
    _checked(return_counts=return_counts)
    if np.ndim(disparity) not in (0, 2):
        raise InvalidInputError(
            f"disparity must be a scalar or an (H, W) map, got shape {np.shape(disparity)}")
    out, cnt = focal_stack(views_or_cube, offsets, [disparity], profile, wavelengths=wavelengths,
                           output=output, exposure=exposure,
                           exposure_percentile=exposure_percentile, white_balance=white_balance,
                           illuminant=illuminant, white=white, ccm=ccm, ccm_source=ccm_source,
                           aperture=aperture, mask=mask, reference=reference, fill=fill,
                           return_counts=True, progress=progress)
    return (out[0], cnt[0]) if return_counts else out[0]


def all_focus(cube_or_views, offsets=None, disparity=None, profile="CIE 1931", *, wavelengths=None,
              view_disparities=None, occlusion="auto", tol: float = 0.5,
              output: str = "camera", exposure="white", exposure_percentile: float = 99.5,
              white_balance: bool = True, illuminant=None, white=None, ccm="fit",
              ccm_source: str = "auto", aperture=None, mask=None, reference=None,
              fill: float = 0.0, return_counts: bool = False, progress: bool = False):
    """All-focus image (SPEC §8): every view sampled at the correspondence of the disparity map.

    Each reference pixel ``p`` averages the views at ``q_v = p - d(p) (pos_v - pos_ref)``, so
    every depth is in focus.

    Parameters
    ----------
    disparity : array_like (H, W)
        Disparity map of the reference view; NaN pixels get ``fill``.
    view_disparities : array_like (R, C, H, W), optional
        Every view's own disparity (e.g. ``LightField.gt_disparity`` or cube completion's).
    occlusion : {"auto", "views", "zbuffer", "none"}
        Which views to trust at each pixel. ``"views"``: only views whose own disparity at
        ``q_v`` (nearest pixel) agrees with ``d(p)`` within ``tol``. ``"zbuffer"``: the same
        test against the reference disparity forward-warped into the view (z-buffer, larger
        disparity wins), which rejects views where a nearer surface hides ``p``. ``"auto"``:
        ``"views"`` when ``view_disparities`` is given, else ``"zbuffer"``. The reference view
        always passes.
    tol : float
        Disparity tolerance (px per baseline) of the occlusion check.

    Other parameters are those of :func:`refocus`.

    Returns
    -------
    ndarray of float32
        Laid out as in :func:`refocus`; with ``return_counts``: ``(image, counts)``.

    Examples
    --------
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> all_focus(lf, disparity=lf.gt_disparity[lf.reference]).shape
    (24, 32, 3)
    """
    if disparity is None:
        raise InvalidInputError("all_focus needs the reference view's disparity map (H, W)")
    _checked(tol=tol, output=output, exposure_percentile=exposure_percentile,
             white_balance=white_balance, fill=fill, return_counts=return_counts,
             progress=progress)
    src = _make_source(cube_or_views, wavelengths, offsets, mask, reference)
    d = _opt.real_array(disparity, "disparity")
    if d.shape != (src.H, src.W):
        raise InvalidInputError(
            f"disparity must be the reference's ({src.H}, {src.W}) map, got {d.shape}")
    occ, vd = _check_occlusion(occlusion, view_disparities, src)
    plan = _make_plan(profile, src, white_balance, illuminant, white, output, ccm, ccm_source)
    num, den, cnt = _accumulate(src, plan, [d], aperture=aperture, occlusion=occ,
                                view_disparities=vd, tol=float(tol), progress=progress,
                                desc="all-focus")
    frame = _average(num[0], den[0], plan)
    out = _finish_frames([frame], plan, exposure, exposure_percentile, fill)[0]
    return (out, cnt[0]) if return_counts else out


# ============================================================================ focal sweep

def _to_uint8_rgb(img: np.ndarray) -> np.ndarray:
    a = np.asarray(img, dtype=np.float32)
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=-1)
    return np.rint(np.clip(np.nan_to_num(a), 0.0, 1.0) * 255.0).astype(np.uint8)


def _annotate(frame: np.ndarray, text: str) -> np.ndarray:
    import cv2

    out = frame.copy()
    H = out.shape[0]
    scale = max(0.3, H / 400.0)
    th = max(1, int(round(scale * 2)))
    org = (max(2, int(4 * scale)), max(10, int(18 * scale)))
    cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), th + 2, cv2.LINE_AA)
    cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), th, cv2.LINE_AA)
    return out


def _write_gif(path: Path, frames: list[np.ndarray], fps: float) -> Path:
    from PIL import Image

    ims = [Image.fromarray(np.ascontiguousarray(f)) for f in frames]
    duration = max(1, int(round(1000.0 / fps)))
    with atomic_path(path) as tmp:
        ims[0].save(tmp, format="GIF", save_all=True, append_images=ims[1:], duration=duration,
                    loop=0, optimize=False, disposal=1)
    return path


#: The focal sweep's videos, by format: (OpenCV fourcc, name in messages, article, codec).
#: MP4 holds MPEG-4 part 2 ('mp4v'), which desktop players play and browsers do not; WebM holds
#: VP9, which browsers play. OpenCV's wheels open no H.264 writer, so neither can be H.264.
_VIDEOS = {"mp4": ("mp4v", "MP4", "an", "MPEG-4"), "webm": ("VP90", "WebM", "a", "VP9")}

#: OpenCV's FFmpeg notice when a container keeps no fourcc tag (WebM keeps none): harmless, and
#: written straight to file descriptor 2, past ``-q``.
_OPENCV_TAG_NOTICE = re.compile(rb"OpenCV: FFMPEG: (tag 0x[0-9a-fA-F]+/'.*' is not supported "
                                rb"with codec id|fallback to use tag)")


@contextlib.contextmanager
def _opencv_tag_notice_held_back():
    """Run the block with file descriptor 2 in a temporary file; write back all but the notices
    of :data:`_OPENCV_TAG_NOTICE` (any other line comes out, only later)."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no stderr to hold back
        yield
        return
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            held.seek(0)
            rest = [ln for ln in held.read().splitlines(keepends=True)
                    if not _OPENCV_TAG_NOTICE.match(ln)]
            if rest:
                os.write(2, b"".join(rest))


def _write_video(path: Path, frames: list[np.ndarray], fps: float, fourcc: str, label: str,
                 article: str, codec: str) -> Path | None:
    """A video through OpenCV, the container picked from ``path``'s suffix (the temporary file
    keeps it), checked by reading it back; None (with a warning naming ``label``) when this
    OpenCV build cannot write or read it. Odd sizes are padded by repeating the last row or
    column: MPEG-4 and VP9 both code even sizes only (VP9 would drop the odd row and column)."""
    try:
        import cv2
    except ImportError:  # pragma: no cover - opencv is a dependency
        warnings.warn(f"OpenCV is not available; no {label} written", RuntimeWarning,
                      stacklevel=3)
        return None
    H, W = frames[0].shape[:2]
    He, We = H + (H % 2), W + (W % 2)
    try:
        with atomic_path(path) as tmp:
            with _opencv_tag_notice_held_back():
                vw = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*fourcc), float(fps),
                                     (We, He))
            if not vw.isOpened():
                raise RuntimeError(f"cv2.VideoWriter could not open {article} '{fourcc}' stream")
            try:
                for f in frames:
                    if (He, We) != (H, W):
                        f = np.pad(f, ((0, He - H), (0, We - W), (0, 0)), mode="edge")
                    vw.write(np.ascontiguousarray(f[..., ::-1]))
            finally:
                vw.release()
            cap = cv2.VideoCapture(str(tmp))
            try:
                ok, _ = cap.read()
            finally:
                cap.release()
            if not ok or os.path.getsize(tmp) == 0:
                raise RuntimeError(f"the written {label} cannot be read back")
    except RuntimeError as exc:
        warnings.warn(f"no {label} written: {exc} (this OpenCV build lacks {article} {codec} "
                      "encoder?)", RuntimeWarning, stacklevel=3)
        return None
    return path


def focal_sweep(views_or_cube, offsets=None, disparities=None, profile="CIE 1931",
                *, out_dir=None, fps: float = 8,
                formats: Sequence[str] = ("gif", "mp4", "webm"),
                wavelengths=None, output: str = "srgb", exposure="percentile",
                exposure_percentile: float = 99.5, annotate: bool = True,
                stem: str = "refocus", bit_depth: int = 8, progress: bool = False,
                **kwargs) -> dict[str, Any]:
    """Focal sweep: refocused frames at ``disparities`` as PNGs, a GIF, an MP4 and a WebM.

    Parameters
    ----------
    views_or_cube, offsets, profile, wavelengths :
        As in :func:`refocus` (other :func:`refocus` keywords pass through ``kwargs``).
    disparities : array_like (n,)
        Focus disparities, one frame each.
    out_dir : path-like
        Folder for ``{stem}_{i:03d}.png``, ``{stem}_frames.csv`` (each frame's disparity),
        ``{stem}.gif``, ``{stem}.mp4`` and ``{stem}.webm``.
    fps : float
        Frames per second of the animations.
    formats : subset of ("gif", "mp4", "webm")
        Animations to write; PNG frames are always written. The GIF plays everywhere (in 256
        colours); the MP4 (OpenCV's 'mp4v', MPEG-4 part 2) is for desktop players (browsers
        do not play it); the WebM (VP9) is for browsers, a web page's ``<video>``. (H.264
        would serve both, but OpenCV's wheels have no H.264 writer.) Each video is checked by
        reading it back; when the OpenCV build cannot write or read one, a RuntimeWarning
        names it and its entry is None. The videos pad an odd frame size to an even one.
    output : {"srgb", "camera"}
        Frames are displayed, so sRGB by default (camera RGB is only clipped).
    exposure : default "percentile"
        One scale for all frames (no flicker).
    annotate : bool
        Print ``d = ...`` in the corner of the GIF / MP4 / WebM frames (PNG frames stay clean).
    bit_depth : {8, 16}
        Of the PNG frames.

    Returns
    -------
    dict
        ``{"frames": [Path, ...], "gif": Path or None, "mp4": Path or None,
        "webm": Path or None, "disparities": ndarray, "table": Path}``.

    Examples
    --------
    A one-band cube of a random texture at disparity 2 (each view is the texture shifted by
    2 px per baseline): the frame focused at 2 lines the nine views up and is by far the
    sharpest; the others average misaligned texture into grey.

    >>> import tempfile
    >>> from hyperlf.formats import read_image
    >>> tex = np.random.default_rng(0).random((40, 48))
    >>> cube = np.array([[tex[6 + 2 * r:30 + 2 * r, 6 + 2 * c:38 + 2 * c][None]
    ...                   for c in range(3)] for r in range(3)])  # (3, 3, 1, 24, 32)
    >>> out = focal_sweep(cube, disparities=[0, 1, 2, 3], profile=550.0, wavelengths=[550.0],
    ...                   out_dir=tempfile.mkdtemp(), formats=["gif"])
    >>> [p.name for p in out["frames"]][:2], out["gif"].name, out["mp4"]
    (['refocus_000.png', 'refocus_001.png'], 'refocus.gif', None)
    >>> sharpness = [float(read_image(p).std()) for p in out["frames"]]
    >>> float(out["disparities"][int(np.argmax(sharpness))])
    2.0
    """
    if out_dir is None:
        raise InvalidInputError("focal_sweep needs out_dir, the folder to write the frames to")
    if disparities is None:
        raise InvalidInputError("focal_sweep needs disparities (n,)")
    ds = np.atleast_1d(_opt.real_array(disparities, "disparities"))
    if ds.ndim != 1 or ds.size == 0 or not np.all(np.isfinite(ds)):
        raise InvalidInputError(f"disparities must be a non-empty 1-D finite array, got {ds!r}")
    _checked(fps=fps, output=output, exposure_percentile=exposure_percentile,
             annotate=annotate, bit_depth=bit_depth, progress=progress)
    if not isinstance(stem, str) or not stem or os.sep in stem or "/" in stem:
        raise InvalidInputError("stem must be a file name without a folder, e.g. 'refocus', "
                                f"got {_opt.shown(stem)}")  # the frames go into out_dir
    fmts = _animation_formats(formats)
    if _all_bands(profile):
        raise InvalidInputError("a focal sweep needs an image profile (a camera, a band or "
                                "weights), not all bands")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    frames = focal_stack(views_or_cube, offsets, list(ds), profile, wavelengths=wavelengths,
                         output=output, exposure=exposure,
                         exposure_percentile=exposure_percentile, progress=progress, **kwargs)
    paths, table = _write_frames(out, stem, frames, ds, bit_depth)
    u8 = [_to_uint8_rgb(f) for f in frames]
    if annotate:
        u8 = [_annotate(f, f"d = {d:+.2f}") for f, d in zip(u8, ds)]
    result: dict[str, Any] = {"frames": paths, "gif": None, "mp4": None, "webm": None,
                              "disparities": ds, "table": table}
    if "gif" in fmts:
        result["gif"] = _write_gif(out / f"{stem}.gif", u8, fps)
    for fmt, codec in _VIDEOS.items():
        if fmt in fmts:
            result[fmt] = _write_video(out / f"{stem}.{fmt}", u8, fps, *codec)
    return result


def _animation_formats(formats) -> list[str]:
    """``formats`` as lower-case names among ``gif``, ``mp4`` and ``webm``."""
    if isinstance(formats, str):
        formats = (formats,)
    if not isinstance(formats, Iterable) or isinstance(formats, dict):
        raise InvalidInputError(f"formats must be a sequence of 'gif', 'mp4' and 'webm', got "
                                f"{_opt.shown(formats)}")
    fmts = [str(f).lower().lstrip(".") for f in formats]
    for f in fmts:
        if f != "gif" and f not in _VIDEOS:
            raise InvalidInputError(f"unknown animation format {f!r}; use any of 'gif', 'mp4' "
                                    "and 'webm'")
    return fmts


def _write_frames(out: Path, stem: str, frames: list, ds: np.ndarray, bit_depth: int):
    """The frames as PNGs and a table of the disparity each is focused at: their paths."""
    from .formats.images import write_image

    paths = [write_image(out / f"{stem}_{i:03d}.png", np.nan_to_num(f), bit_depth=bit_depth)
             for i, f in enumerate(frames)]
    table = out / f"{stem}_frames.csv"
    atomic_write_text(table, "frame,file,disparity\n" + "".join(
        f"{i},{q.name},{d:.6g}\n" for i, (q, d) in enumerate(zip(paths, ds))))
    return paths, table


# ============================================================================ spectra

def spectrum_at(cube, wavelengths=None, x=None, y=None, view=None) -> np.ndarray:
    """Spectral profile of a cube at a pixel (bilinear for non-integer ``x, y``).

    Parameters
    ----------
    cube : array_like (B, H, W) or (R, C, B, H, W), h5py dataset, or CubeFile
    wavelengths : array_like (B,), optional
        Only checked against the band count (from a CubeFile when omitted); all NaN when
        unknown (:func:`hyperlf.spectral.wavelengths_unknown`).
    x, y : float or array_like (n,)
        Column and row in pixels.
    view : (int, int), optional
        View of a 5-D cube; default the reference ``((R-1)//2, (C-1)//2)``.

    Returns
    -------
    ndarray of float64, shape (B,) or (n, B)
        NaN where the point lies outside the image.

    Examples
    --------
    Band ``b`` of this cube holds ``10 b + x``, so halfway between columns 2 and 3 the
    profile is ``10 b + 2.5``; column 5 is beyond the 5-pixel-wide image.

    >>> cube = np.zeros((3, 4, 5)) + 10 * np.arange(3)[:, None, None] + np.arange(5)
    >>> spectrum_at(cube, [450, 550, 650], x=2.5, y=1).tolist()
    [2.5, 12.5, 22.5]
    >>> spectrum_at(cube, x=[4, 5], y=[0, 0]).tolist()
    [[4.0, 14.0, 24.0], [nan, nan, nan]]

    At a whole pixel of a view of a plenoptic cube it is that pixel's bands:

    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> s = spectrum_at(lf.gt_cube, lf.cube_wavelengths, x=7, y=5, view=(0, 2))
    >>> bool(np.array_equal(s, lf.gt_cube[0, 2, :, 5, 7]))
    True
    """
    if _is_cubefile(cube):
        data = cube.cube
        if wavelengths is None:
            wavelengths = cube.wavelengths
    else:
        data = cube if _is_h5_dataset(cube) else np.asarray(cube)
    if x is None or y is None:
        raise InvalidInputError("spectrum_at needs x and y (pixels)")
    shape = tuple(int(s) for s in data.shape)
    if len(shape) == 5:
        R, C = shape[:2]
        lead = centre_view(R, C) if view is None else _opt.index(view, "view", (R, C))
    elif len(shape) == 3:
        lead = ()
    else:
        raise InvalidInputError(f"cube must be (B, H, W) or (R, C, B, H, W), got shape {shape}")
    B, H, W = shape[-3:]
    if wavelengths is not None and (np.size(wavelengths) if spectral.wavelengths_unknown(
            wavelengths) else spectral.as_wavelengths(wavelengths).size) != B:
        raise InvalidInputError(f"the cube has {B} bands but {np.size(wavelengths)} wavelengths")
    xs = np.atleast_1d(_opt.real_array(x, "x"))
    ys = np.atleast_1d(_opt.real_array(y, "y"))
    if xs.shape != ys.shape or xs.ndim != 1:
        raise InvalidInputError("x and y must be scalars or 1-D arrays of the same length")
    if not (np.isfinite(xs).all() and np.isfinite(ys).all()):
        raise InvalidInputError(f"x and y must be finite pixel positions, got x={_opt.shown(x)}, "
                                f"y={_opt.shown(y)}")
    out = np.full((xs.size, B), np.nan)
    tx0, _, _, vx = coordinate_taps(xs, W)
    ty0, _, _, vy = coordinate_taps(ys, H)
    for i, (px, py) in enumerate(zip(xs, ys)):
        if not (vx[i] and vy[i]):
            continue
        x0, y0 = int(tx0[i]), int(ty0[i])
        x1, y1 = min(x0 + 2, W), min(y0 + 2, H)
        patch = np.asarray(data[lead + (slice(None), slice(y0, y1), slice(x0, x1))],
                           dtype=np.float64)  # (B, <=2, <=2)
        img = np.moveaxis(patch, 0, -1)
        v, _ = sample_bilinear(img, np.array(px - x0), np.array(py - y0))
        out[i] = v
    return out[0] if np.ndim(x) == 0 and np.ndim(y) == 0 else out


def save_spectrum_figure(path, cube, wavelengths=None, *, points: Sequence[tuple[float, float]] = (),
                         view=None, labels: Sequence[str] | None = None,
                         title: str = "spectral profiles",
                         ylabel: str = "relative intensity") -> Path:
    """Plot the spectral profiles of scene points (paper Fig. "H-LF reconstruction" (e)).

    Parameters
    ----------
    path : path-like
        PNG (or any Matplotlib format) written atomically.
    cube, wavelengths, view : as in :func:`spectrum_at`
    points : sequence of (x, y)
    labels : sequence of str, optional
        Default ``"(x, y)"``.

    Returns
    -------
    Path

    Examples
    --------
    >>> import tempfile
    >>> from hyperlf import synthesis
    >>> from hyperlf.formats import read_image
    >>> lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    >>> png = save_spectrum_figure(tempfile.mkdtemp() + "/spectra.png", lf.gt_cube,
    ...                            lf.cube_wavelengths, points=[(7, 5), (20, 12)])
    >>> png.name, png.read_bytes()[1:4]  # the PNG signature
    ('spectra.png', b'PNG')
    >>> picture = read_image(png)
    >>> picture.ndim, bool(picture.shape[1] > picture.shape[0])  # colour, wider than tall
    (3, True)
    """
    from . import visualise

    pts = _opt.real_array(points, "points")
    if pts.ndim != 2 or pts.shape[1] != 2 or not pts.size:
        raise InvalidInputError(f"points must be a non-empty sequence of (x, y), got "
                                f"{_opt.shown(points)}")
    if wavelengths is None and _is_cubefile(cube):
        wavelengths = cube.wavelengths
    if wavelengths is None:
        raise InvalidInputError("wavelengths (B,) are required")
    spectra = spectrum_at(cube, wavelengths, pts[:, 0], pts[:, 1], view=view)
    if labels is None:
        labels = [f"({x:g}, {y:g})" for x, y in pts]
    elif isinstance(labels, (str, dict)) or not isinstance(labels, Iterable):
        raise InvalidInputError(f"labels must be a sequence of texts, one per point, got "
                                f"{_opt.shown(labels)}")
    elif len(labels := [str(t) for t in labels]) != len(pts):
        raise InvalidInputError(f"{len(labels)} labels for {len(pts)} points")
    return visualise.save_spectrum_plot(path, np.asarray(wavelengths, dtype=np.float64), spectra,
                                        labels=list(labels), title=title, ylabel=ylabel)
