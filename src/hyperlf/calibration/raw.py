"""Raw images of a camera array: one file per camera, named by a pattern the user states once.

A pattern names each camera's file with ``{index}`` (raster order, ``row * cols + col``) or with
``{row}`` and ``{col}`` (0-based; ``{index+1}`` for files numbered from 1), e.g.
``Cam-{index}.png`` or ``cam_{row}_{col:02d}.tif`` (:mod:`hyperlf.formats.patterns`). Board
shots come as one such set per pose: the set in the folder itself (one pose), or one set per
subfolder (several poses, in name order).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .. import _options as _opt
from .._paths import leads_outside
from ..errors import DataNotFoundError, InvalidInputError
from .grid import MAX_CAMERAS

__all__ = ["camera_files", "beyond_grid", "pose_folders", "read_camera_images", "read_poses",
           "read_raw_image", "sensor_bits", "RawScale", "SENSOR_BITS"]

_FIELDS = ("index", "row", "col")



def _check_folder(folder) -> Path:
    """``folder`` as a Path (a non-empty str or os.PathLike)."""
    return Path(_opt.path_like(folder, "folder", folder=None))


def _check_grid(grid) -> tuple[int, int]:
    """``grid`` as ``(R, C)``: at least two cameras, at most :data:`MAX_CAMERAS`."""
    R, C = _opt.int_pair(grid, "--grid", 1, what="(rows, cols) of cameras")
    if R * C < 2:
        raise InvalidInputError(f"--grid {R},{C}: an array needs at least two cameras")
    if R * C > MAX_CAMERAS:
        raise InvalidInputError(f"--grid {R},{C}: {R * C} cameras is more than the "
                                f"{MAX_CAMERAS} hyperlf handles; check --grid")
    return R, C


def _check_pattern(pattern: str) -> None:
    from ..formats.patterns import pattern_fields

    if not isinstance(pattern, str):
        raise InvalidInputError(f"--pattern must be a file name pattern (a str), got "
                                f"{_opt.shown(pattern)}")
    fields = set(pattern_fields(pattern, _FIELDS, what="--pattern"))
    if "index" not in fields and not {"row", "col"} <= fields:
        raise InvalidInputError(f"--pattern {pattern!r} must name each camera with {{index}} or "
                                "with {row} and {col}, e.g. 'Cam-{index}.png'")


def camera_files(folder: str | os.PathLike, pattern: str, grid: tuple[int, int], *,
                 must_exist: bool = True, skip=()) -> dict:
    """The file of every camera of an ``R x C`` grid: ``{(row, col): Path}``.

    Parameters
    ----------
    folder : path-like
        Where the files are.
    pattern : str
        File name with ``{index}`` or ``{row}``/``{col}`` (see the module notes).
    grid : (int, int)
        Rows and columns of cameras.
    must_exist : bool
        Refuse a missing file (naming the camera and the path).
    skip : collection of (int, int)
        Cameras not looked for (dead cameras, whose files may be missing): left out.

    Returns
    -------
    dict
        ``(row, col) -> Path``.

    Raises
    ------
    InvalidInputError
        A bad pattern or grid, or a file whose real path leaves ``folder``.
    DataNotFoundError
        A camera's file is missing.

    Examples
    --------
    >>> sorted(camera_files(".", "Cam-{index}.png", (1, 2), must_exist=False).items())
    [((0, 0), PosixPath('Cam-0.png')), ((0, 1), PosixPath('Cam-1.png'))]
    """
    from ..formats.patterns import expand_pattern

    root = _check_folder(folder)
    _check_pattern(pattern)
    R, C = _check_grid(grid)
    must_exist = _opt.flag(must_exist, "must_exist")
    if isinstance(skip, (str, bytes)) or not hasattr(skip, "__iter__"):
        raise InvalidInputError(f"skip must be (row, col) pairs, got {_opt.shown(skip)}")
    files = {}
    skip = {_opt.int_pair(k, "a skipped camera", None, what="(row, col)") for k in skip}
    for r in range(R):
        for c in range(C):
            if (r, c) in skip:
                continue
            name = expand_pattern(pattern, _FIELDS, what="--pattern", index=r * C + c, row=r,
                                  col=c)
            p = root / name
            if must_exist and not p.is_file():
                if not root.is_dir():
                    raise DataNotFoundError(f"{root} is not a folder; give the folder of the "
                                            "images")
                raise DataNotFoundError(f"no image for camera {r * C + c} (row {r}, col {c}): "
                                        f"{p} does not exist; check --pattern and --grid"
                                        + _numbered_from_one_hint(root, pattern, r * C + c, r, c))
            if must_exist and leads_outside(root, p):
                how = "a symlink" if any(q.is_symlink() for q in [p, *p.parents]) else "'..'"
                raise InvalidInputError(f"{p} leads outside {root} ({how}); put the file in "
                                        "the folder")
            files[(r, c)] = p
    return files


def _numbered_from_one_hint(root: Path, pattern: str, index: int, row: int, col: int) -> str:
    """A hint when the files are there numbered from 1 (Cam-1 ... Cam-9)."""
    from ..formats.patterns import expand_pattern

    if "+" in pattern:
        return ""
    one = expand_pattern(pattern, _FIELDS, what="--pattern", index=index + 1, row=row + 1,
                         col=col + 1)
    return (f" ({one} is there: are the files numbered from 1? then write {{index+1}}, "
            "{row+1}, {col+1})") if (root / one).is_file() else ""


def beyond_grid(folder: str | os.PathLike, pattern: str, grid: tuple[int, int]) -> Path | None:
    """A file the pattern names for a camera just outside the grid (``{index}`` = R * C, or row
    R / column C), when there is one: a sign that ``grid`` is smaller than the array.

    Examples
    --------
    Four camera files, but a grid of 1 x 3 cameras: ``Cam-3.png`` suggests the grid is too
    small.

    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> for i in range(4):
    ...     (folder / f"Cam-{i}.png").touch()
    >>> beyond_grid(folder, "Cam-{index}.png", (1, 3)).name
    'Cam-3.png'
    >>> print(beyond_grid(folder, "Cam-{index}.png", (2, 2)))
    None
    """
    from ..formats.patterns import expand_pattern

    folder = _check_folder(folder)
    _check_pattern(pattern)
    R, C = _check_grid(grid)
    for index, row, col in ((R * C, R, 0), (R * C, 0, C)):
        p = Path(folder) / expand_pattern(pattern, _FIELDS, what="--pattern", index=index,
                                          row=row, col=col)
        if p.is_file():
            return p
    return None


def pose_folders(folder: str | os.PathLike, pattern: str, grid: tuple[int, int]) -> list[Path]:
    """The folders that hold one full set of camera files: ``folder`` itself, or else each
    subfolder (not following symlinks) that holds a full set, in name order.

    Raises
    ------
    InvalidInputError
        ``folder`` is a file.
    DataNotFoundError
        ``folder`` does not exist, or neither it nor any subfolder holds a file for every
        camera.

    Examples
    --------
    Two pose folders with a file for each camera of a 1 x 2 array, and one without:

    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> for name, n in (("pose1", 2), ("pose0", 2), ("notes", 1)):
    ...     (root / name).mkdir()
    ...     for i in range(n):
    ...         (root / name / f"Cam-{i}.png").touch()
    >>> [p.name for p in pose_folders(root, "Cam-{index}.png", (1, 2))]
    ['pose0', 'pose1']
    >>> [p.name for p in pose_folders(root / "pose1", "Cam-{index}.png", (1, 2))]
    ['pose1']
    """
    root = _check_folder(folder)
    _check_pattern(pattern)
    _check_grid(grid)
    if root.exists() and not root.is_dir():
        raise InvalidInputError(f"{root} is a file; give the folder of the images (and "
                                "--pattern for their names)")
    if not root.is_dir():
        raise DataNotFoundError(f"{root} does not exist; give the folder of the images")

    def complete(d: Path) -> bool:
        return all(p.is_file() for p in camera_files(d, pattern, grid, must_exist=False).values())

    if complete(root):
        return [root]
    subs = sorted(d for d in root.iterdir() if d.is_dir() and not d.is_symlink() and complete(d))
    if not subs:
        camera_files(root, pattern, grid)  # raises, naming the first missing camera
    return subs


class RawScale(NamedTuple):
    """How raw sample values became [0, 1]: divided by ``2**bits - 1``.

    ``bits`` is None for floating-point files (taken as they are); ``file_bits`` is the
    files' integer sample size (8 or 16), None for floating point.
    """
    bits: int | None
    file_bits: int | None


#: Sample depths a sensor may deliver inside wider integer files, right-aligned (a 12-bit
#: camera's values 0..4095 in a 16-bit PNG or TIFF).
SENSOR_BITS = (8, 10, 12, 14, 16)


def sensor_bits(largest: int, file_bits: int) -> int:
    """The fewest bits of :data:`SENSOR_BITS`, at most ``file_bits``, that hold ``largest``.

    A raw image's white level is the sensor's, not the file's: a 12-bit camera saved as
    16-bit integers never exceeds 4095, and its saturated pixels sit there, far below 98 % of
    65535. No file says which; the largest value of all the cameras' images does, unless
    every image is so dark that it stays below a smaller full scale (then its brightest
    pixels would be judged near saturation: ``hyperlf ingest`` says which scale it took).

    Examples
    --------
    >>> sensor_bits(4095, 16), sensor_bits(4096, 16), sensor_bits(65486, 16), sensor_bits(200, 8)
    (12, 14, 16, 8)
    """
    largest = _opt.integer(largest, "largest")
    file_bits = _opt.integer(file_bits, "file_bits", 1, maximum=64)
    for b in SENSOR_BITS:
        if b >= file_bits or largest <= 2 ** b - 1:
            return min(b, file_bits)
    return file_bits


def read_raw_image(path, *, bits: int | None = None) -> np.ndarray:
    """One raw image as grey float32, integer values divided by ``2**bits - 1``.

    ``bits`` None: the file's own sample size (8 or 16); floating-point files are returned as
    they are.

    Raises
    ------
    InvalidInputError
        A value above what ``bits`` bits hold.

    Examples
    --------
    A 16-bit PNG holding the value 2000: scaled by the file's full scale, or by a 12-bit
    sensor's:

    >>> import tempfile, pathlib
    >>> from hyperlf.formats.images import write_image
    >>> path = write_image(pathlib.Path(tempfile.mkdtemp()) / "Cam-0.png",
    ...                    np.full((4, 6), 2000, np.uint16))
    >>> img = read_raw_image(path)
    >>> img.dtype, img.shape, bool(abs(img[0, 0] - 2000 / 65535) < 1e-6)
    (dtype('float32'), (4, 6), True)
    >>> bool(abs(read_raw_image(path, bits=12)[0, 0] - 2000 / 4095) < 1e-6)
    True
    >>> read_raw_image(path, bits=10)
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: ...: values up to 2000, more than 10-bit data holds (1023)...
    """
    from ..formats.images import read_image

    _opt.path_like(path, folder=None)
    bits = _opt.integer(bits, "bits", 1, maximum=64, optional=True)
    arr = read_image(path, as_float=False, channels="grey")
    if not np.issubdtype(arr.dtype, np.integer):
        return np.asarray(arr, np.float32)
    file_bits = 8 * arr.dtype.itemsize
    values = arr.astype(np.float32)
    _to_full_scale(values, file_bits if bits is None else bits, file_bits, str(path))
    return values


def _to_full_scale(values: np.ndarray, bits, file_bits: int, where: str) -> int:
    """Divide integer raw ``values`` (float32, in place) by ``2**bits - 1``; the bits used.

    Raises
    ------
    InvalidInputError
        ``bits`` more than the files hold, or a value above what ``bits`` bits hold.
    """
    b = int(bits)
    if not 1 <= b <= file_bits:
        raise InvalidInputError(f"{where} holds {file_bits}-bit values, the raw data is {b}-bit; "
                                "save it with the raw images' bit depth, or check --raw-bits")
    top = int(values.max())
    if top > 2 ** b - 1:
        raise InvalidInputError(f"{where}: values up to {top}, more than {b}-bit data holds "
                                f"({2 ** b - 1}); check --raw-bits")
    values /= np.float32(2 ** b - 1)
    return b


def read_camera_images(files: dict, *, where: str = "", bits: int | None = None,
                       return_scale: bool = False):
    """Read one grey image per camera, as float32 in [0, 1]: ``{(row, col): (H, W) array}``.

    Colour files are reduced to grey; every image must have the same size and sample type
    (otherwise a one-line error names the files).

    Parameters
    ----------
    files : dict
        ``(row, col) -> Path``, as :func:`camera_files` gives it.
    where : str
        What is being read, for error messages.
    bits : int, optional
        The sensor's bits: integer values are divided by ``2**bits - 1``. Default: the fewest
        of :data:`SENSOR_BITS` that hold the largest value of all the images
        (:func:`sensor_bits`), so that a 12-bit camera's values in 16-bit files reach 1 where
        the sensor saturates.
    return_scale : bool
        Also return the :class:`RawScale` used.

    Returns
    -------
    dict, or (dict, RawScale)

    Examples
    --------
    Two cameras whose 16-bit files hold values of a 12-bit sensor (at most 4095): the images
    are scaled by ``2**12 - 1``:

    >>> import tempfile, pathlib
    >>> from hyperlf.formats.images import write_image
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> for i, value in enumerate((1000, 4000)):
    ...     _ = write_image(folder / f"Cam-{i}.png", np.full((4, 6), value, np.uint16))
    >>> files = camera_files(folder, "Cam-{index}.png", (1, 2))
    >>> images, scale = read_camera_images(files, return_scale=True)
    >>> sorted(images), images[(0, 1)].shape, scale
    ([(0, 0), (0, 1)], (4, 6), RawScale(bits=12, file_bits=16))
    >>> bool(abs(images[(0, 1)][0, 0] - 4000 / 4095) < 1e-6)
    True
    """
    from ..formats.images import read_image, read_images_same_size

    _opt.mapping(files, "files", optional=False)
    if not files:
        raise InvalidInputError("files must name one image per camera, got none")
    for k, p in files.items():
        _opt.int_pair(k, "a camera of files", 0, what="(row, col)")
        _opt.path_like(p, f"the file of camera {k}", folder=None)
    files = {k: Path(p) for k, p in files.items()}
    _opt.text(where, "where")
    bits = _opt.integer(bits, "bits", 1, maximum=64, optional=True)
    return_scale = _opt.flag(return_scale, "return_scale")
    keys = list(files)
    labels = [f"camera {k[0]},{k[1]} ({files[k].name})" for k in keys]
    kinds: dict = {}

    def read(p):
        arr = read_image(p, as_float=False, channels="grey")
        kinds[p] = arr.dtype
        return arr

    stack = read_images_same_size([files[k] for k in keys], read, where or "the raw images",
                                  labels=labels)
    types = {kinds[files[k]] for k in keys}
    if len(types) > 1:
        first = {str(kinds[files[k]]): lab for k, lab in zip(keys, labels)}
        raise InvalidInputError(f"{where or 'the raw images'}: "
                                + " but ".join(f"{lab} holds {t}" for t, lab in first.items())
                                + "; one array, one sample type: save every image with the "
                                "same bit depth")
    dtype = types.pop()
    if not np.issubdtype(dtype, np.integer):
        scale = RawScale(None, None)
    else:
        file_bits = 8 * np.dtype(dtype).itemsize
        b = sensor_bits(int(stack.max()), file_bits) if bits is None else bits
        scale = RawScale(_to_full_scale(stack, b, file_bits, where or "the raw images"),
                         file_bits)
    images = {k: stack[i] for i, k in enumerate(keys)}
    return (images, scale) if return_scale else images


def read_poses(folder: str | os.PathLike, pattern: str, grid: tuple[int, int]) -> dict:
    """Board shots of every camera: ``{(row, col): [image per pose]}`` (see :func:`pose_folders`).

    Raises
    ------
    InvalidInputError
        The poses do not all have the same image size.

    Examples
    --------
    Board shots of a 1 x 2 array in two pose folders:

    >>> import tempfile, pathlib
    >>> from hyperlf.formats.images import write_image
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> for pose in ("pose0", "pose1"):
    ...     (root / pose).mkdir()
    ...     for i in range(2):
    ...         _ = write_image(root / pose / f"Cam-{i}.png", np.full((4, 6), 0.5))
    >>> shots = read_poses(root, "Cam-{index}.png", (1, 2))
    >>> sorted(shots), len(shots[(0, 1)]), shots[(0, 1)][0].shape
    ([(0, 0), (0, 1)], 2, (4, 6))
    """
    per: dict = {}
    shape = None
    for d in pose_folders(folder, pattern, grid):
        images = read_camera_images(camera_files(d, pattern, grid), where=str(d))
        first = next(iter(images.values())).shape
        if shape is not None and first != shape:
            raise InvalidInputError(f"the images in {d} are {first[1]} x {first[0]} px, those "
                                    f"of the first pose {shape[1]} x {shape[0]}; one array, one "
                                    "image size")
        shape = first
        for k, img in images.items():
            per.setdefault(k, []).append(img)
    return per
