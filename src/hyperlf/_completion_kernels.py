"""Numba kernel of :mod:`hyperlf.completion`: one round of the joint-bilateral inference of
entries no view observed.

Its numpy reference is ``completion._infer_round_numpy`` (compared in the tests).  Imported
only inside the function that runs it, so ``import hyperlf.completion`` does not load numba.
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
