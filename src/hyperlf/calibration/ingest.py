"""Raw images of a calibrated array -> a registered (or rectified) light field (SPEC §11).

:func:`ingest` is what ``hyperlf ingest`` runs: dark frame and flat field on the raw images,
the calibration's warp into the common frame, per-view validity masks (outside the camera's
image, saturated, dead cameras), the view geometry from the calibration (positions, reference,
the capture's ``[calibration]`` table for metric depth) and, optionally, the filters'
wavelengths. The views keep their radiometry (no per-view gain): every matching cost divides a
view by its own mean anyway, and a gain would distort the spectra that completion recovers.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..errors import InvalidInputError

__all__ = ["ingest", "correct_raw"]


def _per_camera(value, key, what: str):
    """A per-camera frame (mapping) or one frame for every camera."""
    if value is None:
        return None
    if isinstance(value, Mapping):
        if key not in value:
            raise InvalidInputError(f"{what}: no frame for camera {key[0]},{key[1]}")
        return np.asarray(value[key], np.float32)
    return np.asarray(value, np.float32)


def correct_raw(image: np.ndarray, *, dark=None, flat=None) -> np.ndarray:
    """``(image - dark) / (flat / mean(flat))`` (each optional), clipped at 0.

    Parameters
    ----------
    image : ndarray (H, W)
    dark : ndarray (H, W) or float, optional
        Dark frame (same exposure, lens capped).
    flat : ndarray (H, W), optional
        Flat field (a uniform white target; the dark frame is subtracted from it too). Pixels
        where it is below 5 % of its mean are left unchanged.

    Examples
    --------
    >>> round(float(correct_raw(np.full((2, 2), 0.5), dark=0.1,
    ...                          flat=np.full((2, 2), 0.9))[0, 0]), 6)
    0.4
    """
    out = np.asarray(image, np.float32)
    for frame, what in ((dark, "dark frame"), (flat, "flat field")):
        if frame is not None and np.ndim(frame) and np.shape(frame) != out.shape:
            raise InvalidInputError(f"the {what} is {np.shape(frame)[::-1]} px (W x H), the "
                                    f"raw images {out.shape[::-1]}; take it with the same "
                                    "camera settings")
    if dark is not None:
        out = out - np.asarray(dark, np.float32)
    if flat is not None:
        f = np.asarray(flat, np.float32) - (0.0 if dark is None else np.asarray(dark, np.float32))
        m = float(np.mean(f))
        if not m > 0:
            raise InvalidInputError("the flat field has no positive signal")
        gain = f / m
        out = np.where(gain > 0.05, out / np.maximum(gain, 0.05), out)
    return np.maximum(out, 0.0).astype(np.float32)


def ingest(images: Mapping, calibration, *, wavelengths=None, dark=None, flat=None,
           dead: Sequence = (), saturation: float | None = 0.98,
           disparity_range=None):
    """A registered light field, with validity masks, from one raw image per camera.

    Parameters
    ----------
    images : mapping (row, col) -> ndarray (H, W)
        Raw grey images in [0, 1] (as :func:`hyperlf.calibration.raw.read_camera_images`
        returns them), the size the calibration was made for.
    calibration : Calibration
    wavelengths : array_like (R, C), optional
        Filter centre wavelengths in nm; unknown filters are common (cues that need them say
        so).
    dark, flat : ndarray or mapping (row, col) -> ndarray, optional
        Dark frame and flat field, one for all cameras or one per camera.
    dead : sequence of (row, col)
        Cameras whose images are unusable: their views are entirely invalid.
    saturation : float or None
        Raw value (in [0, 1]) at or above which a pixel is saturated and invalid.
    disparity_range : (float, float), optional
        Stored in the capture; default the calibration's estimate when it has one (plane
        registration with positions from parallax), else measured on these images
        (:func:`hyperlf.calibration.parallax.measured_disparity_range`; none when too few
        points match: ``hyperlf depth`` then asks for one).

    Returns
    -------
    LightField
        Views in the registered/rectified frame, ``valid`` masks, positions and reference
        from the calibration, ``metadata["calibration"]`` the geometry table of
        :func:`hyperlf.calibration.metric.capture_geometry`.
    """
    from ..lightfield import LightField
    from . import apply_calibration
    from .metric import capture_geometry
    from .parallax import measured_disparity_range

    R, C = calibration.grid
    dead = {tuple(int(v) for v in k) for k in dead}
    for k in dead:
        if not (0 <= k[0] < R and 0 <= k[1] < C):
            raise InvalidInputError(f"dead camera {k[0]},{k[1]} is outside the {R} x {C} grid")
    fixed = {}
    for k, img in images.items():
        out = correct_raw(img, dark=_per_camera(dark, k, "dark frame"),
                          flat=_per_camera(flat, k, "flat field"))
        if saturation is not None:  # judged on the raw values; NaN makes the warp mark it
            out[np.asarray(img) >= saturation] = np.nan
        fixed[k] = out
    views, valid = apply_calibration(calibration, fixed)
    for (r, c) in dead:
        valid[r, c] = False
        views[r, c] = 0.0
    wl = None if wavelengths is None else np.asarray(wavelengths, np.float64).reshape(R, C)
    rng = disparity_range if disparity_range is not None else \
        calibration.info.get("disparity_range")
    if rng is None:  # a full calibration (or positions from the board): measure the scene
        rng = measured_disparity_range(views, valid, calibration.positions(),
                                       calibration.reference)
    return LightField(views=views, wavelengths=wl, positions=calibration.positions(),
                      reference=tuple(calibration.reference),
                      disparity_range=None if rng is None else tuple(float(v) for v in rng),
                      metadata={"calibration": capture_geometry(calibration)}, valid=valid)
