"""Raw images of a camera array: one file per camera, named by a pattern the user states once.

A pattern names each camera's file with ``{index}`` (raster order, ``row * cols + col``) or with
``{row}`` and ``{col}`` (0-based), e.g. ``Cam-{index}.png`` or ``cam_{row}_{col:02d}.tif``
(:mod:`hyperlf.formats.patterns`). Board shots come as one such set per pose: the set in the
folder itself (one pose), or one set per subfolder (several poses, in name order).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import DataNotFoundError, InvalidInputError

__all__ = ["camera_files", "pose_folders", "read_camera_images", "read_poses"]

_FIELDS = ("index", "row", "col")

#: The most cameras an array may have (the paper's has 30; a grid of millions is a typo).
MAX_CAMERAS = 4096


def _check_pattern(pattern: str) -> None:
    from ..formats.patterns import pattern_fields

    fields = set(pattern_fields(pattern, _FIELDS, what="--pattern"))
    if "index" not in fields and not {"row", "col"} <= fields:
        raise InvalidInputError(f"--pattern {pattern!r} must name each camera with {{index}} or "
                                "with {row} and {col}, e.g. 'Cam-{index}.png'")


def camera_files(folder: str | os.PathLike, pattern: str, grid: tuple[int, int], *,
                 must_exist: bool = True) -> dict:
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

    _check_pattern(pattern)
    R, C = (int(v) for v in grid)
    if R < 1 or C < 1 or R * C < 2:
        raise InvalidInputError(f"--grid {R},{C}: an array needs at least two cameras")
    if R * C > MAX_CAMERAS:
        raise InvalidInputError(f"--grid {R},{C}: {R * C} cameras is more than the "
                                f"{MAX_CAMERAS} hyperlf handles; check --grid")
    root = Path(folder)
    real_root = os.path.realpath(root)
    files = {}
    for r in range(R):
        for c in range(C):
            name = expand_pattern(pattern, _FIELDS, what="--pattern", index=r * C + c, row=r,
                                  col=c)
            p = root / name
            if must_exist and not p.is_file():
                raise DataNotFoundError(f"no image for camera {r * C + c} (row {r}, col {c}): "
                                        f"{p} does not exist; check --pattern and --grid")
            if must_exist and os.path.commonpath([real_root, os.path.realpath(p)]) != real_root:
                raise InvalidInputError(f"{p} leads outside {root} (a symlink); copy the file in")
            files[(r, c)] = p
    return files


def pose_folders(folder: str | os.PathLike, pattern: str, grid: tuple[int, int]) -> list[Path]:
    """The folders that hold one full set of camera files: ``folder`` itself, or else each
    subfolder (not following symlinks) that holds a full set, in name order.

    Raises
    ------
    DataNotFoundError
        Neither ``folder`` nor any subfolder holds a file for every camera.
    """
    root = Path(folder)
    if not root.is_dir():
        raise DataNotFoundError(f"{root} is not a folder; give the folder of the images")

    def complete(d: Path) -> bool:
        return all(p.is_file() for p in camera_files(d, pattern, grid, must_exist=False).values())

    if complete(root):
        return [root]
    subs = sorted(d for d in root.iterdir() if d.is_dir() and not d.is_symlink() and complete(d))
    if not subs:
        camera_files(root, pattern, grid)  # raises, naming the first missing camera
    return subs


def read_camera_images(files: dict, *, where: str = "") -> dict:
    """Read one grey image per camera, as float32 in [0, 1]: ``{(row, col): (H, W) array}``.

    Colour files are reduced to grey; every image must have the same size (otherwise a one-line
    error names both files).
    """
    from ..formats.images import read_image, read_images_same_size

    keys = list(files)
    labels = [f"camera {k[0]},{k[1]} ({files[k].name})" for k in keys]
    stack = read_images_same_size([files[k] for k in keys],
                                  lambda p: read_image(p, as_float=True, channels="grey"),
                                  where or "the raw images", labels=labels)
    return {k: np.asarray(stack[i], np.float32) for i, k in enumerate(keys)}


def read_poses(folder: str | os.PathLike, pattern: str, grid: tuple[int, int]) -> dict:
    """Board shots of every camera: ``{(row, col): [image per pose]}`` (see :func:`pose_folders`).

    Raises
    ------
    InvalidInputError
        The poses do not all have the same image size.
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
