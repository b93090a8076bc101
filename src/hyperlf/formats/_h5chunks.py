"""Writing and reading image-chunked HDF5 datasets, their gzip chunks (de)compressed in
parallel.

hyperlf's large datasets (views, cubes, masks) are chunked one ``(H, W)`` image per chunk
and compressed with HDF5's shuffle + deflate filters. libhdf5 runs those filters in the
calling thread, holding Python's GIL, so writing a paper-size cube compresses on one core
however many there are. :func:`write_images` applies the same two filters itself, one image
per task in a thread pool (zlib releases the GIL), and stores the results with
``write_direct_chunk``: the file holds the bytes HDF5's own filters would have written
(checked by the tests), readable by any HDF5 reader. :func:`read_images` reads the same way:
raw chunks with ``read_direct_chunk``, inflated and unshuffled in threads, each checked to
give exactly its image's bytes. Datasets chunked or filtered otherwise, chunks stored
without their filters or never written, and a process with one CPU take h5py's plain path
(libhdf5's zlib is as fast as Python's on one thread).
"""

from __future__ import annotations

import contextlib
import functools
import zlib
from itertools import product

import numpy as np

from .._parallel import pipeline, threads

#: Little-endian unsigned integers as wide as an element: the byte planes are put back by
#: shifts, several times faster than a strided byte copy.
_WORDS = {2: np.dtype("<u2"), 4: np.dtype("<u4"), 8: np.dtype("<u8")}


def _gzip_level(ds) -> int | None:
    """The deflate level when ``ds`` is chunked one trailing image per chunk and filtered by
    deflate alone or shuffle + deflate (the filters this module reproduces); else None."""
    chunks = ds.chunks
    if (chunks is None or ds.ndim < 2 or ds.compression != "gzip" or ds.fletcher32
            or ds.scaleoffset is not None
            or tuple(chunks) != (1,) * (ds.ndim - 2) + tuple(ds.shape[-2:])):
        return None
    return int(ds.compression_opts)


# ----------------------------------------------------------------------------- writing
def _filtered(image: np.ndarray, level: int, shuffle: bool) -> bytes:
    """HDF5's shuffle (byte planes) then deflate (a zlib stream) of one image's bytes."""
    raw = image.reshape(-1).view(np.uint8)
    if shuffle and image.itemsize > 1:
        raw = raw.reshape(-1, image.itemsize).T
    return zlib.compress(np.ascontiguousarray(raw).tobytes(), level)


def write_images(ds, index: tuple[int, ...], data) -> None:
    """``ds[index] = data``, compressing the image chunks in parallel where possible.

    Parameters
    ----------
    ds : h5py.Dataset
        Chunked one ``(H, W)`` image per chunk with shuffle + gzip (or gzip alone) for the
        parallel path; any other dataset is written by plain assignment.
    index : tuple of int
        Leading non-negative integer indices; ``data`` fills everything below them.
    data : array_like
        Shaped ``ds.shape[len(index):]``, cast to ``ds.dtype``.
    """
    level, lead = _gzip_level(ds), _chunk_index(ds, index)
    a = np.asarray(data)
    if (level is None or lead is None or a.shape != ds.shape[len(lead):]
            or threads() == 1):
        ds[index] = a  # h5py's own checks and messages; its filters on one thread
        return
    a = np.ascontiguousarray(a, dtype=ds.dtype)
    keys = list(product(*(range(n) for n in a.shape[:-2])))
    shuffle = bool(ds.shuffle)  # read here: h5py calls from the pool would wait on its lock
    tasks = (functools.partial(lambda k: (k, _filtered(a[k], level, shuffle)), key)
             for key in keys)
    pipeline(tasks, len(keys),
              then=lambda kb: ds.id.write_direct_chunk(lead + kb[0] + (0, 0), kb[1]))


# ----------------------------------------------------------------------------- reading
def _unfiltered(buf: bytes, out: np.ndarray, shuffle: bool) -> None:
    """Inflate (and unshuffle) one stored chunk into the contiguous image ``out``."""
    n = out.nbytes
    z = zlib.decompressobj()
    raw = z.decompress(buf, n)
    if len(raw) != n or z.unconsumed_tail:
        raise ValueError(f"a chunk inflates to {'more than ' if z.unconsumed_tail else ''}"
                         f"{len(raw)} bytes instead of its image's {n}")
    b = np.frombuffer(raw, np.uint8)
    if shuffle and out.itemsize > 1:
        _unshuffle(b.reshape(out.itemsize, -1), out.reshape(-1))
    else:
        out.reshape(-1).view(np.uint8)[:] = b


def _unshuffle(planes: np.ndarray, out: np.ndarray) -> None:
    """Interleave the ``(itemsize, n)`` byte planes into the flat array ``out``."""
    word = _WORDS.get(planes.shape[0])
    if word is None:
        out.view(np.uint8)[:] = planes.T.reshape(-1)
        return
    u = out.view(word)
    u[:] = planes[0]
    for k in range(1, planes.shape[0]):
        u |= planes[k].astype(word) << word.type(8 * k)


def _chunk_index(ds, index) -> tuple[int, ...] | None:
    """``index`` as non-negative ints naming whole images of ``ds``; None otherwise."""
    if not isinstance(index, tuple) or len(index) > ds.ndim - 2:
        return None
    if not all(isinstance(i, (int, np.integer)) and 0 <= i < n
               for i, n in zip(index, ds.shape)):
        return None
    return tuple(int(i) for i in index)


class _Plain(Exception):
    """A chunk h5py must read itself (stored without its filters, or never written)."""


def _stored(ds, offset) -> bytes:
    """The stored bytes of the chunk at ``offset``, or :class:`_Plain`."""
    try:
        mask, buf = ds.id.read_direct_chunk(offset)
    except (KeyError, OSError, RuntimeError, ValueError):
        raise _Plain from None  # never written: HDF5 supplies the fill value
    if mask:
        raise _Plain
    return buf


def read_images(ds, index: tuple[int, ...] = ()) -> np.ndarray:
    """``ds[index]``, inflating the image chunks in parallel where possible.

    Parameters
    ----------
    ds : h5py.Dataset
        As in :func:`write_images`; any other dataset is read by h5py.
    index : tuple of int
        Leading non-negative integer indices (other selections are read by h5py).

    Returns
    -------
    ndarray, shape ``ds.shape[len(index):]``, ``ds.dtype``

    Raises
    ------
    ValueError
        A stored chunk does not inflate to exactly its image (a corrupt file); h5py's own
        errors on the plain path.
    """
    level, lead = _gzip_level(ds), _chunk_index(ds, index)
    if level is None or lead is None or threads() == 1:
        return ds[index]
    # h5py spells a native dtype with its byte order ('<f4'); its own reads give the plain one
    dtype = ds.dtype.newbyteorder("=") if ds.dtype.isnative else ds.dtype
    out = np.empty(ds.shape[len(lead):], dtype=dtype)
    keys = list(product(*(range(n) for n in out.shape[:-2])))
    shuffle = bool(ds.shuffle)
    tasks = (functools.partial(_unfiltered, _stored(ds, lead + key + (0, 0)), out[key], shuffle)
             for key in keys)
    with contextlib.suppress(_Plain):
        pipeline(tasks, len(keys))
        return out
    return ds[index]

