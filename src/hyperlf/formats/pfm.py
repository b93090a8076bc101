"""Portable float map (PFM) files: ground-truth disparity maps of HCI and Middlebury v3.

Layout: a text header of three whitespace-separated parts, each normally on its own line::

    Pf | PF          one channel | three channels
    W H              width and height in pixels
    scale            negative: little-endian floats; positive: big-endian

followed by ``W * H * channels`` float32 values stored row by row **from the bottom row up**.

The magnitude of ``scale`` is ignored: :func:`read_pfm` returns the stored values unchanged (HCI's own reader multiplies by ``|scale|``, which is non-standard; every file we know of
uses ``|scale| = 1``).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from .._options import path_like, real, real_array
from ..errors import DataNotFoundError, FormatError, InvalidInputError

__all__ = ["read_pfm", "write_pfm", "describe_pfm"]

# header: identifier, width, height, scale, then exactly one whitespace byte before the data
_HEADER = re.compile(
    rb"\A(?P<id>P[fF])\s+(?P<w>\d+)\s+(?P<h>\d+)\s+(?P<scale>[-+]?[0-9.]+(?:[eE][-+]?\d+)?)(?P<end>\r\n|\s)"
)


def read_pfm(path: str | os.PathLike) -> np.ndarray:
    """Read a PFM file.

    Parameters
    ----------
    path : path-like
        The ``.pfm`` file.

    Returns
    -------
    ndarray of float32, shape (H, W) for ``Pf`` or (H, W, 3) for ``PF``
        Values as stored (not multiplied by ``|scale|``), top row first (the file's bottom-up
        row order is undone). NaN and inf are kept.

    Raises
    ------
    DataNotFoundError
        When the file does not exist.
    FormatError
        When the header is malformed or the data is truncated or too long.
    """
    p = Path(path_like(path, folder=None))
    if not p.is_file():
        raise DataNotFoundError(f"PFM file {p} does not exist")
    try:
        with open(p, "rb") as f:
            channels, w, h, dtype, start = _pfm_header(p, f.read(256))
            have = os.fstat(f.fileno()).st_size - start
            n = w * h * channels
            if have != 4 * n:
                raise FormatError(_size_mismatch(p, w, h, channels, have))
            f.seek(start)
            data = np.fromfile(f, dtype=dtype, count=n)
    except OSError as exc:
        raise FormatError(f"cannot read PFM file {p}: {exc.strerror or exc}") from None
    shape = (h, w) if channels == 1 else (h, w, 3)
    return np.ascontiguousarray(np.flipud(data.reshape(shape)).astype(np.float32))


def _pfm_header(p: Path, head: bytes) -> tuple:
    """``(channels, width, height, dtype, data offset)`` of the PFM header at the start of
    ``head``, each checked."""
    m = _HEADER.match(head)
    if m is None:
        if head[:2] not in (b"Pf", b"PF"):
            raise FormatError(
                f"{p} is not a PFM file: it must start with 'Pf' (grey) or 'PF' (colour), "
                f"found {head[:2]!r}; re-export the map as PFM"
            )
        raise FormatError(
            f"{p} has a malformed PFM header: expected 'Pf|PF', then 'width height', then a "
            "non-zero scale, separated by whitespace; re-export the map as PFM"
        )
    w, h = int(m["w"]), int(m["h"])
    try:
        scale = float(m["scale"])
    except ValueError:
        scale = float("nan")
    if w == 0 or h == 0:
        raise FormatError(f"{p} declares an empty image ({w} x {h}); a PFM needs W, H >= 1")
    if not np.isfinite(scale) or scale == 0:
        raise FormatError(
            f"{p} has PFM scale {m['scale'].decode(errors='replace')!r}; it must be a non-zero "
            "number (negative = little-endian)"
        )
    dtype = np.dtype("<f4") if scale < 0 else np.dtype(">f4")
    return 3 if m["id"] == b"PF" else 1, w, h, dtype, m.end()


def _size_mismatch(p: Path, w: int, h: int, channels: int, have: int) -> str:
    """Why ``have`` bytes after the header do not hold ``w x h x channels`` float32 values."""
    n = w * h * channels
    if have < 4 * n:
        return (f"{p} is truncated: the header declares {w} x {h} x {channels} float32 values "
                f"({4 * n} bytes) but only {have} bytes follow; the file was cut short, copy it "
                "again")
    return (f"{p} has {have - 4 * n} bytes more than its header declares ({w} x {h} x "
            f"{channels} float32 values); the header or the data is corrupt")


def write_pfm(path: str | os.PathLike, array, scale: float = -1.0) -> Path:
    """Write a float map as PFM, atomically.

    Parameters
    ----------
    path : path-like
        Target file (conventionally ``.pfm``); parent folders are created.
    array : array_like, shape (H, W), (H, W, 1) or (H, W, 3)
        Values, converted to float32 (NaN/inf allowed: PFM stores them verbatim).
    scale : float
        Written to the header. Its sign picks the byte order (negative: little-endian, the
        default and what every reader expects); its magnitude is written but the data is **not**
        divided by it.

    Returns
    -------
    Path
        The written file.
    """
    path_like(path)
    arr = real_array(array, "array", None)
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] != 3) or arr.size == 0:
        raise InvalidInputError(
            f"a PFM holds an (H, W) or (H, W, 3) float map; got shape {arr.shape}"
        )
    if not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
        raise InvalidInputError(f"a PFM holds real numbers; got dtype {arr.dtype}")
    scale = real(scale, "PFM scale")
    if scale == 0:
        raise InvalidInputError("PFM scale must be a finite non-zero number, got 0")
    h, w = arr.shape[:2]
    ident = "PF" if arr.ndim == 3 else "Pf"
    dtype = np.dtype("<f4") if scale < 0 else np.dtype(">f4")
    with np.errstate(over="ignore"):  # beyond float32: inf, which PFM stores verbatim
        body = np.ascontiguousarray(np.flipud(arr).astype(dtype)).tobytes()
    header = f"{ident}\n{w} {h}\n{scale:g}\n".encode("ascii")
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(header)
            fh.write(body)
    return Path(path)


def describe_pfm(path: str | os.PathLike) -> str:
    """One line on a PFM map: its size, channels and the range of its finite values.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = write_pfm(pathlib.Path(tempfile.mkdtemp()) / "d.pfm",
    ...               np.array([[1.5, np.nan], [-2.0, 4.0]]))
    >>> describe_pfm(p)
    'PFM map, 2 x 2 px (W x H), values -2..4, 1 of 4 values not finite'
    """
    a = read_pfm(path)
    h, w = a.shape[:2]
    kind = "PFM map" if a.ndim == 2 else "PFM colour image"
    fin = np.isfinite(a)
    if not fin.any():
        return f"{kind}, {w} x {h} px (W x H), no finite value"
    lo, hi = float(a[fin].min()), float(a[fin].max())
    bad = int(fin.size - np.count_nonzero(fin))
    tail = f", {bad} of {fin.size} values not finite" if bad else ""
    return f"{kind}, {w} x {h} px (W x H), values {lo:.6g}..{hi:.6g}{tail}"
