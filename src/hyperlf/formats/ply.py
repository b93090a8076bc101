"""Point clouds as PLY files (binary little-endian; float32 x, y, z, optional uchar colour and
optional float32 per-vertex scalars such as ``confidence``).

PLY is read by MeshLab, CloudCompare, Open3D and Blender. The writer is atomic like every
hyperlf output; the reader reads back what the writer writes (and ASCII files of the same
layout), for tests and scripts. CloudCompare shows a per-vertex scalar as a scalar field that
can be filtered; MeshLab and Open3D read the points and colours and skip the rest.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from .._options import mapping, path_like, real_array, shown
from ..errors import DataNotFoundError, FormatError, InvalidInputError

__all__ = ["write_ply", "read_ply", "read_ply_properties", "describe_ply"]

_XYZ = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
_RGB = [("red", "u1"), ("green", "u1"), ("blue", "u1")]
_PLY_TYPES = {"float": "f4", "float32": "f4", "double": "f8", "float64": "f8", "uchar": "u1",
              "uint8": "u1", "int": "i4", "int32": "i4", "uint": "u4", "short": "i2",
              "ushort": "u2", "char": "i1"}


def write_ply(path: str | os.PathLike, points: np.ndarray, colours: np.ndarray | None = None,
              *, scalars: Mapping[str, np.ndarray] | None = None,
              comment: str | None = None) -> Path:
    """Write points (and colours, and per-vertex scalars) as a binary little-endian PLY file.

    Parameters
    ----------
    path : path-like
    points : ndarray, shape (N, 3)
    colours : ndarray of uint8, shape (N, 3), optional
    scalars : mapping of str to ndarray, shape (N,), optional
        Further per-vertex properties, stored as float32 after the colours in the mapping's
        order, e.g. ``{"confidence": c}``. Names are PLY words: letters, digits and ``_``,
        not starting with a digit, other than the position and colour names.
    comment : str, optional
        One line of ASCII text stored in the header (e.g. the unit).

    Returns
    -------
    Path

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = write_ply(pathlib.Path(tempfile.mkdtemp()) / "a.ply", np.zeros((2, 3)))
    >>> read_ply(p)[0].shape
    (2, 3)
    >>> p = write_ply(p, np.zeros((2, 3)), scalars={"confidence": np.array([0.5, 1.0])})
    >>> read_ply_properties(p)["confidence"].tolist()
    [0.5, 1.0]
    """
    path_like(path)
    mapping(scalars, "scalars")
    if comment is not None and not (isinstance(comment, str) and comment.isascii()
                                    and comment.isprintable()):
        raise InvalidInputError(f"comment must be one line of ASCII text or None, got "
                                f"{shown(comment)}")
    pts = real_array(points, "points", np.float32)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InvalidInputError(f"points must be (N, 3), got {pts.shape}")
    fields = list(_XYZ)
    if colours is not None:
        col = real_array(colours, "colours", None)
        if col.shape != pts.shape or col.dtype != np.uint8:
            raise InvalidInputError(f"colours must be uint8 of shape {pts.shape}, got "
                                    f"{col.dtype} {col.shape}")
        fields += _RGB
    extra = _checked_scalars(scalars, len(pts))
    fields += [(name, "<f4") for name in extra]
    rec = np.empty(len(pts), dtype=fields)
    rec["x"], rec["y"], rec["z"] = pts.T
    if colours is not None:
        rec["red"], rec["green"], rec["blue"] = np.asarray(colours).T
    for name, values in extra.items():
        rec[name] = values
    lines = ["ply", "format binary_little_endian 1.0"]
    if comment:
        lines.append("comment " + " ".join(str(comment).split()))
    lines.append(f"element vertex {len(pts)}")
    lines += [f"property {'float' if t == '<f4' else 'uchar'} {n}" for n, t in fields]
    lines.append("end_header")
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(("\n".join(lines) + "\n").encode("ascii"))
            f.write(rec.tobytes())
    return Path(path)


def _checked_scalars(scalars, n: int) -> dict[str, np.ndarray]:
    """``write_ply``'s ``scalars``, each a float32 array of ``n`` values, names checked."""
    taken = {name for name, _ in _XYZ + _RGB}
    out = {}
    for name, values in (scalars or {}).items():
        if not (isinstance(name, str) and name.isascii() and name.isidentifier()) \
                or name in taken:
            raise InvalidInputError(f"PLY property name {name!r} must be a word of letters, "
                                    "digits and _ other than x, y, z, red, green, blue")
        arr = real_array(values, f"PLY property {name!r}", np.float32)
        if arr.shape != (n,):
            raise InvalidInputError(f"PLY property {name!r} must have shape ({n},), got "
                                    f"{arr.shape}")
        out[name] = arr
    return out


def _header(f, p: Path):
    if f.readline().strip() != b"ply":
        raise FormatError(f"{p} is not a PLY file (no 'ply' line)")
    fmt, count, props = None, None, []
    for _ in range(1000):
        line = f.readline()
        if not line:
            break
        words = line.decode("ascii", "replace").split()
        if not words or words[0] == "comment":
            continue
        if words[0] == "end_header":
            return fmt, count, props
        if words[0] == "format" and len(words) >= 2:
            fmt = words[1]
        elif words[:2] == ["element", "vertex"] and len(words) == 3 and words[2].isdigit():
            count = int(words[2])
        elif words[0] == "property" and len(words) == 3 and words[1] in _PLY_TYPES:
            if words[2] in {n for n, _ in props}:
                raise FormatError(f"{p}: PLY property {words[2]!r} appears twice")
            props.append((words[2], _PLY_TYPES[words[1]]))
        elif words[0] == "element" or words[0] == "property":
            raise FormatError(f"{p}: hyperlf reads vertex-only PLY files; found {' '.join(words)}")
    raise FormatError(f"{p}: PLY header without end_header")


def read_ply(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """Read a vertex PLY file: points ``(N, 3)`` float32 and colours ``(N, 3)`` uint8 or None.

    Raises
    ------
    FormatError
        Not a PLY file, other elements than vertices, or truncated data.
    """
    rec = read_ply_properties(path)
    pts = np.stack([rec["x"], rec["y"], rec["z"]], axis=1).astype(np.float32)
    if {"red", "green", "blue"} <= set(rec):
        return pts, np.stack([rec["red"], rec["green"], rec["blue"]], 1).astype(np.uint8)
    return pts, None


def read_ply_properties(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Every vertex property of a vertex PLY file, by name, as 1-D arrays in file order.

    Raises
    ------
    FormatError
        As :func:`read_ply`.
    """
    p = Path(path_like(path, folder=None))
    if not p.is_file():
        raise DataNotFoundError(f"PLY file {p} does not exist")
    try:
        return _read_properties(p)
    except OSError as exc:
        raise FormatError(f"cannot read PLY file {p}: {exc.strerror or exc}") from None


def _read_properties(p: Path) -> dict[str, np.ndarray]:
    with open(p, "rb") as f:
        fmt, count, props = _header(f, p)
        names = [n for n, _ in props]
        if count is None or not {"x", "y", "z"} <= set(names):
            raise FormatError(f"{p}: PLY without a vertex element holding x, y, z")
        left = p.stat().st_size - f.tell()
        if fmt == "ascii":
            try:
                data = (np.loadtxt(f, ndmin=2, max_rows=count) if count
                        else np.zeros((0, len(props))))
            except ValueError as exc:
                raise FormatError(f"{p}: unreadable ASCII PLY data ({exc})") from None
            if data.shape != (count, len(props)):
                raise FormatError(f"{p}: expected {count} rows of {len(props)} values")
            rec = {n: data[:, i] for i, n in enumerate(names)}
        elif fmt == "binary_little_endian":
            dt = np.dtype([(n, "<" + t) for n, t in props])
            if dt.itemsize * count > left:
                raise FormatError(f"{p}: truncated PLY data")
            buf = f.read(dt.itemsize * count)
            if len(buf) != dt.itemsize * count:
                raise FormatError(f"{p}: truncated PLY data")
            rec = np.frombuffer(buf, dtype=dt)
        else:
            raise FormatError(f"{p}: PLY format {fmt!r} is not supported")
    return {n: np.asarray(rec[n]) for n in names}


def describe_ply(path: str | os.PathLike) -> str:
    """One line on a vertex PLY file from its header: points and properties.

    Raises
    ------
    FormatError
        As :func:`read_ply`.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = write_ply(pathlib.Path(tempfile.mkdtemp()) / "p.ply", np.zeros((3, 3)),
    ...               np.zeros((3, 3), np.uint8))
    >>> describe_ply(p)
    'PLY point cloud, 3 points (x, y, z, red, green, blue)'
    """
    p = Path(path_like(path, folder=None))
    if not p.is_file():
        raise DataNotFoundError(f"PLY file {p} does not exist")
    try:
        with open(p, "rb") as f:
            fmt, count, props = _header(f, p)
    except OSError as exc:
        raise FormatError(f"cannot read PLY file {p}: {exc.strerror or exc}") from None
    if count is None:
        raise FormatError(f"{p}: PLY without a vertex element")
    names = ", ".join(n for n, _ in props)
    return f"PLY point cloud, {count} points ({names})"
