"""Checks of the images a user hands to calibration: a full grid of cameras, one size."""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .. import _options as _opt
from ..errors import InvalidInputError
from .board import camera_label, check_keys

__all__ = ["check_grid", "check_images", "grid_keys"]


#: The most cameras an array may have (the paper's has 30; a grid of millions is a typo).
MAX_CAMERAS = 4096


def grid_keys(rows: int, cols: int) -> list:
    """``(row, col)`` of every camera of an ``rows x cols`` grid, raster order; at most
    :data:`MAX_CAMERAS` cameras.

    Examples
    --------
    A 2 x 3 array, row by row (camera ``index = row * cols + col``):

    >>> grid_keys(2, 3)
    [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2)]
    """
    R = _opt.integer(rows, "rows", minimum=1, maximum=MAX_CAMERAS)
    C = _opt.integer(cols, "cols", minimum=1, maximum=MAX_CAMERAS)
    if R * C > MAX_CAMERAS:
        raise InvalidInputError(f"a grid of {R} x {C} = {R * C} cameras is more than the "
                                f"{MAX_CAMERAS} hyperlf handles")
    return [(r, c) for r in range(R) for c in range(C)]


def check_grid(keys, reference=None) -> tuple[tuple[int, int], tuple[int, int]]:
    """The grid ``(R, C)`` the keys fill, and the reference (default: the centre camera).

    Raises
    ------
    InvalidInputError
        Keys that are not ``(row, col)`` pairs of non-negative ints, a grid with holes, fewer
        than two cameras, or a reference outside the grid.

    Examples
    --------
    The default reference of a 2 x 3 grid is the middle camera of its upper middle row:

    >>> check_grid(grid_keys(2, 3))
    ((2, 3), (0, 1))
    >>> check_grid(grid_keys(2, 3), reference=(1, 2))
    ((2, 3), (1, 2))

    A grid with a hole is refused, naming the camera that is missing:

    >>> check_grid([(0, 0), (0, 1), (1, 1)])
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: the cameras do not fill a 2 x 2 grid: no image for (1, 0)...
    """
    if isinstance(keys, (str, bytes)) or not hasattr(keys, "__iter__"):
        raise InvalidInputError(f"keys must be the cameras' (row, col) pairs, got "
                                f"{_opt.shown(keys)}")
    keys = list(keys)
    if not all(isinstance(k, tuple) and len(k) == 2 and all(isinstance(i, (int, np.integer))
                                                           and i >= 0 for i in k) for k in keys):
        raise InvalidInputError("cameras must be keyed by (row, col) pairs of non-negative ints")
    if len(keys) < 2:
        raise InvalidInputError(f"an array needs at least two cameras, got {len(keys)}")
    R = max(k[0] for k in keys) + 1
    C = max(k[1] for k in keys) + 1
    missing = sorted(set(grid_keys(R, C)) - set(keys))
    if missing:
        raise InvalidInputError(
            f"the cameras do not fill a {R} x {C} grid: no image for "
            f"{', '.join(camera_label(k) for k in missing)}; give every camera of the grid")
    ref = ((R - 1) // 2, (C - 1) // 2) if reference is None else _opt.index(
        reference, "the reference camera", (R, C))
    return (R, C), ref


def check_images(images: Mapping, names: Mapping | None = None, *,
                 what: str = "image") -> tuple[int, int]:
    """Every image is a finite 2-D grey array and all have one size; returns ``(W, H)``.

    Examples
    --------
    >>> check_images({(0, 0): np.zeros((4, 6)), (0, 1): np.ones((4, 6), np.uint16)})
    (6, 4)

    Images of different sizes are refused; ``names`` say which files they came from:

    >>> check_images({(0, 0): np.zeros((4, 6)), (0, 1): np.zeros((5, 6))},
    ...              names={(0, 1): "Cam-1.png"})
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: the images differ in size (... 6 x 5: Cam-1.png)...
    """
    check_keys(images, "images")
    _opt.mapping(names, "names")
    _opt.text(what, "what")
    if not images:
        raise InvalidInputError(f"no {what}s: give one per camera")
    sizes = {}
    for key, img in images.items():
        a = _opt.real_array(img, f"the {what} of camera {camera_label(key, names)}", None)
        if a.ndim != 2 or a.size == 0 or not np.issubdtype(a.dtype, np.number):
            raise InvalidInputError(
                f"the {what} of camera {camera_label(key, names)} must be a grey (H, W) image, "
                f"got shape {a.shape}; convert colour images to grey first")
        sizes.setdefault(a.shape, []).append(camera_label(key, names))
    if len(sizes) > 1:
        parts = "; ".join(f"{w} x {h}: {', '.join(v)}" for (h, w), v in sizes.items())
        raise InvalidInputError(f"the {what}s differ in size ({parts}); every camera must give "
                                "images of one size")
    (H, W), = sizes.keys()
    return W, H
