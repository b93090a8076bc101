"""ENVI hyperspectral images: a text header ``<base>.hdr`` plus raw samples ``<base>.img``.

The header starts with the line ``ENVI`` followed by ``key = value`` lines; list values are in
braces and may span lines (``wavelength = {410, 420, ...}``). :func:`write_envi` writes float32
data; :func:`read_envi` reads interleaves ``bsq``, ``bil`` and ``bip``, data types 1 (uint8),
2 (int16), 3 (int32), 4 (float32), 5 (float64), 12 (uint16), 13 (uint32), either byte order, and
a non-zero ``header offset``.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from .._atomic import atomic_path, atomic_write_text
from .._options import choice, path_like, real_array, shown, text
from .._paths import leads_outside
from ..errors import DataNotFoundError, FormatError, InvalidInputError
from ..spectral import wavelengths_unknown

__all__ = ["write_envi", "read_envi", "ENVI_DTYPES"]

#: ENVI ``data type`` code -> numpy dtype (native byte order; ``byte order`` picks the order).
ENVI_DTYPES = {1: np.uint8, 2: np.int16, 3: np.int32, 4: np.float32, 5: np.float64,
               12: np.uint16, 13: np.uint32, 14: np.int64, 15: np.uint64}
_INTERLEAVES = ("bsq", "bil", "bip")
_DATA_SUFFIXES = (".img", ".dat", ".raw", ".bsq", ".bil", ".bip", "")


def _base(path: str | os.PathLike) -> Path:
    p = Path(path)
    return p.with_suffix("") if p.suffix.lower() in (".hdr", ".img") else p


def write_envi(path_hdr_or_base: str | os.PathLike, cube, wavelengths=None,
               *, interleave: str = "bsq", axes: str = "auto",
               description: str = "written by hyperlf") -> Path:
    """Write a cube as ENVI (float32): ``<base>.img`` first, then ``<base>.hdr``, both atomic.

    Parameters
    ----------
    path_hdr_or_base : path-like
        ``x.hdr``, ``x.img`` or ``x``: the files are ``x.hdr`` and ``x.img``.
    cube : array_like, shape (B, H, W) or (H, W, B)
        Band images. ``axes`` says which; ``"auto"`` takes (B, H, W) when the first axis matches
        the number of wavelengths, else (H, W, B) when the last does (ambiguous shapes resolve to
        (B, H, W)). Without wavelengths ``"auto"`` means (B, H, W).
    wavelengths : array_like, shape (B,), optional
        Band centres in nm (written with ``wavelength units = Nanometers``); all NaN
        (unknown) is written as no wavelengths.
    interleave : {"bsq", "bil", "bip"}
    axes : {"auto", "bhw", "hwb"}
    description : str
        One line of printable text without braces (the header's ``description = {...}``).

    Returns
    -------
    Path
        The header file.

    Examples
    --------
    >>> import os, tempfile
    >>> cube = np.random.default_rng(0).random((3, 8, 10)).astype(np.float32)      # (B, H, W)
    >>> hdr = write_envi(os.path.join(tempfile.mkdtemp(), "scene"), cube, [450, 550, 650])
    >>> sorted(p.name for p in hdr.parent.iterdir())
    ['scene.hdr', 'scene.img']
    >>> (hdr.parent / "scene.img").stat().st_size           # 3 * 8 * 10 float32 samples
    960
    >>> back, wl, header = read_envi(hdr)
    >>> bool(np.array_equal(back, cube)), wl.tolist(), header["interleave"]
    (True, [450.0, 550.0, 650.0], 'bsq')
    >>> hwb = np.moveaxis(cube, 0, -1)          # (H, W, B): told apart by the 3 wavelengths
    >>> hdr = write_envi(hdr, hwb, [450, 550, 650], interleave="bip")
    >>> bool(np.array_equal(read_envi(hdr)[0], cube))       # read back as (B, H, W)
    True
    """
    path_like(path_hdr_or_base)
    choice(axes, "axes", ("auto", "bhw", "hwb"))
    il = choice(str(interleave).lower(), "interleave", _INTERLEAVES)
    text(description, "description", printable=True)
    if "{" in description or "}" in description:
        raise InvalidInputError(f"description must not hold braces (they delimit it in the "
                                f"header), got {shown(description)}")
    a = real_array(cube, "cube", None)
    if a.ndim != 3 or a.size == 0:
        raise InvalidInputError(f"an ENVI cube must be 3-D (B, H, W) or (H, W, B), got {a.shape}")
    if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise InvalidInputError(f"an ENVI cube must hold real numbers, got {a.dtype}")
    wl = None if wavelengths is None else real_array(wavelengths, "wavelengths").ravel()
    if wl is not None and wavelengths_unknown(wl):
        wl = None  # unknown (a cube completed without wavelengths): no wavelength line
    a = _bands_first(a, wl, axes)
    base = _base(path_hdr_or_base)
    hdr, img = base.with_name(base.name + ".hdr"), base.with_name(base.name + ".img")
    with atomic_path(img) as tmp:
        np.ascontiguousarray(_interleaved(a, il), dtype="<f4").tofile(tmp)
    atomic_write_text(hdr, _header_text(a.shape, wl, il, description))
    return hdr


def _bands_first(a: np.ndarray, wl: np.ndarray | None, axes: str) -> np.ndarray:
    """``a`` as (B, H, W), its axes named by ``axes`` or found from the wavelengths."""
    if axes == "auto":
        if wl is None or a.shape[0] == wl.size:
            axes = "bhw"
        elif a.shape[2] == wl.size:
            axes = "hwb"
        else:
            raise InvalidInputError(
                f"{wl.size} wavelengths match neither the first nor the last axis of {a.shape}"
            )
    if axes == "hwb":
        a = np.moveaxis(a, 2, 0)
    if wl is not None and wl.size != a.shape[0]:
        raise InvalidInputError(f"{wl.size} wavelengths for a cube with {a.shape[0]} bands")
    return a


def _interleaved(a: np.ndarray, il: str) -> np.ndarray:
    """The (B, H, W) cube ``a`` in the order of the interleave ``il``."""
    return {"bsq": a, "bil": np.transpose(a, (1, 0, 2)), "bip": np.transpose(a, (1, 2, 0))}[il]


def _header_text(shape: tuple, wl: np.ndarray | None, il: str, description: str) -> str:
    """The header of a float32, little-endian cube of ``shape`` (B, H, W)."""
    B, H, W = shape
    lines = ["ENVI", f"description = {{{description}}}", f"samples = {W}", f"lines = {H}",
             f"bands = {B}", "header offset = 0", "file type = ENVI Standard", "data type = 4",
             f"interleave = {il}", "byte order = 0"]
    if wl is not None:
        lines.append("wavelength units = Nanometers")
        lines.append("wavelength = {" + ", ".join(f"{v:.6g}" for v in wl) + "}")
    return "\n".join(lines) + "\n"


def _parse_header(hdr: Path) -> dict[str, str]:
    try:
        text = hdr.read_text(encoding="utf-8", errors="strict")
    except UnicodeDecodeError:
        raise FormatError(f"{hdr} is not a text ENVI header") from None
    except OSError as exc:
        raise FormatError(f"cannot read {hdr}: {exc.strerror or exc}") from None
    if not text.lstrip("\ufeff").startswith("ENVI"):
        raise FormatError(f"{hdr} is not an ENVI header: the first line must be 'ENVI'")
    body = text.lstrip("\ufeff")[4:]
    out: dict[str, str] = {}
    pos = 0
    pat = re.compile(r"\s*([^=\n]+?)\s*=\s*")
    while pos < len(body):
        if body[pos].isspace():
            pos += 1
            continue
        m = pat.match(body, pos)
        if m is None:
            nl = body.find("\n", pos)
            line = body[pos: nl if nl >= 0 else None].strip()
            if line.startswith(";"):
                pos = len(body) if nl < 0 else nl + 1
                continue
            raise FormatError(f"{hdr}: header line {line[:40]!r} is not 'key = value'")
        key = m.group(1).strip().lower()
        pos = m.end()
        if pos < len(body) and body[pos] == "{":
            end = body.find("}", pos)
            if end < 0:
                raise FormatError(f"{hdr}: the value of '{key}' opens '{{' but never closes it")
            out[key] = body[pos + 1: end].strip()
            pos = end + 1
        else:
            nl = body.find("\n", pos)
            out[key] = body[pos: nl if nl >= 0 else None].strip()
            pos = len(body) if nl < 0 else nl + 1
    return out


def _int(hdr: Path, h: dict, key: str, default=None) -> int:
    if key not in h:
        if default is None:
            raise FormatError(f"{hdr} lacks the required '{key}' entry")
        return default
    try:
        return int(h[key])
    except ValueError:
        raise FormatError(f"{hdr}: {key} = {h[key][:30]!r} is not an integer") from None


def read_envi(path: str | os.PathLike):
    r"""Read an ENVI image.

    Parameters
    ----------
    path : path-like
        The ``.hdr`` file, the data file, or the common base name.

    Returns
    -------
    cube : ndarray, shape (B, H, W)
        Samples in the file's data type (float32 for files from :func:`write_envi`), native
        byte order, no scaling.
    wavelengths : ndarray of float64, shape (B,), or None
        Band centres in nm (values given in micrometres are converted).
    header : dict of str -> str
        Every header entry (keys lower-case, brace lists as raw text).

    Raises
    ------
    DataNotFoundError
        When the header or the data file is missing.
    FormatError
        When the header is malformed, the data file has the wrong size, or a file the reader
        finds itself (the header's ``data file``, or the header or data file beside the one
        named) resolves outside the named file's folder: by an absolute or ``..`` name, or by
        a symlink. A file named in ``path`` is read wherever it leads.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> cube = np.arange(2 * 3 * 4, dtype=np.uint16).reshape(2, 3, 4) * 1000     # (B, H, W)
    >>> np.transpose(cube, (1, 0, 2)).astype(">u2").tofile(folder / "raw.img")    # big-endian bil
    >>> _ = (folder / "raw.hdr").write_text(
    ...     "ENVI\nsamples = 4\nlines = 3\nbands = 2\ndata type = 12\nbyte order = 1\n"
    ...     "interleave = bil\nwavelength units = Micrometers\nwavelength = {0.45,\n 0.55}\n")
    >>> back, wl, header = read_envi(folder / "raw")        # the base name finds both files
    >>> back.shape, back.dtype.name, bool(np.array_equal(back, cube))
    ((2, 3, 4), 'uint16', True)
    >>> wl.round(6).tolist(), header["data type"]          # micrometres become nm
    ([450.0, 550.0], '12')
    """
    p = Path(path_like(path, folder=None))
    base = _base(p)
    hdr = _header_file(p, base)
    h = _parse_header(hdr)
    W, H, B, dt, offset, il = _layout(hdr, h)
    data_file = _data_file(hdr, h, base, p)
    n = W * H * B
    size = data_file.stat().st_size
    if size < offset + n * dt.itemsize:
        raise FormatError(
            f"{data_file} is too small: {size} bytes for {B} bands of {W} x {H} {dt.name} samples "
            f"after a {offset}-byte offset ({offset + n * dt.itemsize} bytes); the file is "
            "truncated"
        )
    raw = np.fromfile(data_file, dtype=dt, count=n, offset=offset)
    if il == "bsq":
        cube = raw.reshape(B, H, W)
    elif il == "bil":
        cube = raw.reshape(H, B, W).transpose(1, 0, 2)
    else:
        cube = raw.reshape(H, W, B).transpose(2, 0, 1)
    cube = np.ascontiguousarray(cube).astype(dt.newbyteorder("="), copy=False)
    return cube, _wavelengths(hdr, h, B), h


def _header_file(p: Path, base: Path) -> Path:
    """The ``.hdr`` of ``p`` (the header itself, its data file or their base name)."""
    hdr = base.with_name(base.name + ".hdr")
    if not hdr.is_file() and p.suffix.lower() not in (".hdr", ".img"):
        alt = p.with_suffix(".hdr")
        hdr = alt if alt.is_file() else hdr
    if not hdr.is_file():
        raise DataNotFoundError(f"ENVI header {hdr} does not exist")
    if hdr != p and leads_outside(p.parent, hdr):
        raise FormatError(f"ENVI header {hdr} of {p.name} resolves outside its folder (to "
                          f"{os.path.realpath(hdr)}); copy the header beside the data file, "
                          "or name the header itself")
    return hdr


def _layout(hdr: Path, h: dict) -> tuple:
    """``(W, H, B, dtype, header offset, interleave)`` of the header ``h``, each checked."""
    W, H, B = _int(hdr, h, "samples"), _int(hdr, h, "lines"), _int(hdr, h, "bands")
    if min(W, H, B) < 1:
        raise FormatError(f"{hdr}: samples, lines and bands must be positive, got {W}, {H}, {B}")
    code = _int(hdr, h, "data type")
    if code not in ENVI_DTYPES:
        raise FormatError(
            f"{hdr}: data type {code} is not supported; use one of {sorted(ENVI_DTYPES)}"
        )
    order = _int(hdr, h, "byte order", 0)
    if order not in (0, 1):
        raise FormatError(f"{hdr}: byte order must be 0 (little) or 1 (big), got {order}")
    offset = _int(hdr, h, "header offset", 0)
    if offset < 0:
        raise FormatError(f"{hdr}: header offset must be >= 0, got {offset}")
    il = h.get("interleave", "bsq").lower()
    if il not in _INTERLEAVES:
        raise FormatError(f"{hdr}: interleave must be bsq, bil or bip, got {il!r}")
    dt = np.dtype(ENVI_DTYPES[code]).newbyteorder("<" if order == 0 else ">")
    return W, H, B, dt, offset, il


def _data_file(hdr: Path, h: dict, base: Path, given: Path) -> Path:
    """The data file: the header's ``data file`` where it exists, else the base name with
    one of the usual suffixes; refused where it resolves outside the header's folder."""
    if "data file" in h and (hdr.parent / h["data file"]).is_file():
        return _beside(hdr, hdr.parent / h["data file"], given)
    for suf in _DATA_SUFFIXES:
        cand = base.with_name(base.name + suf)
        if cand.is_file() and cand != hdr:
            return _beside(hdr, cand, given)
    raise DataNotFoundError(
        f"ENVI data file for {hdr} not found (tried {base.name}.img/.dat/.raw/...)"
    )


def _beside(hdr: Path, data: Path, given: Path) -> Path:
    """``data``, unless the reader found it (the caller named another file) and it leads out
    of the header's folder: by an absolute or ``..`` name in the header, or by a symlink."""
    if data != given and leads_outside(hdr.parent, data):
        raise FormatError(
            f"{hdr}: its data file {data.name!r} resolves outside the header's folder (to "
            f"{os.path.realpath(data)}); copy the data file beside its header, or name the "
            "data file itself"
        )
    return data


def _wavelengths(hdr: Path, h: dict, B: int) -> np.ndarray | None:
    """The header's band centres in nm (micrometres and millimetres converted), or None."""
    if "wavelength" not in h:
        return None
    try:
        wl = np.array([float(v) for v in h["wavelength"].replace("\n", " ").split(",")
                       if v.strip()])
    except ValueError:
        raise FormatError(f"{hdr}: the wavelength list holds a non-number") from None
    if wl.size != B:
        raise FormatError(f"{hdr}: {wl.size} wavelengths listed for {B} bands")
    units = h.get("wavelength units", "nanometers").lower()
    if units in ("micrometers", "micrometres", "microns", "um"):
        wl = wl * 1000.0
    elif units in ("millimeters", "mm"):
        wl = wl * 1e6
    return wl
