"""Checkerboard detection that works in every band of a multispectral array (SPEC §11).

Each camera sees the board through its own filter: low contrast, vignetting, and in some bands
the dark squares reflect more than the light ones. :func:`detect_board` therefore detects on a
normalised image (percentile stretch, then CLAHE), tries OpenCV's sector-based detector first
and the classic detector with sub-pixel refinement second, each on the image and on its
inverse, and puts the corners in one canonical order so that corner ``i`` is the same physical
corner in every camera: rows run top to bottom of the image and every row runs left to right
(valid while the board is seen within 45 degrees of upright, as it is by every camera of an
array). A board partly out of view is not detected (every inner corner is required).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import InvalidInputError

__all__ = ["BoardSpec", "normalise_for_detection", "detect_board", "detect_boards",
           "canonical_order", "refine_corners", "camera_label"]


#: The most inner corners along one side of a checkerboard (OpenCV needs at least 3).
MAX_CORNERS = 200


@dataclass(frozen=True)
class BoardSpec:
    """A checkerboard: ``cols x rows`` inner corners, squares of side ``square`` (any unit:
    positions and baselines of a full calibration come out in it).

    Examples
    --------
    >>> BoardSpec(11, 8, 30.0).object_points()[1].tolist()
    [30.0, 0.0, 0.0]
    """

    cols: int
    rows: int
    square: float = 1.0

    def __post_init__(self):
        if not (3 <= int(self.cols) <= MAX_CORNERS and 3 <= int(self.rows) <= MAX_CORNERS):
            raise InvalidInputError(
                f"a board has 3 to {MAX_CORNERS} inner corners per side (a board of 12 x 9 "
                f"squares has 11 x 8), got {self.cols} x {self.rows}")
        if not (np.isfinite(self.square) and self.square > 0):
            raise InvalidInputError(f"board square size must be > 0, got {self.square}")

    @property
    def n_corners(self) -> int:
        return int(self.cols) * int(self.rows)

    def object_points(self) -> np.ndarray:
        """Board coordinates ``(N, 3)`` of the inner corners in canonical order (row-major,
        ``x`` along a row)."""
        j, i = np.mgrid[0:self.rows, 0:self.cols]
        return np.stack([i.ravel() * self.square, j.ravel() * self.square,
                         np.zeros(self.n_corners)], axis=1).astype(np.float64)


def camera_label(key, names: Mapping | None = None) -> str:
    """How a camera is named in messages: the user's name if given, else ``(row, col)``."""
    if names and key in names:
        return str(names[key])
    return f"({key[0]}, {key[1]})" if isinstance(key, tuple) else str(key)


def normalise_for_detection(image: np.ndarray, *, clahe: bool = True) -> np.ndarray:
    """An 8-bit image for corner detection: 0.5-99.5 percentile stretch, then CLAHE.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Any numeric grey image (raw 16-bit, float, ...).
    clahe : bool
        Apply contrast-limited adaptive histogram equalisation (evens out vignetting).

    Returns
    -------
    ndarray of uint8, shape (H, W)
    """
    import cv2

    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2:
        raise InvalidInputError(f"board shots must be grey images (H, W), got shape {img.shape}")
    finite = img[np.isfinite(img)]
    lo, hi = (np.percentile(finite, [0.5, 99.5]) if finite.size else (0.0, 1.0))
    if hi <= lo:
        hi = lo + 1.0
    out = np.clip((np.nan_to_num(img, nan=lo) - lo) / (hi - lo), 0, 1)
    out = (out * 255 + 0.5).astype(np.uint8)
    if clahe:
        tiles = max(2, min(8, min(img.shape) // 64))
        out = cv2.createCLAHE(clipLimit=2.0, tileGridSize=(tiles, tiles)).apply(out)
    return out


def canonical_order(corners: np.ndarray, cols: int, rows: int) -> np.ndarray:
    """Corners ``(N, 2)`` reordered so rows run down the image and each row runs right.

    A detector may start at any corner of the board and, for a square pattern, walk it
    transposed; this picks the one order that is the same for every upright camera.

    Examples
    --------
    >>> g = np.stack(np.meshgrid(np.arange(3.0), np.arange(2.0)), -1).reshape(-1, 2)
    >>> canonical_order(g[::-1], 3, 2)[0].tolist()
    [0.0, 0.0]
    """
    g = np.asarray(corners, np.float64).reshape(rows, cols, 2)
    cands = [g]
    if rows == cols:
        cands.append(g.transpose(1, 0, 2))
    best, score = None, -np.inf
    for c in cands:
        along = c[:, -1] - c[:, 0]          # along each row
        down = c[-1, :] - c[0, :]           # down each column
        if along[:, 0].mean() < 0:
            c = c[:, ::-1]
            along = -along
        if down[:, 1].mean() < 0:
            c = c[::-1]
            down = -down
        s = along[:, 0].mean() / (np.linalg.norm(along, axis=1).mean() + 1e-12)
        if s > score:
            best, score = c, s
    return np.ascontiguousarray(best.reshape(-1, 2))


def _detect_sb(img8: np.ndarray, size) -> np.ndarray | None:
    import cv2

    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    ok, c = cv2.findChessboardCornersSB(img8, size, flags=flags)
    return c.reshape(-1, 2) if ok else None


def _detect_classic(img8: np.ndarray, size) -> np.ndarray | None:
    import cv2

    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, c = cv2.findChessboardCorners(img8, size, flags=flags)
    if not ok:
        return None
    win = int(np.clip(min(img8.shape) // 80, 3, 11))
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 60, 1e-3)
    c = cv2.cornerSubPix(img8, c.astype(np.float32), (win, win), (-1, -1), crit)
    return c.reshape(-1, 2)


def _inside(corners: np.ndarray, shape, cols: int, rows: int) -> bool:
    """All corners at least 0.9 corner spacings inside the image: the board's outer squares
    must be whole, else the outer corners cannot be located (the board is partly out of
    view)."""
    H, W = shape
    g = corners.reshape(rows, cols, 2)
    m = 0.9 * float(np.median(np.linalg.norm(np.diff(g, axis=1), axis=-1)))
    return bool(np.all((corners[:, 0] >= m) & (corners[:, 0] <= W - 1 - m)
                       & (corners[:, 1] >= m) & (corners[:, 1] <= H - 1 - m)))


def detect_board(image: np.ndarray, board: BoardSpec, *,
                 detect_size: int = 800) -> np.ndarray | None:
    """Inner corners of ``board`` in ``image``, canonical order, or None when not found.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        A raw grey board shot (any dtype, any contrast sign).
    board : BoardSpec
    detect_size : int
        Larger images are searched at a scale whose larger side is this many px (the
        detectors' cost grows fast with size); the corners are then refined at full
        resolution.

    Returns
    -------
    ndarray of float64, shape (board.n_corners, 2), or None
        ``(x, y)`` pixel coordinates (pixel centres at integers).

    Examples
    --------
    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(seed=0)
    >>> shots = rig.render(rig.board_pose(450.0), supersample=2)
    >>> detect_board(shots[(0, 0)], rig.board).shape
    (48, 2)
    """
    import cv2

    img8 = normalise_for_detection(image)
    size = (int(board.cols), int(board.rows))
    scale = min(1.0, detect_size / max(img8.shape))
    small = img8 if scale == 1.0 else cv2.resize(img8, None, fx=scale, fy=scale,
                                                 interpolation=cv2.INTER_AREA)
    for detector in (_detect_sb, _detect_classic):
        for candidate in (small, 255 - small):
            c = detector(candidate, size)
            if (c is not None and c.shape[0] == board.n_corners
                    and _inside(c, small.shape, board.cols, board.rows)):
                c = canonical_order((c + 0.5) / scale - 0.5, board.cols, board.rows)
                return refine_corners(image, c, board)
    return None


def refine_corners(image: np.ndarray, corners: np.ndarray, board: BoardSpec) -> np.ndarray:
    """Saddle-point refinement (OpenCV ``cornerSubPix``) on the linear, percentile-stretched
    image (not the equalised one the detector saw, whose local remapping can bias corners),
    with a window of 0.45 times the local corner spacing. A corner that would move by more
    than a third of the spacing keeps its detected position."""
    import cv2

    img = np.asarray(image, np.float64)
    lo, hi = np.percentile(img, [0.5, 99.5])
    img = np.clip((img - lo) / max(hi - lo, 1e-12), 0, 1).astype(np.float32)
    g = corners.reshape(board.rows, board.cols, 2)
    spacing = float(np.median(np.linalg.norm(np.diff(g, axis=1), axis=-1)))
    win = max(2, int(round(0.45 * spacing)))
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    out = cv2.cornerSubPix(img, corners.astype(np.float32).reshape(-1, 1, 2).copy(), (win, win),
                           (-1, -1), crit).reshape(-1, 2).astype(np.float64)
    moved = np.linalg.norm(out - corners, axis=1) > spacing / 3
    out[moved] = corners[moved]
    return out


def detect_boards(images: Mapping, board: BoardSpec, *, names: Mapping | None = None,
                  what: str = "board shot") -> dict:
    """Corners in every camera's shot; one error naming every camera where it failed.

    Parameters
    ----------
    images : mapping key -> ndarray (H, W)
        One shot per camera (``key`` is usually ``(row, col)``).
    board : BoardSpec
    names : mapping key -> str, optional
        Names for messages (e.g. file names).
    what : str
        What the images are, for the message.

    Returns
    -------
    dict key -> ndarray (N, 2)

    Raises
    ------
    InvalidInputError
        The board was not found in at least one camera (all of them are named).
    """
    found, missing = {}, []
    for key, img in images.items():
        c = detect_board(img, board)
        if c is None:
            missing.append(camera_label(key, names))
        else:
            found[key] = c
    if missing:
        raise InvalidInputError(
            f"checkerboard ({board.cols} x {board.rows} inner corners) not found in the {what} of "
            f"camera(s) {', '.join(missing)}; check the board size, that the whole board is in "
            "view and in focus, or leave those shots out")
    return found
