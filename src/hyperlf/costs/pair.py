"""Rectified-pair cost evaluators: integer disparities, window statistics, fusion (SPEC §3, §4).

Left pixel ``(y, x)`` with disparity ``d`` in ``dmin..dmax`` matches right pixel ``(y, x - d)``.
Every evaluator returns ``cost[L, H, W]`` float32, ``L = dmax - dmin + 1``, index ``k`` <->
``d = dmin + k``, lower is better, with the out-of-image rule applied (:func:`fill_out_of_image`).
The conventions (border rule, numerics, ``impl``) are those of :mod:`hyperlf.costs`.  The
registry (:mod:`hyperlf.costs.registry`) calls these functions; they can also be called
directly.  The papers behind the costs are listed in :mod:`hyperlf.costs` (References).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Sequence

import numpy as np

from .._kernel_args import kernel_input
from .._options import (bool_mask, check_values, choice, flag, integer, number, real,
                        real_array, rule, shown)
from ..errors import InvalidInputError
from ..imageops import gradient_magnitude, normalise_intensity
from ._validate import (check_bytes, check_disp, check_dmin, check_impl, check_map, check_pair,
                        check_scale, check_shape, check_window, map_side)

#: Largest ``tau_rel``, ``rs_tau`` and ``eps`` (relative thresholds and weights of order 1;
#: near 1e300 they overflow into infinite costs).
MAX_COST_CONSTANT = 1e6

#: How the pair costs check their constants before any work.
_COST_RULES = {
    "tau_rel": rule(number, at_most=MAX_COST_CONSTANT),
    "rs_tau": rule(number, at_most=MAX_COST_CONSTANT),
    "eps": rule(number, positive=True, at_most=MAX_COST_CONSTANT),
    "block": rule(integer, minimum=1, optional=True),
    "tau_scope": rule(choice, choices=("block", "view")),
    "return_scores": flag,
}


def _constants(**values) -> dict:
    """``values`` checked by :data:`_COST_RULES`."""
    return check_values(values, _COST_RULES)


__all__ = [
    "candidate_validity",
    "right_validity",
    "fill_out_of_image",
    "worst_fill",
    "rho",
    "rho_table",
    "rsncc_rho",
    "pad_replicate",
    "box_mean",
    "window_stats",
    "inv_sigma",
    "channel_stats",
    "shift_cols",
    "ssd_volume",
    "ncc_volume",
    "rsncc_volume",
    "census_transform",
    "census_volume",
    "bwncc_finish",
    "bwncc_from_descriptors",
    "bwncc_volume",
    "row_moments",
    "moments_std",
    "normalise_volume",
    "fuse",
    "fused_volume",
    "census_rsncc_volume",
]


# --------------------------------------------------------------------------------------------
# Validity and the out-of-image rule
# --------------------------------------------------------------------------------------------


def candidate_validity(shape, dmin: int, dmax: int) -> np.ndarray:
    """Boolean ``valid[L, H, W]``: True where ``0 <= x - d < W``.

    A read-only broadcast view of an ``(L, 1, W)`` array (no ``L*H*W`` memory); use
    ``np.array(...)`` for a writable copy.  ``shape`` is ``(H, W)`` (or any shape ending in them).

    Examples
    --------
    Candidate ``d`` of pixel ``x`` reads the right image at ``x - d``, outside it for ``x < d``:

    >>> from hyperlf.costs import candidate_validity
    >>> valid = candidate_validity((2, 5), 0, 2)
    >>> valid.shape, valid.flags.writeable
    ((3, 2, 5), False)
    >>> valid[:, 0].astype(int).tolist()        # row 0 at disparities 0, 1 and 2
    [[1, 1, 1, 1, 1], [0, 1, 1, 1, 1], [0, 0, 1, 1, 1]]
    """
    H, W, dmin, dmax = _validity_args(shape, dmin, dmax)
    d = np.arange(dmin, dmax + 1)[:, None, None]
    x = np.arange(W)[None, None, :]
    v = (x - d >= 0) & (x - d < W)
    return np.broadcast_to(v, (d.shape[0], H, W))


def _validity_args(shape, dmin, dmax) -> tuple[int, int, int, int]:
    """``(H, W, dmin, dmax)`` of the validity masks, checked (O(1)): an image shape, integer
    disparities, and the ``(L, 1, W)`` mask within the memory."""
    H, W = check_shape(shape)
    dmin, dmax = check_disp(dmin, dmax)
    check_bytes(10 * (dmax - dmin + 1) * W, f"a validity mask of {dmax - dmin + 1} disparities",
                "narrow dmin..dmax")
    return H, W, dmin, dmax


def right_validity(shape, dmin: int, dmax: int) -> np.ndarray:
    """Boolean ``valid_R[L, H, W]``: True where the right pixel's partner ``x_r + d`` is inside.

    The right-referenced counterpart of :func:`candidate_validity` (read-only broadcast view).

    Examples
    --------
    Right pixel ``x_r`` at disparity ``d`` pairs with left ``x_r + d``, beyond the image for the
    last ``d`` columns:

    >>> from hyperlf.costs import right_validity
    >>> right_validity((2, 5), 0, 2)[:, 0].astype(int).tolist()
    [[1, 1, 1, 1, 1], [1, 1, 1, 1, 0], [1, 1, 1, 0, 0]]
    """
    H, W, dmin, dmax = _validity_args(shape, dmin, dmax)
    d = np.arange(dmin, dmax + 1)[:, None, None]
    x = np.arange(W)[None, None, :]
    return np.broadcast_to((x + d >= 0) & (x + d < W), (d.shape[0], H, W))


def fill_out_of_image(cost: np.ndarray, dmin: int, valid: np.ndarray | None = None) -> np.ndarray:
    """Apply the out-of-image rule in place and return ``cost``.

    Invalid entries get the pixel's worst (largest) valid cost; a pixel with no valid candidate
    gets 0 for every disparity.  ``valid`` defaults to :func:`candidate_validity`.

    Examples
    --------
    Four pixels at disparities 1 and 2: pixel 0 has no valid candidate, so both of its costs
    become 0; pixel 1 has one, disparity 1, whose cost 2 replaces its invalid disparity 2:

    >>> import numpy as np
    >>> from hyperlf.costs import fill_out_of_image
    >>> cost = np.array([[[1.0, 2.0, 3.0, 4.0]], [[5.0, 6.0, 7.0, 8.0]]], np.float32)
    >>> fill_out_of_image(cost, 1)[:, 0].tolist()
    [[0.0, 2.0, 3.0, 4.0], [0.0, 2.0, 7.0, 8.0]]
    """
    Lc, H, W = _volume(cost, "cost", writeable=True).shape
    dmin = check_dmin(dmin)
    if valid is None:
        valid = candidate_validity((H, W), dmin, dmin + Lc - 1)
    else:
        valid = bool_mask(valid, "valid", cost.shape, broadcast=True, of="the cost")
    return worst_fill(cost, ~np.asarray(valid, dtype=bool), empty="zero")


def _volume(cost, label: str, *, writeable: bool = False) -> np.ndarray:
    """``cost`` as an ``(L, H, W)`` array of real numbers (O(1), no copy of an ndarray); an
    ndarray that can be written in place where ``writeable``."""
    if writeable and not (isinstance(cost, np.ndarray) and cost.flags.writeable):
        raise InvalidInputError(f"{label} must be a writeable numpy array (it is filled in "
                                f"place), got {shown(cost)}")
    return check_map(cost, f"{label} (L, H, W)", 3)


#: What :func:`worst_fill` gives a pixel with no valid entry.
FILL_EMPTY_MODES = ("zero", "global")


def worst_fill(cost: np.ndarray, invalid, *, empty: str = "zero") -> np.ndarray:
    """The worst-cost rule of SPEC §4, in place: every invalid entry of a cost volume gets its
    pixel's worst (largest) valid cost.

    The one implementation behind :func:`fill_out_of_image` and
    :func:`hyperlf.regularisers.fill_invalid`.

    Parameters
    ----------
    cost : ndarray, shape (L, H, W)
        Modified in place (its dtype is kept).
    invalid : array_like of bool, broadcastable to ``cost``
    empty : {"zero", "global"}
        A pixel with no valid entry gets 0 (``"zero"``) or the worst valid cost of the whole
        volume (``"global"``).

    Returns
    -------
    ndarray
        ``cost``.

    Raises
    ------
    InvalidInputError
        Unknown ``empty``, or ``empty="global"`` with no valid entry at all.

    Examples
    --------
    >>> import numpy as np
    >>> c = np.array([[[1.0, 5.0]], [[3.0, 7.0]]])
    >>> worst_fill(c, np.array([[[False, True]], [[True, True]]]))[:, 0, :].tolist()
    [[1.0, 0.0], [1.0, 0.0]]
    """
    choice(empty, "empty", FILL_EMPTY_MODES)
    _volume(cost, "cost", writeable=True)
    invalid = bool_mask(invalid, "invalid", cost.shape, broadcast=True, of="the cost")
    worst = np.full(cost.shape[1:], -np.inf, np.result_type(cost.dtype, np.float32))
    for k in range(cost.shape[0]):  # label by label: no volume-sized temporary
        np.maximum(worst, np.where(invalid[k], -np.inf, cost[k]), out=worst)
    none_valid = ~np.isfinite(worst)
    if none_valid.any():
        if empty == "global" and none_valid.all():
            raise InvalidInputError("cost volume has no valid entry to fill the invalid ones from")
        worst[none_valid] = 0.0 if empty == "zero" else worst[~none_valid].max()
    np.copyto(cost, np.broadcast_to(worst.astype(cost.dtype), cost.shape), where=invalid)
    return cost


def rho(x):
    """Shen et al.'s robust function ``rho(x) = -log(exp(-|x|) + exp(|x| - 2))``.

    ``x``: a number or an array of real numbers with ``|x| <= RHO_MAX`` (beyond it ``exp``
    overflows); a number is checked whole, an array by its dtype and by the overflow (its
    NaNs are not searched for: this runs per block of labels).

    Examples
    --------
    ``rho`` is lowest at 0 and again at 2, ``-log(1 + exp(-2))``, and highest at 1,
    ``-log(2 exp(-1)) = 1 - log 2``; so ``rho(1 - NCC)`` costs a reversed contrast (NCC -1) as
    little as a match (NCC 1):

    >>> import math
    >>> import numpy as np
    >>> from hyperlf.costs import rho
    >>> [round(float(v), 3) for v in rho(np.array([0.0, 1.0, 2.0]))]
    [-0.127, 0.307, -0.127]
    >>> round(-math.log(1 + math.exp(-2)), 3), round(1 - math.log(2), 3)
    (-0.127, 0.307)
    """
    if isinstance(x, (list, tuple)):
        x = real_array(x, "x", dtype=None)
    if isinstance(x, np.ndarray) and x.ndim:
        check_map(x, "x", x.ndim, empty=True)
    elif not (-RHO_MAX <= real(x[()] if isinstance(x, np.ndarray) else x, "x") <= RHO_MAX):
        raise InvalidInputError(f"x must be within +-{RHO_MAX:g} (exp overflows beyond), got "
                                f"{shown(x)}")
    with np.errstate(over="raise"):
        try:
            return _rho(x)
        except FloatingPointError:
            raise InvalidInputError(f"x must be within +-{RHO_MAX:g} (exp overflows beyond)") \
                from None


#: Largest ``|x|`` :func:`rho` takes: ``exp(|x| - 2)`` is finite up to about 711.
RHO_MAX = 700.0


def _rho(x):
    a = np.abs(x)
    if not (isinstance(a, np.ndarray) and a.dtype.kind == "f"):  # scalars, integers
        return -np.log(np.exp(-a) + np.exp(a - 2.0))
    e = np.negative(a)  # the same operations in place: two arrays instead of six
    np.exp(e, out=e)
    a -= 2.0
    np.exp(a, out=a)
    a += e
    np.log(a, out=a)
    return np.negative(a, out=a)


#: Intervals of the table of :func:`rho` over ``|x|`` in [0, 2] that the numba kernel of
#: :func:`rsncc_rho` interpolates linearly: error at most ``h^2 / 8 = 1.2e-10`` (``h = 2 /
#: RHO_TABLE_INTERVALS``, ``|rho''| <= 1``), far below float32's step at the largest costs
#: (BENCHMARKS.md, thirty-fourth session).
RHO_TABLE_INTERVALS = 1 << 16


@functools.lru_cache(maxsize=1)
def rho_table() -> np.ndarray:
    """:func:`rho` at ``RHO_TABLE_INTERVALS + 1`` evenly spaced ``|x|`` from 0 to 2 (the range
    of ``1 - NCC``), float64, read-only.

    Examples
    --------
    The table's first, middle and last entries are ``rho`` at 0, 1 and 2 (see :func:`rho`):

    >>> from hyperlf.costs import rho_table
    >>> table = rho_table()
    >>> len(table), table.flags.writeable
    (65537, False)
    >>> [round(float(table[i]), 3) for i in (0, 32768, 65536)]
    [-0.127, 0.307, -0.127]
    """
    table = _rho(np.linspace(0.0, 2.0, RHO_TABLE_INTERVALS + 1))
    table.flags.writeable = False
    return table


def rsncc_rho(xi_i, xi_g, rs_tau: float, out: np.ndarray, impl: str = "auto") -> np.ndarray:
    """RSNCC from its two NCC scores: ``out[...] = rho(1 - xi_i) + rs_tau * rho(1 - xi_g)``.

    ``xi_i``, ``xi_g``: float64 NCC of the intensities and of the gradient magnitudes, the
    shape of ``out`` (float32, written and returned).  ``impl="numpy"`` is the reference
    (:func:`rho`); ``"numba"`` (:func:`hyperlf.costs._kernels.rho_sum`) reads ``rho`` from
    :func:`rho_table` by linear interpolation in one parallel pass, without temporaries (the
    formula where ``|1 - xi|`` is beyond 2), instead of the formula's three transcendental
    functions per term; the float32 results differ from the reference's by at most one unit in
    their last place at the largest costs (``2^-24`` at ``rs_tau <= 1``).

    Examples
    --------
    A match (both NCCs 1) and a contrast reversal (intensity NCC -1, gradient NCC 1) both cost
    ``2 rho(0)``; patches with nothing in common (both NCCs 0) cost ``2 rho(1)``:

    >>> import numpy as np
    >>> from hyperlf.costs import rho, rsncc_rho
    >>> xi_i, xi_g = np.array([1.0, -1.0, 0.0]), np.array([1.0, 1.0, 0.0])
    >>> out = rsncc_rho(xi_i, xi_g, 1.0, np.empty(3, np.float32))
    >>> [round(float(v), 3) for v in out]
    [-0.254, -0.254, 0.614]
    >>> round(2 * float(rho(0.0)), 3), round(2 * float(rho(1.0)), 3)
    (-0.254, 0.614)
    """
    impl = check_impl(impl, "rsncc")
    rs_tau = _constants(rs_tau=rs_tau)["rs_tau"]
    if not (isinstance(out, np.ndarray) and out.dtype.kind == "f" and out.flags.writeable):
        raise InvalidInputError(f"out must be a writeable float numpy array, got {shown(out)}")
    for label, xi in (("xi_i", xi_i), ("xi_g", xi_g)):
        if not (isinstance(xi, np.ndarray) and xi.dtype.kind == "f" and xi.shape == out.shape):
            got = f"shape {xi.shape}, dtype {xi.dtype}" if isinstance(xi, np.ndarray) \
                else shown(xi)
            raise InvalidInputError(f"{label} must be a float numpy array of out's shape "
                                    f"{out.shape}, got {got}")
    if impl == "numba" and out.flags.c_contiguous and out.dtype == np.float32 \
            and xi_i.dtype == np.float64 and xi_g.dtype == np.float64:
        from ._kernels import rho_sum

        rho_sum(np.ascontiguousarray(xi_i).reshape(-1), np.ascontiguousarray(xi_g).reshape(-1),
                float(rs_tau), rho_table(), out.reshape(-1))
        return out
    out[...] = _rho(1.0 - xi_i) + float(rs_tau) * _rho(1.0 - xi_g)
    return out


# --------------------------------------------------------------------------------------------
# Window statistics
# --------------------------------------------------------------------------------------------


def pad_replicate(maps: np.ndarray, r: int) -> np.ndarray:
    """Pad the last two axes by ``r`` with replicated borders (same dtype); ``r`` at most
    the maps' longer side (:func:`hyperlf.costs._validate.map_side`).

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.costs import pad_replicate
    >>> pad_replicate(np.array([[1, 2], [3, 4]]), 1).tolist()
    [[1, 1, 2, 2], [1, 1, 2, 2], [3, 3, 4, 4], [3, 3, 4, 4]]
    """
    maps = check_map(maps, "maps", tuple(range(2, 33)))
    r = integer(r, "r", maximum=map_side(maps.shape))
    if r == 0:
        return np.ascontiguousarray(maps)
    pw = [(0, 0)] * (maps.ndim - 2) + [(r, r), (r, r)]
    return np.pad(maps, pw, mode="edge")


def box_mean(image: np.ndarray, n: int) -> np.ndarray:
    """Mean over the ``n x n`` window centred on each pixel, float64, replicate border.

    ``image``: 2-D real numbers; ``n``: an odd window, at most ``2 side + 1`` for the
    image's :func:`hyperlf.costs._validate.map_side`.

    Examples
    --------
    A constant image is its own mean; on a ramp the first column's window holds the replicated
    first value twice, ``(0 + 0 + 1) / 3``, and the inner columns keep their values:

    >>> import numpy as np
    >>> from hyperlf.costs import box_mean
    >>> bool((box_mean(np.full((4, 5), 2.5), 3) == 2.5).all())
    True
    >>> ramp = np.tile(np.arange(5.0), (3, 1))
    >>> [round(float(v), 3) for v in box_mean(ramp, 3)[1]]
    [0.333, 1.0, 2.0, 3.0, 3.667]
    """
    image = check_map(image, "image", 2)
    n = check_window(n, "n", side=map_side(image.shape))
    img = np.ascontiguousarray(image, dtype=np.float64)
    if n == 1:
        return img.copy()
    import cv2

    return cv2.boxFilter(img, cv2.CV_64F, (n, n), normalize=True, borderType=cv2.BORDER_REPLICATE)


def _box_valid(padded: np.ndarray, n: int) -> np.ndarray:
    """'Valid' ``n x n`` box mean of a map padded by ``r = n // 2``: shape shrinks by ``2r``."""
    r = n // 2
    out = box_mean(padded, n)
    if r == 0:
        return out
    return out[r:-r, r:-r]


def window_stats(image: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and (population) variance over ``n x n`` windows, float64, replicate border.

    The image is centred on its global mean (in float64) before the sums, so
    ``var = E[c^2] - E[c]^2`` is computed on centred values (no catastrophic cancellation; a
    naive float32 version loses patch variances of ~1e-4 on values of ~0.5, SPEC §3).  ``var``
    is clipped at 0.

    Examples
    --------
    On columns 0, 2, 0, 2 the 3 x 3 window of column 1 holds 0, 2, 0 in each row: mean 2/3,
    variance ``4/3 - (2/3)^2 = 8/9``.  A flat image has no variance:

    >>> import numpy as np
    >>> from hyperlf.costs import window_stats
    >>> mean, var = window_stats(np.tile([0.0, 2.0], (4, 2)), 3)
    >>> round(float(mean[1, 1]), 3), round(float(var[1, 1]), 3), round(8 / 9, 3)
    (0.667, 0.889, 0.889)
    >>> float(window_stats(np.full((4, 4), 7.0), 3)[1].max())
    0.0
    """
    img = np.asarray(check_map(image, "image", 2), dtype=np.float64)
    n = check_window(n, "n", side=map_side(img.shape))
    m0 = float(img.mean())
    c = img - m0
    mu_c = box_mean(c, n)
    var = box_mean(c * c, n) - mu_c * mu_c
    np.maximum(var, 0.0, out=var)
    return mu_c + m0, var


def inv_sigma(var: np.ndarray, tau: float) -> np.ndarray:
    """``1 / sqrt(var)`` where ``var >= tau`` and ``var > 0``, else 0 (so that ``xi = 0``).

    ``var``: an array of real numbers; ``tau``: a finite number >= 0, or such numbers
    broadcastable to ``var`` (one per channel).

    Examples
    --------
    Variances 4 and 0.25 give ``1 / 2`` and ``1 / 0.5``; one below ``tau`` and one of 0 give 0:

    >>> import numpy as np
    >>> from hyperlf.costs import inv_sigma
    >>> inv_sigma(np.array([4.0, 0.25, 1e-9, 0.0]), 1e-6).tolist()
    [0.5, 2.0, 0.0, 0.0]
    """
    var = check_map(var, "var", tuple(range(1, 33)))
    if var.dtype.kind != "f":
        var = var.astype(np.float64)
    if isinstance(tau, np.ndarray) and tau.ndim:
        t = check_map(tau, "tau", tau.ndim)
        try:
            fits = np.broadcast_shapes(t.shape, var.shape) == var.shape
        except ValueError:
            fits = False
        if not (fits and np.isfinite(t).all() and (t >= 0).all()):
            raise InvalidInputError(f"tau must be finite numbers >= 0 broadcastable to var's "
                                    f"{var.shape}, got shape {t.shape}")
    else:
        number(tau, "tau")
    ok = (var >= tau) & (var > 0)
    out = np.zeros_like(var)
    np.divide(1.0, np.sqrt(var, where=ok, out=np.zeros_like(var)), out=out, where=ok)
    return out


# --------------------------------------------------------------------------------------------
# Generic per-channel NCC cross term (shared by ncc, rsncc, bwncc)
# --------------------------------------------------------------------------------------------


def channel_stats(maps: np.ndarray, n: int | Sequence[int]) -> dict:
    """Per-channel window statistics of one view, computed once.

    Parameters
    ----------
    maps : (nc, H, W) array
    n : int or (nc,) ints — NCC patch size per channel.

    Returns a dict with float64 arrays ``mu`` (nc, H, W), ``var`` (nc, H, W), the per-channel
    global means ``centre`` (nc,) and the per-channel mean patch variance ``mean_var`` (nc,).

    Examples
    --------
    A flat channel and one of columns 0, 1, 0, 1, ...: every 3 x 3 window of the second holds
    one value twice and the other once (the border replicated), a variance of 2/9:

    >>> import numpy as np
    >>> from hyperlf.costs import channel_stats
    >>> maps = np.stack([np.full((4, 6), 3.0), np.tile([0.0, 1.0], (4, 3))])
    >>> stats = channel_stats(maps, 3)
    >>> stats["mu"].shape, stats["centre"].tolist()
    ((2, 4, 6), [3.0, 0.5])
    >>> [round(float(v), 3) for v in stats["mean_var"]], round(2 / 9, 3)
    ([0.0, 0.222], 0.222)
    """
    maps = check_map(maps, "maps (nc, H, W)", 3)
    _check_patch_sizes(n, maps.shape, side=map_side(maps.shape))
    nc = maps.shape[0]
    ns = np.broadcast_to(np.asarray(n, dtype=np.int64), (nc,))
    H, W = maps.shape[1:]
    mu = np.empty((nc, H, W), np.float64)
    var = np.empty((nc, H, W), np.float64)
    for c in range(nc):
        mu[c], var[c] = window_stats(maps[c], int(ns[c]))
    centre = maps.reshape(nc, -1).astype(np.float64).mean(axis=1)
    return {"mu": mu, "var": var, "centre": centre, "mean_var": var.reshape(nc, -1).mean(axis=1)}


def _ncc_cross_accumulate(ref_pad: np.ndarray, oth_pad: np.ndarray, n: int,
                          ref_mu: np.ndarray, ref_is: np.ndarray,
                          oth_mu: np.ndarray, oth_is: np.ndarray,
                          acc_fwd: np.ndarray, acc_bwd: np.ndarray | None = None,
                          weighted: bool = True, valid: np.ndarray | None = None,
                          ref_centre=None, oth_centre=None) -> None:
    """Accumulate per-channel NCC ``xi_i`` for ONE alignment of two views (numpy reference
    of the pair costs' cross terms; private: only :func:`_xcorr_numpy` calls it, with
    arguments the pair costs have checked).

    This is the disparity-independent building block: the caller supplies the other view's
    channel maps **already aligned** to the reference grid (for the two-view case: shifted by
    ``d`` columns; for the H-LF case: shifted by any ``(dx, dy)``), together with the
    precomputed statistics, aligned the same way.

    Parameters
    ----------
    ref_pad, oth_pad : (nc, H + 2r, W + 2r)
        Channel maps padded by ``r = n // 2``; ``oth_pad[Y, X]`` must be the other view's padded
        map sampled at the aligned position (so each view keeps its own replicated border).
    ref_mu, oth_mu : (nc, H, W) float64 — patch means (aligned).
    ref_is, oth_is : (nc, H, W) — ``1/sigma`` of the patches, 0 where the variance is below
        ``tau`` (see :func:`inv_sigma`), aligned.
    acc_fwd, acc_bwd : (H, W) float64, updated in place:
        ``acc_fwd += sum_i xi_i * ref_mu_i`` and ``acc_bwd += sum_i xi_i * oth_mu_i`` when
        ``weighted``; otherwise ``acc_fwd += sum_i xi_i`` (``acc_bwd`` unused).
    valid : (H, W) bool, optional — only these pixels are updated.
    ref_centre, oth_centre : (nc,) optional per-channel constants subtracted before the product
        (numerics only; the result does not depend on them in exact arithmetic).

    ``xi_i = clip((E[a b] - mu_a mu_b) * is_a * is_b, -1, 1)``, cross term in float64.
    """
    nc = ref_pad.shape[0]
    ca = np.zeros(nc) if ref_centre is None else np.asarray(ref_centre, np.float64)
    cb = np.zeros(nc) if oth_centre is None else np.asarray(oth_centre, np.float64)
    for c in range(nc):
        a = ref_pad[c].astype(np.float64) - ca[c]
        b = oth_pad[c].astype(np.float64) - cb[c]
        cross = _box_valid(a * b, n)
        cov = cross - (ref_mu[c] - ca[c]) * (oth_mu[c] - cb[c])
        xi = np.clip(cov * ref_is[c] * oth_is[c], -1.0, 1.0)
        if valid is not None:
            xi = np.where(valid, xi, 0.0)
        if weighted:
            acc_fwd += xi * ref_mu[c]
            acc_bwd += xi * oth_mu[c]
        else:
            acc_fwd += xi


def shift_cols(a: np.ndarray, d: int, fill=0.0) -> np.ndarray:
    """``out[..., x] = a[..., x - d]`` (zero/fill outside).

    ``a``: a numpy array (1-D or more) of numbers; ``d``: an integer; ``fill``: a finite
    number that ``a``'s dtype holds.  O(1) checks (this runs per label).

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.costs import shift_cols
    >>> shift_cols(np.array([1, 2, 3, 4, 5]), 2).tolist()
    [0, 0, 1, 2, 3]
    >>> shift_cols(np.array([1.0, 2.0, 3.0, 4.0, 5.0]), -1, fill=-1).tolist()
    [2.0, 3.0, 4.0, 5.0, -1.0]
    """
    if not (isinstance(a, np.ndarray) and a.ndim and a.dtype.kind in "biuf"):
        raise InvalidInputError(f"a must be a numpy array of numbers (1-D or more), got "
                                f"{shown(a)}")
    d = integer(d, "d", minimum=None)
    fill = real(fill, "fill")
    if a.dtype.kind in "iu" and not (fill.is_integer() and np.iinfo(a.dtype).min <= fill
                                     <= np.iinfo(a.dtype).max) \
            or a.dtype.kind == "f" and abs(fill) > np.finfo(a.dtype).max:
        raise InvalidInputError(f"fill {fill:g} does not fit a's dtype {a.dtype}")
    out = np.full_like(a, fill)
    W = a.shape[-1]
    if d >= 0:
        if d < W:
            out[..., d:] = a[..., :W - d]
    else:
        if -d < W:
            out[..., :W + d] = a[..., -d:]
    return out


def _xcorr_numba(Ap, Bp, ca, cb, muA, isA, muB, isB, ds, r, weighted, accF, accB):
    """Numba path.  Patch means are passed centred on the channel centre, in float64 (a float32
    mean would put an error of ~1e-8 into covariances that may be as small as tau ~1e-9);
    ``1/sigma`` only scales, so it is stored in the maps' dtype (float32 for descriptors).
    Maps are float32 (descriptor output) or float64."""
    from . import _kernels
    k = _kernels.xcorr_accum
    ca = np.ascontiguousarray(ca, np.float64)
    cb = np.ascontiguousarray(cb, np.float64)
    dt = np.float32 if (Ap.dtype == np.float32 and Bp.dtype == np.float32) else np.float64
    mA = muA - ca[:, None, None]
    mB = muB - cb[:, None, None]
    k(np.ascontiguousarray(Ap), np.ascontiguousarray(Bp), ca, cb, mA, isA.astype(dt), mB,
      isB.astype(dt), np.ascontiguousarray(ds, np.int64), int(r), bool(weighted), accF, accB)


def _xcorr_numpy(Ap, Bp, ca, cb, muA, isA, muB, isB, ds, r, weighted, accF, accB):
    """Reference: loop over disparities, align the right view by ``d`` and call
    :func:`_ncc_cross_accumulate`."""
    n = 2 * r + 1
    H, W = muA.shape[1:]
    for k, d in enumerate(ds):
        d = int(d)
        valid = candidate_validity((H, W), d, d)[0]
        if not valid.any():
            continue
        Bs = shift_cols(Bp, d)
        accB_k = accB[k] if weighted else None
        _ncc_cross_accumulate(Ap, Bs, n, muA, isA, shift_cols(muB, d), shift_cols(isB, d),
                             accF[k], accB_k, weighted=weighted, valid=valid,
                             ref_centre=ca, oth_centre=cb)


def _xcorr(impl, *args):
    if impl == "numba":
        _xcorr_numba(*args)
    else:
        _xcorr_numpy(*args)


# --------------------------------------------------------------------------------------------
# Classical costs
# --------------------------------------------------------------------------------------------


def _ds(dmin, dmax):
    return np.arange(dmin, dmax + 1, dtype=np.int64)


def ssd_volume(left, right, dmin, dmax, window: int = 5) -> np.ndarray:
    """Window mean of squared differences of ``I / mean(I)``; float32 ``(L, H, W)``.

    Examples
    --------
    The left image is the right one moved 3 px to the right and twice as bright; dividing each
    image by its mean removes the gain, so on columns 6 to 20 (clear of the borders and of the
    columns ``np.roll`` wrapped round) the cost is 0 at disparity 3 and higher at the others:

    >>> import numpy as np
    >>> from hyperlf.costs import ssd_volume
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> left = 2.0 * np.roll(right, 3, axis=1)
    >>> C = ssd_volume(left, right, 0, 6)
    >>> C.shape, np.unique(C.argmin(axis=0)[:, 6:-3]).tolist()
    ((7, 16, 24), [3])
    >>> round(float(C[3, :, 6:-3].max()), 3)
    0.0
    """
    L, R = check_pair(left, right)
    dmin, dmax = check_disp(dmin, dmax, L.shape)
    n = check_window(window, side=max(L.shape))
    r = n // 2
    Ln = pad_replicate(normalise_intensity(L), r)
    Rn = pad_replicate(normalise_intensity(R), r)
    H, W = L.shape
    out = np.zeros((dmax - dmin + 1, H, W), np.float32)
    for k, d in enumerate(range(dmin, dmax + 1)):
        diff = Ln - shift_cols(Rn, d)
        out[k] = _box_valid(diff * diff, n)
    return fill_out_of_image(out, dmin)


#: Bytes of one float64 ``(labels, H, W)`` block of NCC scores: the single-map volumes (ncc,
#: rsncc) are computed a few labels at a time, so that their float64 scores and temporaries
#: never exceed a few such blocks beside the float32 result.
NCC_BLOCK_BYTES = 64 * 2**20


def _ncc_setup(A, B, n, tau_rel) -> tuple:
    """Everything of two single maps that does not depend on the disparity: padded maps,
    patch statistics, ``1/sigma`` (0 below ``tau_rel`` times the view's mean patch variance)."""
    r = n // 2
    sa = channel_stats(A[None], n)
    sb = channel_stats(B[None], n)
    isA = inv_sigma(sa["var"], tau_rel * float(sa["mean_var"][0]))
    isB = inv_sigma(sb["var"], tau_rel * float(sb["mean_var"][0]))
    return (pad_replicate(A[None], r), pad_replicate(B[None], r), sa["centre"], sb["centre"],
            sa["mu"], isA, sb["mu"], isB)


def _ncc_scores(setup, ds, r, impl) -> np.ndarray:
    """NCC ``xi`` (float64 ``(len(ds), H, W)``, 0 at invalid candidates) at disparities ``ds``
    of two maps prepared by :func:`_ncc_setup`; each disparity is computed on its own, so
    blocks of ``ds`` give exactly the slices of the whole volume."""
    H, W = setup[4].shape[1:]
    acc = np.zeros((len(ds), H, W))
    _xcorr(impl, *setup, ds, r, False, acc, acc)
    return acc


def _label_blocks(n_labels: int, shape) -> list[slice]:
    """Consecutive label slices of at most :data:`NCC_BLOCK_BYTES` of float64 each."""
    step = max(1, NCC_BLOCK_BYTES // (8 * int(np.prod(shape))))
    return [slice(k, min(k + step, n_labels)) for k in range(0, n_labels, step)]


def ncc_volume(left, right, dmin, dmax, window: int = 5, impl: str = "auto",
               tau_rel: float = 1e-5) -> np.ndarray:
    """``1 - NCC`` of intensities over ``window x window`` patches; float32 ``(L, H, W)``.

    NCC is taken as 0 where either patch's variance is below ``tau_rel`` times that view's
    mean patch variance (and where it is exactly 0).

    Examples
    --------
    NCC ignores gain and offset: the right image moved 3 px to the right, times 2 plus 1, has
    NCC 1 (cost 0) at disparity 3 on columns 6 to 20, clear of the borders and of the columns
    ``np.roll`` wrapped round, and costs more at the other disparities:

    >>> import numpy as np
    >>> from hyperlf.costs import ncc_volume
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> left = 2.0 * np.roll(right, 3, axis=1) + 1.0
    >>> C = ncc_volume(left, right, 0, 6)
    >>> np.unique(C.argmin(axis=0)[:, 6:-3]).tolist(), round(float(C[3, :, 6:-3].max()), 3)
    ([3], 0.0)
    """
    L, R = check_pair(left, right)
    dmin, dmax = check_disp(dmin, dmax, L.shape)
    n = check_window(window, side=max(L.shape))
    impl = check_impl(impl, "ncc")
    tau_rel = _constants(tau_rel=tau_rel)["tau_rel"]
    ds, setup = _ds(dmin, dmax), _ncc_setup(L, R, n, tau_rel)
    out = np.empty((len(ds),) + L.shape, np.float32)
    for sl in _label_blocks(len(ds), L.shape):
        out[sl] = 1.0 - _ncc_scores(setup, ds[sl], n // 2, impl)
    return fill_out_of_image(out, dmin)


def rsncc_volume(left, right, dmin, dmax, window: int = 5, impl: str = "auto",
                 rs_tau: float = 1.0, tau_rel: float = 1e-5) -> np.ndarray:
    """RSNCC (Shen et al. 2014): ``rho(1 - NCC(In)) + rs_tau * rho(1 - NCC(|grad In|))``.

    Examples
    --------
    RSNCC matches across a contrast reversal: the right image moved 3 px to the right and
    reversed (``2 - I``) has intensity NCC -1 and gradient NCC 1 at disparity 3, a cost of
    ``rho(2) + rho(0) = 2 rho(0)`` as for an exact copy (columns 6 to 20, clear of the borders
    and of the columns ``np.roll`` wrapped round), and costs more at the other disparities:

    >>> import numpy as np
    >>> from hyperlf.costs import rho, rsncc_volume
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> C = rsncc_volume(2.0 - np.roll(right, 3, axis=1), right, 0, 6)
    >>> np.unique(C.argmin(axis=0)[:, 6:-3]).tolist(), round(float(C[3, :, 6:-3].max()), 3)
    ([3], -0.254)
    >>> round(2 * float(rho(0.0)), 3)
    -0.254
    """
    L, R = check_pair(left, right)
    dmin, dmax = check_disp(dmin, dmax, L.shape)
    n = check_window(window, side=max(L.shape))
    impl = check_impl(impl, "rsncc")
    c = _constants(rs_tau=rs_tau, tau_rel=tau_rel)
    rs_tau, tau_rel = c["rs_tau"], c["tau_rel"]
    Ln, Rn = normalise_intensity(L), normalise_intensity(R)
    ds = _ds(dmin, dmax)
    set_i = _ncc_setup(Ln, Rn, n, tau_rel)
    set_g = _ncc_setup(gradient_magnitude(Ln), gradient_magnitude(Rn), n, tau_rel)
    out = np.empty((len(ds),) + L.shape, np.float32)
    for sl in _label_blocks(len(ds), L.shape):  # float64 per block, as for the whole volume
        xi_i = _ncc_scores(set_i, ds[sl], n // 2, impl)
        xi_g = _ncc_scores(set_g, ds[sl], n // 2, impl)
        rsncc_rho(xi_i, xi_g, rs_tau, out[sl], impl)
    return fill_out_of_image(out, dmin)


def census_transform(image, window: int = 7) -> np.ndarray:
    """Census codes, uint64 ``(H, W)``: one bit per neighbour in the ``window x window``
    square (row-major, centre skipped), set where ``neighbour < centre`` (strict), replicate
    border.  ``window`` <= 7 (at most 63 bits).

    Examples
    --------
    The centre 4 of a 3 x 3 patch has the neighbours 5, 1, 7, 2, 9, 3, 8, 6 in row order; those
    below it are bits 1, 3 and 5, so its code is ``2 + 8 + 32 = 42``:

    >>> import numpy as np
    >>> from hyperlf.costs import census_transform
    >>> code = census_transform(np.array([[5, 1, 7], [2, 4, 9], [3, 8, 6]]), 3)
    >>> code.dtype.name, int(code[1, 1]), bin(int(code[1, 1]))
    ('uint64', 42, '0b101010')
    """
    img = np.asarray(check_map(image, "image", 2), dtype=np.float64)
    n = check_window(window)
    if n * n - 1 > 64:
        raise InvalidInputError(f"census window must be <= 7 (64 bits), got {n}")
    r = n // 2
    p = pad_replicate(img, r)
    H, W = img.shape
    code = np.zeros((H, W), np.uint64)
    bit = 0
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            if dy == 0 and dx == 0:
                continue
            nb = p[r + dy:r + dy + H, r + dx:r + dx + W]
            code |= (nb < img).astype(np.uint64) << np.uint64(bit)
            bit += 1
    return code


def support_weights(image, window: int = 7, gamma: float = 0.1) -> np.ndarray:
    """Adaptive support weights (Yoon & Kweon 2006) of every pixel's census neighbours,
    float32 ``(H, W, window**2 - 1)`` in the bit order of :func:`census_transform`:
    ``exp(-|I(q) - I(p)| / gamma)``, ``I`` the image over its 1st-99th percentile spread (so
    ``gamma`` is a share of the image's range, whatever its gain and offset), replicate
    border.  A neighbour across an intensity edge, likely on another surface, weighs little;
    no weight is below ``1e-6``, so that every window has some support.  ``gamma``: a number
    > 0, else :class:`~hyperlf.errors.InvalidInputError`.
    """
    gamma = number(gamma, "support_gamma (None for the plain census)", positive=True)
    n = check_window(window)
    img = np.asarray(image, dtype=np.float64)
    lo, hi = np.percentile(img, [1.0, 99.0])
    a = img / max(hi - lo, 1e-12)
    r = n // 2
    p = pad_replicate(a, r)
    H, W = a.shape
    out = np.empty((H, W, n * n - 1), np.float32)
    k = 0
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            if dy == 0 and dx == 0:
                continue
            w = np.exp(-np.abs(p[r + dy:r + dy + H, r + dx:r + dx + W] - a) / gamma)
            out[:, :, k] = np.maximum(w, 1e-6)
            k += 1
    return out


def _weighted_hamming_numpy(cl, cr, wl, wr, ds, out) -> None:
    """The reference of ``_kernels.weighted_hamming_volume``: one disparity at a time."""
    H, W = cl.shape
    bits = np.arange(wl.shape[2], dtype=np.uint64)
    for k, d in enumerate(ds):
        x0, x1 = max(0, d), min(W, W + d)
        if x1 <= x0:
            continue
        diff = ((cl[:, x0:x1] ^ cr[:, x0 - d:x1 - d])[..., None] >> bits) & np.uint64(1)
        w = wl[:, x0:x1].astype(np.float64) * wr[:, x0 - d:x1 - d]
        out[k, :, x0:x1] = len(bits) * (w * diff).sum(-1) / w.sum(-1)


def census_volume(left, right, dmin, dmax, window: int = 7, impl: str = "auto", *,
                  support_gamma: float | None = None) -> np.ndarray:
    """Hamming distance between census codes of ``(y, x)`` and ``(y, x - d)``; float32.

    ``support_gamma``: None counts every differing bit once; a number weighs bit ``k`` by
    ``w_L,k(y, x) w_R,k(y, x - d)`` (:func:`support_weights` of each image in its own band)
    and scales the weighted share of differing bits back to bits (``(n^2 - 1) sum w [bit
    differs] / sum w``), so that neighbours on another surface than the centre, where
    foreground and background meet, hardly count.  Symmetric in the two images, so the
    right-referenced volume is still a shift of this one.

    Examples
    --------
    The right image moved 3 px to the right differs in no bit at disparity 3 on columns 6 to 20
    (clear of the borders and of the columns ``np.roll`` wrapped round).  Census codes only
    compare intensities, so squaring the (positive) left image changes nothing:

    >>> import numpy as np
    >>> from hyperlf.costs import census_volume
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> left = np.roll(right, 3, axis=1)
    >>> C = census_volume(left, right, 0, 6)
    >>> np.unique(C.argmin(axis=0)[:, 6:-3]).tolist(), float(C[3, :, 6:-3].max())
    ([3], 0.0)
    >>> bool(np.array_equal(census_volume(left ** 2, right, 0, 6), C))
    True
    """
    L, R = check_pair(left, right)
    dmin, dmax = check_disp(dmin, dmax, L.shape)
    impl = check_impl(impl, "census")
    cl = census_transform(L, window)
    cr = census_transform(R, window)
    H, W = L.shape
    ds = _ds(dmin, dmax)
    out = np.zeros((len(ds), H, W), np.float32)
    if support_gamma is not None:
        wl, wr = (support_weights(im, window, support_gamma) for im in (L, R))
        if impl == "numba":
            from . import _kernels
            _kernels.weighted_hamming_volume(cl, cr, wl, wr, ds, out)
        else:
            _weighted_hamming_numpy(cl, cr, wl, wr, ds, out)
    elif impl == "numba":
        from . import _kernels
        _kernels.hamming_volume(cl, cr, ds, out)
    else:
        for k, d in enumerate(ds):
            out[k] = np.bitwise_count(cl ^ shift_cols(cr, int(d))).astype(np.float32)
    return fill_out_of_image(out, dmin)


# --------------------------------------------------------------------------------------------
# BWNCC (SPEC §3)
# --------------------------------------------------------------------------------------------


def bwncc_finish(acc_fwd, acc_bwd, den_fwd, den_bwd, eps: float = 1e-3, return_scores=False):
    """``S_fwd = acc_fwd / den_fwd``, ``S_bwd = acc_bwd / den_bwd`` (0 where a denominator is
    0), ``BWNCC = sqrt(max(S_fwd, 0) max(S_bwd, 0))``, cost ``-log(max(BWNCC, eps))``.

    ``acc_fwd``, ``acc_bwd``: float arrays of one shape; ``den_fwd``, ``den_bwd``: arrays of
    real numbers broadcastable to it; ``eps`` in ``(0, 1e6]``.  Checked in O(1) (shapes and
    dtypes; an overflow of the scores is refused, NaNs are not searched for).

    Examples
    --------
    Scores of 0.5 both ways (1 / 2 and 0.5 / 1) give BWNCC 0.5, cost ``-log 0.5``; a negative
    score gives BWNCC 0, floored at ``eps``, cost ``-log 0.001``:

    >>> import math
    >>> import numpy as np
    >>> from hyperlf.costs import bwncc_finish
    >>> acc_fwd, acc_bwd = np.array([1.0, -0.2]), np.array([0.5, 0.3])
    >>> cost = bwncc_finish(acc_fwd, acc_bwd, np.array([2.0, 1.0]), np.ones(2))
    >>> [round(float(c), 3) for c in cost]
    [0.693, 6.908]
    >>> round(-math.log(0.5), 3), round(-math.log(1e-3), 3)
    (0.693, 6.908)
    """
    c = _constants(eps=eps, return_scores=return_scores)
    eps, return_scores = c["eps"], c["return_scores"]
    for label, acc in (("acc_fwd", acc_fwd), ("acc_bwd", acc_bwd)):
        if not (isinstance(acc, np.ndarray) and acc.ndim and acc.dtype.kind == "f"):
            raise InvalidInputError(f"{label} must be a float numpy array (L, H, W), got "
                                    f"{shown(acc)}")
    shape = acc_fwd.shape
    den_fwd, den_bwd = (check_map(a, label, tuple(range(acc_fwd.ndim + 1)))
                        for a, label in ((den_fwd, "den_fwd"), (den_bwd, "den_bwd")))
    for label, a in (("acc_bwd", acc_bwd), ("den_fwd", den_fwd), ("den_bwd", den_bwd)):
        try:
            fits = np.broadcast_shapes(a.shape, shape) == shape
        except ValueError:
            fits = False
        if not fits or (label == "acc_bwd" and a.shape != shape):
            raise InvalidInputError(f"{label} of shape {a.shape} does not fit acc_fwd's {shape}")
    try:
        with np.errstate(over="raise"):
            Sf = np.divide(acc_fwd, den_fwd, out=np.zeros_like(acc_fwd), where=den_fwd > 0)
            Sb = np.divide(acc_bwd, den_bwd, out=np.zeros_like(acc_bwd), where=den_bwd > 0)
            B = np.sqrt(np.maximum(Sf, 0.0) * np.maximum(Sb, 0.0))
    except FloatingPointError:
        raise InvalidInputError("the BWNCC scores acc / den overflow: the denominators are "
                                "too small for the sums") from None
    cost = -np.log(np.maximum(B, eps))
    if return_scores:
        return cost, Sf, Sb, B
    return cost


# bw_accum work partition (measured on Teddy 450 x 375, 60 disparities, 2 cores)
_BW_BAND = 8    # rows per parallel band
_BW_DC = 12     # disparities per chunk (channel-outer inside a chunk; local accumulators in L2)
_BW_TILE = 16   # columns per skip tile


class _BwnccAccumulator:
    """Float64 accumulators ``(L, H, W)`` of ``sum_i xi_i hbar`` plus ``(H, W)`` weight sums."""

    def __init__(self, H, W, dmin, dmax, impl):
        self.ds = _ds(dmin, dmax)
        self.dmin = dmin
        self.H, self.W = H, W
        self.accF = np.zeros((len(self.ds), H, W))
        self.accB = np.zeros((len(self.ds), H, W))
        self.denL = np.zeros((H, W))
        self.denR = np.zeros((H, W))
        self.impl = impl
        self.t_stats = 0.0  # seconds in statistics / 1/sigma (numba path)
        self.t_xterm = 0.0  # seconds in cross terms (numba path)

    def add_block(self, A, B, n_per_channel, tau_rel, tau_abs_A=None, tau_abs_B=None):
        """Add one block of channels (A: left, B: right, (nc, H, W)).  ``tau`` is ``tau_rel``
        times the mean patch variance of the block's channels (per view), unless absolute
        values ``tau_abs_*`` are given."""
        ns = np.broadcast_to(np.asarray(n_per_channel, np.int64), (A.shape[0],))
        if self.impl == "numba":
            self._add_block_numba(A, B, ns, tau_rel, tau_abs_A, tau_abs_B)
            return
        sa = channel_stats(A, ns)
        sb = channel_stats(B, ns)
        tA = tau_rel * float(sa["mean_var"].mean()) if tau_abs_A is None else tau_abs_A
        tB = tau_rel * float(sb["mean_var"].mean()) if tau_abs_B is None else tau_abs_B
        self.denL += sa["mu"].sum(axis=0)
        self.denR += sb["mu"].sum(axis=0)
        for n in np.unique(ns):
            sel = np.nonzero(ns == n)[0]
            r = int(n) // 2
            _xcorr(self.impl, pad_replicate(A[sel], r), pad_replicate(B[sel], r),
                   sa["centre"][sel], sb["centre"][sel],
                   np.ascontiguousarray(sa["mu"][sel]), inv_sigma(sa["var"][sel], tA),
                   np.ascontiguousarray(sb["mu"][sel]), inv_sigma(sb["var"][sel], tB),
                   self.ds, r, True, self.accF, self.accB)

    def _buf(self, key, shape, dtype=np.float64):
        """Reusable work array (fresh large allocations cost page faults on every block)."""
        if not hasattr(self, "_ws"):
            self._ws = {}
        a = self._ws.get(key)
        if a is None or a.shape != tuple(shape) or a.dtype != dtype:
            a = np.empty(shape, dtype)
            self._ws[key] = a
        return a

    def _add_block_numba(self, A, B, ns, tau_rel, tau_abs_A, tau_abs_B):
        """Fast path (:mod:`hyperlf.costs._kernels` ``bw_*``): statistics and ``1/sigma`` in numba, then
        the cross terms with exact skipping of column tiles where ``xi = 0``.  Same formulas
        and float64 numerics as the reference path; the result agrees with ``impl="numpy"``
        to rounding (tests)."""
        import time
        t0 = time.perf_counter()
        from . import _kernels as K
        A = np.ascontiguousarray(A)
        B = np.ascontiguousarray(B)
        if A.dtype not in (np.float32, np.float64):
            A = A.astype(np.float64)
        if B.dtype != A.dtype:
            B = B.astype(A.dtype)
        nc, H, W = A.shape
        ns = np.ascontiguousarray(ns, np.int64)
        stats = []
        for v, X in (("A", A), ("B", B)):
            mu_c = self._buf("mu" + v, (nc, H, W))
            var = self._buf("var" + v, (nc, H, W))
            cen = np.empty(nc)
            K.bw_channel_stats(X, ns, mu_c, var, cen)
            stats.append((mu_c, var, cen))
        (mA, vA, cA), (mB, vB, cB) = stats
        # tau: tau_rel times the mean patch variance over the block's channels (per view)
        tA = tau_rel * float(vA.mean()) if tau_abs_A is None else tau_abs_A
        tB = tau_rel * float(vB.mean()) if tau_abs_B is None else tau_abs_B
        K.bw_inv_sigma(vA, float(tA))
        K.bw_inv_sigma(vB, float(tB))
        K.bw_den_add(mA, cA, self.denL)
        K.bw_den_add(mB, cB, self.denR)
        t1 = time.perf_counter()
        self.t_stats += t1 - t0
        for n in np.unique(ns):
            sel = np.nonzero(ns == n)[0]
            every = len(sel) == nc
            r = int(n) // 2
            pick = (lambda X: X) if every else (lambda X: np.ascontiguousarray(X[sel]))
            pads = []
            for v, X in (("A", A), ("B", B)):
                Xs = pick(X)
                P = self._buf("pad" + v, (len(sel), H + 2 * r, W + 2 * r), Xs.dtype)
                K.bw_pad(Xs, r, P)
                pads.append(P)
            K.bw_accum(pads[0], pads[1],
                          np.ascontiguousarray(cA[sel]), np.ascontiguousarray(cB[sel]),
                          pick(mA), pick(vA), pick(mB), pick(vB), self.ds, r,
                          self.accF, self.accB, _BW_BAND, _BW_DC, _BW_TILE)
        self.t_xterm += time.perf_counter() - t1

    def finish(self, eps, return_scores=False):
        if self.impl == "numba" and not return_scores:
            self._ws = {}
            cost = np.empty(self.accF.shape, np.float32)
            from . import _kernels
            _kernels.bw_finish(self.accF, self.accB, self.denL, self.denR, self.ds,
                                        float(eps), cost)
            return cost
        den_b = np.stack([shift_cols(self.denR, int(d)) for d in self.ds])
        res = bwncc_finish(self.accF, self.accB, self.denL[None], den_b, eps, return_scores)
        cost = res[0] if return_scores else res
        cost = fill_out_of_image(cost.astype(np.float32), self.dmin)
        return (cost,) + tuple(res[1:]) if return_scores else cost


def _check_patch_sizes(n, shape, side: int | None = None) -> None:
    """``n``: one odd NCC patch size, or one per channel of ``(nc, H, W)`` stacks, within the
    images (``side``: their longer side by default; a negative size corrupted the kernels'
    memory)."""
    try:
        ns = np.broadcast_to(np.asarray(n, dtype=object), (shape[0],))
    except ValueError:
        raise InvalidInputError(f"n must be one patch size or {shape[0]} (one per channel), "
                                f"got {shown(n)}") from None
    for v in ns:
        check_window(v, "n", side=max(shape[1:]) if side is None else side)


def bwncc_from_descriptors(desc_left, desc_right, dmin, dmax, n=5, tau_rel: float = 1e-5,
                           eps: float = 1e-3, impl: str = "auto", return_scores: bool = False):
    """BWNCC cost volume from in-memory channel stacks ``(nc, H, W)`` of the two views.

    ``n``: NCC patch size, an int or one per channel.  ``tau`` = ``tau_rel`` times the mean
    patch variance over all given channels of each view.  With ``return_scores`` also returns
    float64 ``S_fwd, S_bwd, BWNCC`` volumes (0 at invalid candidates).

    Examples
    --------
    Three random channels and the same channels moved 3 px to the right: at disparity 3 every
    channel's NCC is 1, so both scores and BWNCC are 1 and the cost ``-log 1 = 0`` (columns 6
    to 20, clear of the borders and of the columns ``np.roll`` wrapped round):

    >>> import numpy as np
    >>> from hyperlf.costs import bwncc_from_descriptors
    >>> right = np.random.default_rng(0).random((3, 16, 24)) + 0.5
    >>> left = np.roll(right, 3, axis=2)
    >>> cost, s_fwd, s_bwd, score = bwncc_from_descriptors(left, right, 0, 6, n=5,
    ...                                                    return_scores=True)
    >>> np.unique(cost.argmin(axis=0)[:, 6:-3]).tolist()
    [3]
    >>> round(float(score[3, :, 6:-3].min()), 3), round(float(np.abs(cost[3, :, 6:-3]).max()), 3)
    (1.0, 0.0)
    """
    A = np.asarray(desc_left)
    B = np.asarray(desc_right)
    if A.ndim != 3 or A.shape != B.shape:
        raise InvalidInputError(f"descriptor stacks must be (nc, H, W) of equal shape, got {A.shape}, {B.shape}")
    dmin, dmax = check_disp(dmin, dmax, A.shape)
    impl = check_impl(impl, "bwncc")
    _check_patch_sizes(n, A.shape)
    c = _constants(tau_rel=tau_rel, eps=eps, return_scores=return_scores)
    tau_rel, eps, return_scores = c["tau_rel"], c["eps"], c["return_scores"]
    acc = _BwnccAccumulator(A.shape[1], A.shape[2], dmin, dmax, impl)
    acc.add_block(A, B, n, tau_rel)
    return acc.finish(eps, return_scores)


def _descriptor_params(variant):
    from ..descriptor import DescriptorParams
    if isinstance(variant, DescriptorParams):
        return variant
    if isinstance(variant, str) and variant in ("default", "bwncc"):
        return DescriptorParams.default()
    if isinstance(variant, str) and variant in ("paper", "bwncc-paper"):
        return DescriptorParams.paper()
    raise InvalidInputError("descriptor variant must be 'default', 'paper' or a DescriptorParams, "
                            f"got {shown(variant)}")


def _patch_sizes(params, variant, window, side: int) -> np.ndarray:
    """NCC patch size per descriptor channel (see :func:`bwncc_volume`, ``window``) for images
    of ``side`` px on their longer side."""
    if window is None:
        is_paper = isinstance(variant, str) and variant in ("paper", "bwncc-paper")
        return np.full(params.n_channels, 5, np.int64) if is_paper else params.channel_levels
    return np.full(params.n_channels, check_window(window, side=side), np.int64)


def _view_scope_taus(pL, pR, n_all, block, tau_rel, descriptor_impl):
    """``tau_scope="view"``: thresholds from the mean patch variance over all channels of each
    view (one extra pass over the descriptor).  Returns ``(tauA, tauB, t_desc, t_stats)``."""
    import time
    from ..descriptor import descriptor
    n_channels = pL.params.n_channels
    mvA, mvB, cnt = 0.0, 0.0, 0
    t_desc = t_stats = 0.0
    for start in range(0, n_channels, block):
        sl = slice(start, min(start + block, n_channels))
        t0 = time.perf_counter()
        A = descriptor(pL, channels=sl, impl=descriptor_impl)
        B = descriptor(pR, channels=sl, impl=descriptor_impl)
        t_desc += time.perf_counter() - t0
        t0 = time.perf_counter()
        for c in range(A.shape[0]):
            mvA += float(window_stats(A[c], int(n_all[sl][c]))[1].mean())
            mvB += float(window_stats(B[c], int(n_all[sl][c]))[1].mean())
        cnt += A.shape[0]
        t_stats += time.perf_counter() - t0
    return tau_rel * mvA / cnt, tau_rel * mvB / cnt, t_desc, t_stats


def bwncc_volume(left, right, dmin, dmax, variant="default", window=None, tau_rel: float = 1e-5,
                 tau_scope: str = "block", eps: float = 1e-3, block: int | None = None,
                 impl: str = "auto", descriptor_impl: str = "auto", return_scores: bool = False,
                 timings: dict | None = None):
    """BWNCC cost volume (SPEC §3), streaming descriptor channels in blocks.

    Parameters
    ----------
    variant : "default" (metric ``bwncc``), "paper" (``bwncc-paper``) or a DescriptorParams.
    window : None or odd int
        NCC patch ``n``.  None: ``n = w`` (the channel's descriptor window) for ``"default"``,
        ``n = 5`` for ``"paper"``; an int applies to all channels.
    tau_rel : float
        ``tau_var = tau_rel *`` mean channel patch variance of the view, where the mean runs
        over the channels of the current block (``tau_scope="block"``; with the default
        ``block = n_bins = 68`` one block is exactly one histogram h1/h2/h3 of one level, as in
        the prototype) or over all channels (``tau_scope="view"``: needs a first pass that
        computes every block once more, ~+descriptor time).  The choice matters little
        (prototype notes §2).
    block : channels per block (default ``params.n_bins``).  Memory ~ 2 float64 ``(L, H, W)``
        accumulators + ~40 bytes * block * H * W (numba path: reused work buffers).
    timings : optional dict, filled with ``descriptor_s`` and ``cross_s`` (seconds).

    Returns float32 ``(L, H, W)`` costs (and ``S_fwd, S_bwd, BWNCC`` with ``return_scores``).
    Never holds more than one block of each view's descriptor.

    Examples
    --------
    The right image moved 3 px to the right is found at disparity 3 on columns 6 to 20 (clear
    of the borders and of the columns ``np.roll`` wrapped round):

    >>> import numpy as np
    >>> from hyperlf.costs import bwncc_volume
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> left = np.roll(right, 3, axis=1)
    >>> C = bwncc_volume(left, right, 0, 6)
    >>> C.shape, C.dtype.name, np.unique(C.argmin(axis=0)[:, 6:-3]).tolist()
    ((7, 16, 24), 'float32', [3])
    """
    import time
    from ..descriptor import iter_descriptor_blocks, prepare

    L, R = check_pair(left, right)
    dmin, dmax = check_disp(dmin, dmax, L.shape)
    impl = check_impl(impl, "bwncc")
    params = _descriptor_params(variant)
    c = _constants(tau_rel=tau_rel, tau_scope=tau_scope, eps=eps, block=block,
                   return_scores=return_scores)
    tau_rel, eps, return_scores = c["tau_rel"], c["eps"], c["return_scores"]
    choice(descriptor_impl, "descriptor_impl", ("auto", "numpy", "numba"))
    if timings is not None and not isinstance(timings, dict):
        raise InvalidInputError(f"timings must be a dict to fill (or None), got {shown(timings)}")
    n_all = _patch_sizes(params, variant, window, max(L.shape))
    block = params.n_bins if c["block"] is None else c["block"]
    t0 = time.perf_counter()
    pL = prepare(L, params)
    pR = prepare(R, params)
    t_desc = time.perf_counter() - t0
    t_cross = 0.0
    tauA = tauB = None
    if tau_scope == "view":
        tauA, tauB, t_d, t_cross = _view_scope_taus(pL, pR, n_all, block, tau_rel,
                                                    descriptor_impl)
        t_desc += t_d
    acc = _BwnccAccumulator(L.shape[0], L.shape[1], dmin, dmax, impl)
    t_d, t_c = _accumulate_blocks(acc, iter_descriptor_blocks(pL, block=block,
                                                              impl=descriptor_impl),
                                  iter_descriptor_blocks(pR, block=block, impl=descriptor_impl),
                                  n_all, tau_rel, tauA, tauB)
    t_desc, t_cross = t_desc + t_d, t_cross + t_c
    t0 = time.perf_counter()
    res = acc.finish(eps, return_scores)
    t_fin = time.perf_counter() - t0
    t_cross += t_fin
    if timings is not None:
        timings["descriptor_s"] = t_desc
        timings["cross_s"] = t_cross
        timings["finish_s"] = t_fin
        if impl == "numba":
            timings["stats_s"] = acc.t_stats
            timings["xterm_s"] = acc.t_xterm
    return res


def _accumulate_blocks(acc, blocks_left, blocks_right, n_all, tau_rel, tauA, tauB):
    """Both views' descriptor blocks, one pair at a time, into ``acc``: the seconds spent
    making the blocks and matching them."""
    import time

    t_desc = t_cross = 0.0
    while True:
        t0 = time.perf_counter()
        try:
            slA, A = next(blocks_left)
            slB, B = next(blocks_right)
        except StopIteration:
            break
        t_desc += time.perf_counter() - t0
        t0 = time.perf_counter()
        acc.add_block(A, B, n_all[slA], tau_rel, tauA, tauB)
        del A, B
        t_cross += time.perf_counter() - t0
    return t_desc, t_cross


# --------------------------------------------------------------------------------------------
# Fusion
# --------------------------------------------------------------------------------------------


def row_moments(cost, valid) -> tuple:
    """Per-row moments of the valid entries of a cost volume: the pieces of its global
    standard deviation that a strip of rows can compute alone.

    Parameters
    ----------
    cost : ndarray, shape (L, h, W)
    valid : array_like of bool, broadcastable to ``cost``

    Returns
    -------
    n, mean, m2 : ndarray, shape (h,)
        Count (int64), mean and sum of squared deviations (float64) of row ``y``'s valid
        entries over every label.  Rows of strips concatenated in row order give exactly the
        whole volume's moments (the kernel works row by row); :func:`moments_std` joins them.

    Examples
    --------
    The volume 0 .. 11 as two labels of 2 x 3: row 0 holds 0, 1, 2 and 6, 7, 8 (mean 4, squared
    deviations ``16 + 9 + 4 + 4 + 9 + 16 = 58``), row 1 the same plus 3 (mean 7, again 58):

    >>> import numpy as np
    >>> from hyperlf.costs import row_moments
    >>> C = np.arange(12.0).reshape(2, 2, 3)
    >>> n, mean, m2 = row_moments(C, np.ones(C.shape, bool))
    >>> n.tolist(), mean.tolist(), m2.tolist()
    ([6, 6], [4.0, 7.0], [58.0, 58.0])
    """
    from ._kernels import row_moments as kernel

    C = kernel_input(_kernel_float(_volume(cost, "cost")))
    ok = kernel_input(bool_mask(valid, "valid", C.shape, broadcast=True, of="the cost"))
    h = C.shape[1]
    n, mean, m2 = np.zeros(h, np.int64), np.zeros(h), np.zeros(h)
    kernel(C, ok, n, mean, m2)
    return n, mean, m2


def _kernel_float(cost) -> np.ndarray:
    """``cost`` C-contiguous as float32 or float64 (float64 for any other dtype), the dtypes
    the normalisation kernels are compiled for; a copy only where needed."""
    C = np.ascontiguousarray(cost)
    return C if C.dtype in (np.float32, np.float64) else C.astype(np.float64)


def moments_std(n, mean, m2) -> float:
    """The standard deviation of every entry that :func:`row_moments` counted (rows joined in
    order, float64); 0 when none was valid.

    ``n``, ``mean``, ``m2``: one entry per row each (1-D, of one length), as
    :func:`row_moments` gives them: counts (integers >= 0), finite means, finite sums >= 0.

    Examples
    --------
    The rows of :func:`row_moments`' example, joined, give the standard deviation of all twelve
    entries:

    >>> import numpy as np
    >>> from hyperlf.costs import moments_std, row_moments
    >>> C = np.arange(12.0).reshape(2, 2, 3)
    >>> round(moments_std(*row_moments(C, np.ones(C.shape, bool))), 6), round(float(C.std()), 6)
    (3.452053, 3.452053)
    """
    from ._kernels import combine_moments

    n_, mean_, m2_ = (check_map(v, k, 1, empty=True) for v, k in ((n, "n"), (mean, "mean"),
                                                                   (m2, "m2")))
    if not n_.shape == mean_.shape == m2_.shape:
        raise InvalidInputError(f"n, mean and m2 must have one entry per row each, got shapes "
                                f"{n_.shape}, {mean_.shape}, {m2_.shape}")
    with np.errstate(invalid="ignore"):
        ok = (np.isfinite(n_).all() and (n_ >= 0).all() and (n_ == np.round(n_)).all()
              and (n_ < 2 ** 62).all() and np.isfinite(mean_).all() and np.isfinite(m2_).all()
              and (m2_ >= 0).all())  # one entry per row: small
    if not ok:
        raise InvalidInputError("n must be counts (integers >= 0), mean and m2 finite and m2 "
                                ">= 0 (row_moments' moments)")
    return float(combine_moments(np.ascontiguousarray(n, np.int64),
                                 np.ascontiguousarray(mean, np.float64),
                                 np.ascontiguousarray(m2, np.float64))[0])


#: How :func:`normalise_volume` centres each pixel's costs: on their minimum (SPEC §3, the
#: rectified pair), their mean, or not at all (a scale only).
NORMALISE_CENTRES = ("min", "mean", "none")


def normalise_volume(cost, dmin: int, valid=None, *, sd: float | None = None,
                     impl: str = "auto", overwrite: bool = False,
                     centre: str = "min") -> np.ndarray:
    """``norm(C)`` of SPEC §3 fusion, float32.

    Invalid entries -> the pixel's worst valid cost (:func:`fill_out_of_image`), minus the per-pixel
    minimum, divided by the **global** standard deviation of the valid raw entries of ``C``.
    (Global, not per-pixel: that is what the prototype measured — "divided by the std of the
    valid raw entries" — and a per-pixel std would inflate flat, uninformative pixels.)  A
    constant volume (std 0) is only min-subtracted.  ``sd``: that standard deviation when it
    was measured elsewhere (a strip of rows of a larger volume: :func:`row_moments`), else
    measured on ``cost``.  ``centre`` (:data:`NORMALISE_CENTRES`): ``"min"`` subtracts the
    per-pixel minimum over the valid entries as above, ``"mean"`` their mean, ``"none"``
    nothing (only the scale).  ``impl="numba"`` (the ``"auto"`` choice) runs the same arithmetic
    in kernels without the float64 copies; its standard deviation is summed row by row
    (:func:`row_moments`, :func:`moments_std`), so it agrees with ``"numpy"`` to rounding
    (``rtol`` 1e-12).  ``overwrite``: under ``"numba"``, a C-contiguous float32 ``cost`` is
    normalised in place and returned (the same numbers, one volume less).

    Examples
    --------
    Two pixels, two labels, costs (1, 5) and (5, 1): each pixel loses its minimum 1, and the
    entries 1, 5, 5, 1 have mean 3 and standard deviation 2, so each becomes ``(0, 4) / 2``:

    >>> import numpy as np
    >>> from hyperlf.costs import normalise_volume
    >>> C = np.array([[[1.0, 5.0]], [[5.0, 1.0]]])      # (labels, rows, columns)
    >>> normalise_volume(C, 0, np.ones(C.shape, bool))[:, 0].T.tolist()    # per pixel
    [[0.0, 2.0], [2.0, 0.0]]
    """
    impl = check_impl(impl, "normalise")
    choice(centre, "centre", NORMALISE_CENTRES)
    Lc, H, W = _volume(cost, "cost").shape
    dmin = check_dmin(dmin)
    sd = check_scale(sd, "sd")
    overwrite = flag(overwrite, "overwrite")
    if valid is None:
        valid = candidate_validity((H, W), dmin, dmin + Lc - 1)
    else:
        bool_mask(valid, "valid", (Lc, H, W), broadcast=True, of="the cost")
    if impl == "numba":
        from ._kernels import normalise_fill

        C = _kernel_float(cost)
        ok = kernel_input(np.broadcast_to(np.asarray(valid, bool), C.shape))
        if sd is None:
            sd = moments_std(*row_moments(C, ok))
        out = C if overwrite and _own_float32(cost, C) else np.empty(C.shape, np.float32)
        # reads a pixel's costs before writing them
        normalise_fill(kernel_input(C), ok, float(sd), NORMALISE_CENTRES.index(centre), out)
        return out
    C = np.array(cost, dtype=np.float64)
    ok = np.broadcast_to(np.asarray(valid, bool), C.shape)
    if sd is None:
        vals = C[ok]
        sd = float(vals.std()) if vals.size else 0.0
    if centre == "mean":
        n = ok.sum(axis=0)
        level = np.where(n > 0, np.where(ok, C, 0.0).sum(axis=0) / np.maximum(n, 1), 0.0)
    fill_out_of_image(C, dmin, valid)
    if centre == "min":
        C -= C.min(axis=0, keepdims=True)
    elif centre == "mean":
        C -= level
    if sd > 0:
        C /= sd
    return C.astype(np.float32)


def _own_float32(given, array) -> bool:
    """``array`` is the float32, C-contiguous ``given`` itself, owning its memory (so no view
    of another array, such as a cache, is written over)."""
    return array is given and array.dtype == np.float32 and array.flags.c_contiguous \
        and array.flags.writeable and array.flags.owndata


def weights_tuple(weights) -> tuple | None:
    """``weights`` as a tuple of floats if they are a sequence of finite numbers >= 0, not
    all 0, with a finite sum (of any length), else None: the rule every fusion weight follows
    (the count is the cost's to check, :meth:`hyperlf.costs.FusedCost.check_weights`)."""
    try:
        w = () if isinstance(weights, (str, bytes, Mapping)) else \
            tuple(number(x, "weight") for x in weights)
    except (TypeError, InvalidInputError):  # not a sequence, or an entry not a number >= 0
        return None
    return w if any(w) and math.isfinite(sum(w)) else None


def fuse(volumes: Sequence[np.ndarray], weights: Sequence[float] | None = None, dmin: int = 0,
         valid=None, *, scales: Sequence[float] | None = None, impl: str = "auto",
         overwrite: bool = False, centre: str = "min") -> np.ndarray:
    """Weighted mean of normalised volumes: ``sum_i w_i norm(C_i) / sum_i w_i``; then the
    out-of-image rule again (the fused worst valid cost).  ``dmin`` is needed only to know
    which entries are invalid (the volumes must share ``dmin..dmax``).  ``scales``: the
    standard deviation of each volume's normaliser when measured elsewhere (``sd`` of
    :func:`normalise_volume`); ``centre``: how each volume's pixels are centred (``centre``
    of :func:`normalise_volume`).  ``impl`` as :func:`normalise_volume` (``"numba"``: the sum
    and the fill in one kernel, same float64 arithmetic).  ``overwrite``: the volumes are not
    used again, so under ``"numba"`` the C-contiguous float32 ones are normalised in place
    and the first one holds the result (the same numbers, without new volumes).

    Examples
    --------
    ``a`` normalises to (0, 2) and (2, 0) per pixel (:func:`normalise_volume`'s example); both
    pixels of ``b`` cost (0, 2), standard deviation 1, so it stays as it is.  Their mean is
    (0, 2) and (1, 1); with weights 3 and 1 the second pixel gets ``(3 (2, 0) + (0, 2)) / 4``:

    >>> import numpy as np
    >>> from hyperlf.costs import fuse
    >>> a = np.array([[[1.0, 5.0]], [[5.0, 1.0]]])       # (labels, rows, columns)
    >>> b = np.array([[[0.0, 0.0]], [[2.0, 2.0]]])
    >>> ok = np.ones(a.shape, bool)                      # every candidate valid
    >>> fuse([a, b], valid=ok)[:, 0].T.tolist()          # per pixel
    [[0.0, 2.0], [1.0, 1.0]]
    >>> fuse([a, b], [3, 1], valid=ok)[:, 0, 1].tolist()
    [1.5, 0.5]
    """
    vols, w, sds = _fusion_inputs(volumes, weights, scales)
    shape = vols[0].shape
    dmin = check_dmin(dmin)
    if valid is not None:
        bool_mask(valid, "valid", shape, broadcast=True, of="the volumes")
    choice(centre, "centre", NORMALISE_CENTRES)
    overwrite = flag(overwrite, "overwrite")
    if check_impl(impl, "normalise") == "numba":
        return _fuse_numba(vols, w, sds, dmin, valid, overwrite, centre)
    out = np.zeros(shape, np.float64)
    for wi, v, sd in zip(w, vols, sds):
        if wi:
            out += wi * normalise_volume(v, dmin, valid, sd=sd, impl="numpy", centre=centre)
    out /= w.sum()
    return fill_out_of_image(out.astype(np.float32), dmin, valid)


def _fusion_inputs(volumes, weights, scales) -> tuple[list, np.ndarray, list]:
    """The volumes of :func:`fuse` (equal ``(L, H, W)`` shapes), their weights (float64) and
    their normalisers' scales (None where measured here), each checked."""
    if isinstance(volumes, np.ndarray) or not isinstance(volumes, (list, tuple)):
        raise InvalidInputError(f"volumes must be a list of (L, H, W) arrays, got "
                                f"{shown(volumes)}")
    vols = [_volume(v, "each volume") for v in volumes]
    if not vols:
        raise InvalidInputError("fuse needs at least one volume")
    shape = vols[0].shape
    if any(v.shape != shape for v in vols) or len(shape) != 3:
        raise InvalidInputError(f"volumes must be (L, H, W) of equal shape, got {[v.shape for v in vols]}")
    w = (1.0,) * len(vols) if weights is None else weights_tuple(weights)
    if w is None or len(w) != len(vols):
        raise InvalidInputError(f"weights must be {len(vols)} finite numbers >= 0, not all 0, "
                                f"with a finite sum, got {shown(weights)}")
    if scales is None:
        sds = [None] * len(vols)
    elif isinstance(scales, (list, tuple, np.ndarray)) and np.ndim(scales) == 1:
        sds = [check_scale(x, "each of scales", optional=False) for x in scales]
    else:
        sds = []
    if len(sds) != len(vols):
        raise InvalidInputError(f"scales must give one number per volume ({len(vols)}), got "
                                f"{shown(scales)}")
    return vols, np.asarray(w, np.float64), sds


def _fuse_numba(vols: list, w: np.ndarray, sds: list, dmin: int, valid, overwrite: bool,
                centre: str) -> np.ndarray:
    """:func:`fuse` by the numba kernels: the weighted sum and the out-of-image fill in one
    pass, the result in the first volume where ``overwrite`` lets it."""
    from ._kernels import fuse_fill

    shape = vols[0].shape
    Lc, H, W = shape
    if valid is None:
        valid = candidate_validity((H, W), dmin, dmin + Lc - 1)
    ok = kernel_input(np.broadcast_to(np.asarray(valid, bool), shape))
    keep = [i for i in range(len(vols)) if w[i]]
    parts = tuple(normalise_volume(vols[i], dmin, ok, sd=sds[i], impl="numba",
                                   overwrite=overwrite, centre=centre) for i in keep)
    own = overwrite and _own_float32(vols[keep[0]], parts[0])
    out = parts[0] if own else np.empty(shape, np.float32)
    fuse_fill(parts, np.ascontiguousarray(w[keep]), ok, out)  # reads, then writes, each entry
    return out


def fused_volume(left, right, dmin, dmax, window=None, impl: str = "auto",
                 bwncc_window=None, census_window: int = 7, weights=(1.0, 1.0), **bwncc_params):
    """``F = (norm(bwncc) + norm(census 7x7)) / 2`` (SPEC §3 fusion candidate; ``weights``
    generalise the mean).  ``window`` is ignored (use ``bwncc_window`` / ``census_window``).

    Examples
    --------
    The right image moved 3 px to the right: both parts are lowest at disparity 3 on columns 6
    to 20 (clear of the borders and of the columns ``np.roll`` wrapped round), where the fused
    cost is 0; weights (0, 1) leave the normalised census alone:

    >>> import numpy as np
    >>> from hyperlf.costs import census_volume, fused_volume, normalise_volume
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> left = np.roll(right, 3, axis=1)
    >>> F = fused_volume(left, right, 0, 6)
    >>> np.unique(F.argmin(axis=0)[:, 6:-3]).tolist(), float(F[3, :, 6:-3].max())
    ([3], 0.0)
    >>> census = normalise_volume(census_volume(left, right, 0, 6), 0)
    >>> bool(np.array_equal(fused_volume(left, right, 0, 6, weights=(0, 1)), census))
    True
    """
    b = bwncc_volume(left, right, dmin, dmax, "default", window=bwncc_window, impl=impl, **bwncc_params)
    c = census_volume(left, right, dmin, dmax, window=census_window, impl=impl)
    return fuse([b, c], weights, dmin, overwrite=True)


def census_rsncc_volume(left, right, dmin, dmax, window=None, impl: str = "auto",
                        rsncc_window: int = 5, census_window: int = 7, weights=(1.0, 1.0),
                        **rsncc_params):
    """``(norm(rsncc) + norm(census)) / 2`` (``weights`` generalise the mean).

    ``window`` is ignored (use ``rsncc_window`` / ``census_window``); further keyword
    arguments go to :func:`rsncc_volume`.

    Examples
    --------
    The right image moved 3 px to the right: both parts are lowest at disparity 3 on columns 6
    to 20 (clear of the borders and of the columns ``np.roll`` wrapped round), where the fused
    cost is 0; weights (1, 0) leave the normalised RSNCC alone:

    >>> import numpy as np
    >>> from hyperlf.costs import census_rsncc_volume, normalise_volume, rsncc_volume
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> left = np.roll(right, 3, axis=1)
    >>> F = census_rsncc_volume(left, right, 0, 6)
    >>> np.unique(F.argmin(axis=0)[:, 6:-3]).tolist(), float(F[3, :, 6:-3].max())
    ([3], 0.0)
    >>> rsncc = normalise_volume(rsncc_volume(left, right, 0, 6), 0)
    >>> bool(np.array_equal(census_rsncc_volume(left, right, 0, 6, weights=(1, 0)), rsncc))
    True
    """
    a = rsncc_volume(left, right, dmin, dmax, window=rsncc_window, impl=impl, **rsncc_params)
    c = census_volume(left, right, dmin, dmax, window=census_window, impl=impl)
    return fuse([a, c], weights, dmin, overwrite=True)
