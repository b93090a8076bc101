"""HDF5 storage of light fields and plenoptic cubes.

Light field file (``format = "hyperlf-lightfield"``)
----------------------------------------------------
``/views`` (R, C, H, W[, K]) float32, one view per chunk; ``/positions`` (R, C, 2);
``/wavelengths`` (R, C) nm (optional); ``/gt_disparity`` (H, W) or (R, C, H, W) (optional);
``/gt_cube`` (R, C, B, H, W), one band of one view per chunk, with ``/cube_wavelengths`` (B,)
(optional); ``/valid`` (R, C, H, W) uint8 0/1, the per-view validity mask (optional, written
only when ``lf.valid`` is set). Root attributes: ``format``, ``version``, ``reference`` (2,),
``disparity_range`` (2,) when known, ``metadata`` (a JSON string).

Cube file (``format = "hyperlf-cube"``)
---------------------------------------
``/cube`` (R, C, B, H, W) float32, one (view, band) per chunk; ``/wavelengths`` (B,);
``/mask`` (R, C, H, W) bool (True = valid pixel), optional. :class:`CubeWriter` fills it view by
view so that a full cube never has to sit in memory; :func:`open_cube_h5` reads it lazily.

All writers write to a temporary file beside the target and rename it when complete.

Text attributes (``format``, ``metadata``) are fixed-length UTF-8 strings since version 2
(files need HDF5 1.8 or later to read): a variable-length string lives in the file's global
heap, and a corrupted heap can send libhdf5 into an endless loop that no Python code can
interrupt. Version 1 files, which stored them as variable-length strings, are still read: those
attributes are read in a child process with a time limit (:data:`HEAP_READ_TIMEOUT_S`), so a
corrupt one gives an error instead of a hang.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from .._atomic import atomic_path, publish, temporary_beside
from .._options import (bool_mask, choice, flag, index, integer, mapping, path_like,
                        real_array, shown)
from ..errors import DataNotFoundError, FormatError, HyperLFError, InvalidInputError
from ..lightfield import LightField
from ..spectral import wavelengths_unknown
from ._h5chunks import read_images, write_images

__all__ = [
    "write_lightfield_h5",
    "read_lightfield_h5",
    "open_lightfield_gt_cube",
    "write_cube_h5",
    "read_cube_h5",
    "CubeWriter",
    "CubeFile",
    "ChunkedImages",
    "open_cube_h5",
]

LF_FORMAT = "hyperlf-lightfield"
CUBE_FORMAT = "hyperlf-cube"
VERSION = 2
#: Seconds a child process may take to read a version-1 text attribute (see the module notes).
HEAP_READ_TIMEOUT_S = 30.0
#: HDF5 file-format versions the writers use: 1.8 and later (large fixed-length attributes).
_LIBVER = ("v108", "latest")


def _h5py():
    import h5py

    return h5py


def _compression(compression):
    choice(compression, "compression", (None, "none", False, "gzip", "lzf"))
    if compression in (None, "none", False):
        return {}
    if compression == "gzip":
        return {"compression": "gzip", "compression_opts": 4, "shuffle": True}
    if compression == "lzf":
        return {"compression": "lzf", "shuffle": True}
    raise InvalidInputError(f"compression must be 'gzip', 'lzf' or None, got {compression!r}")


def _json_default(o: Any):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (set, tuple)):
        return list(o)
    if isinstance(o, os.PathLike):
        return os.fspath(o)
    return str(o)


def _dump_metadata(meta: dict) -> str:
    return json.dumps(meta, default=_json_default, allow_nan=True)


def _write_header(f, fmt: str, metadata: dict) -> None:
    """The root attributes every hyperlf HDF5 file carries, text as fixed-length strings."""
    f.attrs["format"] = np.bytes_(fmt.encode())
    f.attrs["version"] = VERSION
    f.attrs["metadata"] = np.bytes_(_dump_metadata(metadata).encode())


_CHILD_READ = (
    "import sys, h5py\n"
    "with h5py.File(sys.argv[1], 'r') as f:\n"
    "    v = f.attrs[sys.argv[2]]\n"
    "sys.stdout.buffer.write(v.encode() if isinstance(v, str) else bytes(v))\n"
)


def _uses_heap(f, name: str) -> bool:
    """Whether root attribute ``name`` is stored in the global heap (variable-length data)."""
    h5t = _h5py().h5t
    t = f.attrs.get_id(name).get_type()
    return bool(t.detect_class(h5t.VLEN)) or (
        isinstance(t, h5t.TypeStringID) and bool(t.is_variable_str()))


def _read_heap_attr(p: Path, name: str) -> bytes:
    """Root attribute ``name`` read in a child process that may take HEAP_READ_TIMEOUT_S."""
    try:
        out = subprocess.run([sys.executable, "-c", _CHILD_READ, os.fspath(p), name],
                             capture_output=True, timeout=HEAP_READ_TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired:
        raise FormatError(f"{p}: reading the '{name}' attribute did not finish in "
                          f"{HEAP_READ_TIMEOUT_S:g} s (its heap is corrupt); re-create the "
                          "file with hyperlf") from None
    if out.returncode != 0:
        raise FormatError(f"{p}: cannot read the '{name}' attribute; the file is corrupt, "
                          "re-create it with hyperlf")
    return out.stdout


def _text_attr(p: Path, f, name: str) -> str | None:
    """Root text attribute ``name`` (None when absent), never read through the heap in-process."""
    if name not in f.attrs:
        return None
    raw = _read_heap_attr(p, name) if _uses_heap(f, name) else f.attrs[name]
    if isinstance(raw, bytes):
        return raw.decode(errors="replace")
    return raw if isinstance(raw, str) else str(raw)


@contextlib.contextmanager
def _open_read(path: str | os.PathLike, expected: str):
    h5py = _h5py()
    p = Path(path_like(path, folder=None))
    if not p.is_file():
        raise DataNotFoundError(f"HDF5 file {p} does not exist")
    try:
        f = h5py.File(p, "r")
    except OSError:
        raise FormatError(
            f"{p} is not a readable HDF5 file (corrupt or another format); "
            "re-create it with hyperlf (hyperlf convert, or hyperlf.save)"
        ) from None
    try:
        fmt = _text_attr(p, f, "format")
        if {fmt, expected} == {LF_FORMAT, CUBE_FORMAT}:  # hyperlf's other kind: readable,
            raise InvalidInputError(_other_kind(p, fmt))  # but the wrong input (exit 2)
        if fmt != expected:
            raise FormatError(
                f"{p} is an HDF5 file but not a {expected} file (format attribute {str(fmt)[:40]!r}); "
                f"write it with hyperlf's {'write_lightfield_h5' if expected == LF_FORMAT else 'write_cube_h5'}"
            )
        yield p, f
    except HyperLFError:
        raise
    except Exception as exc:  # whatever else a corrupt file makes h5py raise
        raise _corrupt(p, exc) from None
    finally:
        f.close()


def _other_kind(p: Path, fmt: str) -> str:
    """The one-line message for a cube file where a light field is expected, or the reverse."""
    if fmt == CUBE_FORMAT:
        return (f"{p} is a cube file (hyperlf complete's output), not a light field: give the "
                f"capture it was completed from ('hyperlf info {p}' describes the cube)")
    return (f"{p} is a light field file, not a cube: complete it first "
            f"('hyperlf complete {p} -o OUT', then use OUT/cube.h5)")


def _corrupt(p: Path, exc: Exception) -> FormatError:
    """The one-line error for an unexpected h5py failure on a corrupt file."""
    first = str(exc).splitlines()[0][:80] if str(exc) else ""
    return FormatError(f"{p}: cannot read the file ({type(exc).__name__}: {first}); "
                       "it is corrupt, re-create it with hyperlf")


def _dataset(p: Path, f, name: str, required: bool = True):
    """The h5py dataset ``/name``, or None when absent and not required."""
    h5py = _h5py()
    try:
        obj = f.get(name)
    except Exception as exc:  # a corrupt object header
        raise FormatError(f"{p}: cannot open '/{name}' ({type(exc).__name__}); the file is corrupt") from None
    if obj is None:
        if required:
            raise FormatError(f"{p} has no dataset '/{name}'; the file is incomplete or corrupt")
        return None
    if not isinstance(obj, h5py.Dataset):
        raise FormatError(f"{p}: '/{name}' is a {type(obj).__name__.lower()}, not a dataset; "
                          "the file was not written by hyperlf or is corrupt")
    return obj


def _check_numeric(p: Path, name: str, ds) -> None:
    """Refuse a dataset of strings, compounds or complex numbers."""
    if ds.dtype.kind not in "biuf":
        raise FormatError(f"{p}: '/{name}' holds {ds.dtype} values, not real numbers; "
                          "the file was not written by hyperlf or is corrupt")


def _check_fits(p: Path, name: str, nbytes: int) -> None:
    """Refuse to read ``nbytes`` that cannot fit in this machine's memory."""
    try:
        ram = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        ram = 2 ** 40
    if nbytes > ram:
        raise FormatError(
            f"{p}: '/{name}' needs {nbytes / 1e9:.1f} GB of memory but this machine has "
            f"{ram / 1e9:.1f} GB; read it lazily with open_cube_h5 or on a larger machine"
        )


def _read(p: Path, name: str, ds, sel=()):
    """``ds[sel]`` as numbers, any decoding failure (e.g. a corrupt chunk) a FormatError."""
    try:
        return read_images(ds, sel)
    except Exception as exc:  # h5py raises OSError/KeyError/TypeError on corrupt data
        raise FormatError(f"{p}: cannot read dataset '/{name}' ({type(exc).__name__}); "
                          "the file is corrupt") from None


class ChunkedImages:
    """An h5py dataset indexed like an array, whole images read in parallel.

    For code that takes any array-like and reads it a view at a time
    (:func:`hyperlf.metrics.cube_scores`, :class:`hyperlf.lightfield.BlockMeanCube`): an index
    of leading integers is read by :func:`hyperlf.formats._h5chunks.read_images`, any other by
    h5py, and a chunk that cannot be decoded is a :class:`~hyperlf.errors.FormatError`.

    Parameters
    ----------
    ds : h5py.Dataset
    """

    def __init__(self, ds):
        self.ds = ds

    @property
    def shape(self) -> tuple[int, ...]:
        return self.ds.shape

    @property
    def dtype(self) -> np.dtype:
        return self.ds.dtype

    @property
    def ndim(self) -> int:
        return self.ds.ndim

    def __len__(self) -> int:
        return len(self.ds)

    def __getitem__(self, index) -> np.ndarray:
        sel = index if isinstance(index, tuple) else (index,)
        return _read(Path(self.ds.file.filename), self.ds.name.lstrip("/"), self.ds, sel)


def _get(p: Path, f, name: str, required: bool = True):
    ds = _dataset(p, f, name, required)
    if ds is None:
        return None
    _check_numeric(p, name, ds)
    _check_fits(p, name, ds.size * max(ds.dtype.itemsize, 4))
    return _read(p, name, ds)


def _pair_attr(p: Path, f, name: str, integral: bool):
    """Root attribute ``name`` as a pair of finite numbers (integers when ``integral``)."""
    if name not in f.attrs:
        return None
    raw = "variable-length data" if _uses_heap(f, name) else f.attrs[name]
    a = np.asarray(raw)
    ok = a.dtype.kind in "biuf" and a.size == 2 and a.ndim <= 1
    if ok:
        a = a.astype(np.float64)
        ok = bool(np.all(np.isfinite(a))) and (not integral or bool(
            np.all((a == np.round(a)) & (np.abs(a) < 2 ** 31))))
    if not ok:
        kind = "integers (row, col)" if integral else "finite numbers (min, max)"
        raise FormatError(f"{p}: the '{name}' attribute must be two {kind}, got "
                          f"{str(raw)[:40]!r}; the file is corrupt")
    return tuple(int(v) for v in a) if integral else tuple(float(v) for v in a)


def _metadata(p: Path, f, strict: bool) -> dict:
    """The 'metadata' JSON attribute as a dict ({} when not ``strict`` and unreadable)."""
    try:
        txt = _text_attr(p, f, "metadata")
    except FormatError:
        if strict:
            raise
        return {}
    try:
        meta = json.loads("{}" if txt is None else txt)
        if isinstance(meta, dict):
            return meta
    except (ValueError, TypeError):
        pass
    if not strict:
        return {}
    raise FormatError(f"{p}: the 'metadata' attribute is not a JSON object; the file is corrupt")


def write_lightfield_h5(path: str | os.PathLike, lf: LightField,
                        compression: str | None = "gzip") -> Path:
    """Write a :class:`LightField` (every field) to an HDF5 file atomically.

    Parameters
    ----------
    path : path-like
        Target ``.h5`` file.
    lf : LightField
    compression : {"gzip", "lzf", None}

    Returns
    -------
    Path

    Examples
    --------
    >>> import os, tempfile
    >>> from hyperlf.lightfield import LightField
    >>> rng = np.random.default_rng(0)
    >>> lf = LightField(views=rng.random((2, 2, 8, 10)).astype(np.float32),
    ...                 wavelengths=[[450.0, 500.0], [550.0, 600.0]],
    ...                 gt_disparity=rng.random((8, 10)), disparity_range=(-1.0, 2.0))
    >>> p = write_lightfield_h5(os.path.join(tempfile.mkdtemp(), "lf.h5"), lf)
    >>> p.name
    'lf.h5'
    >>> back = read_lightfield_h5(p)
    >>> bool(np.array_equal(back.views, lf.views)), back.views.dtype.name
    (True, 'float32')
    >>> bool(np.array_equal(back.gt_disparity, lf.gt_disparity))
    True
    >>> back.wavelengths.tolist(), back.disparity_range, back.reference
    ([[450.0, 500.0], [550.0, 600.0]], (-1.0, 2.0), (0, 0))
    """
    h5py = _h5py()
    path_like(path)
    if not isinstance(lf, LightField):
        raise InvalidInputError(f"expected a LightField, got {type(lf).__name__}")
    comp = _compression(compression)
    R, C = lf.grid_shape
    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w", libver=_LIBVER) as f:
            _write_header(f, LF_FORMAT, lf.metadata)
            f.attrs["reference"] = np.asarray(lf.reference, dtype=np.int64)
            if lf.disparity_range is not None:
                f.attrs["disparity_range"] = np.asarray(lf.disparity_range, dtype=np.float64)
            _images(f, "views", lf.views, chunks=(1, 1) + lf.views.shape[2:], **comp)
            _annotate(f.create_dataset("positions", data=lf.positions))
            if lf.wavelengths is not None:
                _annotate(f.create_dataset("wavelengths", data=lf.wavelengths))
            if lf.gt_disparity is not None:
                g = lf.gt_disparity
                chunks = g.shape if g.ndim == 2 else (1, 1) + g.shape[2:]
                _images(f, "gt_disparity", g, chunks=chunks, **comp)
            if lf.gt_cube is not None:
                cube = lf.gt_cube
                _images(f, "gt_cube", cube, chunks=(1, 1, 1) + cube.shape[3:], **comp)
            if lf.cube_wavelengths is not None:
                _annotate(f.create_dataset("cube_wavelengths", data=lf.cube_wavelengths))
            if lf.valid is not None:
                _images(f, "valid", lf.valid.astype(np.uint8), chunks=(1, 1) + lf.valid.shape[2:],
                        **comp)
    return Path(path)


#: What each dataset holds, stored on it (fixed-length text attributes ``axes``, ``unit``,
#: ``description``) so that a file read with plain h5py explains itself.
_ANNOTATIONS = {
    "views": ("row, col, y, x[, channel]", "", "linear intensities, 1 = full scale"),
    "positions": ("row, col, (x, y)", "baselines", "camera positions"),
    "wavelengths": ("row, col (light field) or band (cube)", "nm",
                    "filter centre wavelengths; NaN = unknown"),
    "gt_disparity": ("[row, col,] y, x", "px per baseline", "ground-truth disparity"),
    "gt_cube": ("row, col, band, y, x", "", "ground-truth plenoptic cube"),
    "cube_wavelengths": ("band", "nm", "wavelengths of the cube's bands"),
    "valid": ("row, col, y, x", "", "1 = the pixel holds data"),
    "cube": ("row, col, band, y, x", "", "plenoptic cube: every band seen from every view"),
    "mask": ("row, col, y, x", "", "True = every band of the pixel holds data"),
    "band_mask": ("row, col, band, y, x", "", "True = registered (observed or warped in)"),
    "inferred_mask": ("row, col, band, y, x", "", "True = inferred from spatial neighbours"),
}


def _annotate(ds) -> None:
    """Store :data:`_ANNOTATIONS` on dataset ``ds`` (by its name)."""
    what = _ANNOTATIONS.get(ds.name.lstrip("/"))
    if what is not None:
        for key, text in zip(("axes", "unit", "description"), what):
            if text:
                ds.attrs[key] = np.bytes_(text.encode())


def _images(f, name: str, data, **options) -> None:
    """Create ``/name`` for an image-chunked array and write it (chunks compressed in
    parallel, :func:`hyperlf.formats._h5chunks.write_images`)."""
    a = np.asarray(data)
    ds = f.create_dataset(name, shape=a.shape, dtype=a.dtype, **options)
    _annotate(ds)
    write_images(ds, (), a)


@contextlib.contextmanager
def open_lightfield_gt_cube(path: str | os.PathLike):
    """The ground-truth cube of a light-field file as a lazy ``(R, C, B, H, W)`` h5py dataset
    (None when it has none), checked and its read errors reported as :func:`read_lightfield_h5`
    does; a context manager.

    Examples
    --------
    >>> import os, tempfile
    >>> from hyperlf.lightfield import LightField
    >>> rng = np.random.default_rng(1)
    >>> cube = rng.random((2, 2, 3, 8, 10)).astype(np.float32)
    >>> lf = LightField(views=cube[:, :, 0], gt_cube=cube, cube_wavelengths=[450, 550, 650])
    >>> p = write_lightfield_h5(os.path.join(tempfile.mkdtemp(), "lf.h5"), lf)
    >>> with open_lightfield_gt_cube(p) as ds:      # nothing is read yet
    ...     shape, band = ds.shape, ds[1, 0, 2]     # reads band 2 of view (1, 0) only
    >>> shape, bool(np.array_equal(band, cube[1, 0, 2]))
    ((2, 2, 3, 8, 10), True)
    >>> lf = LightField(views=cube[:, :, 0])         # no ground-truth cube
    >>> p = write_lightfield_h5(os.path.join(tempfile.mkdtemp(), "lf.h5"), lf)
    >>> with open_lightfield_gt_cube(p) as ds:
    ...     print(ds)
    None
    """
    with _open_read(path, LF_FORMAT) as (_, f):
        yield f["gt_cube"] if "gt_cube" in f else None


def read_lightfield_h5(path: str | os.PathLike, *, cube: bool = True) -> LightField:
    """Read a whole light field file into memory (``cube=False``: without the ground-truth
    cube, which can be many times the size of the views).

    Parameters
    ----------
    path : path-like
        A light field file written by :func:`write_lightfield_h5`.

    Returns
    -------
    LightField

    Raises
    ------
    DataNotFoundError
        When the file does not exist.
    FormatError
        When it is not a hyperlf light-field HDF5 file or is incomplete/corrupt.

    Examples
    --------
    >>> import os, tempfile
    >>> from hyperlf.lightfield import LightField
    >>> rng = np.random.default_rng(2)
    >>> cube = rng.random((2, 2, 3, 8, 10)).astype(np.float32)
    >>> lf = LightField(views=cube[:, :, 1], gt_cube=cube, cube_wavelengths=[450, 550, 650],
    ...                 metadata={"scene": "noise"})
    >>> p = write_lightfield_h5(os.path.join(tempfile.mkdtemp(), "lf.h5"), lf)
    >>> back = read_lightfield_h5(p)
    >>> bool(np.array_equal(back.gt_cube, cube)), back.cube_wavelengths.tolist()
    (True, [450.0, 550.0, 650.0])
    >>> back.metadata["scene"], back.grid_shape
    ('noise', (2, 2))
    >>> light = read_lightfield_h5(p, cube=False)   # the views without the cube
    >>> light.gt_cube is None, bool(np.array_equal(light.views, lf.views))
    (True, True)
    """
    cube = flag(cube, "cube")
    with _open_read(path, LF_FORMAT) as (p, f):
        views = _get(p, f, "views")
        positions = _get(p, f, "positions")
        wl = _get(p, f, "wavelengths", required=False)
        gt = _get(p, f, "gt_disparity", required=False)
        gt_cube = _get(p, f, "gt_cube", required=False) if cube else None
        cw = _get(p, f, "cube_wavelengths", required=False) if cube else None
        valid = _valid_mask(p, _get(p, f, "valid", required=False), views.shape[:4])
        ref = _pair_attr(p, f, "reference", integral=True)
        dr = _pair_attr(p, f, "disparity_range", integral=False)
        meta = _metadata(p, f, strict=True)
    try:
        return LightField(
            views=views, wavelengths=wl, positions=positions, reference=ref,
            disparity_range=dr, gt_disparity=gt, gt_cube=gt_cube, cube_wavelengths=cw,
            metadata=meta, valid=valid,
        )
    except InvalidInputError as exc:
        raise FormatError(f"{p} holds an invalid light field: {exc}") from None


def _valid_mask(p: Path, raw, shape):
    """The ``/valid`` dataset as bool (None when absent); only 0/1 values of the views' shape."""
    if raw is None:
        return None
    if raw.shape != tuple(shape):
        raise FormatError(f"{p}: '/valid' has shape {raw.shape}, the views {tuple(shape)}; "
                          "the file is corrupt, re-create it with hyperlf")
    if raw.dtype != np.bool_ and not np.all((raw == 0) | (raw == 1)):
        raise FormatError(f"{p}: '/valid' holds values other than 0 and 1; "
                          "the file is corrupt, re-create it with hyperlf")
    return raw.astype(bool)


def _check_cube_args(shape, wavelengths):
    try:
        sizes = tuple(shape)
    except TypeError:
        sizes = ()
    if len(sizes) != 5:
        raise InvalidInputError(f"cube shape must be 5 positive sizes (R, C, B, H, W), got "
                                f"{shown(shape)}")
    shape = tuple(integer(v, "each size of the cube shape", 1) for v in sizes)
    wl = real_array(wavelengths, "wavelengths").ravel()
    if wl.size != shape[2]:
        raise InvalidInputError(
            f"{wl.size} wavelengths given for a cube with {shape[2]} bands"
        )
    if wavelengths_unknown(wl):  # a capture ingested without its filters' wavelengths
        return shape, wl
    if not np.all(np.isfinite(wl)) or np.any(wl <= 0):
        raise InvalidInputError("cube wavelengths must be positive finite numbers (nm), or all "
                                "NaN when unknown")
    return shape, wl


class CubeWriter:
    """Stream a plenoptic cube ``(R, C, B, H, W)`` to HDF5 one view at a time.

    Use as a context manager::

        with CubeWriter("cube.h5", (5, 6, 30, 900, 1200), wavelengths) as w:
            for r, c in views:
                w.write_view(r, c, cube_rc, mask_rc)

    The data goes to a temporary file beside ``path``, renamed onto ``path`` only when the block
    ends without error **and** every view was written; otherwise the temporary file is removed
    and nothing appears at ``path``.

    Parameters
    ----------
    path : path-like
        Target ``.h5`` file.
    shape : (R, C, B, H, W)
    wavelengths : array_like, shape (B,)
        Band centres in nm, or all NaN when unknown.
    compression : {"gzip", "lzf", None}
    metadata : dict, optional
        Stored as a JSON attribute.
    """

    def __init__(self, path, shape, wavelengths, compression: str | None = "gzip",
                 metadata: dict | None = None):
        self.path = Path(path_like(path))
        self.shape, self.wavelengths = _check_cube_args(shape, wavelengths)
        self._comp = _compression(compression)
        self._metadata = dict(mapping(metadata, "metadata") or {})
        self._file = None
        self._tmp: Path | None = None
        self._written = np.zeros(self.shape[:2], dtype=bool)

    def __enter__(self) -> "CubeWriter":
        h5py = _h5py()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = temporary_beside(self.path, self.path.suffix)
        self._tmp = Path(tmp)
        try:  # from the file's first moment: an interrupt anywhere below removes it
            os.close(fd)
            f = h5py.File(self._tmp, "w", libver=_LIBVER)
            _write_header(f, CUBE_FORMAT, self._metadata)
            R, C, B, H, W = self.shape
            _annotate(f.create_dataset("cube", shape=self.shape, dtype=np.float32,
                                       chunks=(1, 1, 1, H, W), **self._comp))
            _annotate(f.create_dataset("wavelengths", data=self.wavelengths))
        except BaseException:
            self._discard()
            raise
        self._file = f
        return self

    def write_view(self, r: int, c: int, cube_rc, mask_rc=None) -> None:
        """Store the ``(B, H, W)`` cube of view ``(r, c)`` and optionally its ``(H, W)`` mask.

        Views without a mask count as fully valid when any view has one.
        """
        if self._file is None:
            raise InvalidInputError("CubeWriter.write_view called outside its 'with' block")
        R, C, B, H, W = self.shape
        r, c = index((r, c), "view (r, c)", (R, C))
        a = real_array(cube_rc, f"view ({r}, {c}) cube", np.float32)
        if a.shape != (B, H, W):
            raise InvalidInputError(f"view ({r}, {c}) cube must have shape {(B, H, W)}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise InvalidInputError(f"view ({r}, {c}) cube contains NaN or inf")
        write_images(self._file["cube"], (r, c), a)
        if mask_rc is not None:
            m = bool_mask(mask_rc, f"view ({r}, {c}) mask", (H, W), of="each view")
            if "mask" not in self._file:
                _annotate(self._file.create_dataset("mask", shape=(R, C, H, W), dtype=bool,
                                                    chunks=(1, 1, H, W), fillvalue=True,
                                                    **self._comp))
            write_images(self._file["mask"], (r, c), m)
        self._written[r, c] = True

    def write_view_extra(self, name: str, r: int, c: int, data) -> None:
        """Store a per-view array (e.g. a ``(B, H, W)`` per-entry mask) as ``/name[r, c]``.

        The dataset ``(R, C) + data.shape`` (data's dtype, chunks of one ``(H, W)`` image) is
        created on the first call; it is part of the same atomic file as the cube.
        """
        if self._file is None:
            raise InvalidInputError("CubeWriter.write_view_extra called outside its 'with' block")
        if not isinstance(name, str) or not name.isidentifier() or name in ("cube", "mask",
                                                                            "wavelengths"):
            raise InvalidInputError(f"extra dataset name must be a new identifier, got {name!r}")
        R, C = self.shape[:2]
        r, c = index((r, c), "view (r, c)", (R, C))
        a = real_array(data, f"/{name}", None)
        if a.dtype.kind not in "biuf":
            raise InvalidInputError(f"/{name} must be an array of numbers or bools, got "
                                    f"{shown(data)}")
        if name not in self._file:
            chunks = (1, 1) + (1,) * max(a.ndim - 2, 0) + a.shape[-2:] if a.ndim >= 2 else None
            _annotate(self._file.create_dataset(name, shape=(R, C) + a.shape, dtype=a.dtype,
                                                chunks=chunks, **self._comp))
        ds = self._file[name]
        if ds.shape[2:] != a.shape:
            raise InvalidInputError(f"/{name} of view ({r}, {c}) must have shape {ds.shape[2:]}, "
                                    f"got {a.shape}")
        write_images(ds, (r, c), a)

    def _discard(self) -> None:
        if self._file is not None:
            with contextlib.suppress(Exception):
                self._file.close()
            self._file = None
        if self._tmp is not None:
            with contextlib.suppress(FileNotFoundError):
                self._tmp.unlink()
            self._tmp = None

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self._discard()
            return None
        missing = np.argwhere(~self._written)
        if missing.size:
            self._discard()
            shown = ", ".join(f"({r}, {c})" for r, c in missing[:8])
            raise InvalidInputError(
                f"CubeWriter for {self.path}: {len(missing)} view(s) never written: {shown}"
                f"{' ...' if len(missing) > 8 else ''}; nothing was saved"
            )
        try:
            self._file.close()
            self._file = None
            publish(self._tmp, self.path)
            self._tmp = None
        except BaseException:
            self._discard()
            raise
        return None


def write_cube_h5(path: str | os.PathLike, cube, wavelengths, *, mask=None,
                  compression: str | None = "gzip", metadata: dict | None = None) -> Path:
    """Write a plenoptic cube ``(R, C, B, H, W)`` (and optional mask ``(R, C, H, W)``) atomically.

    Parameters
    ----------
    path : path-like
    cube : array_like, shape (R, C, B, H, W)
        Intensities (float32 on disk).
    wavelengths : array_like, shape (B,)
        Band centres in nm.
    mask : array_like of bool, shape (R, C, H, W), optional
        True where the cube is valid (e.g. not occluded).
    compression : {"gzip", "lzf", None}
    metadata : dict, optional

    Returns
    -------
    Path

    Examples
    --------
    >>> import os, tempfile
    >>> rng = np.random.default_rng(3)
    >>> cube = rng.random((2, 2, 3, 8, 10)).astype(np.float32)
    >>> mask = rng.random((2, 2, 8, 10)) > 0.2
    >>> p = write_cube_h5(os.path.join(tempfile.mkdtemp(), "cube.h5"), cube, [450, 550, 650],
    ...                   mask=mask, metadata={"method": "example"})
    >>> back, wl, m = read_cube_h5(p)
    >>> bool(np.array_equal(back, cube)), bool(np.array_equal(m, mask)), wl.tolist()
    (True, True, [450.0, 550.0, 650.0])
    """
    path_like(path)
    mapping(metadata, "metadata")
    _compression(compression)
    a = cube if isinstance(cube, np.ndarray) else real_array(cube, "cube", np.float32)
    shape, wl = _check_cube_args(a.shape, wavelengths)
    if mask is not None:
        m = bool_mask(mask, "mask", shape[:2] + shape[3:], of="the cube")
    with CubeWriter(path, shape, wl, compression=compression, metadata=metadata) as w:
        for r in range(shape[0]):
            for c in range(shape[1]):
                w.write_view(r, c, a[r, c], None if mask is None else m[r, c])
    return Path(path)


class CubeFile:
    """A cube HDF5 file opened for lazy reading (see :func:`open_cube_h5`).

    Attributes
    ----------
    cube : h5py.Dataset, shape (R, C, B, H, W)
        Slice it to read only what you need (``f.cube[r, c, b]``).
    wavelengths : ndarray, shape (B,)
        Band centres in nm; all NaN when unknown (the bands are then the views in raster
        order, :func:`hyperlf.completion.band_order`).
    mask : h5py.Dataset or None, shape (R, C, H, W)
    metadata : dict
    """

    def __init__(self, path: str | os.PathLike):
        self._cm = _open_read(path, CUBE_FORMAT)
        p, f = self._cm.__enter__()
        try:
            self.path = p
            self.cube = _dataset(p, f, "cube")
            _check_numeric(p, "cube", self.cube)
            if self.cube.ndim != 5:
                raise FormatError(f"{p}: '/cube' must be 5-D (R, C, B, H, W), got {self.cube.shape}")
            self.wavelengths = _get(p, f, "wavelengths").astype(np.float64)
            self.mask = _dataset(p, f, "mask", required=False)
            if self.mask is not None:
                _check_numeric(p, "mask", self.mask)
            self.metadata = _metadata(p, f, strict=False)
            self._file = f
        except BaseException as exc:
            self._cm.__exit__(None, None, None)
            if isinstance(exc, Exception) and not isinstance(exc, HyperLFError):
                raise _corrupt(p, exc) from None
            raise

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(self.cube.shape)

    def describe(self) -> str:
        """Human-readable multi-line summary (used by ``hyperlf info``): grid, bands, size,
        and the share of True entries of each mask, read one view at a time."""
        R, C, B, H, W = self.shape
        wl = self.wavelengths
        lines = [f"cube        : {R} x {C} views x {B} bands of {W} x {H} px (W x H)"]
        n = self.metadata.get("downscale")
        if isinstance(n, int) and n > 1:
            lines[0] += f", at 1/{n} resolution (means of {n} x {n} pixel blocks)"
        ref = self.metadata.get("reference")
        if isinstance(ref, list) and len(ref) == 2:
            lines.append(f"reference   : view ({ref[0]}, {ref[1]})")
        if wavelengths_unknown(wl):
            lines.append("bands       : wavelengths unknown: band k is camera k in raster order")
        elif wl.size:
            lines.append(f"bands       : {wl.size}, {np.nanmin(wl):g}..{np.nanmax(wl):g} nm")
            lines.append("wavelengths : " + " ".join(f"{v:g}" for v in wl))
        what = {"band_mask": "registered  : {} of the entries (observed or warped in)",
                "inferred_mask": "inferred    : {} of the entries (from spatial neighbours)"}
        for name, text in what.items():
            ds = _dataset(self.path, self._file, name, required=False)
            if ds is not None:
                lines.append(text.format(self._share(name, ds)))
        if self.mask is not None:
            done = "every band registered or inferred" if "band_mask" in self._file else "valid"
            lines.append(f"mask        : {self._share('mask', self.mask)} of the pixels ({done})")
        if isinstance(self.metadata.get("method"), str):
            lines.append(f"made by     : {self.metadata['method']}")
        return "\n".join(lines)

    def _share(self, name: str, ds) -> str:
        """The percentage of True entries of a per-view dataset, read view by view."""
        _check_numeric(self.path, name, ds)
        R, C = ds.shape[:2]
        true = sum(int(np.count_nonzero(_read(self.path, name, ds, (r, c))))
                   for r in range(R) for c in range(C))
        return f"{100.0 * true / max(ds.size, 1):.1f} %"

    def view(self, r: int, c: int) -> np.ndarray:
        """The ``(B, H, W)`` float32 cube of view ``(r, c)``."""
        return np.asarray(_read(self.path, "cube", self.cube, (r, c)), dtype=np.float32)

    def close(self) -> None:
        if self._file is not None:
            self._file = None
            self._cm.__exit__(None, None, None)

    def __enter__(self) -> "CubeFile":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def h5_format(path: str | os.PathLike) -> str | None:
    """The ``format`` attribute of a hyperlf HDF5 file (:data:`LF_FORMAT` or
    :data:`CUBE_FORMAT`), or None for a file that is not HDF5 or has none."""
    h5py = _h5py()
    p = Path(path)
    if not p.is_file():
        return None
    try:
        with h5py.File(p, "r") as f:
            return _text_attr(p, f, "format")
    except (OSError, FormatError):  # not HDF5 or an unreadable attribute: the readers say why
        return None


def open_cube_h5(path: str | os.PathLike) -> CubeFile:
    """Open a cube file for lazy reading; use as a context manager or call ``close()``.

    Parameters
    ----------
    path : path-like
        A cube file written by :func:`write_cube_h5` or :class:`CubeWriter`.

    Returns
    -------
    CubeFile
        ``cube`` (an h5py dataset, ``[R, C, B, H, W]``), ``wavelengths``, ``mask``,
        ``metadata``.

    Examples
    --------
    >>> import os, tempfile
    >>> cube = np.arange(2 * 3 * 4 * 6 * 8, dtype=np.float32).reshape(2, 3, 4, 6, 8)
    >>> wl = [450, 520, 590, 660]
    >>> p = write_cube_h5(os.path.join(tempfile.mkdtemp(), "cube.h5"), cube, wl,
    ...                   metadata={"method": "ramp"})
    >>> with open_cube_h5(p) as cf:
    ...     print(cf.shape, cf.wavelengths.tolist(), cf.mask, cf.metadata["method"])
    ...     v = cf.view(1, 2)                        # reads the (B, H, W) cube of one view
    (2, 3, 4, 6, 8) [450.0, 520.0, 590.0, 660.0] None ramp
    >>> v.shape, bool(np.array_equal(v, cube[1, 2]))
    ((4, 6, 8), True)
    """
    return CubeFile(path)


def read_cube_h5(path: str | os.PathLike):
    """Read a whole cube file.

    Parameters
    ----------
    path : path-like
        As in :func:`open_cube_h5`.

    Returns
    -------
    cube : ndarray of float32, shape (R, C, B, H, W)
    wavelengths : ndarray of float64, shape (B,)
    mask : ndarray of bool, shape (R, C, H, W), or None

    Examples
    --------
    >>> import os, tempfile
    >>> cube = np.random.default_rng(4).random((1, 2, 3, 8, 10))
    >>> p = write_cube_h5(os.path.join(tempfile.mkdtemp(), "cube.h5"), cube, [500, 600, 700])
    >>> back, wl, mask = read_cube_h5(p)
    >>> back.dtype.name, back.shape, wl.dtype.name, mask is None
    ('float32', (1, 2, 3, 8, 10), 'float64', True)
    >>> bool(np.array_equal(back, cube.astype(np.float32)))   # float64 input stored as float32
    True
    """
    with open_cube_h5(path) as cf:
        _check_fits(cf.path, "cube", cf.cube.size * 4)
        cube = np.asarray(_read(cf.path, "cube", cf.cube), dtype=np.float32)
        mask = None if cf.mask is None else np.asarray(_read(cf.path, "mask", cf.mask), dtype=bool)
        if cube.shape[2] != cf.wavelengths.size:
            raise FormatError(f"{cf.path}: {cf.wavelengths.size} wavelengths for {cube.shape[2]} bands")
        return cube, cf.wavelengths, mask
