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

from .. import _options as _opt
from ..errors import InvalidInputError

__all__ = ["ingest", "correct_raw", "check_dead"]


def _per_camera(value, key, what: str):
    """A per-camera frame (mapping) or one frame for every camera."""
    if value is None:
        return None
    if isinstance(value, Mapping):
        if key not in value:
            raise InvalidInputError(f"{what}: no frame for camera {key[0]},{key[1]}")
        return _opt.real_array(value[key], what, np.float32)
    return _opt.real_array(value, what, np.float32)


def _frame(value, what: str, shape) -> np.ndarray | None:
    """``value`` (None, a number or an image of ``shape``) as float32, NaN allowed (pixels
    without a value), not infinite (nor beyond float32)."""
    if value is None:
        return None
    a = _opt.real_array(value, what, np.float32)
    if a.ndim and a.shape != shape:
        raise InvalidInputError(f"the {what} is {a.shape[::-1]} px (W x H), the raw images "
                                f"{shape[::-1]}; take it with the same camera settings")
    if np.isinf(a).any():
        raise InvalidInputError(f"the {what} must hold finite values (NaN marks pixels "
                                "without one)")
    return a


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
    out = _opt.real_array(image, "image", np.float32)
    if out.ndim != 2:
        raise InvalidInputError(f"image must be a raw grey image (H, W), got shape {out.shape}")
    _frame(out, "raw image", out.shape)
    dark, flat = _frame(dark, "dark frame", out.shape), _frame(flat, "flat field", out.shape)
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


def check_dead(calibration, dead) -> set:
    """The dead cameras as a set of (row, col), refused when they leave nothing to match.

    Raises
    ------
    InvalidInputError
        A camera outside the grid or the reference; fewer than two cameras alive.

    Examples
    --------
    >>> from hyperlf.calibration.board import BoardSpec
    >>> from hyperlf.calibration.model import Calibration, CameraCalibration
    >>> cams = {(0, c): CameraCalibration(f"Cam-{c}.png", np.array([float(c), 0.0]), 0.0,
    ...                                   homography=np.eye(3)) for c in range(3)}
    >>> cal = Calibration(mode="plane", grid=(1, 3), reference=(0, 1), image_size=(8, 6),
    ...                   output_size=(8, 6), camera_matrix=np.diag([100.0, 100.0, 1.0]),
    ...                   cameras=cams, board=BoardSpec(4, 3, 20.0), baseline=40.0,
    ...                   board_plane=np.array([0.0, 0.0, 1.0, 500.0]))
    >>> check_dead(cal, [[0, 2]])
    {(0, 2)}
    >>> check_dead(cal, [(0, 1)])
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: camera 0,1 is the calibration's reference and cannot...
    >>> check_dead(cal, [(0, 0), (0, 2)])
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: 2 of 3 cameras dead: at least two must work
    """
    from .model import check_calibration

    check_calibration(calibration)
    R, C = calibration.grid
    try:
        dead = {_opt.int_pair(k, "dead camera", None, what="(row, col)") for k in dead}
    except TypeError:
        raise InvalidInputError(f"dead must be (row, col) pairs, got {_opt.shown(dead)}") \
            from None
    for k in sorted(dead):
        if not (0 <= k[0] < R and 0 <= k[1] < C):
            raise InvalidInputError(f"dead camera {k[0]},{k[1]} is outside the {R} x {C} grid")
    ref = tuple(int(v) for v in calibration.reference)
    if ref in dead:
        raise InvalidInputError(
            f"camera {ref[0]},{ref[1]} is the calibration's reference and cannot be dead; "
            "calibrate again with --reference naming a working camera")
    if R * C - len(dead) < 2:
        raise InvalidInputError(f"{len(dead)} of {R * C} cameras dead: at least two must work")
    return dead


def _check_dead(calibration, dead, images) -> set:
    """:func:`check_dead`, and a raw image of the calibrated size for every live camera."""
    from .apply import check_image_size

    dead = check_dead(calibration, dead)
    missing = [k for k in calibration.cameras if k not in dead and k not in images]
    if missing:
        raise InvalidInputError(f"no raw image for camera {missing[0][0]},{missing[0][1]}; "
                                "give one per camera, or name it dead")
    for k in calibration.cameras:
        if k not in dead:
            check_image_size(calibration, k, images[k])
    return dead


def _no_signal(key, raw, corrected) -> str | None:
    """Why a live camera's image holds nothing to match (it is constant), or None."""
    raw = np.asarray(raw)
    where = f"camera {key[0]},{key[1]}"
    if float(np.ptp(raw)) == 0.0:
        return (f"{where}'s raw image is constant (every pixel {float(raw.flat[0]):.4g}): no "
                f"signal; if the camera is broken, name it with --dead {key[0]},{key[1]}")
    if float(np.ptp(corrected)) == 0.0:
        return (f"{where} holds no signal once the dark frame and flat field are applied "
                "(every pixel 0); check --dark: it must be taken with the lens capped")
    return None


def _check_reference_valid(calibration, valid, saturation) -> None:
    r, c = (int(v) for v in calibration.reference)
    if not valid[r, c].any():
        sat = "" if saturation is None else f" (saturated at {saturation:g} of full scale?)"
        raise InvalidInputError(
            f"the reference camera {r},{c}'s view has no valid pixel{sat}; check --saturation "
            "and the exposure")


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
        Cameras whose images are unusable: their views are entirely invalid, and their images
        need not be in ``images``. The reference camera cannot be dead, and at least two
        cameras must be alive.
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

    Raises
    ------
    InvalidInputError
        A dead camera outside the grid or the reference; fewer than two cameras alive; a live
        camera whose image is constant (no signal: a dead camera not named, or a dark frame
        that takes all of it); a reference view with no valid pixel.

    Examples
    --------
    A hand-made plane calibration of a 1 x 3 array whose homographies are the identity (the raw
    images are already registered); camera ``(0, 2)`` is dead and one pixel of camera ``(0, 0)``
    is saturated:

    >>> from hyperlf.calibration.board import BoardSpec
    >>> from hyperlf.calibration.model import Calibration, CameraCalibration
    >>> cams = {(0, c): CameraCalibration(f"Cam-{c}.png", np.array([float(c), 0.0]), 0.0,
    ...                                   homography=np.eye(3)) for c in range(3)}
    >>> cal = Calibration(mode="plane", grid=(1, 3), reference=(0, 1), image_size=(8, 6),
    ...                   output_size=(8, 6), camera_matrix=np.diag([100.0, 100.0, 1.0]),
    ...                   cameras=cams, board=BoardSpec(4, 3, 20.0), baseline=40.0,
    ...                   board_plane=np.array([0.0, 0.0, 1.0, 500.0]))
    >>> rng = np.random.default_rng(0)
    >>> images = {k: rng.uniform(0.1, 0.9, (6, 8)).astype(np.float32) for k in [(0, 0), (0, 1)]}
    >>> images[(0, 0)][2, 3] = 1.0
    >>> lf = ingest(images, cal, dead=[(0, 2)], disparity_range=(-2, 2),
    ...             wavelengths=[[450, 550, 650]])
    >>> lf.views.shape, lf.reference, lf.disparity_range, lf.positions[0, 2].tolist()
    ((1, 3, 6, 8), (0, 1), (-2.0, 2.0), [2.0, 0.0])
    >>> bool(np.array_equal(lf.views[0, 1], images[(0, 1)]))
    True
    >>> np.argwhere(~lf.valid[0, 0]).tolist()  # the saturated pixel alone
    [[2, 3]]
    >>> bool(lf.valid[0, 1].all()), bool(lf.valid[0, 2].any())
    (True, False)
    >>> lf.metadata["calibration"]["mode"], lf.metadata["calibration"]["baseline"]
    ('plane', 40.0)
    """
    from ..lightfield import LightField
    from . import apply_calibration
    from .apply import check_saturation
    from .metric import capture_geometry
    from .parallax import measured_disparity_range

    from ..lightfield import check_disparity_range

    _opt.mapping(images, "images", optional=False)
    dead = _check_dead(calibration, dead, images)
    saturation = check_saturation(saturation, positive=True)
    if disparity_range is not None:
        disparity_range = check_disparity_range(disparity_range)
    wl = _check_wavelengths(wavelengths, calibration.grid)
    for frame, what in ((dark, "dark"), (flat, "flat")):
        if frame is not None and not isinstance(frame, Mapping):
            _opt.real_array(frame, what)
    fixed = _corrected(images, dead, dark, flat, saturation)  # before the warp: no signal
    views, valid = apply_calibration(calibration, fixed)   # refuses images of another size
    for (r, c) in dead:
        valid[r, c] = False
        views[r, c] = 0.0
    _check_reference_valid(calibration, valid, saturation)
    rng = disparity_range if disparity_range is not None else \
        calibration.info.get("disparity_range")
    if rng is None:  # a full calibration (or positions from the board): measure the scene
        rng = measured_disparity_range(views, valid, calibration.positions(),
                                       calibration.reference)
    return LightField(views=views, wavelengths=wl, positions=calibration.positions(),
                      reference=tuple(calibration.reference),
                      disparity_range=None if rng is None else tuple(float(v) for v in rng),
                      metadata={"calibration": capture_geometry(calibration)}, valid=valid)


def _check_wavelengths(wavelengths, grid) -> np.ndarray | None:
    """One positive wavelength (nm) per camera, as the grid ``(R, C)``, or None."""
    if wavelengths is None:
        return None
    wl = _opt.real_array(wavelengths, "wavelengths")
    R, C = grid
    if wl.size != R * C or not np.isfinite(wl).all() or not (wl > 0).all():
        raise InvalidInputError(f"wavelengths must be {R * C} positive wavelengths (nm), "
                                f"one per camera ({R} x {C}), got {_opt.shown(wavelengths)}")
    return wl.reshape(R, C)


def _corrected(images, dead, dark, flat, saturation) -> dict:
    """Every live camera's image dark- and flat-corrected, saturated pixels NaN; zeros for
    the dead ones.  A live camera without signal is refused (the first one found), before
    anything is warped."""
    fixed, silent = {}, []
    for k, img in images.items():
        if k in dead:
            continue
        out = correct_raw(img, dark=_per_camera(dark, k, "dark frame"),
                          flat=_per_camera(flat, k, "flat field"))
        silent += [problem for problem in [_no_signal(k, img, out)] if problem]
        if saturation is not None:  # judged on the raw values; NaN makes the warp mark it
            out[np.asarray(img) >= saturation] = np.nan
        fixed[k] = out
    if silent:
        raise InvalidInputError(silent[0])
    shape = next(iter(fixed.values())).shape
    fixed.update({k: np.zeros(shape, np.float32) for k in dead})
    return fixed
