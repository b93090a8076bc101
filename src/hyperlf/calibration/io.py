"""The calibration file: human-readable TOML, written atomically, read back with validation.

Example (plane mode, abridged)::

    format = "hyperlf-calibration"
    version = 1
    mode = "plane"                 # or "full"
    grid = [3, 3]                  # rows, cols of the user's camera names
    reference = [1, 1]
    image_size = [1600, 1200]      # W, H of the raw images
    output_size = [1600, 1200]     # W, H of the registered / rectified views
    camera_matrix = [[3550.0, 0.0, 799.5], [0.0, 3550.0, 599.5], [0.0, 0.0, 1.0]]
    baseline = 40.1                # one baseline in board units
    board_plane = [0.01, -0.02, 0.99, 1290.0]   # plane mode: n . X = dist, reference frame
    disparity = "a reference pixel (x, y) with disparity d is at (x - d (px - px_ref), ...)"

    [board]
    cols = 11
    rows = 8
    square = 30.0

    [[camera]]
    row = 0
    col = 0
    name = "Cam-0.png"
    position = [2.0, 0.0]          # (px, py) in baselines
    reprojection_error = 0.12      # px, RMS
    homography = [[...], [...], [...]]          # plane mode: raw -> registered
    # full mode instead: K, dist, R, t (X_cam = R X_ref + t), rectify

    [info]                         # diagnostics
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from .._atomic import atomic_write_text
from .._options import shown
from ..errors import DataNotFoundError, FormatError, InvalidInputError
from .board import BoardSpec
from .model import MODES, Calibration, CameraCalibration

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["write_calibration", "read_calibration", "CALIBRATION_FORMAT"]

CALIBRATION_FORMAT = "hyperlf-calibration"
VERSION = 1
_DISPARITY_NOTE = ("a reference pixel (x, y) with disparity d appears in view v at "
                   "(x - d (px_v - px_ref), y - d (py_v - py_ref)); plane mode: "
                   "d = f B (1/Z - 1/Z_board), full mode: d = f B / Z")
_MATRICES = {"homography": (3, 3), "K": (3, 3), "dist": (5,), "R": (3, 3), "t": (3,),
             "rectify": (3, 3)}


def _plain(v: Any) -> Any:
    """numpy -> TOML-able Python values (None entries dropped by the caller)."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        return v.item()
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items() if x is not None}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def _camera_table(key, cam: CameraCalibration) -> dict:
    t = {"row": int(key[0]), "col": int(key[1]), "name": cam.name,
         "position": [float(x) for x in cam.position],
         "reprojection_error": float(cam.reprojection_error)}
    for name in _MATRICES:
        val = getattr(cam, name)
        if val is not None:
            t[name] = np.asarray(val, np.float64).tolist()
    return t


def write_calibration(calibration: Calibration, path: str | os.PathLike) -> Path:
    """Write ``calibration`` as a TOML file (atomically) and return its path.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from hyperlf.calibration.rig import make_rig
    >>> from hyperlf.calibration.plane import register_plane
    >>> rig = make_rig(seed=0, imperfect=0.3)
    >>> cal = register_plane(rig.render(rig.board_pose(450.0), supersample=2), rig.board)
    >>> p = write_calibration(cal, pathlib.Path(tempfile.mkdtemp()) / "cal.toml")
    >>> read_calibration(p).grid
    (3, 3)
    """
    import tomli_w

    from .._options import path_like
    from .model import check_calibration

    path_like(path)
    c = check_calibration(calibration)
    doc = {"format": CALIBRATION_FORMAT, "version": VERSION, "mode": c.mode,
           "grid": list(c.grid), "reference": list(c.reference),
           "image_size": list(c.image_size), "output_size": list(c.output_size),
           "camera_matrix": np.asarray(c.camera_matrix, np.float64).tolist(),
           "baseline": float(c.baseline), "disparity": _DISPARITY_NOTE}
    if c.board_plane is not None:
        doc["board_plane"] = np.asarray(c.board_plane, np.float64).tolist()
    doc["board"] = {"cols": int(c.board.cols), "rows": int(c.board.rows),
                    "square": float(c.board.square)}
    doc["camera"] = [_camera_table(k, c.cameras[k]) for k in sorted(c.cameras)]
    info = {k: v for k, v in _plain(c.info).items()
            if not (isinstance(v, float) and not math.isfinite(v))}
    if info:
        doc["info"] = info
    return atomic_write_text(path, tomli_w.dumps(doc))


class _Reader:
    """Validating accessors that raise one-line FormatErrors naming the file."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, what: str) -> FormatError:
        return FormatError(f"calibration file {self.path}: {what}")

    def get(self, table: dict, key: str, where: str = ""):
        if key not in table:
            raise self.fail(f"missing '{key}'{where}; write the file with hyperlf or add it")
        return table[key]

    def array(self, table: dict, key: str, shape, where: str = "") -> np.ndarray:
        val = self.get(table, key, where)
        if not _all_numbers(val):   # a quoted "0.99" is text, not a number
            raise self.fail(f"'{key}'{where} must be numbers of shape {tuple(shape)} (no "
                            "quotes)")
        try:
            arr = np.asarray(val, dtype=np.float64)
        except (TypeError, ValueError):
            raise self.fail(f"'{key}'{where} must be numbers of shape {tuple(shape)}") from None
        if arr.shape != tuple(shape):
            raise self.fail(f"'{key}'{where} must be numbers of shape {tuple(shape)}, "
                            f"got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise self.fail(f"'{key}'{where} holds a NaN or infinite number")
        return arr

    def ints(self, table: dict, key: str, n: int, low: int, where: str = "") -> tuple:
        val = self.get(table, key, where)
        if not (isinstance(val, list) and len(val) == n and all(
                isinstance(v, int) and not isinstance(v, bool) and v >= low for v in val)):
            raise self.fail(f"'{key}'{where} must be {n} integers >= {low}, got {shown(val)}")
        return tuple(val)


def _is_number(val) -> bool:
    """A TOML int or float (not a bool)."""
    return isinstance(val, (int, float)) and not isinstance(val, bool)


def _all_numbers(val) -> bool:
    """Whether ``val`` is a number or (nested) lists of numbers: TOML ints and floats only."""
    if isinstance(val, list):
        return all(_all_numbers(v) for v in val)
    return _is_number(val)


def _check_info(rd: _Reader, info: dict) -> dict:
    """The ``[info]`` entries that later steps read: ``disparity_range`` is two numbers."""
    rng = info.get("disparity_range")
    if rng is not None and not (isinstance(rng, list) and len(rng) == 2
                                and all(_is_number(v) and math.isfinite(v) for v in rng)
                                and rng[0] < rng[1]):
        raise rd.fail(f"'disparity_range' in [info] must be two numbers MIN < MAX, got "
                      f"{shown(rng)}")
    return info


def _read_camera(rd: _Reader, t: Any, i: int, mode: str, grid) -> tuple:
    where = f" in camera table {i + 1}"
    if not isinstance(t, dict):
        raise rd.fail(f"camera entry {i + 1} is not a table")
    r, c = (rd.get(t, k, where) for k in ("row", "col"))
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in (r, c)):
        raise rd.fail(f"'row' and 'col'{where} must be integers, got {shown(r)}, {shown(c)}")
    if not (0 <= r < grid[0] and 0 <= c < grid[1]):
        raise rd.fail(f"camera ({r}, {c}) is outside the {grid[0]} x {grid[1]} grid")
    err = rd.get(t, "reprojection_error", where)
    if not isinstance(err, (int, float)) or not math.isfinite(err) or err < 0:
        raise rd.fail(f"'reprojection_error'{where} must be a number >= 0")
    need = ("homography",) if mode == "plane" else ("K", "dist", "R", "t", "rectify")
    mats = {k: rd.array(t, k, _MATRICES[k], where) for k in need}
    if "homography" in mats and abs(np.linalg.det(mats["homography"])) < 1e-12:
        raise rd.fail(f"the homography{where} is singular")
    cam = CameraCalibration(name=str(t.get("name", f"({r}, {c})")),
                            position=rd.array(t, "position", (2,), where),
                            reprojection_error=float(err), **mats)
    return (r, c), cam


def _read_doc(path: Path) -> dict:
    if not path.is_file():
        raise DataNotFoundError(f"calibration file {path} does not exist; run the calibration "
                                "first or check the path")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise FormatError(f"calibration file {path}: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise FormatError(f"calibration file {path}: not valid TOML "
                          f"({str(exc).splitlines()[0]})") from None


def read_calibration(path: str | os.PathLike) -> Calibration:
    """Read and validate a calibration file written by :func:`write_calibration`.

    Raises
    ------
    DataNotFoundError
        No such file.
    FormatError
        Not TOML, not a hyperlf calibration, or a missing/malformed entry (one line saying
        which).

    Examples
    --------
    A calibration written with :func:`write_calibration` reads back whole (a hand-made plane
    calibration of two cameras here; :func:`hyperlf.calibration.calibrate` makes real ones):

    >>> import tempfile, pathlib
    >>> from hyperlf.calibration.model import Calibration, CameraCalibration
    >>> shift = np.array([[1.0, 0.0, 2.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    >>> cams = {(0, 0): CameraCalibration("left.png", np.zeros(2), 0.1, homography=np.eye(3)),
    ...         (0, 1): CameraCalibration("right.png", np.array([1.0, 0.0]), 0.2,
    ...                                   homography=shift)}
    >>> cal = Calibration(mode="plane", grid=(1, 2), reference=(0, 0), image_size=(640, 480),
    ...                   output_size=(640, 480), camera_matrix=np.diag([800.0, 800.0, 1.0]),
    ...                   cameras=cams, board=BoardSpec(11, 8, 30.0), baseline=40.0,
    ...                   board_plane=np.array([0.0, 0.0, 1.0, 1200.0]))
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> back = read_calibration(write_calibration(cal, folder / "calibration.toml"))
    >>> back.mode, back.grid, back.reference, back.board
    ('plane', (1, 2), (0, 0), BoardSpec(cols=11, rows=8, square=30.0))
    >>> back.cameras[(0, 1)].name, back.positions().tolist()
    ('right.png', [[[0.0, 0.0], [1.0, 0.0]]])
    >>> bool(np.array_equal(back.cameras[(0, 1)].homography, shift))
    True

    A file that is not there, or not a calibration, is refused in one line:

    >>> read_calibration(folder / "missing.toml")
    Traceback (most recent call last):
        ...
    hyperlf.errors.DataNotFoundError: calibration file .../missing.toml does not exist; ...
    >>> _ = (folder / "other.toml").write_text('format = "something else"')
    >>> read_calibration(folder / "other.toml")
    Traceback (most recent call last):
        ...
    hyperlf.errors.FormatError: calibration file ...: format is 'something else', expected ...
    """
    from .._options import path_like

    path = Path(path_like(path, folder=None))
    doc = _read_doc(path)
    rd = _Reader(path)
    if doc.get("format") != CALIBRATION_FORMAT:
        raise rd.fail(f"format is {shown(doc.get('format'))}, expected '{CALIBRATION_FORMAT}'")
    if doc.get("version") != VERSION:
        raise rd.fail(f"version {shown(doc.get('version'))} is not supported (this hyperlf reads "
                      f"version {VERSION})")
    mode = rd.get(doc, "mode")
    if mode not in MODES:
        raise rd.fail(f"mode must be one of {', '.join(MODES)}, got {shown(mode)}")
    grid = rd.ints(doc, "grid", 2, 1)
    ref = rd.ints(doc, "reference", 2, 0)
    if not (ref[0] < grid[0] and ref[1] < grid[1]):
        raise rd.fail(f"reference {list(ref)} is outside the {grid[0]} x {grid[1]} grid")
    bt = rd.get(doc, "board")
    try:
        board = BoardSpec(int(rd.get(bt, "cols", " in [board]")),
                          int(rd.get(bt, "rows", " in [board]")),
                          float(rd.get(bt, "square", " in [board]")))
    except (InvalidInputError, TypeError, ValueError) as exc:
        raise rd.fail(f"[board] is malformed ({exc})") from None
    cams_t = rd.get(doc, "camera")
    if not isinstance(cams_t, list):
        raise rd.fail("'camera' must be an array of tables ([[camera]])")
    cams = dict(_read_camera(rd, t, i, mode, grid) for i, t in enumerate(cams_t))
    missing = [f"({r}, {c})" for r in range(grid[0]) for c in range(grid[1])
               if (r, c) not in cams]
    if missing or len(cams_t) != len(cams):
        raise rd.fail(f"needs exactly one [[camera]] per grid place; missing or repeated: "
                      f"{', '.join(missing) or 'a repeated camera'}")
    baseline = rd.get(doc, "baseline")
    if not isinstance(baseline, (int, float)) or not (math.isfinite(baseline) and baseline > 0):
        raise rd.fail(f"'baseline' must be a number > 0, got {shown(baseline)}")
    plane = rd.array(doc, "board_plane", (4,)) if mode == "plane" else None
    info = doc.get("info", {})
    return Calibration(mode=mode, grid=grid, reference=ref,
                       image_size=rd.ints(doc, "image_size", 2, 1),
                       output_size=rd.ints(doc, "output_size", 2, 1),
                       camera_matrix=rd.array(doc, "camera_matrix", (3, 3)), cameras=cams,
                       board=board, baseline=float(baseline), board_plane=plane,
                       info=_check_info(rd, info) if isinstance(info, dict) else {})
