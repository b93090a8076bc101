"""Per-pixel basics of a cost volume: data term, winner-takes-all, worst-cost fill (SPEC §4).

A cost volume ``cost`` is an array_like of shape (L, H, W): one cost per label and pixel, lower
is better.

Examples
--------
Two pixels, three labels: the data term measures each label against the pixel's best one, and
winner-takes-all picks the best one.

>>> import numpy as np
>>> from hyperlf.regularisers import data_term, wta
>>> c = np.array([[[2.0, 1.0]], [[5.0, 0.5]], [[3.0, 1.0]]])
>>> data_term(c)[:, 0, :].tolist()
[[0.0, 0.5], [3.0, 0.0], [1.0, 0.5]]
>>> wta(c).tolist()
[[0, 1]]
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import InvalidInputError
from .._options import bool_mask, choice, flag, real_array
from ._checks import check_cost

__all__ = ["data_term", "wta", "fill_invalid"]


def data_term(cost, *, overwrite: bool = False) -> np.ndarray:
    """Subtract each pixel's minimum cost.

    The paper's data term ``|C(f(p)) - C(f*(p))|``; it shifts the MRF energy by a constant and
    leaves its minimiser unchanged.

    Parameters
    ----------
    cost : array_like, shape (L, H, W)
        Finite cost volume (module docstring, with an example).
    overwrite : bool
        Subtract in place when ``cost`` is already a float32 array, saving a volume-sized
        copy; ``cost`` then holds the result.

    Returns
    -------
    ndarray, float32, shape (L, H, W)
        ``cost - min_l cost[l]``.

    Examples
    --------
    >>> cost = np.array([[[3.0, 1.0]], [[2.0, 5.0]], [[4.0, 0.0]]])  # 3 labels, 1 x 2 px
    >>> data_term(cost)[:, 0].tolist()
    [[1.0, 1.0], [0.0, 5.0], [2.0, 0.0]]
    """
    overwrite = flag(overwrite, "overwrite")
    c = check_cost(cost)
    if overwrite:
        c -= c.min(axis=0, keepdims=True)
        return c
    return c - c.min(axis=0, keepdims=True)


def wta(cost) -> np.ndarray:
    """Winner-takes-all: the label index of each pixel's minimum cost.

    Parameters
    ----------
    cost : array_like, shape (L, H, W)
        As in :func:`data_term`.

    Returns
    -------
    ndarray, int32, shape (H, W)
        Label indices; ties go to the lowest index.

    Examples
    --------
    >>> cost = np.array([[[3.0, 1.0]], [[2.0, 5.0]], [[4.0, 0.0]]])  # 3 labels, 1 x 2 px
    >>> wta(cost).tolist()
    [[1, 2]]
    """
    c = check_cost(cost)
    return np.argmin(c, axis=0).astype(np.int32)


def fill_invalid(cost, invalid=None, *, empty: str = "global", value: str = "worst",
                 over: slice | None = None) -> np.ndarray:
    """Give invalid entries the pixel's worst valid cost (SPEC §4), its median, or between.

    Parameters
    ----------
    cost : array_like, shape (L, H, W)
        Cost volume; its non-finite entries are always invalid.
    invalid : array_like of bool, optional
        Further invalid entries, broadcastable to ``cost``.
    empty : {"global", "zero"}
        Value for a pixel with no valid entry at all: ``"global"`` (default) the worst valid
        cost of the whole volume; ``"zero"`` 0 for every label (the rule of
        :func:`hyperlf.costs.fill_out_of_image`).
    value : {"worst", "median", "share"}
        What an invalid entry of a pixel with valid ones gets: the pixel's worst valid cost
        (default: a candidate no image shows is ruled out), the median of its valid costs
        (neutral: the candidate is left to the regulariser, for a light field whose views
        cannot see the pixel at some depths although the scene is there, e.g. beyond the
        edge of a view's image), or ``median + s (worst - median)`` with ``s`` the share of
        the pixel's entries that are valid (``"share"``).  The worst-cost rule is only as
        sound as the chance that the valid candidates hold the answer: a pixel valid at
        nearly every candidate rules the others out, one valid at few leaves them to the
        regulariser.
    over : slice, optional
        The labels whose valid entries the pixel's median, worst and share are taken over
        (default every label); every invalid entry gets them.

    Returns
    -------
    ndarray, float32, shape (L, H, W)
        A new, finite volume.

    Raises
    ------
    InvalidInputError
        ``cost`` is not 3-D, ``empty`` or ``value`` is unknown, or (``empty="global"``) no
        entry is valid.

    Examples
    --------
    >>> import numpy as np
    >>> c = np.array([[[1.0, np.nan]], [[3.0, np.nan]], [[np.nan, np.nan]]])
    >>> fill_invalid(c)[:, 0, :].tolist()
    [[1.0, 3.0], [3.0, 3.0], [3.0, 3.0]]
    >>> fill_invalid(c, empty="zero")[:, 0, 1].tolist()
    [0.0, 0.0, 0.0]
    >>> fill_invalid(c, value="median")[:, 0, 0].tolist()
    [1.0, 3.0, 2.0]
    >>> fill_invalid(c, value="share")[:, 0, 0].tolist()  # 2 + (2/3) (3 - 2)
    [1.0, 3.0, 2.6666667461395264]
    """
    from ..costs.pair import FILL_EMPTY_MODES, worst_fill

    choice(empty, "empty", FILL_EMPTY_MODES)
    choice(value, "value", FILL_VALUES)
    c = np.array(real_array(cost, "cost", np.float32))
    if c.ndim != 3:
        raise InvalidInputError(f"cost must have shape (L, H, W), got {c.shape}")
    bad = ~np.isfinite(c)
    if invalid is not None:
        bad = bad | bool_mask(invalid, "invalid", c.shape, broadcast=True, of="the cost")
    if not bad.any():
        return c
    if value != "worst":
        _graded_fill(c, bad, by_share=value == "share", over=over)
        bad = ~np.isfinite(c)  # pixels with no valid entry: the ``empty`` rule
    return worst_fill(c, bad, empty=empty)


#: The values of :func:`fill_invalid`'s ``value``.
FILL_VALUES = ("worst", "median", "share")


def _graded_fill(c: np.ndarray, bad: np.ndarray, *, by_share: bool, over=None) -> None:
    """In place: the invalid entries of every pixel with valid ones get the median ``m`` of
    those, or (``by_share``) ``m + s (worst - m)`` with ``s`` the pixel's share of valid
    entries; only the pixels with an invalid entry are gathered.  A pixel with no valid entry
    is set to NaN throughout, for the caller's ``empty`` rule."""
    L = c.shape[0]
    flat, badf = c.reshape(L, -1), bad.reshape(L, -1)
    cols = np.flatnonzero(badf.any(axis=0))
    sub = np.where(badf[:, cols], np.nan, flat[:, cols])
    stats = sub if over is None else sub[over]
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # no valid entry: stays NaN
        fill = np.nanmedian(stats, axis=0)
        if by_share:
            share = 1.0 - np.isnan(stats).mean(axis=0)
            fill += share * (np.nanmax(stats, axis=0) - fill)
    flat[:, cols] = np.where(np.isnan(sub), fill[None].astype(np.float32), sub)
