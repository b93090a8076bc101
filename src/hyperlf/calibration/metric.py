"""Metric depth and point clouds from the disparity of a calibrated capture (SPEC §11).

The geometry travels with a capture as a small table (:func:`capture_geometry`, stored in the
manifest's ``[calibration]`` table by ``hyperlf ingest``): the registered/rectified frame's
camera matrix, one baseline in the board's units, and for plane registration the board plane.

* Full calibration (rectified): ``d = f B / Z``, so ``Z = f B / d`` (``d > 0`` in front).
* Plane registration: disparity is relative to the board, ``d = f B (1/Z - 1/Z_board)`` with
  ``Z_board`` the board's depth along the pixel's ray, so ``Z = 1 / (d / (f B) + 1 / Z_board)``.

Depth is along the optical axis (``Z``), in the board's unit (the ``--square`` of calibration:
give it in mm for millimetres). Pixels whose depth would be negative or infinite are NaN.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .. import _options as _opt
from ..errors import InvalidInputError

__all__ = ["capture_geometry", "depth_from_disparity", "point_cloud"]


def capture_geometry(calibration) -> dict:
    """The table a capture keeps to turn its disparity into metric depth.

    Parameters
    ----------
    calibration : Calibration

    Returns
    -------
    dict
        ``mode``, ``camera_matrix`` (3 x 3 list), ``baseline`` (board units), ``unit`` (always
        ``"board square units"`` unless the calibration says otherwise) and, in plane mode,
        ``board_plane`` (``nx, ny, nz, dist``); ``focal_determined`` is False when the board pose
    did not fix the focal length (then no metric figure can be trusted: calibrate with
    ``--focal-px``).

    Examples
    --------
    A hand-made plane calibration whose board stands 500 units in front of the reference
    camera, square to its axis:

    >>> from hyperlf.calibration.board import BoardSpec
    >>> from hyperlf.calibration.model import Calibration, CameraCalibration
    >>> cams = {(0, c): CameraCalibration(f"Cam-{c}.png", np.array([float(c), 0.0]), 0.0,
    ...                                   homography=np.eye(3)) for c in range(2)}
    >>> K = np.array([[100.0, 0.0, 1.0], [0.0, 100.0, 1.0], [0.0, 0.0, 1.0]])
    >>> cal = Calibration(mode="plane", grid=(1, 2), reference=(0, 0), image_size=(3, 3),
    ...                   output_size=(3, 3), camera_matrix=K, cameras=cams,
    ...                   board=BoardSpec(4, 3, 20.0), baseline=40.0,
    ...                   board_plane=np.array([0.0, 0.0, 1.0, 500.0]))
    >>> g = capture_geometry(cal)
    >>> g["mode"], g["baseline"], g["board_plane"], g["unit"]
    ('plane', 40.0, [0.0, 0.0, 1.0, 500.0], 'board square units')

    Zero disparity is the board plane; a positive one is nearer:

    >>> depth_from_disparity(np.array([[0.0, 8.0]]), g).tolist()    # 1 / (8 / (f B) + 1 / 500)
    [[500.0, 250.0]]
    """
    from .model import check_calibration

    check_calibration(calibration)
    table = {"mode": calibration.mode,
             "camera_matrix": np.asarray(calibration.camera_matrix, float).tolist(),
             "baseline": float(calibration.baseline),
             "unit": str(calibration.info.get("unit", "board square units"))}
    if calibration.board_plane is not None:
        table["board_plane"] = np.asarray(calibration.board_plane, float).tolist()
    table["focal_determined"] = bool(calibration.info.get("focal_determined", True))
    return table


def _geometry(geometry: Mapping) -> tuple[np.ndarray, float, np.ndarray | None]:
    _opt.mapping(geometry, "geometry", optional=False)
    try:
        K = np.asarray(geometry["camera_matrix"], dtype=np.float64)
        B = float(geometry["baseline"])
        plane = geometry.get("board_plane")
        plane = None if plane is None else np.asarray(plane, dtype=np.float64)
    except (KeyError, TypeError, ValueError, OverflowError):
        raise InvalidInputError("the capture's [calibration] table lacks camera_matrix or "
                                "baseline; make the capture with 'hyperlf ingest'") from None
    if K.shape != (3, 3) or not np.isfinite(K).all() or not (K[0, 0] > 0 and K[1, 1] > 0) \
            or not np.isfinite(B) or not B > 0 or np.linalg.det(K) == 0:
        raise InvalidInputError("the capture's camera_matrix / baseline are not a valid "
                                "geometry (3 x 3 matrix with f > 0, baseline > 0)")
    if plane is not None and (plane.shape != (4,) or not np.isfinite(plane).all()):
        raise InvalidInputError("the capture's board_plane must be 4 finite numbers")
    return K, B, plane


def _rays(shape, K: np.ndarray) -> np.ndarray:
    """``K^-1 [x, y, 1]`` of every pixel, ``(H, W, 3)`` (z component 1)."""
    H, W = shape
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    return np.stack([xx, yy, np.ones_like(xx)], -1) @ np.linalg.inv(K).T


def _map(value, label: str) -> np.ndarray:
    """``value`` as a float64 map ``(H, W)`` (NaN allowed: pixels without a value)."""
    a = _opt.real_array(value, label)
    if a.ndim != 2:
        raise InvalidInputError(f"{label} must be a map (H, W), got shape {a.shape}")
    return a


def depth_from_disparity(disparity: np.ndarray, geometry: Mapping) -> np.ndarray:
    """Depth ``Z`` (board units) of every reference pixel from its disparity.

    Parameters
    ----------
    disparity : ndarray, shape (H, W)
        Px per baseline (SPEC §1 sign).
    geometry : mapping
        :func:`capture_geometry`'s table.

    Returns
    -------
    ndarray, float32, shape (H, W)
        NaN where the depth is not finite and positive.

    Examples
    --------
    >>> g = {"mode": "full", "camera_matrix": [[100, 0, 1], [0, 100, 1], [0, 0, 1]],
    ...      "baseline": 40.0}
    >>> float(depth_from_disparity(np.full((2, 2), 8.0), g)[0, 0])  # f B / d
    500.0
    """
    K, B, plane = _geometry(geometry)
    d = _map(disparity, "disparity")
    fB = K[0, 0] * B
    with np.errstate(divide="ignore", invalid="ignore"):
        if plane is None:
            Z = fB / d
        else:
            z_board = plane[3] / (_rays(d.shape, K) @ plane[:3])
            Z = 1.0 / (d / fB + 1.0 / z_board)
    Z[~(np.isfinite(Z) & (Z > 0))] = np.nan
    return Z.astype(np.float32)


def point_cloud(depth: np.ndarray, geometry: Mapping, colours: np.ndarray | None = None,
                *, step: int = 1) -> tuple[np.ndarray, np.ndarray | None]:
    """3-D points ``Z K^-1 [x, y, 1]`` of the pixels with a finite depth.

    Parameters
    ----------
    depth : ndarray, shape (H, W)
        From :func:`depth_from_disparity`.
    geometry : mapping
    colours : ndarray, shape (H, W, 3) or (H, W), optional
        Colours in [0, 1] (grey is repeated); returned as uint8 for the same points.
    step : int
        Keep every ``step``-th pixel in x and y (thinner clouds for previews).

    Returns
    -------
    points : ndarray, float32, shape (N, 3)
        In the reference camera's frame (x right, y down, z forward), board units.
    colours : ndarray, uint8, shape (N, 3) or None

    Examples
    --------
    A 3 x 3 depth map at 500 units, one pixel without a depth, and a grey colour:

    >>> g = {"mode": "full", "camera_matrix": [[100, 0, 1], [0, 100, 1], [0, 0, 1]],
    ...      "baseline": 40.0}
    >>> depth = np.full((3, 3), 500.0)
    >>> depth[2, 2] = np.nan
    >>> points, rgb = point_cloud(depth, g, colours=np.full((3, 3), 0.5))
    >>> points.shape, rgb.shape, rgb[0].tolist()
    ((8, 3), (8, 3), [128, 128, 128])
    >>> points[0].tolist(), points[4].tolist()     # pixel (0, 0); the principal point (1, 1)
    ([-5.0, -5.0, 500.0], [0.0, 0.0, 500.0])
    >>> point_cloud(depth, g, step=2)[0].shape     # pixels (0, 0), (2, 0) and (0, 2)
    (3, 3)
    """
    K, _, _ = _geometry(geometry)
    step = _opt.integer(step, "step", 1)
    Z = _map(depth, "depth")
    if colours is not None:
        col = _opt.real_array(colours, "colours")
        if col.shape not in (Z.shape, Z.shape + (3,)):
            raise InvalidInputError(f"colours must be (H, W) or (H, W, 3) like the depth "
                                    f"{Z.shape}, got shape {col.shape}")
    Z = Z[::step, ::step]
    rays = _rays(np.shape(depth), K)[::step, ::step]
    keep = np.isfinite(Z)
    pts = (rays[keep] * Z[keep][:, None]).astype(np.float32)
    if colours is None:
        return pts, None
    col = np.asarray(colours, dtype=np.float64)[::step, ::step]
    if col.ndim == 2:
        col = np.repeat(col[..., None], 3, axis=-1)
    rgb = np.clip(np.rint(np.nan_to_num(col[keep]) * 255.0), 0, 255).astype(np.uint8)
    return pts, rgb
