"""Apply a calibration to raw images: registered/rectified views and per-view validity masks.

A pixel of a registered view is valid when it samples the camera's image inside its borders
(bilinear taps all inside) and no tap it weighs is NaN or, when a saturation level is given,
saturated. Invalid pixels are set to 0 in the views, and the masks say which they are, so
that every cost can leave them out instead of matching black (SPEC §11).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .. import _options as _opt
from ..errors import InvalidInputError
from .board import camera_label, check_key
from .model import Calibration, check_calibration

__all__ = ["view_maps", "apply_calibration", "check_fits"]


def check_saturation(value, *, positive: bool = False) -> float | None:
    """A saturation level: None, or a finite number within float32's range (raw images are
    compared with it as float32), ``> 0`` where ``positive``."""
    if value is None:
        return None
    top = float(np.finfo(np.float32).max)
    if positive:
        return _opt.number(value, "saturation", positive=True, at_most=top)
    value = _opt.real(value, "saturation")
    if abs(value) > top:
        raise InvalidInputError(f"saturation must be within float32's range, got {value:g}")
    return value


def view_maps(calibration: Calibration, key) -> tuple[np.ndarray, np.ndarray]:
    """Raw-image coordinates ``(map_x, map_y)`` (float32, output size) sampled by view ``key``.

    Plane mode: the inverse of the camera's homography; full mode: OpenCV's undistort-rectify
    map with the camera's intrinsics, distortion and rectifying rotation and the shared
    rectified camera matrix.

    Examples
    --------
    A hand-made plane calibration of two cameras: the second camera's homography moves its
    image 2 px to the right, so its view samples the raw image 2 px to the left:

    >>> from hyperlf.calibration.board import BoardSpec
    >>> from hyperlf.calibration.model import Calibration, CameraCalibration
    >>> shift = np.array([[1.0, 0.0, 2.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    >>> cams = {(0, 0): CameraCalibration("left.png", np.zeros(2), 0.0, homography=np.eye(3)),
    ...         (0, 1): CameraCalibration("right.png", np.array([1.0, 0.0]), 0.0,
    ...                                   homography=shift)}
    >>> cal = Calibration(mode="plane", grid=(1, 2), reference=(0, 0), image_size=(6, 4),
    ...                   output_size=(6, 4), camera_matrix=np.diag([100.0, 100.0, 1.0]),
    ...                   cameras=cams, board=BoardSpec(4, 3, 20.0), baseline=40.0,
    ...                   board_plane=np.array([0.0, 0.0, 1.0, 500.0]))
    >>> map_x, map_y = view_maps(cal, (0, 1))
    >>> map_x.dtype, map_x.shape
    (dtype('float32'), (4, 6))
    >>> map_x[0].tolist(), map_y[:, 0].tolist()
    ([-2.0, -1.0, 0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 3.0])
    """
    import cv2

    check_calibration(calibration)
    check_key(key)
    cam = calibration.cameras.get(key) if isinstance(key, tuple) else None
    if cam is None:
        raise InvalidInputError(f"no camera {_opt.shown(key)} in the calibration; its cameras "
                                f"are (row, col) in a {calibration.grid[0]} x "
                                f"{calibration.grid[1]} grid")
    W, H = calibration.output_size
    if calibration.mode == "plane":
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
        pts = np.stack([xx, yy, np.ones_like(xx)], -1) @ np.linalg.inv(cam.homography).T
        with np.errstate(divide="ignore", invalid="ignore"):
            mx, my = pts[..., 0] / pts[..., 2], pts[..., 1] / pts[..., 2]
        bad = ~(np.isfinite(mx) & np.isfinite(my))
        mx[bad], my[bad] = -1e6, -1e6
        return mx.astype(np.float32), my.astype(np.float32)
    return cv2.initUndistortRectifyMap(cam.K, cam.dist, cam.rectify, calibration.camera_matrix,
                                       (W, H), cv2.CV_32FC1)


def check_fits(calibration: Calibration, images: Mapping, names: Mapping | None = None) -> None:
    """Raise InvalidInputError unless ``images`` has one grey image of the calibrated size for
    every camera of the calibration's grid.

    Examples
    --------
    >>> from hyperlf.calibration.board import BoardSpec
    >>> from hyperlf.calibration.model import Calibration, CameraCalibration
    >>> cams = {(0, c): CameraCalibration(f"Cam-{c}.png", np.array([float(c), 0.0]), 0.0,
    ...                                   homography=np.eye(3)) for c in range(2)}
    >>> cal = Calibration(mode="plane", grid=(1, 2), reference=(0, 0), image_size=(6, 4),
    ...                   output_size=(6, 4), camera_matrix=np.diag([100.0, 100.0, 1.0]),
    ...                   cameras=cams, board=BoardSpec(4, 3, 20.0), baseline=40.0,
    ...                   board_plane=np.array([0.0, 0.0, 1.0, 500.0]))
    >>> check_fits(cal, {(0, 0): np.zeros((4, 6)), (0, 1): np.zeros((4, 6))})   # fits: None
    >>> check_fits(cal, {(0, 0): np.zeros((4, 6))})
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: the images do not fit the calibration (1 x 2 cameras): ...
    >>> check_fits(cal, {(0, 0): np.zeros((4, 6)), (0, 1): np.zeros((3, 6))})
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: camera (0, 1): image is (6, 3) (W x H, channels last) but ...
    """
    want = set(check_calibration(calibration).cameras)
    got = set(_opt.mapping(images, "images", optional=False))
    _opt.mapping(names, "names")
    if want != got:
        extra = sorted(got - want, key=str)
        miss = sorted(want - got)
        raise InvalidInputError(
            f"the images do not fit the calibration ({calibration.grid[0]} x "
            f"{calibration.grid[1]} cameras): missing {[camera_label(k) for k in miss]}, "
            f"unknown {[camera_label(k) for k in extra] if extra else []}")
    for key, img in images.items():
        check_image_size(calibration, key, img, names)


def check_image_size(calibration: Calibration, key, img, names: Mapping | None = None) -> None:
    """Raise InvalidInputError unless ``img``, camera ``key``'s, is a grey image of the size
    the calibration was made for."""
    W, H = calibration.image_size
    a = _opt.real_array(img, f"the image of camera {camera_label(key, names)}", None)
    if a.shape != (H, W) or not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
        raise InvalidInputError(
            f"camera {camera_label(key, names)}: image is {a.shape[::-1]} (W x H, channels "
            f"last) but the calibration was made for {W} x {H} grey images; use the "
            "calibration of this array and resolution")


def apply_calibration(calibration: Calibration, images: Mapping, *, names=None,
                      saturation: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Registered (plane mode) or rectified (full mode) views and their validity masks.

    Parameters
    ----------
    calibration : Calibration
    images : mapping (row, col) -> ndarray (H, W)
        Raw grey images of every camera, the size the calibration was made for.
    names : mapping, optional
        Camera names for messages.
    saturation : float, optional
        Raw value at or above which a pixel is saturated (invalid).

    Returns
    -------
    views : ndarray of float32, shape (R, C, H', W')
        Resampled bilinearly, in the raw images' units; 0 where invalid.
    valid : ndarray of bool, shape (R, C, H', W')

    Raises
    ------
    InvalidInputError
        The images do not fit the calibration (cameras or size).

    Examples
    --------
    Register a small synthetic 1 x 3 rig from one board shot, then warp that shot:

    >>> from hyperlf.calibration.board import detect_board
    >>> from hyperlf.calibration.plane import register_plane
    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 3, seed=3, imperfect=0.3, image_size=(160, 120), focal=150.0)
    >>> pose = rig.board_pose(450.0, tilt=(10.0, -8.0, 3.0))
    >>> shots = rig.render(pose, supersample=2)
    >>> cal = register_plane(shots, rig.board)
    >>> views, valid = apply_calibration(cal, shots)
    >>> views.shape, valid.dtype, cal.reference
    ((1, 3, 120, 160), dtype('bool'), (0, 1))
    >>> bool(valid[0, 1].all())         # the reference view is its raw image
    True

    Registered at the board plane, the board's corners lie in every view where the reference
    camera truly sees them (within half a pixel on average):

    >>> truth = rig.project(cal.reference, pose.corners_world(rig.board))
    >>> [bool(np.linalg.norm(detect_board(views[k], rig.board) - truth, axis=1).mean() < 0.5)
    ...  for k in sorted(cal.cameras)]
    [True, True, True]
    """
    import cv2

    check_fits(calibration, images, names)
    saturation = check_saturation(saturation)
    R, C = calibration.grid
    W, H = calibration.output_size
    views = np.zeros((R, C, H, W), np.float32)
    valid = np.zeros((R, C, H, W), bool)
    for (r, c) in calibration.cameras:
        src = np.asarray(images[(r, c)], np.float32)
        mx, my = view_maps(calibration, (r, c))
        Hs, Ws = src.shape
        inside = (mx >= 0) & (mx <= Ws - 1) & (my >= 0) & (my <= Hs - 1)
        bad = ~np.isfinite(src)  # NaN marks a pixel invalid (ingest: saturated, dark, flat)
        if saturation is not None:
            bad |= src >= saturation
        if bad.any():
            # the mask is warped like the image, so a bad tap of zero weight (a sample on a
            # pixel's own row or column) leaves the sample valid; a NaN warped with the image
            # made its neighbours above and to the left invalid too (0 * NaN)
            src = np.where(bad, np.float32(0.0), src)
            inside &= cv2.remap(bad.astype(np.float32), mx, my, cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_REPLICATE) <= 0
        out = cv2.remap(src, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        inside &= np.isfinite(out)
        views[r, c] = np.where(inside, out, 0.0)
        valid[r, c] = inside
    return views, valid
