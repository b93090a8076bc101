"""Numba kernels of :mod:`hyperlf.warp`.

Each has a numpy reference in :mod:`hyperlf.warp` (``_visible_at_labels_reference``,
``_occluder_excess_reference``) that the tests compare it with.  Imported only inside the
functions that run a kernel, so ``import hyperlf.warp`` does not load numba.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(inline="always", cache=True)
def _zbuffer_at(z, dx, dy, d, y, x):  # pragma: no cover
    """``(inside, z)``: whether reference pixel ``(y, x)`` at disparity ``d`` lands inside
    the image, and the z-buffer at the nearest pixel it lands on (float64)."""
    H, W = z.shape
    ty, tx = np.rint(y - d * dy), np.rint(x - d * dx)
    if 0 <= ty < H and 0 <= tx < W:
        return True, np.float64(z[int(ty), int(tx)])
    return False, 0.0


@numba.njit(parallel=True, cache=True)
def visible_at_labels(z, dx, dy, labels, a, b, margin, out):  # pragma: no cover
    for l in numba.prange(labels.size):
        for y in range(a, b):
            for x in range(z.shape[1]):
                inside, zt = _zbuffer_at(z, dx, dy, labels[l], y, x)
                out[l, y - a, x] = inside and labels[l] >= zt - margin


@numba.njit(parallel=True, cache=True)
def occluder_excess(z, dx, dy, labels, a, b, out):  # pragma: no cover
    for l in numba.prange(labels.size):
        for y in range(a, b):
            for x in range(z.shape[1]):
                inside, zt = _zbuffer_at(z, dx, dy, labels[l], y, x)
                out[l, y - a, x] = zt - labels[l] if inside else np.inf
