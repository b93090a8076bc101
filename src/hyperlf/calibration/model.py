"""The calibration of a camera array: what :mod:`hyperlf.calibration` computes and stores.

Two modes (SPEC §11):

* ``"plane"`` (one board pose): every camera has a homography that maps its raw image onto the
  reference view's image at the board plane. Disparity is relative to the board:
  ``d_rel = f B (1/Z - 1/Z_board)`` px per baseline, positive for points nearer than the board.
* ``"full"`` (several poses): every camera has intrinsics, distortion and a pose relative to the
  reference camera, and a rotation onto one rectified image plane parallel to the array, shared
  by all cameras with the camera matrix ``camera_matrix``; ``d = f B / Z``.

In both, a reference pixel ``(x, y)`` with disparity ``d`` appears in the registered/rectified
view ``v`` at ``(x - d (px_v - px_ref), y - d (py_v - py_ref))`` (SPEC §1): positions are the
camera centres in the registered frame's axes (``x`` right, ``y`` down) in baselines, offset so
that the reference sits at its grid place ``(col, row)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .board import BoardSpec

__all__ = ["CameraCalibration", "Calibration", "MODES"]

MODES = ("plane", "full")


def _finite_array(value, label: str, shape, optional: bool = False) -> None:
    """Refuse ``value`` unless it is a finite real array of ``shape`` (or None where
    ``optional``)."""
    from .._options import array

    if not (value is None and optional):
        array(value, label, shape, finite=True)


def check_calibration(value) -> "Calibration":
    """``value`` when it is a :class:`Calibration` (the one check of a calibration argument)."""
    from .._options import instance

    return instance(value, "calibration", Calibration, "a Calibration (read_calibration reads one)")


@dataclass
class CameraCalibration:
    """One camera of a calibrated array.

    Attributes
    ----------
    name : str
        The user's name of the camera (a file name, say).
    position : ndarray, shape (2,)
        ``(px, py)`` in baselines, derived from the images.
    reprojection_error : float
        RMS corner residual in px (plane mode: board corners mapped by the homography onto the
        reference's corners; full mode: Zhang's reprojection error).
    homography : ndarray (3, 3) or None
        Plane mode: raw pixel -> registered pixel.
    K, dist : ndarray or None
        Full mode: intrinsic matrix and OpenCV distortion ``(k1, k2, p1, p2, k3)``.
    R, t : ndarray or None
        Full mode: ``X_cam = R X_ref + t`` (the reference camera's frame, board units).
    rectify : ndarray (3, 3) or None
        Full mode: rotation from this camera's frame onto the rectified frame.
    """

    name: str
    position: np.ndarray
    reprojection_error: float
    homography: np.ndarray | None = None
    K: np.ndarray | None = None
    dist: np.ndarray | None = None
    R: np.ndarray | None = None
    t: np.ndarray | None = None
    rectify: np.ndarray | None = None

    def __post_init__(self):
        from .. import _options as _opt

        _opt.text(self.name, "name")
        _finite_array(self.position, "position", (2,))
        _opt.number(self.reprojection_error, "reprojection_error")
        for name, shape in (("homography", (3, 3)), ("K", (3, 3)), ("dist", (5,)),
                            ("R", (3, 3)), ("t", (3,)), ("rectify", (3, 3))):
            _finite_array(getattr(self, name), name, shape, optional=True)


@dataclass
class Calibration:
    """A calibrated (or plane-registered) camera array; see the module notes.

    Attributes
    ----------
    mode : {"plane", "full"}
    grid : (int, int)
        ``(R, C)`` of the user's grid of camera names.
    reference : (int, int)
    image_size : (int, int)
        ``(W, H)`` of the raw images.
    output_size : (int, int)
        ``(W, H)`` of the registered/rectified views.
    camera_matrix : ndarray (3, 3)
        Intrinsics of the registered/rectified frame (plane mode: an estimate of the reference
        camera's, principal point at the image centre).
    cameras : dict (row, col) -> CameraCalibration
    board : BoardSpec
    baseline : float
        One baseline in the board's units (plane mode: estimated from the board pose).
    board_plane : ndarray (4,) or None
        Plane mode: ``(nx, ny, nz, dist)`` of the board in the reference camera's frame
        (``n . X = dist``), board units; gives ``Z_board`` per pixel for metric depth.
    info : dict
        Diagnostics (where positions came from, parallax statistics, ...).
    residuals : dict (row, col) -> (points (N, 2), vectors (N, 2))
        Corner residuals in px of the calibration run (not stored in the file): plane mode,
        the mapped corners minus the reference's; full mode, reprojected minus detected.
    corners : dict (row, col) -> ndarray (N, 2) or None
        The board corners detected in each camera's first shot (None where the board was not
        found in it), for pictures; not stored in the file.
    """

    mode: str
    grid: tuple[int, int]
    reference: tuple[int, int]
    image_size: tuple[int, int]
    output_size: tuple[int, int]
    camera_matrix: np.ndarray
    cameras: dict
    board: BoardSpec
    baseline: float
    board_plane: np.ndarray | None = None
    info: dict[str, Any] = field(default_factory=dict)
    residuals: dict = field(default_factory=dict, repr=False)
    corners: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        from .. import _options as _opt
        from ..errors import InvalidInputError
        from .board import check_board

        _opt.choice(self.mode, "mode", MODES)
        grid = _opt.int_pair(self.grid, "grid", 1, what="(rows, cols)")
        _opt.index(self.reference, "reference", grid)
        for name in ("image_size", "output_size"):
            _opt.int_pair(getattr(self, name), name, 1, what="(W, H) px")
        _finite_array(self.camera_matrix, "camera_matrix", (3, 3))
        for name in ("cameras", "info", "residuals", "corners"):
            _opt.mapping(getattr(self, name), name, optional=False)
        if not all(isinstance(c, CameraCalibration) for c in self.cameras.values()):
            raise InvalidInputError("cameras must map (row, col) to CameraCalibration")
        check_board(self.board)
        _opt.number(self.baseline, "baseline", positive=True)
        _finite_array(self.board_plane, "board_plane", (4,), optional=True)

    @property
    def focal_px(self) -> float:
        """Focal length of the registered/rectified frame in px."""
        return float(self.camera_matrix[0, 0])

    def positions(self) -> np.ndarray:
        """Positions ``(R, C, 2)`` in baselines (SPEC §1 ``positions``)."""
        R, C = self.grid
        out = np.zeros((R, C, 2))
        for (r, c), cam in self.cameras.items():
            out[r, c] = cam.position
        return out

    def reprojection_errors(self) -> dict:
        """RMS corner residual in px of every camera, keyed ``(row, col)``."""
        return {k: cam.reprojection_error for k, cam in self.cameras.items()}

    def describe(self) -> str:
        """One line: mode, grid, frame, focal length, baseline and the reprojection errors."""
        errs = np.array([e for e in self.reprojection_errors().values() if e is not None],
                        dtype=np.float64)
        errs = errs[np.isfinite(errs)]
        W, H = self.output_size
        text = (f"calibration ({self.mode} mode), {self.grid[0]} x {self.grid[1]} cameras, "
                f"{W} x {H} px frame, focal {self.focal_px:.1f} px, baseline "
                f"{self.baseline:.4g} board units")
        if errs.size:
            text += (f", reprojection error median {np.median(errs):.3f} px "
                     f"(largest {errs.max():.3f})")
        return text

    def board_depth(self) -> np.ndarray | None:
        """Plane mode: the board's depth ``Z_board`` (board units) along every reference
        pixel's ray, ``(H, W)``; None in full mode."""
        if self.board_plane is None:
            return None
        W, H = self.output_size
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
        Kinv = np.linalg.inv(self.camera_matrix)
        rays = np.stack([xx, yy, np.ones_like(xx)], -1) @ Kinv.T
        n, dist = self.board_plane[:3], self.board_plane[3]
        with np.errstate(divide="ignore", invalid="ignore"):
            return dist / (rays @ n)
