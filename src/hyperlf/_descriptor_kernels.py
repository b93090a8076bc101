"""Numba kernel of the spectral-invariant descriptor (private; imported only inside
:func:`hyperlf.descriptor.descriptor`'s numba path, so ``import hyperlf.descriptor`` does not
import numba).  Its numpy reference is :func:`hyperlf.descriptor.descriptor_reference`; the
tests compare the two."""

from __future__ import annotations

import numba
import numpy as np
from numba import prange


@numba.njit(parallel=True, cache=True)
def hist_kernel(idx0, idx1, val, use_val, g, K, a, dest, out):  # pragma: no cover - numba
    """Gaussian-window histograms of one (level, hist) group; rows in parallel.

    idx0/idx1: (H, W) int32 bins (idx1 = -1: none); val: (H, W) vote weight, used if use_val
    (h3: M); g: (2r+1,) separable window factor; a: (H, W) edge weight; dest: (K,) output plane
    of each bin or -1; out: (n, H, W) float32.  Each output pixel gathers its w x w window
    (indices clamped = replicate border); each window pixel votes into at most two bins, so the
    cost is O(w^2) per pixel and histogram instead of O(K w) for dense filtering.  The
    normaliser is the sum of all votes, accumulated alongside, in float64.
    """
    H, W = idx0.shape
    r = g.shape[0] // 2
    for y in prange(H):
        hist = np.zeros((W, K), dtype=np.float64)
        total = np.zeros(W, dtype=np.float64)
        for dy in range(-r, r + 1):
            yy = min(max(y + dy, 0), H - 1)
            gy = g[dy + r]
            for x in range(W):
                acc_t = 0.0
                for dx in range(-r, r + 1):
                    xx = min(max(x + dx, 0), W - 1)
                    wgt = gy * g[dx + r]
                    if use_val:
                        wgt *= val[yy, xx]
                    hist[x, idx0[yy, xx]] += wgt
                    acc_t += wgt
                    k1 = idx1[yy, xx]
                    if k1 >= 0:
                        hist[x, k1] += wgt
                        acc_t += wgt
                total[x] += acc_t
        for x in range(W):
            if total[x] > 0:
                total[x] = a[y, x] / total[x]
            else:
                total[x] = 0.0
        for k in range(K):
            d = dest[k]
            if d >= 0:
                for x in range(W):
                    out[d, y, x] = hist[x, k] * total[x]
