"""Light-field cost evaluators: one view against the reference at sub-pixel shifts (SPEC §5).

For a label ``d`` and a view at offset ``o = pos_v - pos_ref`` the reference pixel ``p`` is
compared with ``q = p - d o`` in the view; the view's maps are sampled there **bilinearly**
(:func:`hyperlf.warp.axis_taps`), and candidates with ``q`` outside the image are marked
invalid (:func:`view_costs` returns the mask with the volume).

* NCC terms (``ncc``, ``rsncc``, ``bwncc``): the kernel recomputes the patch mean and variance of
  the *interpolated* map together with the cross term, so for sub-pixel shifts the NCC is the
  exact NCC of the reference patch with the bilinearly resampled patch (shifting precomputed
  statistics would be exact only for integer shifts).  Window pixels beyond the other view's
  border take its replicated border values (SPEC §4); validity is decided by the centre ``q``.
  ``tau_var = tau_rel`` x the mean patch variance of the block's channels, per view (as
  :func:`hyperlf.costs.bwncc_volume` with ``tau_scope="block"``).
* ``census``: Hamming distance between the reference's census code and the census code of the
  bilinearly shifted view (one fused shift + census + popcount kernel).
* ``bwncc`` / ``bwncc-paper``: the reference's descriptor statistics are computed once per
  channel block; the other view's channels are streamed in blocks of 68 (one histogram of one
  level) and the cross terms accumulated in float64, one kernel pass per (view, label, block).

Validity masks (SPEC §11; ``ref_valid`` / ``view_valid`` of :func:`view_costs`): a pixel
without data counts exactly like a sample outside the image.  A sample ``q`` of the view is
valid only if it is in the image **and every bilinear tap it uses with a non-zero weight is a
valid pixel** (the mask warped with the view's shift; an integer shift uses one tap), and only
if the reference pixel ``p`` itself is valid; so an invalid reference pixel has no valid
sample at any label.  Before the costs are evaluated, invalid pixels of both images take the
value of the nearest valid pixel (:func:`hyperlf.imageops.fill_masked`): window pixels that
reach into a region without data see its edge continued, as window pixels beyond the border
see the replicated border, and validity is decided by the centre taps alone in both cases.
Both images are first scaled by their mean over valid pixels
(:func:`hyperlf.imageops.normalise_intensity` with ``valid``).

Strips (SPEC §12): every evaluator takes ``rows=(a, b)`` and returns only those reference rows,
bit for bit what the whole image gives there: the images stay whole (samples and windows read
the rows they need), per-view statistics are the whole view's, the NCC kernels restart their
running column sums every :data:`ROW_BLOCK` rows (a strip starts on that grid) and run over
blocks of :data:`KERNEL_ROWS` rows for the caches; a fusion's normalisers come from
:func:`view_moments` over every strip (``scales`` of :func:`view_costs`).

Every evaluator takes ``shifts``, a list of ``(sx, sy)`` with ``sample = img(p + (sx, sy))``,
and returns float32 ``(L, H, W)``; :func:`view_costs` picks the cost from the registry and
applies the out-of-image rule.  At integer shifts the results equal the rectified-pair ones
(tests).  The papers behind the costs are listed in :mod:`hyperlf.costs` (References).
"""

from __future__ import annotations

import numpy as np

from .._kernel_args import kernel_input
from ..imageops import fill_masked, gradient_magnitude, normalise_intensity
from ..warp import axis_taps, axis_valid, shift_map
from .._options import bool_mask, flag, integer, number, real, real_array, real_pair, shown
from ..errors import InvalidInputError
from .pair import (_constants, _patch_sizes, bwncc_finish, census_transform, channel_stats,
                   fill_out_of_image, inv_sigma, pad_replicate, rsncc_rho, window_stats)
from ._validate import (MAX_VIEW_WINDOW, check_bytes, check_impl, check_map, check_shape,
                        check_window)

__all__ = [
    "view_costs",
    "light_field_window",
    "DENSE_VIEWS",
    "view_moments",
    "check_rows",
    "view_shifts",
    "view_validity",
    "tap_validity",
    "ncc_view_volume",
    "rsncc_view_volume",
    "census_view_volume",
    "average_over_shift",
    "bwncc_view_volume",
    "REF_CACHE_BYTES",
    "ROW_BLOCK",
]

#: The reference descriptor blocks with their float64 statistics (~20 bytes per channel and
#: pixel, twice that with the row blocks the kernels cut from them) are cached across views
#: when they fit in this many bytes, else recomputed per view.
REF_CACHE_BYTES = 512 * 1024 ** 2

#: A strip of rows (``rows`` of :func:`view_costs`) starts at a multiple of this: the window
#: sums of the NCC kernels run down the columns afresh every ``ROW_BLOCK`` rows, so a strip
#: that starts on the grid gets bit for bit what the whole image gets there.
ROW_BLOCK = 32

#: The NCC and census kernels run over blocks of this many rows (a multiple of
#: :data:`ROW_BLOCK`, so the result is the same): their per-label work arrays then stay in the
#: processor's caches (at 1200 px wide, whole images made them 4 x slower per pixel).
KERNEL_ROWS = 128


class _RefBlock:
    """Reference channel block with padded maps and statistics (one NCC patch size).

    ``per_channel``: each channel gets its own variance threshold (``tau_rel`` x its own mean
    patch variance) instead of one for the block; for stacking unrelated maps (RSNCC's
    intensity and gradient magnitude) so that they are computed in parallel."""

    def __init__(self, A: np.ndarray, n: int, tau_rel: float, per_channel: bool = False):
        self.n = int(n)
        self.r = self.n // 2
        st = channel_stats(A, self.n)
        self.centre = st["centre"]
        tau = (tau_rel * st["mean_var"][:, None, None] if per_channel
               else tau_rel * float(st["mean_var"].mean()))
        self.mu = np.ascontiguousarray(st["mu"])
        self.isig = np.ascontiguousarray(inv_sigma(st["var"], tau))
        self.pad = np.ascontiguousarray(pad_replicate(np.asarray(A, np.float32), self.r))
        self.den = self.mu.sum(axis=0)
        self._rows: dict = {}

    def rows(self, i: int, j: int):
        """``(pad, mu, isig)`` of the rows ``i .. j - 1`` (the padded map with its ``2 r``
        extra rows), contiguous, cut once and kept for every shift."""
        if (i, j) not in self._rows:
            c = np.ascontiguousarray
            self._rows[i, j] = (c(self.pad[:, i:j + 2 * self.r]), c(self.mu[:, i:j]),
                                c(self.isig[:, i:j]))
        return self._rows[i, j]


def _view_tau(B: np.ndarray, n: int, tau_rel: float, per_channel: bool = False):
    """The other view's variance threshold: one for the block (float), or per channel."""
    mv = np.array([float(window_stats(B[c], n)[1].mean()) for c in range(B.shape[0])])
    if per_channel:
        return tau_rel * mv
    return tau_rel * float(np.mean(mv)) if mv.size else 0.0


def _xi_terms(ref: _RefBlock, B: np.ndarray, centre_b, tauB, sx, sy, weighted=True,
              per_channel: bool = False, rows=None):
    """Sums over channels of ``xi muA``, ``xi muB`` and ``muB`` for one shift: 3 x (h, W).

    ``weighted=False``: the sum of ``xi`` instead of ``xi muA``, and None for the other two
    (the kernel's sums of them go to scratch that is never zeroed or read).
    ``per_channel=True`` returns ``xi`` (or ``xi muA``) of every channel instead, as
    ``(nc, h, W)`` (one channel per parallel group), and the other two as None.  ``rows``
    ``(a, b)``: only the reference rows ``a .. b - 1`` (``h = b - a``; ``a`` a multiple of
    :data:`ROW_BLOCK`, see :func:`view_costs`), else every row."""
    import numba

    from . import _kernels
    nc, H, W = ref.mu.shape
    r = ref.r
    a, b = (0, H) if rows is None else rows
    y0, y1, fy = axis_taps(H, sy, r)
    x0, x1, fx = axis_taps(W, sx, r)
    G = nc if per_channel else max(1, min(nc, numba.get_num_threads()))
    oF = np.zeros((G, b - a, W))
    scratch = np.zeros if weighted else np.empty
    oB = scratch((G, b - a, W))
    oM = scratch((G, b - a, W))
    tau = np.broadcast_to(np.asarray(tauB, np.float64), (nc,)).copy()
    Bc = np.ascontiguousarray(B, np.float32)
    cb = np.asarray(centre_b, np.float64)
    for i in range(a, b, KERNEL_ROWS):  # blocks on the ROW_BLOCK grid: the sums are the same
        j = min(i + KERNEL_ROWS, b)
        band = slice(i, j + 2 * r)
        pad, mu, isig = ref.rows(i, j)
        _kernels.xi_shift(pad, mu, isig, ref.centre, Bc, cb, y0[band], y1[band], fy[band], x0,
                          x1, fx, r, tau, bool(weighted), ROW_BLOCK, oF[:, i - a:j - a],
                          oB[:, i - a:j - a], oM[:, i - a:j - a])
    if per_channel:
        return oF, None, None
    if not weighted:
        return oF.sum(axis=0), None, None
    return oF.sum(axis=0), oB.sum(axis=0), oM.sum(axis=0)


def _check_view_args(ref_img, img, shifts, window, rows, *, default_window: bool = False,
                     **constants) -> None:
    """Refuse, before the kernels read them, two views that are not 2-D images of one shape,
    shifts that are not finite ``(sx, sy)`` pairs, ``rows`` outside the views, a window beyond
    the views (or :data:`MAX_VIEW_WINDOW`) and bad cost constants
    (:data:`hyperlf.costs.pair._COST_RULES`): mismatched shapes crashed the interpreter in
    numba's kernels. ``window`` may be None (the cost's own) where ``default_window``."""
    a = _check_views(ref_img, img)
    _check_shifts(shifts)
    if rows is not None and not _row_range(rows, a[0]):
        raise InvalidInputError(f"rows must be (a, b) with 0 <= a < b <= {a[0]}, got "
                                f"{shown(rows)}")
    if window is not None or not default_window:  # wider than a small view is fine
        check_window(window, side=max(max(a), MAX_VIEW_WINDOW // 2))
    _constants(**constants)


def _check_views(ref_img, img) -> tuple[int, int]:
    """The shape ``(H, W)`` of two views: 2-D numeric images of one non-empty shape (O(1))."""
    try:
        a, b = np.shape(ref_img), np.shape(img)
    except ValueError:  # ragged
        a = b = ()
    if len(a) != 2 or a != b or 0 in a:
        raise InvalidInputError(f"ref_img and img must be 2-D images of one shape, got "
                                f"{shown(ref_img, 30)} and {shown(img, 30)}")
    if not all(np.issubdtype(np.asarray(x).dtype, np.number) for x in (ref_img, img)):
        raise InvalidInputError("ref_img and img must be numeric arrays")
    return a


def _check_shifts(shifts) -> np.ndarray:
    """``shifts`` as finite ``(sx, sy)`` pairs, float64 ``(L, 2)``, each at most
    :data:`MAX_SHIFT` px in size."""
    sh = real_array(shifts, "shifts")
    if sh.ndim != 2 or sh.shape[1] != 2 or not np.isfinite(sh).all() or \
            (sh.size and np.abs(sh).max() > MAX_SHIFT):
        raise InvalidInputError(f"shifts must be finite (sx, sy) pairs of at most {MAX_SHIFT:g} "
                                f"px, shape (L, 2), got {shown(shifts)}")
    return sh


def _row_range(rows, height: int) -> bool:
    """Whether ``rows`` is ``(a, b)``, two ints with ``0 <= a < b <= height``."""
    try:
        a, b = (int(x) for x in rows)
        return (a, b) == tuple(rows) and 0 <= a < b <= height
    except (TypeError, ValueError, OverflowError):
        return False


def ncc_view_volume(ref_img, img, shifts, window: int = 5, tau_rel: float = 1e-5, *,
                    rows=None) -> np.ndarray:
    """``1 - NCC`` of the intensities ``I / mean(I)`` at each shift, float32 ``(L, H, W)``.

    Parameters
    ----------
    ref_img, img : (H, W) arrays
        Reference and other view.
    shifts : sequence of (sx, sy)
        The other view is sampled at ``p + (sx, sy)``.
    window : int
        Odd NCC patch size.
    tau_rel : float
        Flat-patch threshold relative to the view's mean patch variance (NCC 0 below it).
    rows : (int, int), optional
        Only the reference rows ``a .. b - 1`` (``(L, b - a, W)``; :func:`view_costs`).

    Examples
    --------
    The view is the reference moved 2 px to the right, times 3 plus 2, so a reference pixel
    ``p`` sits at ``p + (2, 0)`` in it: at that shift NCC is 1 (cost 0) on columns 6 to 17
    (clear of the borders and of the columns ``np.roll`` wrapped round), and every other shift,
    whole or half pixel, costs more:

    >>> import numpy as np
    >>> from hyperlf.costs import ncc_view_volume
    >>> ref = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> view = 3.0 * np.roll(ref, 2, axis=1) + 2.0
    >>> shifts = [(sx, 0.0) for sx in (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)]
    >>> C = ncc_view_volume(ref, view, shifts)
    >>> C.shape, np.unique(C.argmin(axis=0)[:, 6:-6]).tolist()       # label 4: shift (2, 0)
    ((7, 16, 24), [4])
    >>> round(float(C[4, :, 6:-6].max()), 3)
    0.0
    """
    _check_view_args(ref_img, img, shifts, window, rows, tau_rel=tau_rel)
    L = len(shifts)
    H, W = ref_img.shape
    a, b = (0, H) if rows is None else rows
    A = normalise_intensity(ref_img)[None].astype(np.float32)
    B = normalise_intensity(img)[None].astype(np.float32)
    ref = _RefBlock(A, window, tau_rel)
    tauB = _view_tau(B, window, tau_rel)
    cb = np.array([float(B.mean())])
    out = np.empty((L, b - a, W), np.float32)
    for k, (sx, sy) in enumerate(shifts):
        F, _, _ = _xi_terms(ref, B, cb, tauB, sx, sy, weighted=False, rows=rows)
        out[k] = 1.0 - F
    return out


def rsncc_view_volume(ref_img, img, shifts, window: int = 5, tau_rel: float = 1e-5,
                      rs_tau: float = 1.0, *, rows=None, impl: str = "auto") -> np.ndarray:
    """RSNCC (Shen et al. 2014) at each shift:
    ``rho(1 - NCC(In)) + rs_tau * rho(1 - NCC(|grad In|))``.

    The gradient term is unchanged by a contrast reversal between bands.  The two NCCs run as
    two channels of one kernel call (one per core), each with its own variance thresholds, so
    the result is that of two separate single-channel NCCs.  Arguments as
    :func:`ncc_view_volume`; ``impl``: of ``rho`` (:func:`hyperlf.costs.pair.rsncc_rho`);
    float32 ``(L, H, W)``.

    Examples
    --------
    The view is the reference moved 2 px to the right with its contrast reversed (``3 - I``):
    at the shift ``(2, 0)`` the intensity NCC is -1 and the gradient NCC 1, so the cost is
    ``rho(2) + rho(0) = 2 rho(0)``, that of an exact copy, on columns 6 to 17 (clear of the
    borders and of the columns ``np.roll`` wrapped round); every other shift costs more:

    >>> import numpy as np
    >>> from hyperlf.costs import rho, rsncc_view_volume
    >>> ref = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> view = 3.0 - np.roll(ref, 2, axis=1)
    >>> shifts = [(sx, 0.0) for sx in (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)]
    >>> C = rsncc_view_volume(ref, view, shifts)
    >>> np.unique(C.argmin(axis=0)[:, 6:-6]).tolist(), round(float(C[4, :, 6:-6].max()), 3)
    ([4], -0.254)
    >>> round(2 * float(rho(0.0)), 3)
    -0.254
    """
    _check_view_args(ref_img, img, shifts, window, rows, tau_rel=tau_rel, rs_tau=rs_tau)
    L = len(shifts)
    H, W = ref_img.shape
    a_, b_ = (0, H) if rows is None else rows
    a, b = normalise_intensity(ref_img), normalise_intensity(img)
    A = np.stack([a, gradient_magnitude(a)]).astype(np.float32)
    B = np.stack([b, gradient_magnitude(b)]).astype(np.float32)
    ref = _RefBlock(A, window, tau_rel, per_channel=True)
    tauB = _view_tau(B, window, tau_rel, per_channel=True)
    cb = B.reshape(2, -1).astype(np.float64).mean(axis=1)
    out = np.empty((L, b_ - a_, W), np.float32)
    for k, (sx, sy) in enumerate(shifts):
        xi, _, _ = _xi_terms(ref, B, cb, tauB, sx, sy, weighted=False, per_channel=True,
                             rows=rows)
        rsncc_rho(xi[0], xi[1], rs_tau, out[k], impl)
    return out


def census_view_volume(ref_img, img, shifts, window: int = 7, impl: str = "numba", *,
                       rows=None) -> np.ndarray:
    """Census (Zabih & Woodfill 1994) Hamming costs of the reference against ``img`` shifted by each ``(sx, sy)``.

    ``impl="numpy"``: the reference (shift with :func:`hyperlf.warp.shift_map`, then
    :func:`hyperlf.costs.census_transform` and a popcount); ``"numba"``: one fused kernel,
    identical results.  ``rows`` ``(a, b)``: only the reference rows ``a .. b - 1``.

    Examples
    --------
    The view is the reference moved 2 px to the right: at the shift ``(2, 0)`` no census bit
    differs on columns 6 to 17 (clear of the borders and of the columns ``np.roll`` wrapped
    round), and the fused kernel gives what the reference implementation gives:

    >>> import numpy as np
    >>> from hyperlf.costs import census_view_volume
    >>> ref = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> view = np.roll(ref, 2, axis=1)
    >>> shifts = [(float(sx), 0.0) for sx in range(5)]
    >>> C = census_view_volume(ref, view, shifts)
    >>> np.unique(C.argmin(axis=0)[:, 6:-6]).tolist(), float(C[2, :, 6:-6].max())
    ([2], 0.0)
    >>> bool(np.array_equal(census_view_volume(ref, view, shifts, impl="numpy"), C))
    True
    """
    _check_view_args(ref_img, img, shifts, window, rows)
    impl = check_impl(impl, "census")
    L = len(shifts)
    H, W = ref_img.shape
    a_, b_ = (0, H) if rows is None else rows
    cref = census_transform(ref_img, window)[a_:b_]
    out = np.empty((L, b_ - a_, W), np.float32)
    if impl == "numpy":
        for k, (sx, sy) in enumerate(shifts):
            s, _ = shift_map(img, sx, sy, 0)
            out[k] = np.bitwise_count(cref ^ census_transform(s, window)[a_:b_])
        return out
    from . import _kernels
    a = np.ascontiguousarray(img, dtype=np.float64)
    buf = np.empty((H, W), np.float64)
    for k, (sx, sy) in enumerate(shifts):
        y0, y1, fy = axis_taps(H, sy, 0)
        x0, x1, fx = axis_taps(W, sx, 0)
        for i in range(a_, b_, KERNEL_ROWS):
            j = min(i + KERNEL_ROWS, b_)
            _kernels.census_shift(a, np.ascontiguousarray(cref[i - a_:j - a_]), y0, y1, fy, x0,
                                  x1, fx, int(window) // 2, i, buf, out[k, i - a_:j - a_])
    return out


def _reference_blocks(pA, slB, n_all, tau_rel):
    """``[(channel selection, n, _RefBlock)]`` of the reference's channels ``slB``, one per
    NCC patch size."""
    from ..descriptor import descriptor
    Ablk = descriptor(pA, channels=slB)
    ns = n_all[slB]
    refs = []
    for nn in np.unique(ns):
        sel = np.nonzero(ns == nn)[0]
        refs.append((sel, int(nn), _RefBlock(Ablk[sel], int(nn), tau_rel)))
    return refs


def average_over_shift(cost, shifts, half: float, *, valid=None,
                       impl: str = "auto") -> np.ndarray:
    """Each label's cost averaged over the labels whose shift lies within ``half`` px of its
    own (a box along the label axis, its ends weighted by the part of a label step they
    cover), over the ``valid`` entries only.

    A cost that is exact only at whole-pixel shifts (census: a bilinearly shifted view is
    smoother than the reference, and its census bits differ wherever it is interpolated) is
    then a function of the sub-pixel shift instead of one that dips at each whole pixel.

    Parameters
    ----------
    cost : ndarray, shape (L, H, W)
    shifts : sequence of (sx, sy)
        The view's shift at each label, in label order.
    half : float
        Half-width in px of shift (at most :data:`MAX_SHIFT`); 0, or less than half a label
        step, leaves ``cost`` as it is.
    valid : ndarray of bool, shape (L, H, W), optional
        Entries that may enter an average (an entry with no valid neighbour keeps its value).
    impl : {"auto", "numpy", "numba"}
        ``"numpy"``: the reference, a loop over the labels; ``"numba"`` (the ``"auto"``
        choice): one kernel over the rows in parallel, without the temporaries, the same
        numbers to float32 rounding.

    Returns
    -------
    ndarray, float32, shape (L, H, W)

    Examples
    --------
    >>> c = np.array([4.0, 4.0, 1.0, 4.0, 4.0])[:, None, None]   # a dip at one label
    >>> shifts = [(0.25 * k, 0.0) for k in range(5)]              # a quarter pixel apart
    >>> [round(float(v), 2) for v in average_over_shift(c, shifts, 0.5)[:, 0, 0]]
    [3.4, 3.14, 3.25, 3.14, 3.4]
    """
    C = np.asarray(check_map(cost, "cost (L, H, W)", 3), np.float32)
    s = _check_shifts(shifts)
    if len(s) != len(C):
        raise InvalidInputError(f"shifts must give one (sx, sy) per label ({len(C)}), got "
                                f"{len(s)}")
    half = number(half, "half", at_most=MAX_SHIFT)
    if valid is not None:
        valid = bool_mask(valid, "valid", C.shape, broadcast=True, of="the cost")
    impl = check_impl(impl, "census")
    if len(C) < 2 or not half > 0:
        return C
    step = np.hypot(*np.diff(s, axis=0).T)
    delta = float(np.median(step))
    if not delta > 0 or half / delta < 0.5:
        return C
    t = np.concatenate([[0.0], np.cumsum(step)])
    with np.errstate(over="ignore"):  # a box far wider than a tiny step: weight 1, clipped
        w = np.clip((half + delta / 2 - np.abs(t[:, None] - t[None, :])) / delta, 0.0, 1.0)
    v = None if valid is None else np.asarray(valid, bool)
    if impl == "numba":
        return _average_over_shift_numba(C, w, v)
    out = np.empty_like(C)
    for k in range(len(C)):
        js = np.nonzero(w[k])[0]
        if v is None:
            out[k] = np.tensordot(w[k, js] / w[k, js].sum(), C[js], axes=1)
            continue
        wj = w[k, js][:, None, None] * v[js]
        total = wj.sum(axis=0)
        avg = (wj * C[js]).sum(axis=0) / np.maximum(total, 1e-12)
        out[k] = np.where(total > 0, avg, C[k])
    return out


def _average_over_shift_numba(C: np.ndarray, w: np.ndarray, valid) -> np.ndarray:
    """:func:`average_over_shift`'s kernel call: each label's band of weights ``w[k]`` (its
    nonzero run) and the valid entries, if any."""
    from . import _kernels

    nz = w > 0
    j0 = np.argmax(nz, axis=1).astype(np.int64)
    j1 = (len(w) - np.argmax(nz[:, ::-1], axis=1)).astype(np.int64)
    use = valid is not None
    v = np.broadcast_to(valid, C.shape) if use else np.ones((1, 1, 1), bool)
    out = np.empty(C.shape, np.float32)
    _kernels.shift_average(kernel_input(C), kernel_input(w, np.float64), j0, j1,
                           kernel_input(v), use, out)
    return out


def bwncc_view_volume(ref_img, img, shifts, *, paper: bool = False, window=None,
                      tau_rel: float = 1e-5, eps: float = 1e-3, block: int = 68,
                      cache: dict | None = None, rows=None) -> np.ndarray:
    """BWNCC (SPEC §3) on the descriptor of :mod:`hyperlf.descriptor` at each shift.

    Parameters
    ----------
    paper : bool
        False: ``DescriptorParams.default()`` with NCC patch ``n = w`` per level; True:
        ``DescriptorParams.paper()`` with ``n = 5``.  An int ``window`` sets ``n`` for all.
    tau_rel, eps : float
        Flat-patch threshold (per block, as ``tau_scope="block"``) and the BWNCC floor.
    block : int
        Channels per streamed block.
    cache : dict, optional
        Shared across the views of one light field: holds the reference's prepared inputs and,
        if they fit in :data:`REF_CACHE_BYTES`, its channel statistics.
    rows : (int, int), optional
        Only the reference rows ``a .. b - 1`` (:func:`view_costs`).

    Examples
    --------
    The view is the reference moved 2 px to the right; among whole and half-pixel shifts the
    cost is lowest at ``(2, 0)`` on columns 6 to 17 (clear of the borders and of the columns
    ``np.roll`` wrapped round):

    >>> import numpy as np
    >>> from hyperlf.costs import bwncc_view_volume
    >>> ref = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> view = np.roll(ref, 2, axis=1)
    >>> shifts = [(sx, 0.0) for sx in (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)]
    >>> C = bwncc_view_volume(ref, view, shifts)
    >>> C.shape, C.dtype.name, np.unique(C.argmin(axis=0)[:, 6:-6]).tolist()   # label 4: (2, 0)
    ((7, 16, 24), 'float32', [4])
    """
    from ..descriptor import DescriptorParams, iter_descriptor_blocks, prepare
    _check_view_args(ref_img, img, shifts, window, rows, default_window=True, tau_rel=tau_rel,
                     eps=eps, block=block)
    paper = flag(paper, "paper")
    if cache is not None and not isinstance(cache, dict):
        raise InvalidInputError(f"cache must be a dict to share across views (or None), got "
                                f"{shown(cache)}")
    params = DescriptorParams.paper() if paper else DescriptorParams.default()
    variant = "bwncc-paper" if paper else "bwncc"
    H, W = ref_img.shape
    n_all = _patch_sizes(params, variant, window, max(H, W))
    ref_cache = {} if cache is None else cache
    L = len(shifts)
    a, b = (0, H) if rows is None else rows
    accF = np.zeros((L, b - a, W))
    accB = np.zeros((L, b - a, W))
    denB = np.zeros((L, b - a, W))
    denF = np.zeros((b - a, W))
    key = ("prep", variant)
    if key not in ref_cache:
        ref_cache[key] = prepare(ref_img, params)
    pA = ref_cache[key]
    pB = prepare(img, params)
    keep = 40.0 * params.n_channels * H * W <= REF_CACHE_BYTES
    for (slB, Bblk) in iter_descriptor_blocks(pB, block=block):
        bkey = ("block", variant, slB.start, slB.stop)
        refs = ref_cache.get(bkey)
        if refs is None:
            refs = _reference_blocks(pA, slB, n_all, tau_rel)
            if keep:
                ref_cache[bkey] = refs
        for sel, nn, rb in refs:
            Bs = np.ascontiguousarray(Bblk[sel])
            tauB = _view_tau(Bs, nn, tau_rel)
            cb = Bs.reshape(Bs.shape[0], -1).astype(np.float64).mean(axis=1)
            denF += rb.den[a:b]
            for k, (sx, sy) in enumerate(shifts):
                F, Bw, M = _xi_terms(rb, Bs, cb, tauB, sx, sy, rows=rows)
                accF[k] += F
                accB[k] += Bw
                denB[k] += M
    cost = bwncc_finish(accF, accB, denF[None], denB, eps)
    return cost.astype(np.float32)


def view_shifts(offset, labels) -> list[tuple[float, float]]:
    """``[(sx, sy)]`` per label: ``(-d dx, -d dy)`` for ``offset = (dx, dy)``.

    ``offset``: two finite numbers; ``labels``: finite numbers (1-D), whose shifts stay
    finite.

    Examples
    --------
    Label ``d`` of a view at offset ``(dx, dy)`` from the reference samples the view at
    ``p - d (dx, dy)``:

    >>> from hyperlf.costs import view_shifts
    >>> [(float(sx), float(sy)) for sx, sy in view_shifts((1, -2), [0.5, 1.0, 2.0])]
    [(-0.5, 1.0), (-1.0, 2.0), (-2.0, 4.0)]
    """
    dx, dy = real_pair(offset, "offset", "two finite numbers (dx, dy)")
    lab = _check_labels(labels)
    with np.errstate(over="ignore"):
        big = float(np.abs(lab).max(initial=0.0)) * max(abs(dx), abs(dy))
    if not big <= MAX_SHIFT:
        raise InvalidInputError(f"labels times offset must stay within +-{MAX_SHIFT:g} px, got "
                                f"labels up to {float(np.abs(lab).max()):g} and offset "
                                f"({dx:g}, {dy:g})")
    return [(-d * dx, -d * dy) for d in lab]


#: Largest shift (px) :func:`view_shifts` makes: far beyond any image, finite.
MAX_SHIFT = 1e12


def _check_labels(labels) -> np.ndarray:
    """``labels`` as finite float64 numbers, 1-D."""
    lab = real_array(labels, "labels")
    if lab.ndim != 1 or not np.isfinite(lab).all():
        raise InvalidInputError(f"labels must be finite numbers (1-D), got {shown(labels)}")
    return lab


def view_validity(shape, shifts, *, mask=None, rows=None) -> np.ndarray:
    """Boolean ``(L, H, W)``: True where the shifted sample ``p + (sx, sy)`` is in the image.

    Parameters
    ----------
    shape : (..., H, W)
        The image shape.
    shifts : sequence of (sx, sy)
        As :func:`view_shifts`.
    mask : array_like of bool, shape (H, W), optional
        The view's validity mask (SPEC §11): a sample is then valid only if, besides lying in
        the image, every bilinear tap it uses with a non-zero weight is a valid pixel
        (:func:`tap_validity`).
    rows : (int, int), optional
        Only the rows ``a .. b - 1`` (shape ``(L, b - a, W)``).

    Returns
    -------
    ndarray of bool, shape (L, H, W)

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.costs import view_validity
    >>> m = np.ones((1, 4), bool); m[0, 2] = False
    >>> view_validity((1, 4), [(0.5, 0.0)], mask=m)[0].tolist()
    [[True, False, False, False]]
    """
    H, W = check_shape(shape)
    sh = _check_shifts(shifts)
    if rows is not None and not _row_range(rows, H):
        raise InvalidInputError(f"rows must be (a, b) with 0 <= a < b <= {H}, got {shown(rows)}")
    a, b = (0, H) if rows is None else (int(rows[0]), int(rows[1]))
    if mask is not None:
        mask = bool_mask(mask, "mask", (H, W), of="the image")
    check_bytes(len(sh) * (b - a) * W, f"a validity mask of {len(sh)} shifts",
                "use fewer labels")
    out = np.stack([axis_valid(H, sy)[a:b, None] & axis_valid(W, sx)[None, :]
                    for sx, sy in shifts])
    if mask is not None:
        m = np.asarray(mask, bool)
        if not m.all():
            for k, (sx, sy) in enumerate(shifts):
                out[k] &= tap_validity(m, sx, sy)[a:b]
    return out


def tap_validity(mask, sx: float, sy: float) -> np.ndarray:
    """True where every bilinear tap of the sample ``p + (sx, sy)`` with a non-zero weight is
    a valid pixel of ``mask`` (taps clamped at the border, as :func:`hyperlf.warp.axis_taps`).

    Separable and exact: along y, a row pair is valid where both rows it weights are valid;
    along x, the same on that result.

    Parameters
    ----------
    mask : ndarray of bool, shape (H, W)
    sx, sy : float
        The shift.

    Returns
    -------
    ndarray of bool, shape (H, W)

    Examples
    --------
    A row whose pixel 2 has no data.  Shifted by half a pixel, pixel ``x`` reads pixels ``x``
    and ``x + 1``, so pixels 1 and 2 lose their sample; shifted by a whole pixel, it reads
    ``x + 1`` alone, so only pixel 1 does (the last pixel's taps are clamped to itself):

    >>> import numpy as np
    >>> from hyperlf.costs import tap_validity
    >>> mask = np.array([[True, True, False, True]])
    >>> tap_validity(mask, 0.5, 0.0).tolist(), tap_validity(mask, 1.0, 0.0).tolist()
    ([[True, False, False, True]], [[True, False, True, True]])
    """
    m = mask if isinstance(mask, np.ndarray) and mask.dtype == np.bool_ else \
        check_map(mask, "mask", 2).astype(bool)
    if m.ndim != 2 or not m.size:
        raise InvalidInputError(f"mask must be a non-empty 2-D array of bools, got shape "
                                f"{m.shape}")
    sx, sy = real(sx, "sx"), real(sy, "sy")
    H, W = m.shape
    y0, y1, fy = axis_taps(H, sy, 0)
    x0, x1, fx = axis_taps(W, sx, 0)
    my = (m[y0] | (fy == 1)[:, None]) & (m[y1] | (fy == 0)[:, None])
    return (my[:, x0] | (fx == 1)[None]) & (my[:, x1] | (fx == 0)[None])


def check_rows(rows, height: int):
    """``rows`` as ``(a, b)`` ints with ``0 <= a < b <= height`` and ``a`` a multiple of
    :data:`ROW_BLOCK`, or None; else :class:`~hyperlf.errors.InvalidInputError`.

    Examples
    --------
    >>> from hyperlf.costs import ROW_BLOCK, check_rows
    >>> ROW_BLOCK, check_rows((32, 64), 100), check_rows(None, 100)
    (32, (32, 64), None)
    >>> check_rows((10, 20), 100)
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: rows must be (a, b) with ... a multiple of 32, got (10, 20)
    """
    height = integer(height, "height")
    if rows is None:
        return None
    if not _row_range(rows, height) or int(rows[0]) % ROW_BLOCK:
        raise InvalidInputError(
            f"rows must be (a, b) with 0 <= a < b <= {height} and a a multiple of {ROW_BLOCK}, "
            f"got {shown(rows)}")
    return int(rows[0]), int(rows[1])


def _view_inputs(ref_img, img, offset, labels, ref_valid, view_valid, rows):
    """The two images as the evaluators take them, the shifts and the samples' validity."""
    H, W = _check_views(ref_img, img)
    masks = [None if m is None else bool_mask(m, name, (H, W), of="the views")
             for m, name in ((ref_valid, "ref_valid"), (view_valid, "view_valid"))]
    ref_valid, view_valid = masks
    A = np.asarray(ref_img, dtype=np.float64)
    B = np.asarray(img, dtype=np.float64)
    rows = check_rows(rows, A.shape[0])
    shifts = view_shifts(offset, labels)
    valid = view_validity(A.shape, shifts, mask=view_valid, rows=rows)
    if ref_valid is not None:
        m = np.asarray(ref_valid, bool)
        valid &= (m if rows is None else m[rows[0]:rows[1]])[None]
        A = normalise_intensity(fill_masked(A, ref_valid), valid=ref_valid)
    if view_valid is not None:
        B = normalise_intensity(fill_masked(B, view_valid), valid=view_valid)
    return A, B, shifts, valid, rows


#: A reference with at least this many other views uses its cost's :attr:`Cost.dense_window`
#: (:func:`light_field_window`).
DENSE_VIEWS = 12


def light_field_window(metric: str, n_other_views: int, *, window: int | None = None,
                       dense_views: int = DENSE_VIEWS) -> int | None:
    """The window of a light-field cost: ``window`` if given, else the cost's
    :attr:`~hyperlf.costs.Cost.dense_window` when the reference has at least ``dense_views``
    other views, else None (the cost's own :attr:`~hyperlf.costs.Cost.window`).

    Why: the per-view costs are averaged over the other views, so the noise a window has to
    average away shrinks with their number while the fattening of depth edges by the window
    does not: with many views a smaller window resolves depth edges without more noise.  The
    threshold lies between the 3 x 3 arrays (8 other views), where the larger window is the
    better one, and the 4 x 4 ones (15), where the smaller one is (the measurements:
    BENCHMARKS.md, "Dense arrays, small windows").

    Examples
    --------
    >>> light_field_window("census-rsncc", 29), light_field_window("census-rsncc", 8)
    (3, None)
    """
    from .registry import get_cost

    cost = get_cost(metric)
    n_other_views = integer(n_other_views, "n_other_views")
    dense_views = integer(dense_views, "dense_views", 1)
    if window is not None:
        return check_window(window)
    if n_other_views >= dense_views:
        return cost.dense_window
    return None


def view_costs(ref_img, img, offset, labels, metric: str = "ncc", window: int | None = None,
               tau_rel: float = 1e-5, eps: float = 1e-3, block: int = 68, _cache=None, *,
               ref_valid=None, view_valid=None, rows=None, scales=None, weights=None):
    """Correspondence cost of one view against the reference, and its validity.

    Parameters
    ----------
    ref_img, img : (H, W) arrays
        Reference view and the other view.
    offset : (dx, dy)
        ``pos_v - pos_ref``; label ``d`` compares ``p`` with ``p - d (dx, dy)``.
    labels : (L,) floats
        Disparities.
    metric : str
        A light-field cost of the registry (:func:`hyperlf.costs.cost_names` with
        ``light_field=True``) or ``"auto"``.
    window : int, optional
        Cost window; None = the cost's own default.
    tau_rel, eps, block
        NCC flat-patch threshold, BWNCC floor, descriptor channels per block.
    ref_valid, view_valid : array_like of bool, shape (H, W), optional
        Validity masks of the reference and of the view (SPEC §11; module docstring): an
        invalid pixel counts like a sample outside the image.  None = all valid (the
        computation is then exactly the unmasked one).
    rows : (int, int), optional
        A strip of reference rows ``a .. b - 1`` (``a`` a multiple of :data:`ROW_BLOCK`):
        the volume of those rows only, bit for bit what the whole image gives there (the
        images stay whole: every sample and window reads the rows it needs, and the per-view
        statistics are the whole view's).  SPEC §12 tiles.
    scales : sequence of float, optional
        For a cost with whole-volume scales (:attr:`hyperlf.costs.Cost.global_scales`: a
        fusion's normalisers), the scales of the whole view (:func:`view_moments` over every
        strip, then :func:`hyperlf.costs.moments_std`); needed with ``rows``, since a strip
        alone would give its own.
    weights : sequence of float, optional
        For a fused cost (:class:`hyperlf.costs.FusedCost`), one weight per part instead of
        its own (``census-rsncc``: rsncc, census); None = the cost's.

    Returns
    -------
    cost : float32 (L, H, W)
        Lower is better; invalid entries carry the pixel's worst valid cost (for display; the
        aggregation masks them anyway); a pixel with no valid entry gets 0 at every label.
        ``(L, b - a, W)`` for a strip ``rows=(a, b)``.
    valid : bool (L, H, W)
        ``q_v`` inside the image (and, with masks, its taps and ``p`` valid); the strip's rows.

    Raises
    ------
    InvalidInputError
        Unknown metric, or one without a light-field evaluator (``ssd``); bad ``rows``; a
        strip of a cost with whole-volume scales without ``scales``; ``weights`` for a cost
        that is not a fusion, or not one valid weight per part.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.costs import view_costs
    >>> a = np.random.default_rng(0).random((16, 20)) + 0.5
    >>> b = np.roll(a, 1, axis=1)                      # the view sees p at x + 1
    >>> labels = np.arange(0.0, 2.5, 0.5)              # sub-pixel labels
    >>> C, valid = view_costs(a, b, (-1.0, 0.0), labels, "census")
    >>> float(labels[C[:, 8, 10].argmin()])
    1.0
    """
    from .registry import fusion_weights, get_cost
    cost = get_cost(metric, light_field=True)
    A, B, shifts, valid, rows = _view_inputs(ref_img, img, offset, labels, ref_valid,
                                             view_valid, rows)
    if rows is not None and cost.global_scales and scales is None:
        raise InvalidInputError(
            f"a strip of rows of {cost.name!r} needs the whole view's scales (view_moments)")
    cache = {} if _cache is None else _cache
    extra = {} if scales is None else {"scales": scales}
    if weights is not None:
        extra["weights"] = fusion_weights(metric, weights)
    C = cost.view_volume(A, B, shifts, window=window, valid=valid, tau_rel=tau_rel, eps=eps,
                         block=block, cache=cache, rows=rows, **extra)
    C = fill_out_of_image(np.ascontiguousarray(C, dtype=np.float32), 0, valid)
    return C, valid


def view_moments(ref_img, img, offset, labels, metric: str = "ncc", window: int | None = None,
                 tau_rel: float = 1e-5, eps: float = 1e-3, block: int = 68, _cache=None, *,
                 ref_valid=None, view_valid=None, rows=None):
    """The pieces of a cost's whole-volume scales that a strip of rows holds.

    Arguments as :func:`view_costs`.  Strips that cover the image, taken in row order, give
    the whole view's scales: per part, ``moments_std(*concatenated moments)``
    (:func:`hyperlf.costs.moments_std`), bit for bit what the untiled volume measures.

    Returns
    -------
    list of (n, mean, m2) or None
        Per part of the cost, its :func:`hyperlf.costs.row_moments` on the strip; None for a
        cost without whole-volume scales.

    Examples
    --------
    Offset ``(1, 0)`` and labels 0, 1, 2: the sample ``x - d`` is in the 24 columns for
    ``24 - d`` of them, so each part of ``census-rsncc`` counts ``40 (24 + 23 + 22) = 2760``
    valid entries.  Two strips that cover the 40 rows, joined in row order, give the whole
    view's standard deviations exactly; ``ncc`` has no whole-volume scales:

    >>> import numpy as np
    >>> from hyperlf.costs import moments_std, view_moments
    >>> ref = np.random.default_rng(0).random((40, 24)) + 0.5
    >>> view = np.roll(ref, -1, axis=1)
    >>> labels = [0.0, 1.0, 2.0]
    >>> whole = view_moments(ref, view, (1, 0), labels, "census-rsncc")
    >>> [int(n.sum()) for n, mean, m2 in whole]
    [2760, 2760]
    >>> top, bottom = (view_moments(ref, view, (1, 0), labels, "census-rsncc", rows=rows)
    ...                for rows in ((0, 32), (32, 40)))
    >>> joined = [[np.concatenate(pair) for pair in zip(t, b)] for t, b in zip(top, bottom)]
    >>> [moments_std(*j) == moments_std(*w) for j, w in zip(joined, whole)]
    [True, True]
    >>> view_moments(ref, view, (1, 0), labels, "ncc") is None
    True
    """
    from .registry import get_cost
    cost = get_cost(metric, light_field=True)
    if not cost.global_scales:
        return None
    A, B, shifts, valid, rows = _view_inputs(ref_img, img, offset, labels, ref_valid,
                                             view_valid, rows)
    return cost.view_moments(A, B, shifts, window=window, valid=valid, tau_rel=tau_rel,
                             eps=eps, block=block, cache={} if _cache is None else _cache,
                             rows=rows)
