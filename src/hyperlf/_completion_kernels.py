"""Numba kernels of :mod:`hyperlf.completion`: one round of the joint-bilateral inference of
entries no view observed (:func:`infer_round`), and the spectral fill of what is still
missing (:func:`fill_bands`).

Their numpy references are ``completion._infer_round_numpy`` and
``completion._interpolate_bands`` (compared in the tests).  Imported only inside the
functions that run them, so ``import hyperlf.completion`` does not load numba.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(parallel=True, cache=True)
def infer_round(cube, src, disp, guide, radius, sigma_d, sigma_g, min_weight, out, got):
    B, H, W = cube.shape
    sig_s = max(radius / 2.0, 0.5)
    cs = 1.0 / (2.0 * sig_s * sig_s)
    cd = 1.0 / (2.0 * sigma_d * sigma_d)
    cg = 1.0 / (2.0 * sigma_g * sigma_g)
    for b in numba.prange(B):
        for y in range(H):
            for x in range(W):
                out[b, y, x] = cube[b, y, x]
                got[b, y, x] = False
                if src[b, y, x]:
                    continue
                dp = disp[y, x]
                gp = guide[y, x]
                if not (np.isfinite(dp) and np.isfinite(gp)):
                    continue
                acc = 0.0
                ws = 0.0
                for qy in range(max(y - radius, 0), min(y + radius + 1, H)):
                    for qx in range(max(x - radius, 0), min(x + radius + 1, W)):
                        if not src[b, qy, qx]:
                            continue
                        dq = disp[qy, qx]
                        gq = guide[qy, qx]
                        if not (np.isfinite(dq) and np.isfinite(gq)):
                            continue
                        e = (((qy - y) ** 2 + (qx - x) ** 2) * cs + (dp - dq) ** 2 * cd
                             + (gp - gq) ** 2 * cg)
                        w = np.exp(-e)
                        acc += w * cube[b, qy, qx]
                        ws += w
                if ws >= min_weight:
                    out[b, y, x] = acc / ws
                    got[b, y, x] = True


#: ``np.nan_to_num``'s stand-in for an infinite interpolation weight (duplicate wavelengths).
_BIG = np.finfo(np.float64).max


@numba.njit(parallel=True, cache=True, error_model="numpy")
def fill_bands(out, m, wl):
    """The spectral fill of one view's ``(B, H, W)`` float32 cube ``out`` in place: each entry
    not in ``m`` linearly interpolated over ``wl`` between the pixel's nearest valid bands, the
    nearest valid band beyond the ends, 0 with none. The numpy reference,
    ``completion._interpolate_bands``, computes the same operations (float32 difference,
    float64 weight and sum, rounded to float32), so the results are equal bit for bit."""
    B, H, W = out.shape
    for y in numba.prange(H):
        lo = np.empty(B, np.int64)
        hi = np.empty(B, np.int64)
        for x in range(W):
            last = -1
            for b in range(B):
                if m[b, y, x]:
                    last = b
                lo[b] = last
            last = B
            for b in range(B - 1, -1, -1):
                if m[b, y, x]:
                    last = b
                hi[b] = last
            for b in range(B):
                if m[b, y, x]:
                    continue
                l, h = lo[b], hi[b]
                if l >= 0 and h < B:
                    t = (wl[b] - wl[l]) / (wl[h] - wl[l])
                    if np.isnan(t):
                        t = 0.0
                    elif t > _BIG:
                        t = _BIG
                    elif t < -_BIG:
                        t = -_BIG
                    d = out[h, y, x] - out[l, y, x]
                    out[b, y, x] = np.float32(np.float64(out[l, y, x]) + t * np.float64(d))
                elif l >= 0:
                    out[b, y, x] = out[l, y, x]
                elif h < B:
                    out[b, y, x] = out[h, y, x]
                else:
                    out[b, y, x] = 0.0
