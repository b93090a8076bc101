"""Checkerboard detection that works in every band of a multispectral array (SPEC §11).

Each camera sees the board through its own filter: low contrast, vignetting, and in some bands
the dark squares reflect more than the light ones. :func:`detect_board` therefore detects on a
normalised image (percentile stretch, then CLAHE), tries OpenCV's sector-based detector first
and the classic detector with sub-pixel refinement second, each on the image and on its
inverse, and puts the corners in one canonical order so that corner ``i`` is the same physical
corner in every camera: rows run top to bottom of the image and every row runs left to right.
That order is ambiguous where the board is held turned by about 90 degrees (its rows then run
down the image, and which end is "first" depends on each camera's perspective), so the
calibrations put every camera's corners in the order of the reference camera's in the same
pose (:func:`order_like`: the symmetry of the grid whose row and column directions agree with
the reference's); a camera mounted turned against the others is then found by its fit
(:mod:`~hyperlf.calibration.plane`, :mod:`~hyperlf.calibration.full`). A board partly out of
view (``detect_board(..., partial=True)``, used by the plane registration) is accepted when at
least 3 x 3 of its inner corners are seen and the image border alone explains the missing
ones: exactly one placement of the seen block within the board puts every unseen corner
outside the image (:func:`place_partial_grid`); unseen corners are NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .. import _options as _opt
from .._parallel import map_threads
from ..errors import InvalidInputError

__all__ = ["BoardSpec", "normalise_for_detection", "detect_board", "detect_boards",
           "check_board_size", "largest_grid", "canonical_order", "refine_corners",
           "camera_label", "place_partial_grid", "grid_symmetries", "order_like",
           "orders_like", "image_turn", "turn_report", "MIN_PARTIAL_SIDE",
           "DETECT_THREADS"]


#: The most inner corners along one side of a checkerboard (OpenCV needs at least 3).
MAX_CORNERS = 200

#: Fewest inner corners along each side of the seen part of a board partly out of view.
MIN_PARTIAL_SIDE = 3

#: Most shots searched for the board at once (threads; each holds a few full-size float64
#: copies of its shot while its corners are refined).
DETECT_THREADS = 8


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
        _opt.check_fields(self, _BOARD_RULES, "board ")
        if not (3 <= self.cols <= MAX_CORNERS and 3 <= self.rows <= MAX_CORNERS):
            raise InvalidInputError(
                f"a board has 3 to {MAX_CORNERS} inner corners per side (a board of 12 x 9 "
                f"squares has 11 x 8), got {self.cols} x {self.rows}")

    @property
    def n_corners(self) -> int:
        return int(self.cols) * int(self.rows)

    def object_points(self) -> np.ndarray:
        """Board coordinates ``(N, 3)`` of the inner corners in canonical order (row-major,
        ``x`` along a row)."""
        j, i = np.mgrid[0:self.rows, 0:self.cols]
        return np.stack([i.ravel() * self.square, j.ravel() * self.square,
                         np.zeros(self.n_corners)], axis=1).astype(np.float64)


#: What a board's fields take (the corner counts' range is checked with its own message).
_BOARD_RULES = {"cols": _opt.integer, "rows": _opt.integer,
                "square": _opt.rule(_opt.number, positive=True)}

#: The smallest side (px) of an image in which a board is searched for; OpenCV's detectors
#: fail on less.
MIN_SHOT_SIDE = 16


def check_board(board) -> BoardSpec:
    """``board`` when it is a :class:`BoardSpec`."""
    if not isinstance(board, BoardSpec):
        raise InvalidInputError(f"board must be a BoardSpec(cols, rows, square), got "
                                f"{_opt.shown(board)}")
    return board


def check_shot(image, label: str = "a board shot") -> np.ndarray:
    """``image`` as a float64 grey image ``(H, W)`` of at least :data:`MIN_SHOT_SIDE` px a
    side (its values are not scanned: NaN marks pixels without a value)."""
    img = _opt.real_array(image, label)
    if img.ndim != 2:
        raise InvalidInputError(f"{label} must be a grey image (H, W), got shape {img.shape}")
    if min(img.shape) < MIN_SHOT_SIDE:
        raise InvalidInputError(f"{label} of {img.shape[1]} x {img.shape[0]} px is too small "
                                f"to find a board in; at least {MIN_SHOT_SIDE} px a side")
    return img


def check_corners(corners, label: str, board: BoardSpec, *, unseen: bool = True) -> np.ndarray:
    """``corners`` as float64 ``(board.n_corners, 2)`` image points ``(x, y)``: finite, or NaN
    for corners not seen where ``unseen`` (one pass over a board's few corners)."""
    a = _opt.real_array(corners, label)
    if a.shape != (board.n_corners, 2):
        raise InvalidInputError(f"{label} must be the ({board.n_corners}, 2) corners (x, y) of "
                                f"a {board.cols} x {board.rows} board, got shape {a.shape}")
    if np.isinf(a).any() or (not unseen and np.isnan(a).any()):
        what = "finite or NaN (unseen)" if unseen else "finite"
        raise InvalidInputError(f"{label} must be {what} pixel coordinates")
    return a


def check_corner_sets(corners, label: str, board: BoardSpec) -> Mapping:
    """``corners``: a mapping camera -> corners (:func:`check_corners`, NaN for unseen)."""
    check_keys(corners, label)
    for k, c in corners.items():
        check_corners(c, f"{label}[{_opt.shown(k)}]", board)
    return corners


def check_key(key, label: str = "camera") -> object:
    """``key`` when it names a camera: a ``(row, col)`` pair of hashable entries, a name (str)
    or an int.  Other labels are refused: a NumPy scalar compared with a pair gives an array,
    not a truth value."""
    ok = isinstance(key, (str, int)) and not isinstance(key, bool)
    if isinstance(key, tuple) and len(key) == 2:
        try:
            hash(key)
            ok = True
        except TypeError:  # an unhashable entry
            ok = False
    if not ok:
        raise InvalidInputError(f"{label} must be a (row, col) pair, a name (str) or an int, "
                                f"got {_opt.shown(key)}")
    return key


def check_keys(table, label: str) -> Mapping:
    """``table``: a mapping whose keys are cameras (:func:`check_key`)."""
    _opt.mapping(table, label, optional=False)
    for k in table:
        check_key(k, f"a camera of {label}")
    return table


def camera_label(key, names: Mapping | None = None) -> str:
    """How a camera is named in messages: the user's name if given, else ``(row, col)``.

    Examples
    --------
    >>> camera_label((1, 2))
    '(1, 2)'
    >>> camera_label((1, 2), names={(1, 2): "Cam-5.png"})
    'Cam-5.png'
    """
    check_key(key)
    _opt.mapping(names, "names")
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

    Examples
    --------
    A faint ramp (values 0.2 to 0.3) is stretched to the full 8-bit range:

    >>> ramp = np.tile(np.linspace(0.2, 0.3, 64), (32, 1))
    >>> img8 = normalise_for_detection(ramp, clahe=False)
    >>> img8.dtype, img8.shape, int(img8.min()), int(img8.max())
    (dtype('uint8'), (32, 64), 0, 255)
    """
    import cv2

    img = check_shot(image)
    clahe = _opt.flag(clahe, "clahe")
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
    cols, rows = (_opt.integer(v, k, 1, maximum=MAX_CORNERS) for v, k in ((cols, "cols"),
                                                                            (rows, "rows")))
    g = _opt.real_array(corners, "corners")
    if g.size != 2 * rows * cols or g.shape[-1:] != (2,):
        raise InvalidInputError(f"corners must be the ({rows * cols}, 2) corners (x, y) of a "
                                f"{cols} x {rows} grid, got shape {g.shape}")
    g = g.reshape(rows, cols, 2)
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


def grid_symmetries(cols: int, rows: int) -> list[np.ndarray]:
    """The orders of a board's corners that look the same: index arrays into the canonical
    order, the identity first and the 180-degree turn second.

    A checkerboard's inner-corner grid maps onto itself when it is turned by 180 degrees about
    its normal or about either of its axes (a board seen from behind is the same grid); a square
    grid also when turned by 90 degrees or flipped about a diagonal. Any of these orders fits a
    camera's own calibration equally well, so only the cameras' agreement tells them apart.

    Examples
    --------
    >>> [s.tolist() for s in grid_symmetries(3, 1)]
    [[0, 1, 2], [2, 1, 0], [0, 1, 2], [2, 1, 0]]
    >>> len(grid_symmetries(4, 4))
    8
    """
    cols, rows = (_opt.integer(v, k, 1, maximum=MAX_CORNERS) for v, k in ((cols, "cols"),
                                                                            (rows, "rows")))
    idx = np.arange(rows * cols).reshape(rows, cols)
    grids = [idx, idx[::-1, ::-1], idx[::-1], idx[:, ::-1]]
    if rows == cols:
        grids += [g.T for g in grids]
    return [g.ravel() for g in grids]


def _directions(corners: np.ndarray, cols: int, rows: int) -> np.ndarray:
    """Unit mean steps along the rows and down the columns of a corner grid, ``(2, 2)``
    (unseen, NaN, corners ignored)."""
    g = np.asarray(corners, np.float64).reshape(rows, cols, 2)
    steps = []
    for d in (np.diff(g, axis=1).reshape(-1, 2), np.diff(g, axis=0).reshape(-1, 2)):
        d = d[np.all(np.isfinite(d), axis=1)]
        v = d.mean(axis=0) if len(d) else np.zeros(2)
        steps.append(v / (np.linalg.norm(v) + 1e-12))
    return np.stack(steps)


def order_like(corners: np.ndarray, anchor: np.ndarray, board: BoardSpec) -> np.ndarray:
    """``corners`` in the order of the grid symmetry (:func:`grid_symmetries`) whose row and
    column directions in the image agree best with ``anchor``'s (another camera's corners of
    the same board pose).

    Cameras of an array look the same way, so the same physical corner gets the same index in
    all of them whichever way the board is held; the image-based canonical order alone cannot
    promise that for a board held turned by about 90 degrees.

    Examples
    --------
    >>> g = np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0)), -1).reshape(-1, 2)
    >>> order_like(g[::-1] + 0.1, g, BoardSpec(4, 3))[0].tolist()
    [0.1, 0.1]
    """
    check_board(board)
    corners = check_corners(corners, "corners", board)
    ref = _directions(check_corners(anchor, "anchor", board), board.cols, board.rows)
    cands = grid_symmetries(board.cols, board.rows)
    score = [np.sum(_directions(corners[s], board.cols, board.rows) * ref) for s in cands]
    return np.ascontiguousarray(corners[cands[int(np.argmax(score))]])


def orders_like(corners: Mapping, reference, board: BoardSpec) -> dict:
    """Every camera's corners of one pose in the reference camera's order (:func:`order_like`);
    when the reference missed the pose, in the first camera's that saw it.

    Examples
    --------
    Camera ``(0, 1)`` lists the corners of the same 4 x 3 board from the other end; they come
    back in the reference's order:

    >>> g = 10.0 * np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0)), -1).reshape(-1, 2)
    >>> out = orders_like({(0, 0): g, (0, 1): g[::-1] + [50, 0]}, (0, 0), BoardSpec(4, 3))
    >>> out[(0, 1)][:2].tolist()
    [[50.0, 0.0], [60.0, 0.0]]
    """
    check_board(board)
    check_corner_sets(corners, "corners", board)
    check_key(reference, "reference")
    anchor = reference if reference in corners else next(iter(corners), None)
    return {k: c if k == anchor else order_like(c, corners[anchor], board)
            for k, c in corners.items()}


def image_turn(corners: np.ndarray, anchor: np.ndarray, board: BoardSpec) -> int:
    """By how many degrees (0, 90, 180 or 270, clockwise on screen) the board's rows run
    turned in one camera's image against another's (same pose), rounded to a quarter turn.

    Examples
    --------
    >>> g = np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0)), -1).reshape(-1, 2)
    >>> image_turn(g[::-1], g, BoardSpec(4, 3))
    180
    >>> image_turn(g[:, ::-1] * [-1, 1], g, BoardSpec(4, 3))   # rows now run down the image
    90
    """
    check_board(board)
    a = _directions(check_corners(anchor, "anchor", board), board.cols, board.rows)[0]
    b = _directions(check_corners(corners, "corners", board), board.cols, board.rows)[0]
    angle = np.degrees(np.arctan2(a[0] * b[1] - a[1] * b[0], a @ b))
    return int(np.round(angle / 90.0) * 90) % 360


def turn_report(corners: Mapping, anchors: Mapping, board: BoardSpec, names=None) -> dict:
    """The calibration's ``turned_cameras`` (labels) and ``camera_turns`` (label -> degrees
    clockwise on screen) of the cameras whose board runs turned (:func:`image_turn`):
    ``corners[k]`` against ``anchors[k]``, the reference camera's corners of the same pose.

    Examples
    --------
    Camera ``(0, 1)`` sees the board's rows run the other way (turned by 180 degrees), camera
    ``(0, 2)`` sees them as the reference does:

    >>> g = 10.0 * np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0)), -1).reshape(-1, 2)
    >>> turn_report({(0, 1): g[::-1], (0, 2): g + [100, 0]}, {(0, 1): g, (0, 2): g},
    ...             BoardSpec(4, 3))
    {'turned_cameras': ['(0, 1)'], 'camera_turns': {'(0, 1)': 180}}
    """
    check_board(board)
    check_corner_sets(corners, "corners", board)
    check_corner_sets(anchors, "anchors", board)
    _opt.mapping(names, "names")
    if not set(corners) <= set(anchors):
        raise InvalidInputError(f"anchors must hold the reference's corners for every camera "
                                f"of corners; missing {sorted(set(corners) - set(anchors), key=str)}")
    turns = {camera_label(k, names): image_turn(c, anchors[k], board) for k, c in corners.items()}
    turns = {k: v for k, v in turns.items() if v}
    return {"turned_cameras": list(turns), "camera_turns": turns}


#: The state OpenCV's random generator is set to before each sector-based board search
#: (:func:`_reseed_opencv`); 0 is the state a new thread starts with.
OPENCV_SEED = 0


def _reseed_opencv() -> None:
    """Set OpenCV's random generator (one per thread) to :data:`OPENCV_SEED`.

    The sector-based detector draws from it, so a search's result depended on how many
    searches the same thread had run before: with the cameras shared out over threads in
    whatever order they finished, the same shots were found in one run and refused in the
    next (2 searches in 720 on a small synthetic rig)."""
    import cv2

    cv2.setRNGSeed(OPENCV_SEED)


def _detect_sb(img8: np.ndarray, size) -> np.ndarray | None:
    import cv2

    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    _reseed_opencv()
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


def _spacing(grid: np.ndarray) -> float:
    """Median distance of neighbouring corners along the rows of a grid ``(rows, cols, 2)``."""
    return float(np.nanmedian(np.linalg.norm(np.diff(grid, axis=1), axis=-1)))


def _in_image(points: np.ndarray, shape, margin: float) -> np.ndarray:
    """Which points ``(N, 2)`` lie at least ``margin`` px inside an image of ``shape``."""
    H, W = shape
    return ((points[:, 0] >= margin) & (points[:, 0] <= W - 1 - margin)
            & (points[:, 1] >= margin) & (points[:, 1] <= H - 1 - margin))


def _inside(corners: np.ndarray, shape, cols: int, rows: int) -> bool:
    """All corners at least 0.9 corner spacings inside the image: the board's outer squares
    must be whole, else the outer corners cannot be located (the board is partly out of
    view)."""
    m = 0.9 * _spacing(corners.reshape(rows, cols, 2))
    return bool(np.all(_in_image(corners, shape, m)))


def _orient_grid(grid: np.ndarray) -> np.ndarray:
    """A corner grid ``(r, c, 2)`` turned so that its rows run right and its columns down."""
    along = np.mean(grid[:, -1] - grid[:, 0], axis=0)
    if abs(along[1]) > abs(along[0]):
        grid = grid.transpose(1, 0, 2)
    if np.mean(grid[:, -1, 0] - grid[:, 0, 0]) < 0:
        grid = grid[:, ::-1]
    if np.mean(grid[-1, :, 1] - grid[0, :, 1]) < 0:
        grid = grid[::-1]
    return np.ascontiguousarray(grid)


def place_partial_grid(grid: np.ndarray, board: BoardSpec, shape) -> np.ndarray | None:
    """Where a block of seen corners sits within the board, if the image border explains it.

    Parameters
    ----------
    grid : ndarray, shape (r, c, 2)
        Seen corners (``x, y`` px), rows running down the image and each row running right.
    board : BoardSpec
    shape : (H, W)
        The image's shape.

    Returns
    -------
    ndarray of float64, shape (board.n_corners, 2), or None
        The board's corners in canonical order, NaN where unseen; None when the block is not
        a part of this board cut by the image border: too small (fewer than
        :data:`MIN_PARTIAL_SIDE` corners a side), larger than the board, or not exactly one
        placement of the block that puts every unseen corner outside the image or nearer its
        border than 0.9 corner spacings (where no detector locates a corner). The outer
        columns (rows) of the block on a side where a corner lies nearer the border than half
        a corner spacing count as unseen (the refinement window would leave the image).

    Examples
    --------
    >>> b = BoardSpec(5, 4)
    >>> j, i = np.mgrid[0:4, 0:5]
    >>> full = np.stack([40.0 * i - 50, 40.0 * j + 50], -1)      # columns 0-1 left of x = 0
    >>> placed = place_partial_grid(full[:, 2:], b, (300, 300))
    >>> int(np.isnan(placed[:, 0]).sum()), placed[2].tolist()
    (8, [30.0, 50.0])
    """
    import cv2

    check_board(board)
    grid = _opt.real_array(grid, "grid")
    if grid.ndim != 3 or grid.shape[-1] != 2 or not np.isfinite(grid).all():
        raise InvalidInputError(f"grid must be finite corners (r, c, 2), got shape {grid.shape}")
    shape = _opt.int_pair(shape, "shape", 1, what="(H, W) of the image")
    if min(grid.shape[:2]) < MIN_PARTIAL_SIDE:
        return None
    spacing = _spacing(grid)
    grid = _trim_to_image(grid, shape, 0.5 * spacing)
    if grid is None:
        return None
    r, c = grid.shape[:2]
    if min(r, c) < MIN_PARTIAL_SIDE or r > board.rows or c > board.cols:
        return None
    seen = grid.reshape(-1, 2)
    j, i = np.mgrid[0:r, 0:c]
    block = np.stack([i.ravel(), j.ravel()], 1).astype(np.float64)
    H, _ = cv2.findHomography(block, seen, 0)
    if H is None:
        return None
    jb, ib = np.mgrid[0:board.rows, 0:board.cols]
    places = []
    for i0 in range(board.rows - r + 1):
        for j0 in range(board.cols - c + 1):
            idx = np.stack([ib.ravel() - j0, jb.ravel() - i0], 1).astype(np.float64)
            unseen = ~((idx[:, 0] >= 0) & (idx[:, 0] < c) & (idx[:, 1] >= 0) & (idx[:, 1] < r))
            if not unseen.any():  # the block is the whole board (OpenCV gives None for none)
                places.append((i0, j0))
                continue
            pred = cv2.perspectiveTransform(idx[unseen].reshape(-1, 1, 2), H).reshape(-1, 2)
            if not np.any(_in_image(pred, shape, 0.9 * spacing)):
                places.append((i0, j0))
    if len(places) != 1:
        return None
    i0, j0 = places[0]
    out = np.full((board.rows, board.cols, 2), np.nan)
    out[i0:i0 + r, j0:j0 + c] = grid
    return out.reshape(-1, 2)


def _trim_to_image(grid: np.ndarray, shape, margin: float) -> np.ndarray | None:
    """The block less its outer columns (rows) on each side of the image where a corner lies
    nearer that border than ``margin``; None if nothing is left. (A column dropped that was
    not cut leaves a corner in view unseen, which :func:`place_partial_grid` refuses.)"""
    H, W = shape
    while grid.size:
        x, y = grid[..., 0], grid[..., 1]
        if (x < margin).any():
            grid = grid[:, 1:]
        elif (x > W - 1 - margin).any():
            grid = grid[:, :-1]
        elif (y < margin).any():
            grid = grid[1:]
        elif (y > H - 1 - margin).any():
            grid = grid[:-1]
        else:
            return grid
    return None


def _detect_partial(img8: np.ndarray) -> list:
    """Candidate blocks of seen corners ``(r, c, 2)``, oriented, from the sector-based detector
    allowed to return any grid of at least 4 x 4 (then 3 x 3) corners, on the image and on its
    inverse."""
    import cv2

    flags = cv2.CALIB_CB_LARGER | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE
    out = []
    for candidate in (img8, 255 - img8):
        for side in (4, MIN_PARTIAL_SIDE):
            _reseed_opencv()
            ok, c, meta = cv2.findChessboardCornersSBWithMeta(candidate, (side, side), flags)
            if ok and meta is not None and c is not None and c.size == 2 * meta.size:
                out.append(_orient_grid(np.asarray(c, np.float64).reshape(*meta.shape, 2)))
    return out


def _detection_image(image: np.ndarray, detect_size: int) -> tuple[np.ndarray, float]:
    """The 8-bit image the detectors search (:func:`normalise_for_detection`), scaled so that
    its larger side is at most ``detect_size`` px, and that scale."""
    import cv2

    img8 = normalise_for_detection(image)
    scale = min(1.0, detect_size / max(img8.shape))
    small = img8 if scale == 1.0 else cv2.resize(img8, None, fx=scale, fy=scale,
                                                 interpolation=cv2.INTER_AREA)
    return small, scale


def detect_board(image: np.ndarray, board: BoardSpec, *, detect_size: int = 800,
                 partial: bool = False) -> np.ndarray | None:
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
    partial : bool
        If the whole board is not found, accept a part of it cut by the image border
        (:func:`place_partial_grid`); its unseen corners are NaN.

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
    check_board(board)
    detect_size = _opt.integer(detect_size, "detect_size", 64)
    small, scale = _detection_image(image, detect_size)
    size = (int(board.cols), int(board.rows))
    for detector in (_detect_sb, _detect_classic):
        for candidate in (small, 255 - small):
            c = detector(candidate, size)
            if (c is not None and c.shape[0] == board.n_corners
                    and _inside(c, small.shape, board.cols, board.rows)):
                c = canonical_order((c + 0.5) / scale - 0.5, board.cols, board.rows)
                return refine_corners(image, c, board)
    return _partial_board(image, small, scale, board) if partial else None


def _partial_board(image, small, scale: float, board: BoardSpec) -> np.ndarray | None:
    """The placed candidate block with the most seen corners, refined, or None."""
    best = None
    for grid in _detect_partial(small):
        placed = place_partial_grid((grid + 0.5) / scale - 0.5, board, np.shape(image))
        if placed is not None and (best is None or np.isfinite(placed).sum()
                                   > np.isfinite(best).sum()):
            best = placed
    return None if best is None else refine_corners(image, best, board)


def refine_corners(image: np.ndarray, corners: np.ndarray, board: BoardSpec) -> np.ndarray:
    """Saddle-point refinement (OpenCV ``cornerSubPix``) on the linear, percentile-stretched
    image (not the equalised one the detector saw, whose local remapping can bias corners),
    with a window of 0.45 times the local corner spacing. A corner that would move by more
    than a third of the spacing keeps its detected position; unseen (NaN) corners stay NaN.

    Examples
    --------
    Corners up to 0.8 px off their true places move closer to them:

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0, image_size=(160, 120), focal=150.0)
    >>> pose = rig.board_pose(450.0, tilt=(10.0, -5.0, 3.0))
    >>> shot = rig.render(pose, supersample=2)[(0, 0)]
    >>> truth = rig.project((0, 0), pose.corners_world(rig.board))
    >>> rough = truth + np.random.default_rng(0).uniform(-0.8, 0.8, truth.shape)
    >>> fine = refine_corners(shot, rough, rig.board)
    >>> bool(np.abs(fine - truth).mean() < 0.5 * np.abs(rough - truth).mean())
    True
    """
    import cv2

    check_board(board)
    img = check_shot(image)
    corners = check_corners(corners, "corners", board)
    lo, hi = np.percentile(img, [0.5, 99.5])
    img = np.clip((img - lo) / max(hi - lo, 1e-12), 0, 1).astype(np.float32)
    spacing = _spacing(corners.reshape(board.rows, board.cols, 2))
    win = max(2, int(round(0.45 * spacing)))
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    seen = np.all(np.isfinite(corners), axis=1)
    out = corners.astype(np.float64).copy()
    out[seen] = cv2.cornerSubPix(img, corners[seen].astype(np.float32).reshape(-1, 1, 2).copy(),
                                 (win, win), (-1, -1), crit).reshape(-1, 2)
    moved = np.linalg.norm(out - corners, axis=1) > spacing / 3
    out[moved] = corners[moved]
    return out


def detect_boards(images: Mapping, board: BoardSpec, *, names: Mapping | None = None,
                  what: str = "board shot", partial: bool = False) -> dict:
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
    partial : bool
        Accept a board partly out of view (:func:`detect_board`).

    Returns
    -------
    dict key -> ndarray (N, 2)

    Raises
    ------
    InvalidInputError
        The board was not found in at least one camera (all of them are named).

    Examples
    --------
    A two-camera synthetic rig: the corners found lie where the rig's exact projection puts
    them (within 0.3 px on average):

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0, image_size=(160, 120), focal=150.0)
    >>> pose = rig.board_pose(450.0, tilt=(10.0, -5.0, 3.0))
    >>> shots = rig.render(pose, supersample=2)
    >>> corners = detect_boards(shots, rig.board)
    >>> sorted(corners), corners[(0, 1)].shape
    ([(0, 0), (0, 1)], (48, 2))
    >>> truth = {k: rig.project(k, pose.corners_world(rig.board)) for k in rig.cameras}
    >>> all(bool(np.linalg.norm(corners[k] - truth[k], axis=1).mean() < 0.3) for k in rig.cameras)
    True

    A shot without the board is named:

    >>> detect_boards({**shots, (0, 1): np.full((120, 160), 0.5)}, rig.board)
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: checkerboard ... not found in the ... of camera(s) (0, 1)...
    """
    check_board(board)
    keys = list(_opt.mapping(images, "images", optional=False))
    _opt.mapping(names, "names")
    corners = map_threads(lambda k: detect_board(images[k], board, partial=partial), keys,
                          cap=DETECT_THREADS)
    found = {k: c for k, c in zip(keys, corners) if c is not None}
    missing = [k for k, c in zip(keys, corners) if c is None]
    whole = [k for k, c in found.items() if np.isfinite(c).all()]
    if whole:  # a part of a larger board is found first; say so before any other error
        check_board_size(images[whole[0]], board, found[whole[0]],
                         name=f"the {what} of camera {camera_label(whole[0], names)}")
    if missing:
        seen = (f"at least {MIN_PARTIAL_SIDE} x {MIN_PARTIAL_SIDE} of its inner corners are in "
                "view, the board cut by at most one side of the image in each direction,"
                if partial else "the whole board is in view")
        raise InvalidInputError(
            f"checkerboard ({board.cols} x {board.rows} inner corners) not found in the {what} of "
            f"camera(s) {', '.join(camera_label(k, names) for k in missing)}"
            f"{_board_size_hint(images[missing[0]], board)}; check the board size, that "
            f"{seen} and in focus, or leave those shots out")
    return found


def largest_grid(image: np.ndarray, *, detect_size: int = 800) -> np.ndarray | None:
    """The largest checkerboard grid of inner corners in a shot, ``(rows, cols, 2)`` image
    coordinates with rows running right and columns down (the whole board when it is in
    view), or None when there is none of at least 3 x 3.

    Examples
    --------
    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0, image_size=(160, 120), focal=150.0)
    >>> shot = rig.render(rig.board_pose(450.0), supersample=2)[(0, 0)]
    >>> largest_grid(shot).shape        # the whole 8 x 6 board: 6 rows of 8 corners
    (6, 8, 2)
    >>> largest_grid(np.full((120, 160), 0.5)) is None
    True
    """
    detect_size = _opt.integer(detect_size, "detect_size", 64)
    small, scale = _detection_image(image, detect_size)
    grids = _detect_partial(small)
    if not grids:
        return None
    g = max(grids, key=lambda g: g.shape[0] * g.shape[1])
    return (g + 0.5) / scale - 0.5


def _fits(grid: np.ndarray, board: BoardSpec) -> bool:
    """Whether a corner grid ``(rows, cols, 2)`` fits within ``board``, either way round."""
    r, c = grid.shape[:2]
    return (c <= board.cols and r <= board.rows) or (c <= board.rows and r <= board.cols)


def check_board_size(image: np.ndarray, board: BoardSpec, corners: np.ndarray, *,
                     name: str = "a board shot") -> None:
    """Refuse a ``board`` smaller than the board whose ``corners`` were found in ``image``.

    A detector asked for fewer inner corners than a board has may lock onto a part of it,
    and onto different parts in different cameras: every correspondence would then be off by
    whole squares, silently. So when the largest grid of corners in the shot
    (:func:`largest_grid`) holds the found corners and has more than ``board``, that is a
    named error (a larger grid elsewhere, a tiled floor, is not).

    Raises
    ------
    InvalidInputError
        The found board is part of a larger one.

    Examples
    --------
    The shot shows an 8 x 6 board; the corners of a 5 x 4 part of it, given as a 5 x 4 board,
    are refused:

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0, image_size=(160, 120), focal=150.0)
    >>> shot = rig.render(rig.board_pose(450.0), supersample=2)[(0, 0)]
    >>> part = largest_grid(shot)[:4, :5].reshape(-1, 2)
    >>> check_board_size(shot, BoardSpec(5, 4), part)
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: a board shot shows a board of 8 x 6 inner corners, more...
    """
    check_board(board)
    corners = check_corners(corners, "corners", board)
    _opt.text(name, "name")
    grid = largest_grid(image)
    if grid is None or _fits(grid, board):
        return
    spacing = _spacing(grid)
    found = np.asarray(corners, np.float64).reshape(-1, 2)
    found = found[np.all(np.isfinite(found), axis=1)]
    near = np.min(np.linalg.norm(found[:, None] - grid.reshape(1, -1, 2), axis=-1), axis=1)
    if np.mean(near < 0.25 * spacing) >= 0.9:
        seen = (grid.shape[1], grid.shape[0])
        raise InvalidInputError(
            f"{name} shows a board of {seen[0]} x {seen[1]} inner corners, more than --board "
            f"{board.cols},{board.rows}; give the inner corners of the whole board (a 12 x 9 "
            "squares board has 11,8), else a part of it is matched")


def _board_size_hint(image: np.ndarray, board: BoardSpec) -> str:
    """`` (the largest grid in it has C x R inner corners ...)`` when that is not ``board``:
    most often the squares were counted instead of the inner corners."""
    grid = largest_grid(image)
    if grid is None or sorted(grid.shape[:2]) == sorted((board.cols, board.rows)):
        return ""
    seen = (grid.shape[1], grid.shape[0])
    return (f" (the largest checkerboard grid in it has {seen[0]} x {seen[1]} inner corners: "
            "--board counts the inner corners, one fewer than the squares along each side)")
