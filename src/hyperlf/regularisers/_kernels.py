"""Numba kernels of :mod:`hyperlf.regularisers` (compiled on first use, cached on disk).

Each kernel has a numpy reference beside its user that the tests compare it with:
:func:`sgm_path` <-> ``semiglobal._sgm_numpy_direction``, :func:`weighted_median` <->
``postprocess._weighted_median_numpy``, :func:`plane_scores` <-> ``planes._plane_scores_numpy``,
:func:`expansion_terms` <-> ``graphcuts._move_terms_numpy``, :func:`restricted_terms` <->
``graphcuts._restricted_terms_numpy``, :func:`move_delta` <-> ``graphcuts._move_delta_numpy``.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(parallel=True, cache=True, fastmath=False)
def sgm_path(C, acc, starts_y, starts_x, dy, dx, p1, p2map, mode):  # pragma: no cover - numba
    """Add one SGM path direction ``(dy, dx)`` to ``acc[H, W, L]``; one scanline per start.

    ``mode`` 0: P1/P2 smoothness; 1: truncated linear ``min(p1 |dl|, P2)`` (distance transform).
    """
    H, W, L = C.shape
    n = starts_y.shape[0]
    for s in numba.prange(n):
        prev = np.empty(L, dtype=np.float64)
        cur = np.empty(L, dtype=np.float64)
        dt = np.empty(L, dtype=np.float64)
        y = starts_y[s]
        x = starts_x[s]
        first = True
        while y >= 0 and y < H and x >= 0 and x < W:
            if first:
                for l in range(L):
                    cur[l] = C[y, x, l]
                first = False
            else:
                mprev = prev[0]
                for l in range(1, L):
                    if prev[l] < mprev:
                        mprev = prev[l]
                p2 = p2map[y, x]
                jump = mprev + p2
                if mode == 0:
                    for l in range(L):
                        v = prev[l]
                        if l > 0:
                            t = prev[l - 1] + p1
                            if t < v:
                                v = t
                        if l < L - 1:
                            t = prev[l + 1] + p1
                            if t < v:
                                v = t
                        if jump < v:
                            v = jump
                        cur[l] = C[y, x, l] + v - mprev
                else:
                    dt[0] = prev[0]
                    for l in range(1, L):
                        t = dt[l - 1] + p1
                        dt[l] = prev[l] if prev[l] < t else t
                    for l in range(L - 2, -1, -1):
                        t = dt[l + 1] + p1
                        if t < dt[l]:
                            dt[l] = t
                    for l in range(L):
                        v = dt[l]
                        if jump < v:
                            v = jump
                        cur[l] = C[y, x, l] + v - mprev
            for l in range(L):
                acc[y, x, l] += cur[l]
                prev[l] = cur[l]
            y += dy
            x += dx


@numba.njit(parallel=True, cache=True)
def weighted_median(d, g, r, sigma, mask, out):  # pragma: no cover - numba
    """Guided weighted median of ``d`` into ``out`` (window radius ``r``, borders replicated)
    at the pixels of ``mask``; the others copy ``d``."""
    H, W = d.shape
    n = (2 * r + 1) * (2 * r + 1)
    c = 1.0 / (2.0 * sigma * sigma)
    for y in numba.prange(H):
        v = np.empty(n)
        w = np.empty(n)
        for x in range(W):
            if not mask[y, x]:
                out[y, x] = d[y, x]
                continue
            gp = g[y, x]
            k = 0
            tot = 0.0
            for dy in range(-r, r + 1):
                yy = min(max(y + dy, 0), H - 1)
                for dx in range(-r, r + 1):
                    xx = min(max(x + dx, 0), W - 1)
                    v[k] = d[yy, xx]
                    e = g[yy, xx] - gp
                    w[k] = np.exp(-e * e * c)
                    tot += w[k]
                    k += 1
            order = np.argsort(v)
            half = 0.5 * tot
            acc = 0.0
            res = v[order[n - 1]]
            for i in range(n):
                acc += w[order[i]]
                if acc >= half:
                    res = v[order[i]]
                    break
            out[y, x] = res


@numba.njit(parallel=True, cache=True)
def plane_scores(P, dx, dy, A, B, c, min_inside, out):  # pragma: no cover - numba
    """Mean cost of every plane ``c_k + A_i dx + B_j dy`` over the samples.

    ``P`` (n, L) the samples' costs per label (label units: label ``l`` at position ``l``);
    ``dx``, ``dy`` (n,) the samples' offsets from the tile's centre; ``A``, ``B``, ``c`` the
    hypotheses in label units.  ``out[i, j, k]``: the mean over the samples whose plane value
    lies within ``0 .. L - 1`` (linear interpolation between labels), ``inf`` when fewer than
    ``min_inside`` of them do.  Numpy reference: ``planes._plane_scores_numpy``.
    """
    n, L = P.shape
    nb, nc = B.size, c.size
    for ij in numba.prange(A.size * nb):  # every slope pair in parallel (3 x 3 near the best)
        i = ij // nb
        j = ij - i * nb
        s = np.zeros(nc)
        m = np.zeros(nc, np.int64)
        for q in range(n):  # a sample's row of costs read once, along its labels
            ax = A[i] * dx[q]
            by = B[j] * dy[q]
            for k in range(nc):
                f = c[k] + ax + by
                if f < 0.0 or f > L - 1:
                    continue
                l0 = min(int(f), L - 2)
                t = f - l0
                s[k] += (1.0 - t) * P[q, l0] + t * P[q, l0 + 1]
                m[k] += 1
        for k in range(nc):
            out[i, j, k] = s[k] / m[k] if m[k] >= min_inside and m[k] > 0 else np.inf


@numba.njit(cache=True, inline="always")
def _pair_terms(w, v_pq, v_qa, v_pa):  # pragma: no cover - numba
    """A pair's share of ``du[p]`` and its capacity (clipped at 0): with ``A = w V(f_p, f_q)``,
    ``B = w V(f_p, alpha)``, ``C = w V(f_q, alpha)``, ``C - A`` and ``B + C - A``."""
    a = w * v_pq
    c = w * v_qa
    cap = w * v_pa + c - a
    return c - a, (cap if cap > 0.0 else 0.0)


@numba.njit(parallel=True, cache=True, fastmath=False)
def expansion_terms(c_alpha, alpha, f, unary_f, Vm, wx, wy, du, capx, capy):  # pragma: no cover
    """One alpha-expansion move's terms into ``du``, ``capx`` and ``capy`` (float64 (H, W)):
    ``graphcuts._move_terms_numpy``, the same operations in the same order per pixel."""
    H, W = f.shape
    for y in numba.prange(H):
        for x in range(W):
            fp = f[y, x]
            vpa = Vm[fp, alpha]
            d = np.float64(c_alpha[y, x]) - unary_f[y, x]
            if x + 1 < W:
                fq = f[y, x + 1]
                share, capx[y, x] = _pair_terms(wx[y, x], Vm[fp, fq], Vm[fq, alpha], vpa)
                d += share
            if x > 0:
                d -= wx[y, x - 1] * vpa
            if y + 1 < H:
                fq = f[y + 1, x]
                share, capy[y, x] = _pair_terms(wy[y, x], Vm[fp, fq], Vm[fq, alpha], vpa)
                d += share
            if y > 0:
                d -= wy[y - 1, x] * vpa
            du[y, x] = d


@numba.njit(cache=True)
def restricted_terms(active, du, capx, capy):  # pragma: no cover - numba
    """The terms of a move whose variables are only the ``active`` pixels:
    ``graphcuts._restricted_terms_numpy``, the same values in the same order.

    Node ``i`` is the ``i``-th active pixel in row-major order.  Returns ``(d, src, dst, caps)``:
    the nodes' unary terms, and the pairs with both pixels active (the right pairs, then the
    down pairs, each row-major).  A pair whose first pixel is fixed adds its capacity to the
    second pixel's term (right pairs before down pairs); a pair with a fixed second pixel drops.
    """
    H, W = active.shape
    idx = np.full((H, W), -1, dtype=np.int64)
    n = 0
    m = 0
    for y in range(H):
        for x in range(W):
            if active[y, x]:
                idx[y, x] = n
                n += 1
                if x > 0 and active[y, x - 1]:
                    m += 1
                if y > 0 and active[y - 1, x]:
                    m += 1
    d = np.empty(n, dtype=np.float64)
    src = np.empty(m, dtype=np.int64)
    dst = np.empty(m, dtype=np.int64)
    caps = np.empty(m, dtype=np.float64)
    k = 0
    for y in range(H):
        for x in range(W):
            if active[y, x]:
                v = du[y, x]
                if x > 0:
                    if active[y, x - 1]:
                        src[k] = idx[y, x - 1]
                        dst[k] = idx[y, x]
                        caps[k] = capx[y, x - 1]
                        k += 1
                    else:
                        v += capx[y, x - 1]
                d[idx[y, x]] = v
    for y in range(1, H):
        for x in range(W):
            if active[y, x]:
                if active[y - 1, x]:
                    src[k] = idx[y - 1, x]
                    dst[k] = idx[y, x]
                    caps[k] = capy[y - 1, x]
                    k += 1
                else:
                    d[idx[y, x]] += capy[y - 1, x]
    return d, src, dst, caps


@numba.njit(cache=True)
def move_delta(switch, c_alpha, alpha, f, unary_f, Vm, wx, wy):  # pragma: no cover - numba
    """The change of the MRF energy when the ``switch`` pixels of ``f`` take ``alpha``:
    ``graphcuts._move_delta_numpy``, up to the order of the sum.

    Only the switched pixels and the pairs that hold one are read.  A pair of two switched
    pixels is counted once, from its left or upper pixel.  Serial, so that the sum's order does
    not depend on the number of threads.
    """
    H, W = f.shape
    total = 0.0
    for y in range(H):
        for x in range(W):
            if not switch[y, x]:
                continue
            fp = f[y, x]
            total += np.float64(c_alpha[y, x]) - unary_f[y, x]
            if x + 1 < W:
                fq = f[y, x + 1]
                nq = alpha if switch[y, x + 1] else fq
                total += wx[y, x] * (Vm[alpha, nq] - Vm[fp, fq])
            if x > 0 and not switch[y, x - 1]:
                fq = f[y, x - 1]
                total += wx[y, x - 1] * (Vm[fq, alpha] - Vm[fq, fp])
            if y + 1 < H:
                fq = f[y + 1, x]
                nq = alpha if switch[y + 1, x] else fq
                total += wy[y, x] * (Vm[alpha, nq] - Vm[fp, fq])
            if y > 0 and not switch[y - 1, x]:
                fq = f[y - 1, x]
                total += wy[y - 1, x] * (Vm[fq, alpha] - Vm[fq, fp])
    return total
