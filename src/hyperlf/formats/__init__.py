"""File formats: reading and writing light fields, cubes, images and benchmark data.

Supported
---------
* hyperlf capture folders (``capture.toml`` + one image per view): :mod:`.capture`;
* hyperlf HDF5 light fields and plenoptic cubes (``.h5``/``.hdf5``): :mod:`.hdf5`;
* HCI 4D light field benchmark scenes (``input_Cam###.png``): :mod:`.hci`;
* Middlebury stereo pairs (v2 and 2005 layouts): :mod:`.middlebury`;
* PFM float maps, PNG/TIFF images, ENVI cubes: :mod:`.pfm`, :mod:`.images`, :mod:`.envi`.

Every reader turns malformed input into :class:`~hyperlf.errors.FormatError` (missing files into
:class:`~hyperlf.errors.DataNotFoundError`) with a one-line message; every writer writes
atomically (temporary file beside the target, then rename).
"""

from __future__ import annotations

import contextlib

import os
from pathlib import Path

from ..errors import DataNotFoundError, FormatError, InvalidInputError
from ..lightfield import LightField
from . import capture, envi, hci, hdf5, images, middlebury, pfm
from .capture import (CAPTURE_FORMAT, MANIFEST, gt_cube_file, is_capture, read_capture,
                      write_capture)
from .envi import ENVI_DTYPES, read_envi, write_envi
from .hci import HCI_LICENCE, is_hci_scene, read_hci_scene
from .hdf5 import (ChunkedImages, CubeFile, CubeWriter, open_cube_h5, open_lightfield_gt_cube,
                   read_cube_h5, read_lightfield_h5, write_cube_h5, write_lightfield_h5)
from .images import REC709_WEIGHTS, read_image, read_images_same_size, to_grey, write_image
from .middlebury import MASK_NAMES, StereoPair, read_middlebury, write_middlebury
from .pfm import read_pfm, write_pfm

# the package's public API: its own two functions and every format module's
__all__ = ["load_lightfield", "save_lightfield", "open_gt_cube"] + [
    name for module in (pfm, images, hci, middlebury, capture, hdf5, envi)
    for name in module.__all__]

_H5 = (".h5", ".hdf5")
_SUPPORTED = ("a capture folder with capture.toml, an HCI scene folder with input_Cam000.png, "
              "or an HDF5 file (.h5/.hdf5) written by hyperlf")


@contextlib.contextmanager
def open_gt_cube(path: str | os.PathLike):
    """The ground-truth cube of a capture folder or light-field HDF5 file, read lazily.

    A context manager that yields the ``(R, C, B, H, W)`` cube as an h5py dataset (index one
    view, ``cube[r, c]``, to read just that view), or None when the input has none (an HCI
    scene folder, a capture without ``gt_cube``).  At the paper's size the cube is 3.9 GB:
    scoring a completion against it view by view keeps it on disk
    (:func:`hyperlf.metrics.cube_scores`).

    Raises
    ------
    DataNotFoundError, FormatError
        As :func:`load_lightfield`, for a missing or malformed file.
    """
    p = Path(path)
    if is_capture(p):
        cfile = gt_cube_file(p)
        if cfile is None:
            yield None
            return
        with open_cube_h5(cfile) as cf:
            yield cf.cube
    elif p.is_file() and p.suffix.lower() in _H5:
        with open_lightfield_gt_cube(p) as cube:
            yield cube
    else:
        yield None


def load_lightfield(path: str | os.PathLike, *, cube: bool = True, **kwargs) -> LightField:
    """Load a light field, picking the reader from what ``path`` is (``cube=False`` leaves a
    ground-truth cube on disk: depth needs only the views).

    * folder with ``capture.toml`` -> :func:`read_capture`;
    * folder with ``input_Cam000.png`` -> :func:`read_hci_scene` (``kwargs``: grid, rows, cols);
    * ``.h5`` / ``.hdf5`` file -> :func:`read_lightfield_h5`.

    Parameters
    ----------
    path : path-like
        Capture folder, HCI scene folder or HDF5 file.
    **kwargs
        Passed to the HCI reader.

    Returns
    -------
    LightField

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from hyperlf.synthesis import procedural_scene
    >>> lf = procedural_scene(seed=2, rows=2, cols=3, height=12, width=16)
    >>> tmp = pathlib.Path(tempfile.mkdtemp())
    >>> h5 = save_lightfield(lf, tmp / "lf.h5")  # an HDF5 file
    >>> cap = save_lightfield(lf, tmp / "cap").parent  # a capture folder (returns its manifest)
    >>> load_lightfield(h5).grid_shape, load_lightfield(cap).grid_shape
    ((2, 3), (2, 3))

    Raises
    ------
    DataNotFoundError
        When ``path`` does not exist (or is a folder without a manifest that holds images,
        i.e. an unfinished capture).
    FormatError
        When ``path`` exists but is none of the supported formats.
    """
    p = Path(path)
    if not p.exists():
        raise DataNotFoundError(f"{p} does not exist; expected {_SUPPORTED}")
    if p.is_dir():
        if is_capture(p):
            return read_capture(p, cube=cube, **kwargs)
        if is_hci_scene(p):
            return read_hci_scene(p, **kwargs)
        if any(f.suffix.lower() in (".png", ".tif", ".tiff") for f in p.iterdir()):
            raise DataNotFoundError(
                f"{p} holds images but no {MANIFEST}; an unfinished capture or a folder of "
                f"loose images. hyperlf loads {_SUPPORTED}"
            )
        raise FormatError(f"{p} is not a light field: hyperlf loads {_SUPPORTED}")
    if p.suffix.lower() in _H5:
        return read_lightfield_h5(p, cube=cube, **kwargs)
    raise FormatError(f"cannot load {p} (suffix {p.suffix or 'none'!r}): hyperlf loads {_SUPPORTED}")


def save_lightfield(lf: LightField, path: str | os.PathLike, bit_depth: int = 16,
                    overwrite: bool = False, progress: bool = False, **kwargs) -> Path:
    """Save a light field: ``.h5``/``.hdf5`` -> HDF5 file, anything else -> capture folder.

    Parameters
    ----------
    lf : LightField
    path : path-like
    bit_depth : {8, 16, 32}
        Depth of a capture's view files; ignored for HDF5 (always float32).
    overwrite : bool
        Replace an existing HDF5 file / non-empty capture folder; otherwise refuse with
        :class:`~hyperlf.errors.InvalidInputError`.
    progress : bool
        Show a progress bar while a capture's views are written.
    **kwargs
        Passed on to :func:`write_lightfield_h5` (``compression``) or :func:`write_capture`
        (``image_format``).

    Returns
    -------
    Path
        The written file (the manifest for a capture).
    """
    p = Path(path)
    if p.suffix.lower() in _H5:
        if p.exists() and not overwrite:
            raise InvalidInputError(f"{p} exists; choose another name or pass overwrite=True")
        return write_lightfield_h5(p, lf, **kwargs)
    return write_capture(lf, p, bit_depth=bit_depth, overwrite=overwrite, progress=progress,
                         **kwargs)
