"""Numba kernels of :mod:`hyperlf.hlf` (view-selection aggregation and the defocus cost).

Each has a numpy reference in :mod:`hyperlf.hlf` (``aggregate_view_reference``,
``defocus_cost_reference``) that the tests compare it with.  Imported only inside the functions
that run a kernel, so ``import hyperlf.hlf`` does not load numba.
"""

from __future__ import annotations

import math

import numba


@numba.njit(parallel=True, cache=True)
def aggregate(Cv, valid, Mq, Mbar, M_ref, use_sel, separate, S_sel, N_sel, S_all, N_all,
              edge_idx, edge_side, ES_sel, EN_sel, ES_all, EN_all):  # pragma: no cover
    """``separate`` False: the ``*_sel`` arrays are the ``*_all`` ones (no view selection),
    so they are added to once."""
    L, H, W = Cv.shape
    for l in numba.prange(L):
        for y in range(H):
            for x in range(W):
                if not valid[l, y, x]:
                    continue
                c = Cv[l, y, x]
                S_all[l, y, x] += c
                N_all[l, y, x] += 1.0
                s = True
                if use_sel:
                    s = (M_ref[y, x] > Mbar[l, y, x]) == (Mq[l, y, x] > Mbar[l, y, x])
                if s and separate:
                    S_sel[l, y, x] += c
                    N_sel[l, y, x] += 1.0
        for e in range(edge_idx.shape[0]):
            i = edge_idx[e]
            y = i // W
            x = i - y * W
            if not valid[l, y, x]:
                continue
            c = Cv[l, y, x]
            s = True
            if use_sel:
                s = (M_ref[y, x] > Mbar[l, y, x]) == (Mq[l, y, x] > Mbar[l, y, x])
            sd = edge_side[e]
            for h in range(2):
                if sd == 0 or (h == 0 and sd == 1) or (h == 1 and sd == -1):
                    ES_all[h, l, e] += c
                    EN_all[h, l, e] += 1.0
                    if s and separate:
                        ES_sel[h, l, e] += c
                        EN_sel[h, l, e] += 1.0


@numba.njit(parallel=True, cache=True)
def defocus(P, valid, wl_sorted_idx, wl, lam_r, prior, sigma_d, p_eps, out):  # pragma: no cover
    N, H, W = P.shape
    inv2s2 = 1.0 / (2.0 * sigma_d * sigma_d)
    for y in numba.prange(H):
        for x in range(W):
            tot = 0.0
            nv = 0
            for v in range(N):
                if valid[v, y, x]:
                    tot += P[v, y, x]
                    nv += 1
            if nv == 0:
                out[y, x] = 0.0
                continue
            if prior == 2:
                d = 0.0
                have = False
                last = 0.0
                for k in range(N):
                    v = wl_sorted_idx[k]
                    if valid[v, y, x]:
                        ps = P[v, y, x] / tot if tot > 0 else 0.0
                        if ps < p_eps:
                            ps = p_eps
                        if have:
                            d += abs(ps - last)
                        last = ps
                        have = True
                out[y, x] = d
                continue
            gs = 0.0
            lr = lam_r[y, x]
            for v in range(N):
                if valid[v, y, x]:
                    if prior == 1:
                        gs += 1.0
                    else:
                        gs += math.exp(-(wl[v] - lr) * (wl[v] - lr) * inv2s2)
            d = 0.0
            if gs > 0:
                for v in range(N):
                    if valid[v, y, x]:
                        if prior == 1:
                            g = 1.0 / gs
                        else:
                            g = math.exp(-(wl[v] - lr) * (wl[v] - lr) * inv2s2) / gs
                        if g > 0:
                            ps = P[v, y, x] / tot if tot > 0 else 0.0
                            if ps < p_eps:
                                ps = p_eps
                            d += g * math.log(g / ps)
            out[y, x] = d
