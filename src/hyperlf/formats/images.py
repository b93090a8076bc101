"""Reading and writing ordinary images (PNG, TIFF, and what OpenCV reads).

Conventions
-----------
* Arrays are ``(H, W)`` for grey images and ``(H, W, 3)`` in **RGB** order for colour images
  (OpenCV's BGR order never leaks out). An alpha channel is dropped.
* Palette PNGs (several Middlebury masks and ground truths) are expanded to the colours of their
  palette; when the palette is grey (all three channels equal) the image is returned as ``(H, W)``
  grey levels, so Tsukuba's ``groundtruth.png`` reads as 0..224, not as palette indices 0..7.
* TIFF files (8/16-bit integer and float32) go through :mod:`tifffile`; the rest through OpenCV,
  and so do TIFF files whose compression tifffile cannot decode without the optional
  ``imagecodecs`` package (LZW, as OpenCV and many camera programs write them, and JPEG).
* ``as_float=True`` maps integer images to [0, 1] by dividing by the dtype's maximum
  (255 or 65535); float images are returned as float32 unchanged.

Memory limit (decompression bombs)
----------------------------------
Before anything is decoded, the image size is read from the file's header (PNG ``IHDR``,
TIFF page tags) and the memory reading it needs is estimated as
``width * height * channels * (bytes per sample + 4)`` (the stored image plus its float32 copy).
Above :data:`MAX_IMAGE_BYTES` (2 GiB) the read is refused with a :class:`FormatError` saying how
much it would need. To read a genuine larger image, set the environment variable
``HYPERLF_MAX_IMAGE_BYTES`` (bytes) or assign ``hyperlf.formats.images.MAX_IMAGE_BYTES``.
PNG files are also checked whole (chunk CRCs, zlib stream, row filters) before OpenCV sees them,
so a corrupt PNG gives hyperlf's one-line error and libpng prints nothing.
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from .._options import choice, flag, path_like, path_list, real_array, shown, text
from ..errors import DataNotFoundError, FormatError, HyperLFError, InvalidInputError

__all__ = ["read_image", "read_images_same_size", "write_image", "to_grey", "REC709_WEIGHTS"]

#: Rec. 709 luma weights (R, G, B) used by :func:`to_grey`.
REC709_WEIGHTS = (0.2126, 0.7152, 0.0722)

#: Largest estimated memory (bytes) :func:`read_image` may use for one image; see the module
#: docstring. The environment variable named by :data:`MAX_IMAGE_BYTES_ENV` overrides it.
MAX_IMAGE_BYTES = 2 * 1024 ** 3
MAX_IMAGE_BYTES_ENV = "HYPERLF_MAX_IMAGE_BYTES"

_TIFF = (".tif", ".tiff")
#: TIFF compressions (LZW, JPEG) that tifffile decodes only with the optional ``imagecodecs``
#: package; such files are read through OpenCV's libtiff instead.
_LIBTIFF_ONLY = (5, 7)
_PNG_SIG = b"\x89PNG\r\n\x1a\n"
_WRITABLE = (".png", ".tif", ".tiff")


def _is_palette_png(buf: bytes) -> bool:
    """True when ``buf`` (a file's bytes) is a PNG with colour type 3 (palette)."""
    return len(buf) >= 26 and buf[:8] == _PNG_SIG and buf[12:16] == b"IHDR" and buf[25] == 3


def human_bytes(n: int) -> str:
    """``n`` bytes as "12 MB" / "4.6 GB" for messages."""
    return f"{n / 1e9:.1f} GB" if n >= 1e9 else f"{n / 1e6:.0f} MB"


def max_image_bytes() -> int:
    """The memory limit per image: ``$HYPERLF_MAX_IMAGE_BYTES`` or :data:`MAX_IMAGE_BYTES`."""
    text = os.environ.get(MAX_IMAGE_BYTES_ENV)
    if text is None:
        return int(MAX_IMAGE_BYTES)
    try:
        value = int(text.strip())
    except ValueError:
        value = 0
    if value < 1:
        raise InvalidInputError(
            f"{MAX_IMAGE_BYTES_ENV}={text[:30]!r} is not a positive number of bytes; "
            "unset it or give e.g. 4000000000"
        )
    return value


def check_image_size(p: Path, w: int, h: int, channels: int, itemsize: int) -> None:
    """Refuse an image whose decoding would need more than :func:`max_image_bytes`."""
    need = w * h * channels * (itemsize + 4)
    limit = max_image_bytes()
    if need > limit:
        raise FormatError(
            f"{p} declares a {w} x {h} image ({channels} x {itemsize}-byte samples) that needs "
            f"about {human_bytes(need)} of memory to read, above the {human_bytes(limit)} limit; "
            f"if it is genuine, raise the limit with {MAX_IMAGE_BYTES_ENV}=<bytes>"
        )


# colour type -> (samples per pixel in the file, bit depths allowed, channels OpenCV returns)
_PNG_TYPES = {0: (1, (1, 2, 4, 8, 16), 1), 2: (3, (8, 16), 3), 3: (1, (1, 2, 4, 8), 3),
              4: (2, (8, 16), 4), 6: (4, (8, 16), 4)}
_ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2),
          (0, 1, 1, 2))


def _bad_png(p: Path, what: str) -> FormatError:
    return FormatError(f"{p} is a corrupt PNG ({what}); re-export or copy the image again")


def _png_ihdr(p: Path, buf: bytes) -> tuple[int, int, int, int, int]:
    """(width, height, bit depth, colour type, interlace) of a PNG, validated."""
    if len(buf) < 33 or buf[12:16] != b"IHDR" or buf[8:12] != b"\0\0\0\x0d":
        raise _bad_png(p, "no IHDR header chunk")
    w, h, depth, colour, comp, filt, inter = struct.unpack(">IIBBBBB", buf[16:29])
    if not (0 < w < 2 ** 31 and 0 < h < 2 ** 31) or colour not in _PNG_TYPES \
            or depth not in _PNG_TYPES[colour][1] or comp or filt or inter > 1:
        raise _bad_png(p, f"impossible header: {w} x {h}, depth {depth}, colour type {colour}")
    return w, h, depth, colour, inter


def _png_data_size(w: int, h: int, depth: int, colour: int, inter: int) -> tuple[int, int]:
    """(decompressed IDAT bytes, row stride or 0 when interlaced) the header implies."""
    bits = _PNG_TYPES[colour][0] * depth
    if not inter:
        stride = 1 + (w * bits + 7) // 8
        return h * stride, stride
    total = 0
    for x0, y0, dx, dy in _ADAM7:
        pw, ph = max(0, (w - x0 + dx - 1) // dx), max(0, (h - y0 + dy - 1) // dy)
        total += ph * (1 + (pw * bits + 7) // 8) if pw else 0
    return total, 0


def _png_idat(p: Path, buf: bytes) -> list[memoryview]:
    """The IDAT payloads, after checking every chunk's length and CRC up to IEND."""
    view, pos, idat = memoryview(buf), 8, []
    while True:
        if pos + 12 > len(buf):
            raise _bad_png(p, "truncated: it ends before its IEND chunk")
        n, kind = struct.unpack(">I4s", buf[pos: pos + 8])
        end = pos + 12 + n
        if end > len(buf):
            raise _bad_png(p, f"truncated inside a {kind.decode('latin-1')!r} chunk")
        if zlib.crc32(view[pos + 4: end - 4]) != struct.unpack(">I", buf[end - 4: end])[0]:
            raise _bad_png(p, f"CRC error in a {kind.decode('latin-1')!r} chunk")
        if kind == b"IDAT":
            idat.append(view[pos + 8: end - 4])
        if kind == b"IEND":
            return idat
        pos = end


def _check_png_rows(p: Path, idat: list[memoryview], size: int, stride: int) -> None:
    """Inflate the image data in bounded pieces: it must be whole zlib data of ``size`` bytes
    with valid row filter types (0..4); nothing the size of the image is kept."""
    d, total = zlib.decompressobj(), 0
    try:
        for data in idat:
            while data:
                out = d.decompress(data, 1 << 20)
                if stride:
                    rows = np.frombuffer(out, np.uint8)[(-total) % stride::stride]
                    if rows.size and rows.max() > 4:
                        raise _bad_png(p, "invalid row filter type")
                total += len(out)
                if total > size:
                    raise _bad_png(p, "more image data than its header declares")
                data = d.unconsumed_tail
    except zlib.error as exc:
        raise _bad_png(p, f"bad compressed data: {exc}") from None
    if total != size or not d.eof:
        raise _bad_png(p, f"image data ends after {total} of {size} bytes")


def _check_png(p: Path, buf: bytes) -> None:
    """Refuse a PNG that is corrupt or too large to decode, before OpenCV sees it."""
    w, h, depth, colour, inter = _png_ihdr(p, buf)
    check_image_size(p, w, h, _PNG_TYPES[colour][2], 2 if depth == 16 else 1)
    idat = _png_idat(p, buf)
    if not idat:
        raise _bad_png(p, "no IDAT image data")
    _check_png_rows(p, idat, *_png_data_size(w, h, depth, colour, inter))


def _read_tiff(p: Path) -> np.ndarray:
    import tifffile

    try:
        with tifffile.TiffFile(p) as tif:
            page = tif.pages[0]
            shape, dtype = tuple(int(v) for v in page.shape), np.dtype(page.dtype)
            if len(shape) >= 2:
                contig = len(shape) == 3 and shape[-1] == page.samplesperpixel
                h, w = shape[:2] if contig else shape[-2:]
                check_image_size(p, w, h, int(np.prod(shape)) // (w * h), dtype.itemsize)
            if page.compression in _LIBTIFF_ONLY and page.compression not in \
                    tifffile.TIFF.DECOMPRESSORS:
                return _read_cv2(p)
            arr = tif.asarray(key=0)
    except HyperLFError:
        raise
    except Exception as exc:  # tifffile raises many kinds on corrupt input
        raise FormatError(
            f"{p} is not a readable TIFF image ({type(exc).__name__}: {str(exc)[:80]}); "
            "re-export it as an 8/16-bit or float32 TIFF"
        ) from None
    arr = np.asarray(arr)
    if arr.ndim == 3 and arr.shape[0] in (3, 4) and arr.shape[2] not in (3, 4):
        arr = np.moveaxis(arr, 0, -1)  # planar (separate) configuration
    return arr


def _read_cv2(p: Path) -> np.ndarray:
    import cv2

    try:
        buf = p.read_bytes()
    except OSError as exc:
        raise FormatError(f"cannot read image file {p}: {exc.strerror or exc}") from None
    if buf[:8] == _PNG_SIG:
        _check_png(p, buf)
    try:
        # IMREAD_UNCHANGED keeps 16-bit depth; OpenCV expands palette PNGs to BGR itself.
        arr = cv2.imdecode(np.frombuffer(buf, np.uint8), cv2.IMREAD_UNCHANGED) if buf else None
    except cv2.error:
        arr = None
    if arr is None:
        raise FormatError(
            f"{p} is not a readable image (corrupt, truncated or an unsupported format); "
            "use PNG or TIFF (8/16-bit, or float32 TIFF)"
        )
    if arr.ndim == 3:
        if arr.shape[2] == 4:
            arr = arr[..., :3]
        if arr.shape[2] == 3:
            arr = arr[..., ::-1]  # BGR -> RGB
        if arr.shape[2] == 1:
            arr = arr[..., 0]
    if _is_palette_png(buf) and arr.ndim == 3 and arr.shape[2] == 3 \
            and np.array_equal(arr[..., 0], arr[..., 1]) and np.array_equal(arr[..., 0], arr[..., 2]):
        arr = arr[..., 0]
    return np.ascontiguousarray(arr)


def read_image(path: str | os.PathLike, *, as_float: bool = True,
               channels: str | None = None) -> np.ndarray:
    """Read an image file.

    Parameters
    ----------
    path : path-like
        PNG (8/16-bit, grey, RGB(A) or palette), TIFF (8/16-bit or float32), or anything else
        OpenCV reads.
    as_float : bool
        True: return float32, integer images scaled to [0, 1] by the dtype maximum.
        False: return the stored dtype (uint8, uint16, float32, ...).
    channels : {None, "grey", "rgb"}
        None: as stored. ``"grey"``: colour images are reduced by :func:`to_grey`. ``"rgb"``:
        grey images are repeated into three channels.

    Returns
    -------
    ndarray, shape (H, W) or (H, W, 3) in RGB order

    Raises
    ------
    DataNotFoundError
        When the file does not exist.
    FormatError
        When the file cannot be decoded, is a folder, or would need more memory than
        ``HYPERLF_MAX_IMAGE_BYTES`` / :data:`MAX_IMAGE_BYTES` (checked from its header).

    Examples
    --------
    >>> import os, tempfile
    >>> rgb = np.zeros((8, 10, 3), dtype=np.uint8)
    >>> rgb[..., 0], rgb[..., 2] = 255, 51                  # red 1.0, blue 0.2
    >>> p = write_image(os.path.join(tempfile.mkdtemp(), "rgb.png"), rgb)
    >>> raw = read_image(p, as_float=False)                 # the stored samples
    >>> raw.shape, raw.dtype.name, bool(np.array_equal(raw, rgb))
    ((8, 10, 3), 'uint8', True)
    >>> im = read_image(p)                                  # float32, scaled by 255
    >>> im.dtype.name, [round(float(v), 6) for v in im[0, 0]]
    ('float32', [1.0, 0.0, 0.2])
    >>> grey = read_image(p, channels="grey")               # 0.2126 * 1 + 0.0722 * 0.2
    >>> grey.shape, round(float(grey[0, 0]), 5)
    ((8, 10), 0.22704)
    """
    p = Path(path_like(path, folder=None))
    as_float = flag(as_float, "as_float")
    choice(channels, "channels", (None, "grey", "rgb"))
    if p.is_dir():
        raise FormatError(f"{p} is a folder, not an image file; give the path of an image in it")
    if not p.is_file():
        raise DataNotFoundError(f"image file {p} does not exist")
    arr = _read_tiff(p) if p.suffix.lower() in _TIFF else _read_cv2(p)
    if arr.ndim == 3 and arr.shape[2] == 4:
        arr = arr[..., :3]
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] != 3) or arr.size == 0:
        raise FormatError(
            f"{p} has an unsupported image layout {arr.shape}; expected a grey or RGB image"
        )
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8) * 255
    if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise FormatError(f"{p} has unsupported sample type {arr.dtype}; use 8/16-bit or float32")
    if as_float:
        if np.issubdtype(arr.dtype, np.integer):
            arr = arr.astype(np.float32) / np.float32(np.iinfo(arr.dtype).max)
        else:
            arr = arr.astype(np.float32, copy=False)
    if channels == "grey" and arr.ndim == 3:
        g = to_grey(arr)
        arr = g if as_float or np.issubdtype(arr.dtype, np.floating) else \
            np.clip(np.rint(g), 0, np.iinfo(arr.dtype).max).astype(arr.dtype)
    elif channels == "rgb" and arr.ndim == 2:
        arr = np.repeat(arr[..., None], 3, axis=2)
    return arr


def to_grey(rgb) -> np.ndarray:
    """Weighted sum of the R, G, B channels with the Rec. 709 luma weights.

    The weights are applied to the values as they are (no sRGB linearisation): for linear data
    this is relative luminance, for sRGB-encoded data it is luma.

    Parameters
    ----------
    rgb : array_like, shape (..., 3)

    Returns
    -------
    ndarray of float32, shape (...)

    Examples
    --------
    >>> round(float(to_grey([1.0, 0.0, 0.0])), 6)    # pure red: the red weight
    0.2126
    >>> g = to_grey(np.ones((8, 10, 3)))            # white: the weights sum to 1
    >>> g.shape, g.dtype.name, bool(np.allclose(g, 1.0))
    ((8, 10), 'float32', True)
    >>> round(float(to_grey([0.2, 0.4, 0.6])), 4)   # 0.2126 * 0.2 + 0.7152 * 0.4 + 0.0722 * 0.6
    0.3719
    """
    a = np.asarray(rgb)
    if a.ndim < 1 or a.shape[-1] != 3:
        raise InvalidInputError(f"to_grey needs a trailing RGB axis of length 3, got {a.shape}")
    w = np.asarray(REC709_WEIGHTS, dtype=np.float32)
    return (a.astype(np.float32, copy=False) @ w).astype(np.float32, copy=False)


def write_image(path: str | os.PathLike, array, bit_depth: int = 16) -> Path:
    """Write an image atomically as PNG or TIFF.

    Parameters
    ----------
    path : path-like
        Target; the suffix picks the codec: ``.png``, ``.tif`` or ``.tiff``.
    array : array_like, shape (H, W), (H, W, 1) or (H, W, 3) (RGB)
        Float data is taken as [0, 1], clipped, and quantised with rounding to ``bit_depth``
        bits. Integer data (uint8 / uint16) is written verbatim in its own dtype and
        ``bit_depth`` is ignored, so integer images round-trip exactly.
    bit_depth : {8, 16, 32}
        Bits per sample for float input (checked for any input). 32 writes float32 samples
        unchanged (no clipping); only TIFF supports it.

    Returns
    -------
    Path
        The written file.

    Examples
    --------
    >>> import os, tempfile
    >>> folder = tempfile.mkdtemp()
    >>> a = np.random.default_rng(0).random((8, 10))
    >>> p = write_image(os.path.join(folder, "a.png"), a)               # 16 bits by default
    >>> back = read_image(p)
    >>> back.shape, back.dtype.name
    ((8, 10), 'float32')
    >>> bool(np.abs(back - a).max() <= 0.5 / 65535 + 1e-7)    # within half a 16-bit step
    True
    >>> q = write_image(os.path.join(folder, "a.tif"), a, bit_depth=32)   # float32 TIFF
    >>> bool(np.array_equal(read_image(q), a.astype(np.float32)))
    True
    >>> u = np.arange(80, dtype=np.uint8).reshape(8, 10)              # integers: written verbatim
    >>> bool(np.array_equal(read_image(write_image(p, u), as_float=False), u))
    True
    """
    p = Path(path_like(path))
    ext = p.suffix.lower()
    if ext not in _WRITABLE:
        raise InvalidInputError(
            f"cannot write {p}: supported image formats are .png, .tif and .tiff"
        )
    choice(bit_depth, "bit_depth", (8, 16, 32))
    arr = real_array(array, "array", None)
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] != 3) or arr.size == 0:
        raise InvalidInputError(f"an image must be (H, W) or (H, W, 3), got shape {arr.shape}")
    out = np.ascontiguousarray(_samples(arr, bit_depth, p))
    with atomic_path(p) as tmp:
        _encode(tmp, out, p)
    return p


def _samples(arr: np.ndarray, bit_depth: int, p: Path) -> np.ndarray:
    """The samples written for ``arr``: integers verbatim, floats quantised from [0, 1] (or
    float32 for a 32-bit TIFF)."""
    if arr.dtype == np.bool_:
        return arr.astype(np.uint8) * 255
    if arr.dtype in (np.uint8, np.uint16):
        return arr
    if np.issubdtype(arr.dtype, np.integer):
        raise InvalidInputError(
            f"integer images must be uint8 or uint16, got {arr.dtype}; convert or pass floats in [0, 1]"
        )
    if not np.issubdtype(arr.dtype, np.floating):
        raise InvalidInputError(f"cannot write an image of dtype {arr.dtype}")
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"cannot write {p}: the image contains NaN or inf")
    if bit_depth == 32:
        if p.suffix.lower() not in _TIFF:
            raise InvalidInputError(f"cannot write {p}: 32-bit float images need a .tif/.tiff "
                                    f"file, not {p.suffix.lower()}")
        return arr.astype(np.float32)
    top = 255.0 if bit_depth == 8 else 65535.0
    return np.rint(np.clip(arr, 0.0, 1.0) * top).astype(np.uint8 if bit_depth == 8 else np.uint16)


def _encode(tmp: Path, out: np.ndarray, p: Path) -> None:
    """Write ``out`` to ``tmp`` in the codec of ``p``'s suffix (TIFF by tifffile, PNG by
    OpenCV)."""
    if p.suffix.lower() in _TIFF:
        import tifffile

        tifffile.imwrite(tmp, out, photometric="rgb" if out.ndim == 3 else "minisblack")
        return
    import cv2

    bgr = np.ascontiguousarray(out[..., ::-1]) if out.ndim == 3 else out
    # encode in memory, write with Python: cv2.imwrite crashes on names that are not UTF-8 (a
    # lone surrogate in the str)
    ok, buf = cv2.imencode(tmp.suffix or ".png", bgr)
    if not ok:
        raise FormatError(f"OpenCV failed to encode {p}")
    tmp.write_bytes(buf.tobytes())


def _path_list(paths, label: str) -> list:
    """``paths`` as a list of at least one path."""
    return path_list(paths, label)


def _labels(labels, n: int) -> list[str]:
    """One name per file, for messages."""
    items = list(labels) if isinstance(labels, (list, tuple)) else None
    if items is None or len(items) != n:
        raise InvalidInputError(f"labels must be a list of {n} names (or None), got "
                                f"{shown(labels)}")
    return items


def read_images_same_size(paths, read, where: str, labels=None) -> np.ndarray:
    """Read several images in parallel threads into one float32 stack ``(N, ...)``.

    ``read(path)`` reads one image; every image must have the first one's shape, otherwise a
    :class:`FormatError` names both files (``labels`` give each one a name for the message,
    default the file names; ``where`` says which light field is being read).

    Parameters
    ----------
    paths : sequence of path-like
        The image files.
    read : callable
        ``read(path) -> ndarray`` for one file.
    where : str
        What is being read, for error messages.
    labels : sequence of str, optional
        A name per file for error messages.

    Returns
    -------
    ndarray of float32, shape (N, ...)

    Examples
    --------
    >>> import os, tempfile
    >>> folder = tempfile.mkdtemp()
    >>> rng = np.random.default_rng(1)
    >>> ims = [rng.integers(0, 256, (8, 10), dtype=np.uint8) for _ in range(3)]
    >>> paths = [write_image(os.path.join(folder, f"v{i}.png"), im) for i, im in enumerate(ims)]
    >>> stack = read_images_same_size(paths, read_image, "example")
    >>> stack.shape, stack.dtype.name
    ((3, 8, 10), 'float32')
    >>> bool(np.allclose(stack, np.stack(ims) / 255))
    True
    >>> p = write_image(os.path.join(folder, "small.png"), np.zeros((4, 5), dtype=np.uint8))
    >>> read_images_same_size(paths + [p], read_image, "example")
    Traceback (most recent call last):
    ...
    hyperlf.errors.FormatError: example: small.png is 5 x 4 px but v0.png is 10 x 8; ...
    """
    from .._parallel import thread_pool

    paths = _path_list(paths, "paths")
    if not callable(read):
        raise InvalidInputError(f"read must be a function reading one image, got "
                                f"{type(read).__name__}")
    text(where, "where")
    labels = [Path(p).name for p in paths] if labels is None else _labels(labels, len(paths))
    first = read(paths[0])
    stack = np.empty((len(paths),) + first.shape, dtype=np.float32)
    stack[0] = first

    def load(i: int) -> None:
        im = read(paths[i])
        if im.shape != first.shape:
            raise FormatError(
                f"{where}: {labels[i]} is {im.shape[1]} x {im.shape[0]} px but {labels[0]} is "
                f"{first.shape[1]} x {first.shape[0]}; all views must have the same size"
            )
        stack[i] = im

    if len(paths) > 1:
        with thread_pool(min(8, len(paths) - 1)) as pool:
            list(pool.map(load, range(1, len(paths))))
    return stack
