"""hyperlf's capture format: a folder of per-view images plus a ``capture.toml`` manifest.

Example manifest::

    format = "hyperlf-capture"
    version = 1
    grid = [5, 6]                  # rows, cols
    reference = [2, 2]             # optional, default ((R-1)//2, (C-1)//2)
    disparity_range = [-1.0, 3.0]  # optional, px per baseline
    bit_depth = 16                 # of the view files: 8, 16 (PNG/TIFF) or 32 (float32 TIFF)
    channels = 1                   # optional: 1 (monochrome, default) or 3 (RGB views)
    gt_disparity = "gt_disparity.pfm"          # optional: reference view, or a per-view pattern
                                               # with {row} and {col}, e.g. "gt_r{row}_c{col}.pfm"
    gt_cube = "gt_cube.h5"                     # optional: hyperlf cube file (write_cube_h5)
    valid = "valid_r{row}_c{col}.png"          # optional: per-view validity masks (pattern)

    [[view]]                       # one table per view
    row = 0
    col = 0
    file = "view_r0_c0.png"
    wavelength = 410.0             # nm; give it for all views or for none
    position = [0.0, 0.0]          # optional (px, py) in baselines, default (col, row)

    [calibration]                  # optional free table -> metadata["calibration"]
    [metadata]                     # optional free table -> metadata

Decisions
---------
* Intensities: integer files are scaled to [0, 1] by their own dtype maximum (the file's real
  depth wins over ``bit_depth``, which documents how the capture was written).
* A monochrome capture (``channels = 1``) whose file is RGB with three identical channels is
  accepted as grey; RGB with different channels is an error (a spectral view must not be
  silently mixed from colour channels): convert it with :func:`hyperlf.formats.to_grey` first
  or declare ``channels = 3``.
* Validity masks (``valid``, SPEC §11): one 8-bit grey PNG per view, 255 where the view's
  pixel holds real data and 0 where it does not (warped in from outside the camera's image,
  saturated, dead camera). The entry must be a ``{row}``/``{col}`` pattern; each mask must
  have the views' size and only values near 0 or near the maximum (within 10 % of the
  range), anything else is refused. Written only when ``LightField.valid`` is set.
* The manifest is written last, so a folder without ``capture.toml`` is an unfinished capture.
* File names in the manifest are relative to the folder and may not leave it, on real paths
  too: a view file that is a symlink (or sits in a symlinked folder) pointing outside the
  folder is refused; a symlink that stays inside is fine.
* ``write_capture(..., overwrite=True)`` deletes only what the old capture left that the new
  one does not use, and only plain files really inside the folder (see :func:`write_capture`).
"""

from __future__ import annotations

import contextlib
import math
import os
import stat
import sys
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from .._atomic import atomic_write_bytes
from .._options import check_values, choice, flag, path_like, rule
from .._parallel import thread_pool
from .._paths import leads_outside
from .._progress import progress_bar
from ..errors import DataNotFoundError, FormatError, InvalidInputError
from ..lightfield import LightField
from .hdf5 import read_cube_h5, write_cube_h5
from .images import read_image, read_images_same_size, write_image
from .pfm import read_pfm, write_pfm

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["read_capture", "write_capture", "is_capture", "gt_cube_file", "MANIFEST",
           "CAPTURE_FORMAT"]

MANIFEST = "capture.toml"
CAPTURE_FORMAT = "hyperlf-capture"
VERSION = 1
_KNOWN_KEYS = {"format", "version", "grid", "reference", "disparity_range", "bit_depth",
               "channels", "gt_disparity", "gt_cube", "valid", "view", "calibration",
               "metadata"}


def is_capture(folder: str | os.PathLike) -> bool:
    """True when ``folder`` is a folder with a ``capture.toml`` manifest.

    Parameters
    ----------
    folder : path-like
        Any path.

    Returns
    -------
    bool

    Examples
    --------
    >>> import os, tempfile
    >>> from hyperlf.lightfield import LightField
    >>> folder = tempfile.mkdtemp()
    >>> is_capture(folder)                          # an empty folder
    False
    >>> lf = LightField(views=np.full((2, 2, 8, 10), 0.5, dtype=np.float32))
    >>> man = write_capture(lf, os.path.join(folder, "cap"))
    >>> is_capture(man.parent), is_capture(man)     # the folder, not the manifest file
    (True, False)
    """
    p = Path(path_like(folder, "folder", folder=None))
    return p.is_dir() and (p / MANIFEST).is_file()


def _err(manifest: Path, what: str) -> FormatError:
    return FormatError(f"{manifest}: {what}")


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v) -> bool:
    return (isinstance(v, (int, float)) and not isinstance(v, bool)) and math.isfinite(v)


def _pair(man: Path, doc: dict, key: str, kind: str, required: bool):
    v = doc.get(key)
    if v is None:
        if required:
            raise _err(man, f"missing '{key}'; add e.g. {key} = [5, 6]")
        return None
    ok = _is_int if kind == "int" else _is_num
    if not isinstance(v, list) or len(v) != 2 or not all(ok(x) for x in v):
        raise _err(man, f"'{key}' must be a list of two {'integers' if kind == 'int' else 'numbers'}, got {v!r}")
    return tuple(int(x) if kind == "int" else float(x) for x in v)


def _entry_parts(name: str) -> tuple[str, ...] | None:
    """The components of a relative manifest file name; None when it is absolute or uses '..'."""
    pp = PurePosixPath(name.replace("\\", "/"))
    if pp.is_absolute() or ".." in pp.parts or Path(name).is_absolute() or not pp.parts:
        return None
    return pp.parts


def _safe_file(man: Path, root: Path, name, what: str) -> Path:
    """The file ``name`` of the manifest ``man``, refused unless it stays inside ``root``.

    The check is on real paths too: a symlinked file or folder leading out of the capture
    folder is refused before anything is read.
    """
    if not isinstance(name, str) or not name.strip():
        raise _err(man, f"{what} must be a non-empty file name string, got {name!r}")
    parts = _entry_parts(name)
    if parts is None:
        raise _err(man, f"{what} {name!r} must be a path inside the capture folder")
    path = root / Path(*parts)
    if leads_outside(root, path):
        raise _err(man, f"{what} {name!r} resolves outside the capture folder (to "
                        f"{os.path.realpath(path)}); copy the file into the folder instead of "
                        "linking to it")
    return path


def _read_manifest(root: Path) -> tuple[Path, dict]:
    """The parsed ``capture.toml`` of ``root`` (errors say what is missing or malformed)."""
    if not root.is_dir():
        raise DataNotFoundError(f"capture folder {root} does not exist")
    man = root / MANIFEST
    if not man.is_file():
        has_images = any(f.suffix.lower() in (".png", ".tif", ".tiff") for f in root.iterdir())
        hint = (" (it holds images: the capture was not finished writing, since the manifest is "
                "written last; write it again)" if has_images else "")
        raise DataNotFoundError(f"no {MANIFEST} manifest in {root}{hint}")
    try:
        doc = tomllib.loads(man.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise _err(man, "is not UTF-8 text; save the manifest as UTF-8 TOML") from None
    except tomllib.TOMLDecodeError as exc:
        raise _err(man, f"is not valid TOML ({str(exc).splitlines()[0]}); fix the syntax") from None
    except OSError as exc:
        raise _err(man, f"cannot be read ({exc.strerror or exc})") from None
    return man, doc


def _manifest_header(man: Path, doc: dict) -> dict[str, Any]:
    """Checked top-level keys: grid, reference, disparity range, bit depth, channels."""
    fmt = doc.get("format")
    if fmt != CAPTURE_FORMAT:
        raise _err(man, f"format is {fmt!r}, expected format = \"{CAPTURE_FORMAT}\"")
    ver = doc.get("version")
    if not _is_int(ver) or ver < 1:
        raise _err(man, f"version must be a positive integer, got {ver!r}")
    if ver > VERSION:
        raise _err(man, f"version {ver} is newer than this hyperlf reads ({VERSION}); upgrade hyperlf")
    R, C = _pair(man, doc, "grid", "int", True)
    if R < 1 or C < 1:
        raise _err(man, f"grid must be at least [1, 1], got [{R}, {C}]")
    reference = _pair(man, doc, "reference", "int", False)
    if reference is not None and not (0 <= reference[0] < R and 0 <= reference[1] < C):
        raise _err(man, f"reference {list(reference)} is outside the {R} x {C} grid "
                        f"(rows 0..{R - 1}, cols 0..{C - 1})")
    drange = _pair(man, doc, "disparity_range", "num", False)
    if drange is not None and not drange[0] < drange[1]:
        raise _err(man, f"disparity_range must be [min, max] with min < max, got {list(drange)}")
    bit_depth = doc.get("bit_depth", 16)
    if bit_depth not in (8, 16, 32) or isinstance(bit_depth, bool):
        raise _err(man, f"bit_depth must be 8, 16 or 32, got {bit_depth!r}")
    channels = doc.get("channels", 1)
    if channels not in (1, 3) or isinstance(channels, bool):
        raise _err(man, f"channels must be 1 (monochrome) or 3 (RGB), got {channels!r}")
    for key in ("calibration", "metadata"):
        if key in doc and not isinstance(doc[key], dict):
            raise _err(man, f"'{key}' must be a table ([{key}]), got {type(doc[key]).__name__}")
    return dict(R=R, C=C, reference=reference, drange=drange, bit_depth=bit_depth,
                channels=channels)


def _view_entry(man: Path, root: Path, i: int, e: dict, R: int, C: int, files: dict,
                wl: np.ndarray, pos: np.ndarray) -> bool:
    """Check one ``[[view]]`` table and record it; True when it gives a wavelength."""
    r, c = e.get("row"), e.get("col")
    if not (_is_int(r) and _is_int(c)):
        raise _err(man, f"view #{i + 1} needs integer 'row' and 'col', got row={r!r}, col={c!r}")
    if not (0 <= r < R and 0 <= c < C):
        raise _err(man, f"view #{i + 1} at ({r}, {c}) is outside grid = [{R}, {C}]; "
                        "fix the view or the grid")
    if (r, c) in files:
        raise _err(man, f"view ({r}, {c}) is listed twice; keep one [[view]] per (row, col)")
    files[(r, c)] = _safe_file(man, root, e.get("file"), f"view ({r}, {c}) 'file'")
    has_wl = "wavelength" in e
    if has_wl:
        w = e["wavelength"]
        if not _is_num(w) or w <= 0:
            raise _err(man, f"view ({r}, {c}) wavelength must be a positive number (nm), got {w!r}")
        wl[r, c] = float(w)
    if "position" in e:
        pv = e["position"]
        if not isinstance(pv, list) or len(pv) != 2 or not all(_is_num(x) for x in pv):
            raise _err(man, f"view ({r}, {c}) position must be [px, py] numbers, got {pv!r}")
        pos[r, c] = pv
    else:
        pos[r, c] = (c, r)
    return has_wl


def _view_table(man: Path, root: Path, doc: dict, R: int, C: int):
    """Files, wavelengths (NaN when absent), positions and wavelength count of every view."""
    entries = doc.get("view")
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise _err(man, "needs one [[view]] table per view (row, col, file, wavelength)")
    files: dict[tuple[int, int], Path] = {}
    wl = np.full((R, C), np.nan)
    pos = np.full((R, C, 2), np.nan)
    n_wl = 0
    for i, e in enumerate(entries):
        n_wl += _view_entry(man, root, i, e, R, C, files, wl, pos)
    missing = [(r, c) for r in range(R) for c in range(C) if (r, c) not in files]
    if missing:
        shown = ", ".join(f"({r}, {c})" for r, c in missing[:10])
        raise _err(man, f"grid = [{R}, {C}] but {len(missing)} view(s) are not listed: {shown}"
                        f"{' ...' if len(missing) > 10 else ''}")
    if 0 < n_wl < R * C:
        raise _err(man, f"only {n_wl} of {R * C} views give a wavelength; give it for all or none")
    absent = [f"({r}, {c}) {p.name}" for (r, c), p in sorted(files.items()) if not p.is_file()]
    if absent:
        raise DataNotFoundError(
            f"capture {root}: {len(absent)} view file(s) not found: {', '.join(absent[:6])}"
            f"{' ...' if len(absent) > 6 else ''}"
        )
    return files, wl, pos, n_wl


def _read_views(root: Path, files: dict, R: int, C: int, channels: int) -> np.ndarray:
    order = [(r, c) for r in range(R) for c in range(C)]
    rc_of = {files[rc]: rc for rc in order}
    stack = read_images_same_size(
        [files[rc] for rc in order], lambda f: _load_view(f, channels, rc_of[f]),
        f"capture {root}", labels=[f"view {rc} ({files[rc].name})" for rc in order])
    return stack.reshape((R, C) + stack.shape[1:])


def _gt_disparity_files(man: Path, root: Path, gspec, R: int, C: int,
                        key: str = "gt_disparity"):
    """The checked file(s) named by ``gt_disparity`` (or the manifest entry ``key``): None,
    one path, or {(row, col): path}."""
    if gspec is None:
        return None
    if not isinstance(gspec, str):
        raise _err(man, f"{key} must be a file name or pattern, got {gspec!r}")
    if not _is_gt_pattern(man, gspec, key):
        return _safe_file(man, root, _short_name(man, gspec, key), key)
    files = {}
    for r, c in [(r, c) for r in range(R) for c in range(C)]:
        name = _short_name(man, gspec.format(row=r, col=c), key)
        files[(r, c)] = _safe_file(man, root, name, key)
    return files


def _is_gt_pattern(man: Path, gspec: str, key: str = "gt_disparity") -> bool:
    """Whether ``gspec`` has ``{row}``/``{col}`` fields; any other field (attributes, indices,
    conversions, wide or odd format specs, stray braces) is a FormatError
    (:func:`hyperlf.formats.patterns.pattern_fields` decides)."""
    from .patterns import pattern_fields

    try:
        return bool(pattern_fields(gspec, ("row", "col"), what=f"{key} pattern"))
    except InvalidInputError as exc:
        raise _err(man, str(exc)) from None


def _short_name(man: Path, name: str, key: str = "gt_disparity") -> str:
    """``name``, refused when one of its parts is longer than a file name can be (255 bytes)."""
    if any(len(os.fsencode(part)) > 255 for part in name.replace("\\", "/").split("/")):
        raise _err(man, f"{key} names a file over 255 bytes long ({name[:40]}...); "
                        "use a shorter name")
    return name


def _read_gt_disparity(man: Path, root: Path, gfiles, R: int, C: int, H: int, W: int):
    """The ground truth from :func:`_gt_disparity_files`' answer, or None."""
    if gfiles is None:
        return None
    if isinstance(gfiles, Path):
        gt = read_pfm(gfiles)
        if gt.shape != (H, W):
            raise _err(man, f"ground truth {gfiles.relative_to(root).as_posix()} is {gt.shape}, "
                            f"views are {(H, W)}")
        return gt
    gt = np.empty((R, C, H, W), dtype=np.float32)
    for (r, c), path in gfiles.items():
        g = read_pfm(path)
        if g.shape != (H, W):
            raise _err(man, f"ground truth {path.relative_to(root).as_posix()} is {g.shape}, "
                            f"views are {(H, W)}")
        gt[r, c] = g
    return gt


def _valid_files(man: Path, root: Path, vspec, R: int, C: int):
    """The checked mask files named by the ``valid`` pattern: None or {(row, col): path}."""
    files = _gt_disparity_files(man, root, vspec, R, C, key="valid")
    if isinstance(files, Path):
        raise _err(man, f"valid must be a pattern with {{row}} and {{col}} (one mask per view), "
                        f"got {vspec!r}; e.g. valid = \"valid_r{{row}}_c{{col}}.png\"")
    return files


def _read_mask(man: Path, root: Path, path: Path, H: int, W: int) -> np.ndarray:
    """One validity mask file as bool (H, W): near-0 = invalid, near-maximum = valid."""
    name = path.relative_to(root).as_posix()
    im = read_image(path, as_float=False)
    if im.ndim == 3:
        if not all(np.array_equal(im[..., 0], im[..., k]) for k in range(1, im.shape[2])):
            raise _err(man, f"mask {name} is a colour image; save it as 8-bit grey (0 / 255)")
        im = im[..., 0]
    if im.shape != (H, W):
        raise _err(man, f"mask {name} is {im.shape}, views are {(H, W)}")
    top = float(np.iinfo(im.dtype).max) if np.issubdtype(im.dtype, np.integer) else 1.0
    x = im.astype(np.float64) / top
    if not np.all(np.isfinite(x)) or np.any((x > 0.1) & (x < 0.9)) or np.any((x < 0) | (x > 1)):
        raise _err(man, f"mask {name} holds values that are neither ~0 (invalid) nor ~{top:g} "
                        "(valid); save it as 0 / 255")
    return x >= 0.5


def _read_valid(man: Path, root: Path, vfiles, R: int, C: int, H: int, W: int):
    """The validity masks (R, C, H, W) bool from :func:`_valid_files`' answer, or None."""
    if vfiles is None:
        return None
    valid = np.empty((R, C, H, W), dtype=bool)
    for (r, c), path in vfiles.items():
        valid[r, c] = _read_mask(man, root, path, H, W)
    return valid


def _read_gt_cube(man: Path, cfile: Path | None, cspec, R: int, C: int, H: int, W: int):
    if cfile is None:
        return None, None
    cube, cube_wl, _mask = read_cube_h5(cfile)
    if cube.shape[:2] != (R, C) or cube.shape[3:] != (H, W):
        raise _err(man, f"gt_cube {cspec} has shape {cube.shape}, expected ({R}, {C}, B, {H}, {W})")
    return cube, cube_wl


def _manifest_metadata(doc: dict, root: Path, bit_depth: int) -> dict[str, Any]:
    metadata: dict[str, Any] = dict(doc.get("metadata", {}))
    if "calibration" in doc:
        metadata["calibration"] = doc["calibration"]
    extra = {k: v for k, v in doc.items() if k not in _KNOWN_KEYS}
    if extra:
        metadata["manifest_extra"] = extra
    metadata["capture_folder"] = str(root)
    metadata["bit_depth"] = bit_depth
    return metadata


def gt_cube_file(folder: str | os.PathLike) -> Path | None:
    """The ground-truth cube file a capture's manifest names (checked to stay inside the
    folder, as :func:`read_capture` does), or None when it names none; for reading the cube
    view by view (:func:`hyperlf.formats.open_gt_cube`).

    Examples
    --------
    >>> import os, tempfile
    >>> from hyperlf.lightfield import LightField
    >>> cube = np.random.default_rng(0).random((2, 2, 3, 8, 10)).astype(np.float32)
    >>> lf = LightField(views=cube[:, :, 0], gt_cube=cube, cube_wavelengths=[450, 550, 650])
    >>> man = write_capture(lf, os.path.join(tempfile.mkdtemp(), "cap"))
    >>> f = gt_cube_file(man.parent)
    >>> f == man.parent / "gt_cube.h5"
    True
    >>> from hyperlf.formats.hdf5 import read_cube_h5
    >>> bool(np.array_equal(read_cube_h5(f)[0], cube))
    True
    >>> lf = LightField(views=cube[:, :, 0])
    >>> man = write_capture(lf, os.path.join(tempfile.mkdtemp(), "cap"))
    >>> print(gt_cube_file(man.parent))             # no ground-truth cube
    None
    """
    root = Path(path_like(folder, "folder", folder=None))
    man, doc = _read_manifest(root)
    cspec = doc.get("gt_cube")
    return None if cspec is None else _safe_file(man, root, cspec, "gt_cube")


def read_capture(folder: str | os.PathLike, *, cube: bool = True) -> LightField:
    """Read a capture folder (``cube=False``: without the ground-truth cube, which can be many
    times the size of the views; its file is still checked to stay inside the folder).

    Parameters
    ----------
    folder : path-like
        Folder holding ``capture.toml`` and the view images.

    Returns
    -------
    LightField
        ``views`` float32 ``(R, C, H, W)`` (or ``(R, C, H, W, 3)`` with ``channels = 3``) in
        [0, 1]; wavelengths (nm), positions, reference, disparity range, ground truth and
        validity masks (``valid``) from the manifest; ``metadata`` holds the ``[metadata]`` table, ``calibration`` and
        ``capture_folder``.

    Raises
    ------
    DataNotFoundError
        When the folder, the manifest or a file it names is missing.
    FormatError
        When the manifest is malformed or inconsistent (one line saying what and where), or
        names a file that leaves the folder: an absolute path, ``..``, or a symlinked file or
        folder whose real path is outside it (checked before any file is decoded).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from hyperlf.synthesis import procedural_scene
    >>> lf = procedural_scene(seed=3, rows=2, cols=2, height=12, width=16)
    >>> man = write_capture(lf, pathlib.Path(tempfile.mkdtemp()) / "cap")
    >>> back = read_capture(man.parent)
    >>> back.views.shape, bool(abs(back.views - lf.views).max() < 1e-4)
    ((2, 2, 12, 16), True)
    """
    root = Path(path_like(folder, "folder", folder=None))
    cube = flag(cube, "cube")
    man, doc = _read_manifest(root)
    hd = _manifest_header(man, doc)
    R, C = hd["R"], hd["C"]
    files, wl, pos, n_wl = _view_table(man, root, doc, R, C)
    gfiles = _gt_disparity_files(man, root, doc.get("gt_disparity"), R, C)
    vfiles = _valid_files(man, root, doc.get("valid"), R, C)
    cspec = doc.get("gt_cube")
    cfile = None if cspec is None else _safe_file(man, root, cspec, "gt_cube")
    views = _read_views(root, files, R, C, hd["channels"])
    H, W = views.shape[2:4]
    gt = _read_gt_disparity(man, root, gfiles, R, C, H, W)
    valid = _read_valid(man, root, vfiles, R, C, H, W)
    gt_cube, cube_wl = _read_gt_cube(man, cfile, cspec, R, C, H, W) if cube else (None, None)
    metadata = _manifest_metadata(doc, root, hd["bit_depth"])
    try:
        return LightField(
            views=views, wavelengths=wl if n_wl else None, positions=pos,
            reference=hd["reference"], disparity_range=hd["drange"], gt_disparity=gt,
            gt_cube=gt_cube, cube_wavelengths=cube_wl, metadata=metadata, valid=valid,
        )
    except InvalidInputError as exc:
        raise _err(man, f"describes an invalid light field: {exc}") from None


def _load_view(path: Path, channels: int, rc) -> np.ndarray:
    im = read_image(path, as_float=True)
    if channels == 1:
        if im.ndim == 3:
            if np.array_equal(im[..., 0], im[..., 1]) and np.array_equal(im[..., 0], im[..., 2]):
                return im[..., 0]
            raise FormatError(
                f"view {rc} file {path} is a colour image but the capture is monochrome; convert "
                "it to grey (hyperlf.formats.to_grey) or set channels = 3 in the manifest"
            )
        return im
    if im.ndim == 2:
        return np.repeat(im[..., None], 3, axis=2)
    return im


# ----------------------------------------------------------------------------- writing
def _toml_value(v: Any):
    """Convert to something TOML can hold; None -> dropped (returns a sentinel)."""
    if v is None:
        return _DROP
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, bool) or isinstance(v, (int, str)):
        return v
    if isinstance(v, float):
        return v  # tomli-w writes nan/inf as TOML's nan/inf
    if isinstance(v, dict):
        out = {}
        for k, x in v.items():
            y = _toml_value(x)
            if y is not _DROP:
                out[str(k)] = y
        return out
    if isinstance(v, (list, tuple, set)):
        return [y for y in (_toml_value(x) for x in v) if y is not _DROP]
    if isinstance(v, os.PathLike):
        return os.fspath(v)
    return str(v)


_DROP = object()


#: The options of :func:`write_capture`, checked before any work.
_WRITE_RULES = {"folder": rule(path_like, folder=True),
                "bit_depth": rule(choice, choices=(8, 16, 32)), "overwrite": flag,
                "image_format": rule(choice, choices=("png", "tiff", "tif")), "progress": flag}


def _check_write_args(lf: Any, bit_depth: int, image_format: str) -> str:
    """Validate the arguments of :func:`write_capture`; the view files' suffix."""
    if not isinstance(lf, LightField):
        raise InvalidInputError(f"expected a LightField, got {type(lf).__name__}")
    if lf.channels not in (1, 3):
        raise InvalidInputError(
            f"a capture holds monochrome or RGB views, got {lf.channels} channels per view"
        )
    if bit_depth != 32:
        lo, hi = float(lf.views.min()), float(lf.views.max())
        if lo < 0 or hi > 1:
            raise InvalidInputError(
                f"views range {lo:.4g}..{hi:.4g} does not fit {bit_depth}-bit files (0..1); "
                "rescale them or use bit_depth=32 (float TIFF)"
            )
    return ".tif" if (bit_depth == 32 or image_format != "png") else ".png"


def _old_capture_files(man: Path) -> set[str]:
    """Files named by an existing manifest (empty when it cannot be read)."""
    try:
        old = tomllib.loads(man.read_text(encoding="utf-8"))
        old_files = {e["file"] for e in old.get("view", []) if isinstance(e, dict)
                     and isinstance(e.get("file"), str)}
        for k in ("gt_disparity", "gt_cube"):
            if isinstance(old.get(k), str) and "{" not in old[k]:
                old_files.add(old[k])
    except Exception:  # an unreadable old manifest is simply replaced
        old_files = set()
    return old_files


def _prepare_folder(root: Path, man: Path, overwrite: bool) -> set[str]:
    """Create ``root``; with ``overwrite`` remove the old manifest and return its files."""
    old_files: set[str] = set()
    if root.exists():
        if not root.is_dir():
            raise InvalidInputError(f"{root} exists and is not a folder")
        if any(root.iterdir()):
            if not overwrite:
                raise InvalidInputError(
                    f"{root} is not empty; choose a new folder or pass overwrite=True"
                )
            if man.is_file():
                old_files = _old_capture_files(man)
                man.unlink()  # the folder is visibly incomplete until the new manifest lands
    root.mkdir(parents=True, exist_ok=True)
    return old_files


def _write_views(lf: LightField, root: Path, ext: str, bit_depth: int, progress: bool,
                 new_files: set[str]) -> list[dict[str, Any]]:
    """Write every view (in parallel: encoding 16-bit PNGs is the slow part); the entries."""
    R, C = lf.grid_shape
    entries = []
    jobs = []
    for r in range(R):
        for c in range(C):
            name = f"view_r{r}_c{c}{ext}"
            e: dict[str, Any] = {"row": r, "col": c, "file": name}
            if lf.wavelengths is not None:
                e["wavelength"] = float(lf.wavelengths[r, c])
            e["position"] = [float(v) for v in lf.positions[r, c]]
            entries.append(e)
            jobs.append((root / name, lf.views[r, c]))
            new_files.add(name)
    with thread_pool(min(8, len(jobs))) as pool:
        results = pool.map(lambda j: write_image(j[0], j[1], bit_depth=bit_depth), jobs)
        list(progress_bar(results, "writing views", total=len(jobs), enabled=progress,
                          unit="view"))
    return entries


def _write_ground_truth(lf: LightField, root: Path, doc: dict, new_files: set[str]) -> None:
    """Write the ground-truth disparity, the validity masks and the cube (if any) and name
    them in ``doc``."""
    R, C = lf.grid_shape
    if lf.gt_disparity is not None:
        if lf.gt_disparity.ndim == 2:
            doc["gt_disparity"] = "gt_disparity.pfm"
            write_pfm(root / "gt_disparity.pfm", lf.gt_disparity)
            new_files.add("gt_disparity.pfm")
        else:
            doc["gt_disparity"] = "gt_disparity_r{row}_c{col}.pfm"
            for r in range(R):
                for c in range(C):
                    name = f"gt_disparity_r{r}_c{c}.pfm"
                    write_pfm(root / name, lf.gt_disparity[r, c])
                    new_files.add(name)
    if lf.valid is not None:
        doc["valid"] = "valid_r{row}_c{col}.png"
        for r in range(R):
            for c in range(C):
                name = f"valid_r{r}_c{c}.png"
                write_image(root / name, lf.valid[r, c].astype(np.uint8) * np.uint8(255))
                new_files.add(name)
    if lf.gt_cube is not None:
        doc["gt_cube"] = "gt_cube.h5"
        write_cube_h5(root / "gt_cube.h5", lf.gt_cube, lf.cube_wavelengths)
        new_files.add("gt_cube.h5")


def _metadata_tables(lf: LightField, doc: dict) -> None:
    """Add the ``[calibration]`` and ``[metadata]`` tables of ``lf`` to ``doc``."""
    meta = {k: v for k, v in lf.metadata.items()
            if k not in ("calibration", "capture_folder", "bit_depth", "manifest_extra")}
    if "calibration" in lf.metadata:
        cal = _toml_value(lf.metadata["calibration"])
        if isinstance(cal, dict):
            doc["calibration"] = cal
        elif cal is not _DROP:
            meta["calibration"] = cal
    meta_t = _toml_value(meta)
    if meta_t:
        doc["metadata"] = meta_t


def _unlink_plain_file(root: Path, parts: tuple[str, ...], protected: set) -> None:
    """Unlink ``root/parts`` only when it is a regular file reached through real folders.

    Each folder on the way is opened with ``O_NOFOLLOW`` relative to the previous one, so a
    symlinked folder (even one swapped in meanwhile) is never followed; the last component is
    examined without following it, so a symlink is left alone, and ``protected`` (device, inode)
    pairs are never unlinked.
    """
    if not {os.open, os.stat, os.unlink} <= os.supports_dir_fd:  # pragma: no cover - not POSIX
        path = root.joinpath(*parts)
        if os.path.realpath(path) != os.path.join(os.path.realpath(root), *parts):
            return
        st = os.lstat(path)
        if stat.S_ISREG(st.st_mode) and (st.st_dev, st.st_ino) not in protected:
            path.unlink()
        return
    dir_flags = os.O_RDONLY | os.O_DIRECTORY
    fd = os.open(root, dir_flags)
    try:
        for part in parts[:-1]:
            sub = os.open(part, dir_flags | os.O_NOFOLLOW, dir_fd=fd)
            os.close(fd)
            fd = sub
        st = os.stat(parts[-1], dir_fd=fd, follow_symlinks=False)
        if stat.S_ISREG(st.st_mode) and (st.st_dev, st.st_ino) not in protected:
            os.unlink(parts[-1], dir_fd=fd)
    finally:
        os.close(fd)


def _remove_stale(root: Path, old_names: set[str], keep: set[str]) -> None:
    """Delete the files the old manifest named that the new capture does not use.

    Only plain files really inside ``root`` go. Left alone: the manifest and every file in
    ``keep`` (what the new capture wrote, also matched by inode), an absolute name or one with
    '..', anything reached through a symlinked folder, a symlink itself (the writer did not make
    it, and its target is not the capture's), a folder, anything missing or unreadable.
    """
    keep = keep | {MANIFEST}
    protected = set()
    for name in keep:
        with contextlib.suppress(OSError):
            st = os.lstat(root / name)
            protected.add((st.st_dev, st.st_ino))
    for name in old_names:
        parts = _entry_parts(name) if isinstance(name, str) and name.strip() else None
        if parts is None or "/".join(parts) in keep:
            continue
        with contextlib.suppress(OSError):
            _unlink_plain_file(root, parts, protected)


def write_capture(lightfield: LightField, folder: str | os.PathLike, *, bit_depth: int = 16,
                  overwrite: bool = False, image_format: str = "png",
                  progress: bool = False) -> Path:
    """Write a light field as a capture folder (views, ground truth, validity masks, then
    ``capture.toml``).

    Parameters
    ----------
    lightfield : LightField
        Monochrome ``(R, C, H, W)`` or RGB ``(R, C, H, W, 3)`` views.
    folder : path-like
        Target folder (created).
    bit_depth : {8, 16, 32}
        8/16: integer PNG/TIFF, views must lie in [0, 1]. 32: float32 TIFF, values kept as
        they are.
    overwrite : bool
        Refuse (InvalidInputError) to write into a folder that is not empty unless True. When
        True, the old manifest is removed first and files it named but the new capture does not
        use are deleted afterwards, but only plain files really inside ``folder``: never the
        new manifest or a file the new capture wrote, never a symlink (the link and its target
        both stay), nor anything reached through ``..``, an absolute path or a symlinked folder.
    image_format : {"png", "tiff"}
        Container of the view files (``bit_depth=32`` always uses TIFF).
    progress : bool
        Show a progress bar while the views are written.

    Returns
    -------
    Path
        The manifest.

    Notes
    -----
    ``metadata`` entries that are None are dropped (TOML has no null); numpy values become
    lists/numbers, other objects their ``str``. ``metadata["calibration"]`` becomes the
    ``[calibration]`` table; keys the reader adds (``capture_folder``, ``bit_depth``) are not
    written back.

    Examples
    --------
    >>> import os, tempfile
    >>> from hyperlf.lightfield import LightField
    >>> rng = np.random.default_rng(1)
    >>> lf = LightField(views=rng.random((2, 2, 8, 10)).astype(np.float32),
    ...                 wavelengths=[[450.0, 500.0], [550.0, 600.0]], disparity_range=(-1.0, 1.0))
    >>> man = write_capture(lf, os.path.join(tempfile.mkdtemp(), "cap"))
    >>> man.name, sorted(p.name for p in man.parent.iterdir())
    ('capture.toml', ['capture.toml', 'view_r0_c0.png', 'view_r0_c1.png', 'view_r1_c0.png',
    'view_r1_c1.png'])
    >>> back = read_capture(man.parent)
    >>> back.views.shape, back.wavelengths.tolist(), back.disparity_range
    ((2, 2, 8, 10), [[450.0, 500.0], [550.0, 600.0]], (-1.0, 1.0))
    >>> bool(np.abs(back.views - lf.views).max() <= 0.5 / 65535 + 1e-7)   # 16-bit PNG views
    True
    >>> man = write_capture(lf, man.parent, bit_depth=32, overwrite=True)   # float32 TIFF views
    >>> bool(np.array_equal(read_capture(man.parent).views, lf.views))
    True
    >>> sorted(p.suffix for p in man.parent.iterdir())     # the old PNG views are removed
    ['.tif', '.tif', '.tif', '.tif', '.toml']
    """
    import tomli_w

    check_values(dict(folder=folder, bit_depth=bit_depth, overwrite=overwrite,
                      image_format=image_format, progress=progress), _WRITE_RULES)
    ext = _check_write_args(lightfield, bit_depth, image_format)
    lf = lightfield
    root = Path(folder)
    man = root / MANIFEST
    old_files = _prepare_folder(root, man, overwrite)

    R, C = lf.grid_shape
    doc: dict[str, Any] = {
        "format": CAPTURE_FORMAT,
        "version": VERSION,
        "grid": [R, C],
        "reference": list(lf.reference),
    }
    if lf.disparity_range is not None:
        doc["disparity_range"] = [float(v) for v in lf.disparity_range]
    doc["bit_depth"] = bit_depth
    doc["channels"] = lf.channels
    new_files: set[str] = set()
    entries = _write_views(lf, root, ext, bit_depth, progress, new_files)
    _write_ground_truth(lf, root, doc, new_files)
    doc["view"] = entries
    _metadata_tables(lf, doc)
    try:
        text = tomli_w.dumps(doc)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"metadata cannot be stored in TOML: {exc}") from None
    atomic_write_bytes(man, text.encode("utf-8"))  # last: marks the capture complete
    _remove_stale(root, old_files, new_files)
    return man
