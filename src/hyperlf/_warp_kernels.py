"""Numba kernels of :mod:`hyperlf.warp`.

Each has a numpy reference in :mod:`hyperlf.warp` (``_visible_at_labels_reference``,
``_occluder_excess_reference``) that the tests compare it with.  Imported only inside the functions that run a kernel, so
``import hyperlf.warp`` does not load numba.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(parallel=True, cache=True)
def visible_at_labels(z, dx, dy, labels, a, b, margin, out):  # pragma: no cover
    H, W = z.shape
    for l in numba.prange(labels.size):
        d = labels[l]
        for y in range(a, b):
            ty = np.rint(y - d * dy)
            row_in = 0 <= ty < H
            for x in range(W):
                tx = np.rint(x - d * dx)
                if row_in and 0 <= tx < W:
                    out[l, y - a, x] = d >= z[int(ty), int(tx)] - margin
                else:
                    out[l, y - a, x] = False


@numba.njit(parallel=True, cache=True)
def occluder_excess(z, dx, dy, labels, a, b, out):  # pragma: no cover
    H, W = z.shape
    for l in numba.prange(labels.size):
        d = labels[l]
        for y in range(a, b):
            ty = np.rint(y - d * dy)
            row_in = 0 <= ty < H
            for x in range(W):
                tx = np.rint(x - d * dx)
                if row_in and 0 <= tx < W:
                    out[l, y - a, x] = np.float64(z[int(ty), int(tx)]) - d
                else:
                    out[l, y - a, x] = np.inf
