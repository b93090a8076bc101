"""Calibration and registration of real camera arrays (SPEC §11, paper §7.1).

The one home of the geometry that turns raw images of a camera array into views hyperlf can
match:

* :func:`calibrate` picks the mode from the data: one board pose per camera ->
  :func:`register_plane` (homographies onto the reference view at the board plane, positions
  from the parallax of the scene around the board); several poses -> :func:`calibrate_full`
  (Zhang per camera, extrinsics relative to the reference, rectification onto one plane
  parallel to the array).
* :func:`write_calibration` / :func:`read_calibration`: the human-readable TOML file.
* :func:`apply_calibration`: raw images -> registered/rectified views and validity masks.
* :func:`save_corner_pictures`, :func:`save_registration_picture`,
  :func:`save_residual_picture`: pictures for users.
* :mod:`hyperlf.calibration.rig`: a synthetic, deliberately imperfect array with exact ground
  truth, for tests.

Positions follow SPEC §1: a reference pixel with disparity ``d`` appears in view ``v`` at
``x_ref - d (p_v - p_ref)``; they are derived from the images, never from a description of the
array's axes. Cameras are keyed by the user's ``(row, col)`` naming; the reference defaults to
the centre of that grid.
"""

from __future__ import annotations

import contextlib
from typing import Iterator, Mapping

import numpy as np

from .. import _options as _opt
from ..errors import InvalidInputError
from .apply import apply_calibration, check_fits, view_maps
from .board import BoardSpec, camera_label, check_board, detect_board, detect_boards
from .full import calibrate_full
from .io import read_calibration, write_calibration
from .model import Calibration, CameraCalibration
from .pictures import save_corner_pictures, save_registration_picture, save_residual_picture
from .plane import register_plane

__all__ = ["calibrate", "register_plane", "calibrate_full", "BoardSpec", "detect_board",
           "detect_boards", "Calibration", "CameraCalibration", "write_calibration",
           "read_calibration", "apply_calibration", "view_maps", "check_fits",
           "save_corner_pictures", "save_registration_picture", "save_residual_picture"]


def calibrate(shots: Mapping, board: BoardSpec, *, mode: str = "auto", reference=None,
              names=None, **options) -> Calibration:
    """Calibrate an array from board shots; the mode follows from the number of poses.

    Parameters
    ----------
    shots : mapping (row, col) -> ndarray (H, W) or sequence of ndarray
        One board shot per camera (plane registration) or a list of shots per camera, the same
        poses in the same order (full calibration when there are at least ``3``).
    board : BoardSpec
    mode : {"auto", "plane", "full"}
        ``auto``: ``full`` with three or more poses, else ``plane`` (with several poses,
        ``plane`` uses the first).
    reference : (int, int), optional
    names : mapping, optional
        Camera names for messages.
    **options
        Passed to :func:`register_plane` or :func:`calibrate_full`.

    Returns
    -------
    Calibration

    Examples
    --------
    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(seed=0, imperfect=0.3)
    >>> cal = calibrate(rig.render(rig.board_pose(450.0), supersample=2), rig.board)
    >>> cal.mode
    'plane'
    """
    _opt.choice(mode, "mode", ("auto", "plane", "full"))
    check_board(board)
    _opt.mapping(names, "names")
    per = {k: _shots_of(v, k, names) for k, v in _opt.mapping(shots, "shots",
                                                               optional=False).items()}
    n = min((len(v) for v in per.values()), default=0)
    with _reproducible_opencv():
        if mode == "full" or (mode == "auto" and n >= 3):
            options.pop("focal_px", None)  # a full calibration measures every camera's own
            return calibrate_full(per, board, reference=reference, names=names, **options)
        return register_plane({k: v[0] for k, v in per.items()}, board, reference=reference,
                              names=names, **options)


def _shots_of(value, key, names) -> list:
    """One camera's board shots as a list (one image, or a sequence of them)."""
    if isinstance(value, np.ndarray) and value.ndim == 2:
        return [value]
    if isinstance(value, (str, bytes, Mapping)) or not hasattr(value, "__iter__"):
        raise InvalidInputError(f"the board shots of camera {camera_label(key, names)} must be "
                                f"an image or a list of images, got {_opt.shown(value)}")
    return list(value)


@contextlib.contextmanager
def _reproducible_opencv() -> Iterator[None]:
    """Run OpenCV on one thread in the block.  With its parallel loops, the same board shots
    gave focal lengths differing in the fifth digit from run to run (and depth maps that
    differed by a few percent downstream); one thread makes a calibration reproducible bit
    for bit."""
    import cv2

    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(before)
