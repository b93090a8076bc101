"""Numba kernels of the matching costs (private; imported only inside the functions that run
them, so that ``import hyperlf.costs`` does not import numba).

Each kernel has a readable numpy reference in :mod:`hyperlf.costs.pair` or
:mod:`hyperlf.costs.lightfield`; the tests compare the two.

Rectified pair (integer disparities): :func:`xcorr_accum` (NCC cross terms), :func:`hamming_volume`
(census), :func:`weighted_hamming_volume` (census with adaptive support weights), and the BWNCC
pipeline :func:`bw_channel_stats`, :func:`bw_inv_sigma`, :func:`bw_pad`,
:func:`bw_den_add`, :func:`bw_accum`, :func:`bw_finish`.  Light field (sub-pixel shifts):
:func:`xi_shift` (NCC with the bilinearly shifted view), :func:`census_shift` and
:func:`shift_average` (census averaged over sub-pixel shifts).  RSNCC's robust function:
:func:`rho_sum`.  Fusion:
:func:`valid_std` and :func:`normalise_fill` (``norm(C)`` of
:func:`hyperlf.costs.pair.normalise_volume`), :func:`fuse_fill` (:func:`hyperlf.costs.pair.fuse`).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange


@numba.njit(inline="always")
def overlap(d, W):
    """Columns ``x0 <= x < x1`` of a row of width ``W`` whose match ``x - d`` is in the image."""
    return max(0, d), min(W, W + d)


@numba.njit(inline="always")
def window_geometry(Ap, mA, r):
    """Sizes for the cross-term kernels: channels ``nc``, image ``H``, ``W`` (of the patch
    means ``mA``), window side ``n = 2r + 1``, ``1 / n^2`` and the padded width ``W + 2r``."""
    n = 2 * r + 1
    W = mA.shape[2]
    return Ap.shape[0], mA.shape[1], W, n, 1.0 / (n * n), W + 2 * r


@numba.njit(inline="always")
def products_init(Ap, Bp, c, y0, n, a0, b0, m, ca, cb, V):
    """``V[j] = sum_{v < n} (Ap[c, y0 + v, a0 + j] - ca) (Bp[c, y0 + v, b0 + j] - cb)`` for
    ``j < m``: the vertical window sums of centred products at the top row of a band (float64,
    ``v`` ascending)."""
    for j in range(m):
        V[j] = 0.0
    for v in range(n):
        ar = Ap[c, y0 + v, a0:a0 + m]
        br = Bp[c, y0 + v, b0:b0 + m]
        for j in range(m):
            V[j] += (np.float64(ar[j]) - ca) * (np.float64(br[j]) - cb)


@numba.njit(inline="always")
def products_slide(Ap, Bp, c, yin, yout, a0, b0, m, ca, cb, V):
    """Move the window sums of :func:`products_init` down one row: add row ``yin``'s centred
    products and remove row ``yout``'s (one update per column)."""
    ai = Ap[c, yin, a0:a0 + m]
    bi = Bp[c, yin, b0:b0 + m]
    ao = Ap[c, yout, a0:a0 + m]
    bo = Bp[c, yout, b0:b0 + m]
    for j in range(m):
        V[j] += ((np.float64(ai[j]) - ca) * (np.float64(bi[j]) - cb)
                 - (np.float64(ao[j]) - ca) * (np.float64(bo[j]) - cb))


@numba.njit(inline="always")
def band_columns_active(s, c, y0, y1, fl):
    """``fl[x]`` = some row ``y0 <= y < y1`` of channel ``c`` of ``s`` is non-zero at ``x``."""
    fl[:] = False
    for y in range(y0, y1):
        row = s[c, y]
        for x in range(fl.shape[0]):
            fl[x] = fl[x] or (row[x] != 0.0)


@numba.njit(parallel=True, cache=True, fastmath=False)
def xcorr_accum(Ap, Bp, ca, cb, mA, isA, mB, isB, ds, r, weighted, accF, accB):
    """For every disparity ds[k] and channel c: xi of the left patch at (y, x) and the right
    patch at (y, x - d) (both from replicate-padded maps Ap, Bp of shape (nc, H+2r, W+2r)),
    accumulated into accF[k] (and accB[k]).  ``mA``/``mB`` are the patch means minus the
    channel centres ``ca``/``cb``, ``isA``/``isB`` 1/sigma.  Float64 sums.

    Loop order (cache): parallel over bands of BAND rows; inside a band, every disparity
    and channel reuses the band's rows from cache (a disparity-outer order is DRAM-bound).
    Vertical box sums run down the band (re-initialised per band), horizontal ones use
    prefix sums; the per-pixel loop is branch-free."""
    BAND = 16
    nc, H, W, n, inv, Wp = window_geometry(Ap, mA, r)
    nb = (H + BAND - 1) // BAND
    for b in prange(nb):
        y0 = b * BAND
        y1 = min(H, y0 + BAND)
        V = np.zeros(Wp)
        P = np.zeros(Wp + 1)
        bF = np.zeros((BAND, W))
        bB = np.zeros((BAND, W))
        for k in range(ds.shape[0]):
            d = ds[k]
            x0, x1 = overlap(d, W)
            if x1 <= x0:
                continue
            X0 = x0
            X1 = x1 + 2 * r
            bF[:, :] = 0.0
            bB[:, :] = 0.0
            for c in range(nc):
                cac = ca[c]
                cbc = cb[c]
                VX = V[X0:X1]
                products_init(Ap, Bp, c, y0, n, X0, X0 - d, X1 - X0, cac, cbc, VX)
                for y in range(y0, y1):
                    if y > y0:
                        products_slide(Ap, Bp, c, y + 2 * r, y - 1, X0, X0 - d, X1 - X0, cac, cbc,
                                       VX)
                    acc = 0.0
                    P[X0] = 0.0
                    for X in range(X0, X1):
                        acc += V[X]
                        P[X + 1] = acc
                    yb = y - y0
                    for x in range(x0, x1):
                        xq = x - d
                        ma = np.float64(mA[c, y, x])
                        mb = np.float64(mB[c, y, xq])
                        cov = (P[x + n] - P[x]) * inv - ma * mb
                        xi = cov * isA[c, y, x] * isB[c, y, xq]
                        xi = min(max(xi, -1.0), 1.0)
                        if weighted:
                            bF[yb, x] += xi * (ma + cac)
                            bB[yb, x] += xi * (mb + cbc)
                        else:
                            bF[yb, x] += xi
            for y in range(y0, y1):
                for x in range(x0, x1):
                    accF[k, y, x] += bF[y - y0, x]
                    if weighted:
                        accB[k, y, x] += bB[y - y0, x]

@numba.njit(inline="always")
def popcount64(v):
    v = v - ((v >> np.uint64(1)) & np.uint64(0x5555555555555555))
    v = (v & np.uint64(0x3333333333333333)) + ((v >> np.uint64(2)) & np.uint64(0x3333333333333333))
    v = (v + (v >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return (v * np.uint64(0x0101010101010101)) >> np.uint64(56)

@numba.njit(parallel=True, cache=True)
def hamming_volume(cl, cr, ds, out):
    H, W = cl.shape
    for k in prange(ds.shape[0]):
        d = ds[k]
        x0, x1 = overlap(d, W)
        for y in range(H):
            for x in range(x0, x1):
                out[k, y, x] = np.float32(popcount64(cl[y, x] ^ cr[y, x - d]))

@numba.njit(parallel=True, cache=True)
def weighted_hamming_volume(cl, cr, wl, wr, ds, out):  # pragma: no cover
    """``out[k, y, x] = K sum_b w_b [bit b of cl ^ cr differs] / sum_b w_b`` with ``w_b =
    wl[y, x, b] wr[y, x - d, b]``, ``d = ds[k]``, ``K`` bits, in float64; rows in parallel.
    Reference: :func:`hyperlf.costs.pair.census_volume` with ``impl="numpy"``."""
    H, W = cl.shape
    K = wl.shape[2]
    for y in prange(H):
        for k in range(ds.shape[0]):
            d = ds[k]
            x0, x1 = overlap(d, W)
            for x in range(x0, x1):
                v = cl[y, x] ^ cr[y, x - d]
                num = 0.0
                den = 0.0
                for b in range(K):
                    w = np.float64(wl[y, x, b]) * wr[y, x - d, b]
                    den += w
                    if (v >> np.uint64(b)) & np.uint64(1):
                        num += w
                out[k, y, x] = K * num / den

@numba.njit(cache=True)
def shifted_sum(out, a, b, sb, m):
    """``out[j] = a[j] + b[sb + j]`` for ``j < m``."""
    bs = b[sb:]
    for j in range(m):
        out[j] = a[j] + bs[j]


@numba.njit(cache=True)
def shifted_sum3(out, a, b, sb, c, sc, m):
    """``out[j] = a[j] + b[sb + j] + c[sc + j]`` for ``j < m`` (summed left to right)."""
    bs = b[sb:]
    cs = c[sc:]
    for j in range(m):
        out[j] = a[j] + bs[j] + cs[j]


@numba.njit(cache=True)
def shifted_add(out, b, sb, m):
    """``out[j] += b[sb + j]`` for ``j < m``."""
    bs = b[sb:]
    for j in range(m):
        out[j] += bs[j]


@numba.njit(cache=True)
def hsum(Vs, T1, T2, S, nX, n):
    """``S[j] = sum_{t < n} Vs[j + t]`` for ``j < nX - n + 1`` by doubling (vectorisable
    passes over contiguous rows; a prefix sum is a serial dependency chain): ``T1`` holds the
    sums of 2 neighbours, ``T2`` of 4; n = 1, 3, 5, 9 have their own closed forms."""
    m = nX - n + 1
    if n == 1:
        for j in range(m):
            S[j] = Vs[j]
        return
    shifted_sum(T1, Vs, Vs, 1, nX - 1)
    if n == 3:
        shifted_sum(S, T1, Vs, 2, m)
        return
    if n == 5:
        shifted_sum3(S, T1, T1, 2, Vs, 4, m)
        return
    shifted_sum(T2, T1, T1, 2, nX - 3)
    if n == 9:
        shifted_sum3(S, T2, T2, 4, Vs, 8, m)
        return
    for j in range(m):
        S[j] = T2[j]
    for t in range(1, n // 4):
        shifted_add(S, T2, 4 * t, m)
    for t in range(4 * (n // 4), n):
        shifted_add(S, Vs, t, m)


@numba.njit(parallel=True, cache=True)
def bw_channel_stats(maps, ns, mu_c, var, centre):
    """Per channel (parallel): ``centre`` = global float64 mean; ``mu_c`` = patch mean of
    the centred map; ``var`` = patch variance (clipped at 0).  Replicate border, ``n x n``
    windows, float64: vertical running sums, horizontal direct sums."""
    nc, H, W = maps.shape
    for c in prange(nc):
        n = ns[c]
        r = n // 2
        s = 0.0
        for y in range(H):
            row = maps[c, y]
            for x in range(W):
                s += np.float64(row[x])
        m0 = s / (H * W)
        centre[c] = m0
        inv = 1.0 / (n * n)
        V1 = np.zeros(W + 2 * r)
        V2 = np.zeros(W + 2 * r)
        cv = np.zeros(W)
        T1 = np.zeros(W + 2 * r)
        T2 = np.zeros(W + 2 * r)
        for y in range(H):
            if y == 0:
                V1[:] = 0.0
                V2[:] = 0.0
                for v in range(-r, r + 1):
                    yy = min(max(v, 0), H - 1)
                    row = maps[c, yy]
                    for x in range(W):
                        cv[x] = np.float64(row[x]) - m0
                    for x in range(W):
                        V1[x + r] += cv[x]
                        V2[x + r] += cv[x] * cv[x]
            else:
                yi = min(y + r, H - 1)
                yo = max(y - r - 1, 0)
                ri = maps[c, yi]
                ro = maps[c, yo]
                for x in range(W):
                    a = np.float64(ri[x]) - m0
                    b = np.float64(ro[x]) - m0
                    V1[x + r] += a - b
                    V2[x + r] += a * a - b * b
            for t in range(r):
                V1[t] = V1[r]
                V2[t] = V2[r]
                V1[W + r + t] = V1[W + r - 1]
                V2[W + r + t] = V2[W + r - 1]
            mr = mu_c[c, y]
            vr = var[c, y]
            hsum(V1, T1, T2, mr, W + 2 * r, n)
            hsum(V2, T1, T2, vr, W + 2 * r, n)
            for x in range(W):
                mm = mr[x] * inv
                vv = vr[x] * inv - mm * mm
                mr[x] = mm
                vr[x] = vv if vv > 0.0 else 0.0

@numba.njit(parallel=True, cache=True)
def bw_inv_sigma(var, tau):
    """In place: ``var -> 1/sqrt(var)`` where ``var >= tau`` and ``var > 0``, else 0."""
    nc, H, W = var.shape
    for c in prange(nc):
        for y in range(H):
            row = var[c, y]
            for x in range(W):
                v = row[x]
                row[x] = 1.0 / np.sqrt(v) if (v >= tau and v > 0.0) else 0.0

@numba.njit(parallel=True, cache=True)
def bw_accum(Ap, Bp, ca, cb, mA, sA, mB, sB, ds, r, accF, accB, BAND, DC, TW):
    """BWNCC cross terms (SPEC §3): for every disparity ``ds[k]`` and channel ``c``,
    ``xi = clip((E[ab] - mu_a mu_b) / (sigma_a sigma_b), -1, 1)`` of the left patch at
    ``(y, x)`` and the right patch at ``(y, x - d)``; ``accF[k] += xi * hbar_p``,
    ``accB[k] += xi * hbar_q`` (``hbar = mu + centre``).

    ``Ap, Bp``: replicate-padded maps (nc, H+2r, W+2r) (float32 or float64); ``ca, cb``
    channel centres; ``mA, mB`` float64 patch means minus the centres; ``sA, sB`` float64
    ``1/sigma`` (0 below ``tau``: ``xi = 0`` there).  All sums float64 on centred values.

    Work: parallel over bands of ``BAND`` rows; per band, chunks of ``DC`` disparities,
    channel-outer (its band rows stay in cache across the chunk's disparities) with local
    accumulators.  Per (channel, band), columns are grouped in tiles of ``TW`` columns and
    only tiles where some ``1/sigma`` of the band is non-zero in both views (exact skip:
    ``xi = 0`` elsewhere) are computed, in runs of consecutive tiles; within a run the
    window sums are separable: a vertical running sum down the band, then horizontal sums
    by doubling (O(1) per pixel in the window size, vectorised)."""
    nc, H, W, n, inv, Wp = window_geometry(Ap, mA, r)
    L = ds.shape[0]
    nb = (H + BAND - 1) // BAND
    ntile = (W + TW - 1) // TW
    for b in prange(nb):
        y0 = b * BAND
        y1 = min(H, y0 + BAND)
        V = np.zeros(Wp)
        T1 = np.zeros(Wp)
        T2 = np.zeros(Wp)
        S = np.zeros(Wp)
        lF = np.zeros((DC, BAND, W))
        lB = np.zeros((DC, BAND, W))
        # per-channel activity of this band: tiles of A with some 1/sigma != 0, and a
        # prefix count of B's columns with some 1/sigma != 0 (computed once per band)
        colAs = np.zeros((nc, ntile), np.bool_)
        cntBs = np.zeros((nc, W + 1), np.int32)
        fl = np.zeros(W, np.bool_)
        for c in range(nc):
            band_columns_active(sA, c, y0, y1, fl)
            for t in range(ntile):
                f = False
                for x in range(t * TW, min(W, (t + 1) * TW)):
                    f = f or fl[x]
                colAs[c, t] = f
            band_columns_active(sB, c, y0, y1, fl)
            for x in range(W):
                cntBs[c, x + 1] = cntBs[c, x] + (1 if fl[x] else 0)
        for k0 in range(0, L, DC):
            k1 = min(L, k0 + DC)
            lF[:, :, :] = 0.0
            lB[:, :, :] = 0.0
            for c in range(nc):
                cac = ca[c]
                cbc = cb[c]
                colA = colAs[c]
                cntB = cntBs[c]
                if cntB[W] == 0:
                    continue
                for k in range(k0, k1):
                    d = ds[k]
                    x0, x1 = overlap(d, W)
                    if x1 <= x0:
                        continue
                    t = x0 // TW
                    while t < ntile:
                        # next run of active tiles
                        while t < ntile:
                            if colA[t]:
                                xs = max(x0, t * TW)
                                xe = min(x1, (t + 1) * TW)
                                if xe > xs and cntB[xe - d] - cntB[xs - d] > 0:
                                    break
                            t += 1
                        if t >= ntile or t * TW >= x1:
                            break
                        xs = max(x0, t * TW)
                        xe = min(x1, (t + 1) * TW)
                        t += 1
                        while t < ntile and t * TW < x1 and colA[t]:
                            a0 = t * TW
                            a1 = min(x1, (t + 1) * TW)
                            if cntB[a1 - d] - cntB[a0 - d] == 0:
                                break
                            xe = a1
                            t += 1
                        m = xe - xs
                        xq0 = xs - d
                        nX = m + 2 * r
                        products_init(Ap, Bp, c, y0, n, xs, xq0, nX, cac, cbc, V)
                        for y in range(y0, y1):
                            if y > y0:
                                products_slide(Ap, Bp, c, y + 2 * r, y - 1, xs, xq0, nX, cac, cbc, V)
                            hsum(V, T1, T2, S, nX, n)
                            yb = y - y0
                            mar = mA[c, y, xs:xe]
                            sar = sA[c, y, xs:xe]
                            mbr = mB[c, y, xq0:xq0 + m]
                            sbr = sB[c, y, xq0:xq0 + m]
                            fr = lF[k - k0, yb, xs:xe]
                            brr = lB[k - k0, yb, xs:xe]
                            for j in range(m):
                                ma = mar[j]
                                mb = mbr[j]
                                xi = (S[j] * inv - ma * mb) * (sar[j] * sbr[j])
                                xi = xi if xi < 1.0 else 1.0
                                xi = xi if xi > -1.0 else -1.0
                                fr[j] += xi * (ma + cac)
                                brr[j] += xi * (mb + cbc)
            for k in range(k0, k1):
                for y in range(y0, y1):
                    af = accF[k, y]
                    ab = accB[k, y]
                    lf = lF[k - k0, y - y0]
                    lb = lB[k - k0, y - y0]
                    for x in range(W):
                        af[x] += lf[x]
                        ab[x] += lb[x]

@numba.njit(parallel=True, cache=True)
def bw_pad(X, r, out):
    """Replicate-pad the last two axes of ``X`` by ``r`` into ``out``."""
    nc, H, W = X.shape
    for c in prange(nc):
        for Y in range(H + 2 * r):
            src = X[c, min(max(Y - r, 0), H - 1)]
            dst = out[c, Y]
            for t in range(r):
                dst[t] = src[0]
                dst[W + r + t] = src[W - 1]
            d2 = dst[r:r + W]
            for x in range(W):
                d2[x] = src[x]

@numba.njit(parallel=True, cache=True)
def bw_den_add(mu_c, centre, den):
    """``den += sum_c (mu_c[c] + centre[c])`` (the BWNCC weight sums)."""
    nc, H, W = mu_c.shape
    cs = 0.0
    for c in range(nc):
        cs += centre[c]
    for y in prange(H):
        row = den[y]
        for x in range(W):
            row[x] += cs
        for c in range(nc):
            m = mu_c[c, y]
            for x in range(W):
                row[x] += m[x]

@numba.njit(parallel=True, cache=True)
def bw_finish(accF, accB, denL, denR, ds, eps, cost):
    """:func:`bwncc_finish` + :func:`fill_out_of_image` fused: float32 cost volume."""
    L, H, W = accF.shape
    lg = -np.log(eps)
    for y in prange(H):
        for x in range(W):
            worst = -np.inf
            for k in range(L):
                xq = x - ds[k]
                if xq < 0 or xq >= W:
                    continue
                dl = denL[y, x]
                dr = denR[y, xq]
                sf = accF[k, y, x] / dl if dl > 0 else 0.0
                sb = accB[k, y, x] / dr if dr > 0 else 0.0
                sf = sf if sf > 0.0 else 0.0
                sb = sb if sb > 0.0 else 0.0
                bw = np.sqrt(sf * sb)
                cst = -np.log(bw) if bw > eps else lg
                c32 = np.float32(cst)
                cost[k, y, x] = c32
                if c32 > worst:
                    worst = c32
            if worst == -np.inf:
                worst = 0.0
            for k in range(L):
                xq = x - ds[k]
                if xq < 0 or xq >= W:
                    cost[k, y, x] = np.float32(worst)


# --------------------------------------------------------------------------------------------
# Light field: sub-pixel shifts
# --------------------------------------------------------------------------------------------


@numba.njit(parallel=True, cache=True)
def xi_shift(Apad, muA, isA, ca, B, cb, y0, y1, fy, x0, x1, fx, r, tauB, weighted, restart,
             outF, outB, outM):  # pragma: no cover - numba
    """Per-channel NCC of the reference patches with the bilinearly shifted other view.

    Apad (nc, H+2r, W+2r) reference channels padded (replicate); muA, isA (nc, H, W) their
    patch means and 1/sigma (0 below tau); B (nc, H, W) other view's channels (unshifted);
    ca, cb (nc,) per-channel centring constants; y0, y1, fy (H+2r,) and x0, x1, fx (W+2r,)
    the shift's sampling arrays; tauB (nc,) the other view's variance threshold per channel.
    outF, outB, outM (G, H, W) float64: group ``g`` of channels ``c = g, g + G, ...`` adds
    ``sum_c xi_c muA_c``, ``sum_c xi_c muB_c`` and ``sum_c muB_c`` (muB = exact patch mean of
    the shifted map) to its own slice (no write races; the caller sums over ``g``).
    With ``weighted=False`` outF gets ``sum_c xi_c``.

    The rows may be a strip of the image (``muA``, ``isA``, the outputs and ``Apad`` cut to
    it, ``y0, y1, fy`` to its padded rows; ``B`` whole): the running column sums start afresh
    every ``restart`` rows of the strip, so a strip that starts at a multiple of ``restart``
    gets exactly the rows the whole image gets (:data:`ROW_BLOCK`).
    """
    nc, H, W = muA.shape
    G = outF.shape[0]
    Hp = H + 2 * r
    Wp = W + 2 * r
    n = 2 * r + 1
    inv = 1.0 / (n * n)
    for g in prange(G):
        bs = np.empty((Hp, Wp))
        v1 = np.empty((H, Wp))
        v2 = np.empty((H, Wp))
        v3 = np.empty((H, Wp))
        for c in range(g, nc, G):
            cbc = cb[c]
            cac = ca[c]
            for Y in range(Hp):
                ya = y0[Y]
                yb = y1[Y]
                wy = fy[Y]
                for X in range(Wp):
                    xa = x0[X]
                    xb = x1[X]
                    wx = fx[X]
                    bs[Y, X] = ((B[c, ya, xa] * (1.0 - wx) + B[c, ya, xb] * wx) * (1.0 - wy)
                                + (B[c, yb, xa] * (1.0 - wx) + B[c, yb, xb] * wx) * wy) - cbc
            for X in range(Wp):
                s1 = 0.0
                s2 = 0.0
                s3 = 0.0
                for y in range(H):
                    if y % restart == 0:
                        s1 = 0.0
                        s2 = 0.0
                        s3 = 0.0
                        for Y in range(y, y + n):
                            b = bs[Y, X]
                            s1 += b
                            s2 += b * b
                            s3 += (Apad[c, Y, X] - cac) * b
                    else:
                        bo = bs[y - 1, X]
                        bn = bs[y + n - 1, X]
                        s1 += bn - bo
                        s2 += bn * bn - bo * bo
                        s3 += ((Apad[c, y + n - 1, X] - cac) * bn
                               - (Apad[c, y - 1, X] - cac) * bo)
                    v1[y, X] = s1
                    v2[y, X] = s2
                    v3[y, X] = s3
            for y in range(H):
                s1 = 0.0
                s2 = 0.0
                s3 = 0.0
                for X in range(n):
                    s1 += v1[y, X]
                    s2 += v2[y, X]
                    s3 += v3[y, X]
                for x in range(W):
                    if x > 0:
                        s1 += v1[y, x + n - 1] - v1[y, x - 1]
                        s2 += v2[y, x + n - 1] - v2[y, x - 1]
                        s3 += v3[y, x + n - 1] - v3[y, x - 1]
                    mb = s1 * inv
                    var = s2 * inv - mb * mb
                    ma = muA[c, y, x]
                    cov = s3 * inv - (ma - cac) * mb
                    isb = 0.0
                    if var >= tauB[c] and var > 0.0:
                        isb = 1.0 / math.sqrt(var)
                    xi = cov * isA[c, y, x] * isb
                    if xi > 1.0:
                        xi = 1.0
                    elif xi < -1.0:
                        xi = -1.0
                    mbt = mb + cbc
                    if weighted:
                        outF[g, y, x] += xi * ma
                    else:
                        outF[g, y, x] += xi
                    outB[g, y, x] += xi * mbt
                    outM[g, y, x] += mbt


@numba.njit(parallel=True, cache=True)
def census_shift(img, cref, y0, y1, fy, x0, x1, fx, r, row0, buf, out):  # pragma: no cover
    """Hamming distance between the reference census codes ``cref`` and the census codes of
    ``img`` bilinearly shifted (sampling arrays as :func:`hyperlf.warp.shift_map` with ``r = 0``), without
    building the shifted codes: bit ``k`` of a code is ``neighbour_k < centre`` (row-major
    window, centre skipped, replicated border), as :func:`hyperlf.costs.census_transform`.
    ``buf`` (H, W) float64 receives the shifted image; ``out`` (h, W) float32 the distances of
    the rows ``row0 .. row0 + h - 1`` (``cref`` of those rows; the shifted image is built on
    them and ``r`` rows around them)."""
    H, W = img.shape
    h = out.shape[0]
    lo = max(row0 - r, 0)
    hi = min(row0 + h + r, H)
    for y in prange(lo, hi):
        wy = fy[y]
        for x in range(W):
            wx = fx[x]
            top0 = img[y0[y], x0[x]]
            top1 = img[y0[y], x1[x]]
            bot0 = img[y1[y], x0[x]]
            bot1 = img[y1[y], x1[x]]
            a0 = top0 * (1 - wy) + bot0 * wy
            a1 = top1 * (1 - wy) + bot1 * wy
            buf[y, x] = a0 * (1 - wx) + a1 * wx
    for i in prange(h):
        y = row0 + i
        code = np.zeros(W, np.uint64)
        k = np.uint64(0)
        for dy in range(-r, r + 1):
            nb = buf[min(max(y + dy, 0), H - 1)]
            for dx in range(-r, r + 1):
                if dy != 0 or dx != 0:
                    census_bit(code, nb, buf[y], dx, k)
                    k += np.uint64(1)
        for x in range(W):
            out[i, x] = np.float32(popcount64(code[x] ^ cref[i, x]))


@numba.njit(inline="always")
def census_bit(code, nb, ce, dx, k):
    """Bit ``k`` of every ``code[x]``: ``nb[x + dx] < ce[x]``, ``nb`` replicated beyond its
    ends.  The columns whose neighbour is inside run on slices (no index can be negative), a
    loop the compiler vectorises; the others clamp."""
    W = ce.shape[0]
    a = min(max(-dx, 0), W)  # the first column whose neighbour is inside the row
    b = max(min(W - dx, W), a)  # one past the last
    for x in range(a):
        code[x] |= np.uint64(nb[min(max(x + dx, 0), W - 1)] < ce[x]) << k
    nbs, ces, cos = nb[a + dx:b + dx], ce[a:b], code[a:b]
    for t in range(b - a):
        cos[t] |= np.uint64(nbs[t] < ces[t]) << k
    for x in range(b, W):
        code[x] |= np.uint64(nb[min(max(x + dx, 0), W - 1)] < ce[x]) << k


@numba.njit(parallel=True, cache=True)
def shift_average(C, w, j0, j1, valid, use_valid, out):  # pragma: no cover
    """``out[k] = sum_j w[k, j] C[j] / sum_j w[k, j]`` over ``j = j0[k] .. j1[k] - 1``, in
    float64; with ``use_valid`` only over the entries with ``valid[j]``, and an entry with no
    valid one in its range keeps ``C[k]``.  Rows in parallel.  Reference:
    :func:`hyperlf.costs.lightfield.average_over_shift` (``impl="numpy"``)."""
    L, H, W = C.shape
    for y in prange(H):
        num = np.empty(W)
        den = np.empty(W)
        for k in range(L):
            num[:] = 0.0
            den[:] = 0.0
            for j in range(j0[k], j1[k]):
                wk = w[k, j]
                for x in range(W):
                    if use_valid and not valid[j, y, x]:
                        continue
                    num[x] += wk * C[j, y, x]
                    den[x] += wk
            for x in range(W):
                out[k, y, x] = num[x] / den[x] if den[x] > 0 else C[k, y, x]


@numba.njit(inline="always")
def rho_at(a, table):
    """Shen et al.'s ``rho`` at ``a = |x|``: linear interpolation of ``table`` (``rho`` at
    ``N + 1`` evenly spaced values from 0 to 2) where ``a <= 2``, else (and for NaN) the
    formula ``-log(exp(a - 2) + exp(-a))``."""
    N = table.shape[0] - 1
    if a <= 2.0:
        t = a * (N * 0.5)
        i = min(int(t), N - 1)
        return table[i] + (table[i + 1] - table[i]) * (t - i)
    return -math.log(math.exp(a - 2.0) + math.exp(-a))


@numba.njit(parallel=True, cache=True)
def rho_sum(xi, xg, tau, table, out):  # pragma: no cover
    """``out = rho(1 - xi) + tau rho(1 - xg)`` entry by entry (1-D arrays; ``xi``, ``xg``
    float64, ``out`` float32), ``rho`` by :func:`rho_at` from ``table``
    (:func:`hyperlf.costs.pair.rho_table`).  Reference: :func:`hyperlf.costs.pair.rsncc_rho`
    (``impl="numpy"``)."""
    for i in prange(out.shape[0]):
        out[i] = rho_at(abs(1.0 - xi[i]), table) + tau * rho_at(abs(1.0 - xg[i]), table)


@numba.njit(parallel=True, cache=True)
def row_moments(C, valid, n, mean, m2):  # pragma: no cover
    """Moments of the entries of ``C`` (L, h, W) where ``valid``, per image row: ``n``,
    ``mean`` and ``m2`` (h,) receive the count, the mean and the sum of squared deviations of
    row ``y``'s valid entries over every label (two passes in float64; an empty row gets
    zeros).  A row's moments depend on that row alone, so a strip of rows gets exactly what
    the whole volume gets there (:func:`combine_moments` joins them)."""
    L, H, W = C.shape
    for y in prange(H):
        s = 0.0
        c = 0
        for k in range(L):
            for x in range(W):
                if valid[k, y, x]:
                    s += C[k, y, x]
                    c += 1
        mu = s / c if c > 0 else 0.0
        q = 0.0
        for k in range(L):
            for x in range(W):
                if valid[k, y, x]:
                    e = C[k, y, x] - mu
                    q += e * e
        n[y] = c
        mean[y] = mu
        m2[y] = q


@numba.njit(cache=True)
def combine_moments(n, mean, m2):  # pragma: no cover
    """Standard deviation and count of the union of rows with moments ``n, mean, m2``
    (:func:`row_moments`), summed in row order: ``(0.0, 0)`` when no entry is valid.
    Reference: ``C[valid].std()`` in :func:`hyperlf.costs.pair.normalise_volume`."""
    count = 0
    s = 0.0
    for y in range(n.size):
        count += n[y]
        s += n[y] * mean[y]
    if count == 0:
        return 0.0, 0
    mu = s / count
    q = 0.0
    for y in range(n.size):
        if n[y] > 0:
            d = mean[y] - mu
            q += m2[y] + n[y] * d * d
    return math.sqrt(q / count), count


@numba.njit(parallel=True, cache=True)
def normalise_fill(C, valid, sd, centre, out):  # pragma: no cover
    """``out = (fill(C) - c) / sd`` per pixel, float64 arithmetic: invalid entries take the
    pixel's worst valid cost, a pixel with none is 0; ``sd <= 0`` divides by 1.  ``c``: the
    pixel's minimum over its valid entries (``centre`` 0), their mean (1), or 0 (2).  Rows in
    parallel, each swept label by label (contiguous).  Reference:
    :func:`hyperlf.costs.pair.normalise_volume`."""
    L, H, W = C.shape
    scale = sd if sd > 0 else 1.0
    for y in prange(H):
        worst = np.full(W, -np.inf)
        lo = np.full(W, np.inf)
        total = np.zeros(W)
        count = np.zeros(W)
        for k in range(L):
            for x in range(W):
                if valid[k, y, x]:
                    v = C[k, y, x]
                    if v > worst[x]:
                        worst[x] = v
                    if v < lo[x]:
                        lo[x] = v
                    if centre == 1:
                        total[x] += v
                        count[x] += 1.0
        for x in range(W):
            if centre == 1:
                lo[x] = total[x] / count[x] if count[x] > 0 else 0.0
            elif centre == 2:
                lo[x] = 0.0
        for k in range(L):
            for x in range(W):
                if worst[x] == -np.inf:
                    out[k, y, x] = 0.0
                else:
                    v = C[k, y, x] if valid[k, y, x] else worst[x]
                    out[k, y, x] = (v - lo[x]) / scale


@numba.njit(parallel=True, cache=True)
def fuse_fill(parts, weights, valid, out):  # pragma: no cover
    """``out = float32(sum_i weights[i] parts[i] / sum(weights))`` (float64 sums, in the order
    of ``parts``), then its invalid entries set to the pixel's worst valid value (0 where none
    is valid).  Reference: :func:`hyperlf.costs.pair.fuse`."""
    L, H, W = out.shape
    wsum = 0.0
    for i in range(len(weights)):
        wsum += weights[i]
    for y in prange(H):
        worst = np.full(W, -np.inf, np.float32)
        for k in range(L):
            for x in range(W):
                acc = 0.0
                for i in range(len(parts)):
                    acc += weights[i] * parts[i][k, y, x]
                v = np.float32(acc / wsum)
                out[k, y, x] = v
                if valid[k, y, x] and v > worst[x]:
                    worst[x] = v
        for x in range(W):
            if worst[x] == -np.inf:
                worst[x] = 0.0
        for k in range(L):
            for x in range(W):
                if not valid[k, y, x]:
                    out[k, y, x] = worst[x]
