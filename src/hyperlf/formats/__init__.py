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

import numpy as np

from ..errors import DataNotFoundError, FormatError, HyperLFError, InvalidInputError
from .._options import check_values, flag, mapping, path_like
from ..lightfield import LightField
from . import capture, envi, hci, hdf5, images, middlebury, pfm
from .capture import (CAPTURE_FORMAT, MANIFEST, gt_cube_file, is_capture, read_capture,
                      write_capture)
from .envi import ENVI_DTYPES, read_envi, write_envi
from .hci import HCI_LICENCE, is_hci_scene, read_hci_scene
from .hdf5 import (CUBE_FORMAT, ChunkedImages, CubeFile, CubeWriter, h5_format, open_cube_h5,
                   open_lightfield_gt_cube, read_cube_h5, read_lightfield_h5, write_cube_h5,
                   write_lightfield_h5)
from .images import REC709_WEIGHTS, read_image, read_images_same_size, to_grey, write_image
from .middlebury import MASK_NAMES, StereoPair, read_middlebury, write_middlebury
from .pfm import describe_pfm, read_pfm, write_pfm
from .ply import describe_ply

# the package's public API: its own functions and every format module's
__all__ = ["load_lightfield", "save_lightfield", "open_gt_cube", "describe"] + [
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

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from hyperlf.synthesis import procedural_scene
    >>> lf = procedural_scene(seed=2, rows=2, cols=3, height=12, width=16)
    >>> tmp = pathlib.Path(tempfile.mkdtemp())
    >>> with open_gt_cube(save_lightfield(lf, tmp / "lf.h5")) as cube:
    ...     print(cube.shape, bool(np.array_equal(cube[1, 2], lf.gt_cube[1, 2])))
    (2, 3, 6, 12, 16) True
    >>> bare = lf.replace(gt_cube=None, cube_wavelengths=None)
    >>> with open_gt_cube(save_lightfield(bare, tmp / "bare.h5")) as cube:
    ...     print(cube)
    None
    """
    p = Path(path_like(path, folder=None))
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

    Raises
    ------
    DataNotFoundError
        When ``path`` does not exist (or is a folder without a manifest that holds images,
        i.e. an unfinished capture).
    FormatError
        When ``path`` exists but is none of the supported formats.

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
    """
    p = Path(path_like(path, folder=None))
    cube = flag(cube, "cube")
    if not p.exists():
        raise DataNotFoundError(f"{p} does not exist; expected {_SUPPORTED}")
    if p.is_file() and p.name == MANIFEST and is_capture(p.parent):
        p = p.parent   # what save_lightfield returns for a folder: its capture.toml
    if p.is_dir():
        if is_capture(p):
            return read_capture(p, cube=cube, **kwargs)
        if is_hci_scene(p):
            return read_hci_scene(p, **kwargs)
        _refuse_result_folder(p)
        if any(f.suffix.lower() in (".png", ".tif", ".tiff") for f in p.iterdir()):
            raise DataNotFoundError(
                f"{p} holds images but no {MANIFEST}; an unfinished capture or a folder of "
                f"loose images (raw camera images become a capture with 'hyperlf calibrate' "
                f"and 'hyperlf ingest'). hyperlf loads {_SUPPORTED}"
            )
        raise FormatError(f"{p} is not a light field: hyperlf loads {_SUPPORTED}")
    if p.suffix.lower() in _H5:
        return read_lightfield_h5(p, cube=cube, **kwargs)
    raise FormatError(f"cannot load {p} (suffix {p.suffix or 'none'!r}): hyperlf loads {_SUPPORTED}")


def _refuse_result_folder(p: Path) -> None:
    """A folder a hyperlf command wrote its results to (not a light field) is named as such."""
    from ..errors import InvalidInputError
    from ..outputs import read_manifest

    record = read_manifest(p)
    if record is not None and record["command"] not in (None, "synth", "ingest", "convert"):
        raise InvalidInputError(f"{p} holds the results of 'hyperlf {record['command']}', not a "
                                f"light field; give the capture it was made from "
                                f"('hyperlf info {p}' says what it holds)")


def describe(path: str | os.PathLike) -> str:
    """What ``path`` holds, as ``hyperlf info`` prints it.

    * a light field (capture folder, HCI scene, ``.h5``) -> :meth:`LightField.describe`;
    * a cube file (``complete``'s ``cube.h5``) -> :meth:`CubeFile.describe`;
    * a ``.pfm`` map, a ``.ply`` point cloud or a ``calibration.toml`` -> one line
      (:func:`describe_pfm`, :func:`describe_ply`,
      :meth:`hyperlf.calibration.Calibration.describe`);
    * a folder a hyperlf command wrote (its manifest, :func:`hyperlf.outputs.read_manifest`)
      -> the command, then a line for each map, point cloud and HDF5 file in it, and the names
      of its pictures. Symlinks in it are named, not followed.

    Raises
    ------
    DataNotFoundError, FormatError
        As :func:`load_lightfield`, or for an unreadable map, cloud or cube given alone.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from hyperlf.outputs import result_folder
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "depth"
    >>> with result_folder(out, command="depth") as stage:
    ...     _ = write_pfm(stage / "disparity.pfm", np.full((2, 3), 1.5))
    ...     _ = (stage / "disparity.png").write_bytes(b"")
    >>> print(describe(out))
    result set  : written by `hyperlf depth` (hyperlf ...), 2 files
    disparity.pfm: PFM map, 3 x 2 px (W x H), values 1.5..1.5
    pictures    : disparity.png
    """
    from ..outputs import read_manifest

    p = Path(path_like(path, folder=None))
    if not p.exists():
        raise DataNotFoundError(f"{p} does not exist; expected {_SUPPORTED}")
    if p.is_dir() and not is_capture(p) and not is_hci_scene(p):
        manifest = read_manifest(p)
        if manifest is not None:
            return _describe_result(p, manifest)
        from ..batch import BATCH_FILE

        if (p / BATCH_FILE).is_file():
            return _describe_batch(p)
    if p.is_file() and p.name in _BY_NAME:
        return _BY_NAME[p.name](p)
    if p.is_file() and p.name == MANIFEST and is_capture(p.parent):
        return describe(p.parent)   # a capture's manifest stands for the capture
    if p.is_file() and p.suffix.lower() in _ONE_LINE:
        return _ONE_LINE[p.suffix.lower()](p)
    if p.is_file() and h5_format(p) == CUBE_FORMAT:
        with open_cube_h5(p) as cf:
            return cf.describe()
    lf = load_lightfield(p, cube=False)  # a paper-size ground-truth cube is 3.9 GB
    return lf.describe(cube=_gt_cube_bands(p))


def _describe_batch(p: Path) -> str:
    """``hyperlf batch``'s output folder: its captures and their status from summary.csv."""
    import csv
    from collections import Counter

    try:
        with open(p / "summary.csv", newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except (OSError, ValueError, csv.Error):
        rows = []
    status = Counter(r.get("status", "?") for r in rows)
    counts = ", ".join(f"{n} {k}" for k, n in sorted(status.items())) or "no summary yet"
    lines = [f"batch output: {len(rows)} captures ({counts}); the table: summary.html"]
    lines += [f"  {r.get('capture')}: {r.get('status')}"
              + (f" ({r.get('message')})" if r.get("message") else "") for r in rows[:20]]
    if len(rows) > 20:
        lines.append(f"  ... and {len(rows) - 20} more")
    return "\n".join(lines)


def _gt_cube_bands(path: Path):
    """Band count and wavelengths of the ground-truth cube of a capture or light-field file,
    read without its data; None when it has none."""
    with open_gt_cube(path) as cube:
        if cube is None:
            return None
        name = "wavelengths" if cube.name == "/cube" else "cube_wavelengths"  # cube file / LF
        try:
            wl = np.asarray(cube.file[name][()], dtype=np.float64).ravel()
        except (KeyError, OSError, TypeError, ValueError):  # absent or unreadable: no range
            wl = None
        return int(cube.shape[2]), wl


def _describe_calibration(path: Path) -> str:
    from ..calibration import read_calibration

    return read_calibration(path).describe()


#: One-line describers of the files a result set may hold, by suffix (or by whole name).
_ONE_LINE = {".pfm": describe_pfm, ".ply": describe_ply}
_BY_NAME = {"calibration.toml": _describe_calibration}
_PICTURES = (".png", ".tif", ".tiff", ".jpg", ".jpeg")


def _describe_result(p: Path, manifest: dict) -> str:
    """A result folder: its command, a line per map, cloud and HDF5 file, its pictures."""
    cmd = f"`hyperlf {manifest['command']}`" if manifest["command"] else "a hyperlf command"
    files = sorted(manifest["files"])
    lines = [f"result set  : written by {cmd} ({manifest['written_by']}), {len(files)} files"]
    if manifest.get("argv"):
        import shlex
        lines.append(f"made by     : {shlex.join(manifest['argv'])}")
    source = (manifest.get("input") or {}).get("path")
    if isinstance(source, str):
        lines.append(f"made from   : {source}")
    pictures, other = [], []
    captures = sorted({_top(n) for n in files
                       if _top(n) and _inside(n, p) and is_capture(p / _top(n))})
    for sub in captures:  # one line for a capture inside (its views and truth are its own)
        n = sum(_top(f) == sub for f in files)
        lines.append(f"{sub + '/':<12}: a capture, {n} files ('hyperlf info {p / sub}')")
    files = [f for f in files if _top(f) not in captures]
    for name in files:
        suffix = Path(name).suffix.lower()
        if suffix in _ONE_LINE or suffix in _H5 or Path(name).name in _BY_NAME:
            text = _one_line(p / name) if _inside(name, p) else "outside the folder (not read)"
            lines.append(f"{name:<12}: {text}")
        else:
            (pictures if suffix in _PICTURES else other).append(name)
    if pictures:
        lines.append(f"pictures    : {', '.join(pictures)}")
    if other:
        lines.append(f"other files : {', '.join(other)}")
    return "\n".join(lines)


def _top(name: str) -> str:
    """The first folder of a manifest's relative path ('' for a file at the top)."""
    parts = Path(name).parts
    return parts[0] if len(parts) > 1 else ""


def _inside(name: str, folder: Path) -> bool:
    """Whether a manifest's relative path stays in ``folder``: not absolute, no ``..``, no
    symlinked folder on the way (a manifest is a file anyone can edit)."""
    rel = Path(name)
    if rel.is_absolute() or ".." in rel.parts or not rel.parts:
        return False
    here = folder
    for part in rel.parts[:-1]:
        here = here / part
        if here.is_symlink():
            return False
    return True


def _one_line(f: Path) -> str:
    """One line on a map, cloud or HDF5 file of a result set; what is wrong with it if it
    cannot be read (the rest of the folder is still described)."""
    if f.is_symlink():
        return "a symlink (not followed)"
    if not f.is_file():
        return "missing (removed since it was written)"
    try:
        if f.name in _BY_NAME:
            return _BY_NAME[f.name](f)
        if f.suffix.lower() in _ONE_LINE:
            return _ONE_LINE[f.suffix.lower()](f)
        if h5_format(f) == CUBE_FORMAT:
            with open_cube_h5(f) as cf:
                return "cube, " + cf.describe().splitlines()[0].split(":", 1)[1].strip()
        return f"HDF5 {h5_format(f) or 'file'} (hyperlf info {f.name} describes it)"
    except HyperLFError as exc:
        return f"unreadable: {exc}"


def save_lightfield(lf: LightField, path: str | os.PathLike, *, bit_depth: int = 16,
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
        (``image_format``); any other name is refused.

    Returns
    -------
    Path
        The written file (the manifest for a capture).

    Examples
    --------
    HDF5 keeps the float32 views exactly; a capture's 16-bit images are within half a step
    (``0.5 / 65535``) of them.

    >>> import tempfile, pathlib
    >>> from hyperlf.synthesis import procedural_scene
    >>> lf = procedural_scene(seed=2, rows=2, cols=3, height=12, width=16)
    >>> tmp = pathlib.Path(tempfile.mkdtemp())
    >>> h5 = save_lightfield(lf, tmp / "lf.h5")
    >>> manifest = save_lightfield(lf, tmp / "cap")
    >>> h5.name, manifest.name
    ('lf.h5', 'capture.toml')
    >>> bool(np.array_equal(load_lightfield(h5).views, lf.views))
    True
    >>> error = np.abs(load_lightfield(manifest).views - lf.views).max()
    >>> bool(error <= 0.5 / 65535)
    True
    >>> save_lightfield(lf, h5, overwrite=True) == h5  # an existing file needs overwrite
    True
    """
    h5 = Path(path_like(path, folder=None)).suffix.lower() in _H5
    p = Path(path_like(path, folder=not h5))
    check_values(dict(bit_depth=bit_depth, overwrite=overwrite, progress=progress),
                 capture._WRITE_RULES)
    mapping(kwargs, "the options of save_lightfield",
            keys=("compression",) if h5 else ("image_format",),
            taker="an HDF5 file" if h5 else "a capture folder")
    if h5:
        if p.exists() and not overwrite:
            raise InvalidInputError(f"{p} exists; choose another name or pass overwrite=True")
        return write_lightfield_h5(p, lf, **kwargs)
    return write_capture(lf, p, bit_depth=bit_depth, overwrite=overwrite, progress=progress,
                         **kwargs)
