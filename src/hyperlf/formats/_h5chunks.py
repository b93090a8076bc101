"""Writing image-chunked HDF5 datasets with their gzip chunks compressed in parallel.

hyperlf's large datasets (views, cubes, masks) are chunked one ``(H, W)`` image per chunk
and compressed with HDF5's shuffle + deflate filters. libhdf5 runs those filters in the
calling thread, holding Python's GIL, so writing a paper-size cube compresses on one core
however many there are. :func:`write_images` applies the same two filters itself, one image
per task in a thread pool (zlib releases the GIL), and stores the results with
``write_direct_chunk``: the file holds the bytes HDF5's own filters would have written
(checked by the tests), readable by any HDF5 reader. Datasets chunked or filtered otherwise
are written by plain assignment.
"""

from __future__ import annotations

import os
import zlib
from concurrent.futures import ThreadPoolExecutor
from itertools import product

import numpy as np

#: Images compressed per batch and thread: bounds the compressed bytes waiting to be written.
_BATCH_PER_THREAD = 4


def compress_threads() -> int:
    """The threads :func:`write_images` compresses with: the CPUs this process may use
    (``HYPERLF_H5_THREADS`` overrides; 1 compresses in the calling thread)."""
    env = os.environ.get("HYPERLF_H5_THREADS", "").strip()
    if env.isdigit() and int(env) > 0:
        return int(env)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _gzip_level(ds) -> int | None:
    """The deflate level when ``ds`` is chunked one trailing image per chunk and filtered by
    deflate alone or shuffle + deflate (the filters this module reproduces); else None."""
    chunks = ds.chunks
    if (chunks is None or ds.ndim < 2 or ds.compression != "gzip" or ds.fletcher32
            or ds.scaleoffset is not None
            or tuple(chunks) != (1,) * (ds.ndim - 2) + tuple(ds.shape[-2:])):
        return None
    return int(ds.compression_opts)


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
        Leading integer indices; ``data`` fills everything below them.
    data : array_like
        Shaped ``ds.shape[len(index):]``, cast to ``ds.dtype``.
    """
    level = _gzip_level(ds)
    a = np.asarray(data)
    if level is None or a.shape != ds.shape[len(index):]:
        ds[index] = a  # h5py's own checks and messages
        return
    a = np.ascontiguousarray(a, dtype=ds.dtype)
    lead = [range(n) for n in a.shape[:-2]]
    keys = list(product(*lead))
    threads = min(compress_threads(), max(len(keys), 1))
    tail = (0, 0)

    def work(key):
        return _filtered(a[key], level, bool(ds.shuffle))

    if threads == 1:
        for key in keys:
            ds.id.write_direct_chunk(tuple(index) + key + tail, work(key))
        return
    batch = threads * _BATCH_PER_THREAD
    with ThreadPoolExecutor(threads) as pool:
        for start in range(0, len(keys), batch):
            part = keys[start:start + batch]
            for key, buf in zip(part, pool.map(work, part)):
                ds.id.write_direct_chunk(tuple(index) + key + tail, buf)
