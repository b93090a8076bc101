"""Reading and writing ordinary images (PNG, TIFF, and what OpenCV reads).

Conventions
-----------
* Arrays are ``(H, W)`` for grey images and ``(H, W, 3)`` in **RGB** order for colour images
  (OpenCV's BGR order never leaks out). An alpha channel is dropped.
* Palette PNGs (several Middlebury masks and ground truths) are expanded to the colours of their
  palette; when the palette is grey (all three channels equal) the image is returned as ``(H, W)``
  grey levels, so Tsukuba's ``groundtruth.png`` reads as 0..224, not as palette indices 0..7.
* TIFF files (8/16-bit integer and float32) go through :mod:`tifffile`; the rest through OpenCV.
* ``as_float=True`` maps integer images to [0, 1] by dividing by the dtype's maximum
  (255 or 65535); float images are returned as float32 unchanged.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from ..errors import DataNotFoundError, FormatError, InvalidInputError

__all__ = ["read_image", "read_images_same_size", "write_image", "to_grey", "REC709_WEIGHTS"]

#: Rec. 709 luma weights (R, G, B) used by :func:`to_grey`.
REC709_WEIGHTS = (0.2126, 0.7152, 0.0722)

_TIFF = (".tif", ".tiff")
_WRITABLE = (".png", ".tif", ".tiff")


def _is_palette_png(path: Path) -> bool:
    """True when ``path`` is a PNG with colour type 3 (palette)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(26)
    except OSError:
        return False
    return len(head) == 26 and head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR" \
        and head[25] == 3


def _read_tiff(p: Path) -> np.ndarray:
    import tifffile

    try:
        arr = tifffile.imread(p, key=0)
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
        # IMREAD_UNCHANGED keeps 16-bit depth; OpenCV expands palette PNGs to BGR itself.
        arr = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
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
    if _is_palette_png(p) and arr.ndim == 3 and arr.shape[2] == 3 \
            and np.array_equal(arr[..., 0], arr[..., 1]) and np.array_equal(arr[..., 0], arr[..., 2]):
        arr = arr[..., 0]
    return np.ascontiguousarray(arr)


def read_image(path: str | os.PathLike, as_float: bool = True,
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
        When the file cannot be decoded.
    """
    p = Path(path)
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
    elif channels not in (None, "grey", "rgb"):
        raise InvalidInputError(f"channels must be None, 'grey' or 'rgb', got {channels!r}")
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
        Bits per sample for float input. 32 writes float32 samples unchanged (no clipping);
        only TIFF supports it.

    Returns
    -------
    Path
        The written file.
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in _WRITABLE:
        raise InvalidInputError(
            f"cannot write {p}: supported image formats are .png, .tif and .tiff"
        )
    arr = np.asarray(array)
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] != 3) or arr.size == 0:
        raise InvalidInputError(f"an image must be (H, W) or (H, W, 3), got shape {arr.shape}")
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8) * 255
    if arr.dtype in (np.uint8, np.uint16):
        out = arr
    elif np.issubdtype(arr.dtype, np.integer):
        raise InvalidInputError(
            f"integer images must be uint8 or uint16, got {arr.dtype}; convert or pass floats in [0, 1]"
        )
    elif np.issubdtype(arr.dtype, np.floating):
        if not np.all(np.isfinite(arr)):
            raise InvalidInputError(f"cannot write {p}: the image contains NaN or inf")
        if bit_depth == 8:
            out = np.rint(np.clip(arr, 0.0, 1.0) * 255.0).astype(np.uint8)
        elif bit_depth == 16:
            out = np.rint(np.clip(arr, 0.0, 1.0) * 65535.0).astype(np.uint16)
        elif bit_depth == 32:
            if ext not in _TIFF:
                raise InvalidInputError(
                    f"cannot write {p}: 32-bit float images need a .tif/.tiff file, not {ext}"
                )
            out = arr.astype(np.float32)
        else:
            raise InvalidInputError(f"bit_depth must be 8, 16 or 32, got {bit_depth!r}")
    else:
        raise InvalidInputError(f"cannot write an image of dtype {arr.dtype}")
    out = np.ascontiguousarray(out)
    with atomic_path(p) as tmp:
        if ext in _TIFF:
            import tifffile

            tifffile.imwrite(tmp, out, photometric="rgb" if out.ndim == 3 else "minisblack")
        else:
            import cv2

            bgr = np.ascontiguousarray(out[..., ::-1]) if out.ndim == 3 else out
            if not cv2.imwrite(str(tmp), bgr):
                raise FormatError(f"OpenCV failed to write {p}")
    return p


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
    """
    from concurrent.futures import ThreadPoolExecutor

    paths = list(paths)
    labels = [Path(p).name for p in paths] if labels is None else list(labels)
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
        with ThreadPoolExecutor(max_workers=min(8, len(paths) - 1)) as pool:
            list(pool.map(load, range(1, len(paths))))
    return stack
