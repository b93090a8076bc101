"""Edge-aware aggregation of cost volumes: one home, a registry of named methods.

Every window cost (:mod:`hyperlf.costs.registry`) can have its volume aggregated further
before the optimiser, for two-view stereo (:func:`hyperlf.twoview.stereo`, both referenced
volumes, each with its own image as the guide) and for H-LF depth
(:class:`hyperlf.hlf.DepthParams` ``aggregation``, the reference view as the guide).

Methods (:data:`AGGREGATION_METHODS`):

* ``"none"``: the cost's own window only (the default everywhere; why: BENCHMARKS.md,
  "Edge-aware aggregation").
* ``"guided"``: cost-volume filtering (Hosni et al. [1]_): every label slice is smoothed by the
  guided filter of He et al. [2]_, an edge-preserving local linear model of the guide, so that
  support follows intensity edges of the reference rather than a square window.  The guide is
  the image divided by its 99th percentile (``eps`` is in those units, squared); the out-of-
  image rule of :mod:`hyperlf.costs` is applied again afterwards where a validity mask is given.

References
----------
.. [1] A. Hosni, C. Rhemann, M. Bleyer, C. Rother, M. Gelautz, "Fast cost-volume filtering for
   visual correspondence and beyond", IEEE TPAMI 35(2), 2013.
.. [2] K. He, J. Sun, X. Tang, "Guided image filtering", IEEE TPAMI 35(6), 2013.

Examples
--------
>>> import numpy as np
>>> from hyperlf.costs.aggregation import AggregationParams, aggregate_volume
>>> guide = np.zeros((8, 8)); guide[:, 4:] = 1.0            # two flat regions
>>> cost = np.random.default_rng(0).random((3, 8, 8))
>>> out = aggregate_volume(cost, guide, AggregationParams("guided", radius=1, eps=1e-4))
>>> out.shape, out.dtype.name
((3, 8, 8), 'float32')
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._options import bool_mask, choice, integer, number, shown
from ..errors import InvalidInputError
from ._validate import check_dmin, check_map, map_side
from .pair import box_mean, candidate_validity, right_validity, worst_fill

__all__ = ["AGGREGATION_METHODS", "AggregationParams", "guide_image", "guided_filter",
           "aggregate_volume", "aggregate_pair"]

#: Named aggregation methods and what they do (the registry the options are checked against).
AGGREGATION_METHODS = {
    "none": "the cost's own window only",
    "guided": "guided-filter cost-volume filtering (Hosni et al. 2013, He et al. 2013)",
}


@dataclass(frozen=True)
class AggregationParams:
    """Which aggregation, and its constants.

    Parameters
    ----------
    method : {"none", "guided"}
        A name of :data:`AGGREGATION_METHODS`.
    radius : int
        Half-size of the guided filter's box (window ``2 radius + 1``), >= 1.
    eps : float
        The guided filter's regulariser (> 0), in squared units of the guide scaled to its
        99th percentile: larger smooths across weaker edges.
    """

    method: str = "none"
    radius: int = 4
    eps: float = 1e-3

    def __post_init__(self):
        choice(self.method, "aggregation", tuple(AGGREGATION_METHODS))
        object.__setattr__(self, "radius", integer(self.radius, "aggregation_radius", 1))
        number(self.eps, "aggregation_eps", positive=True)

    @classmethod
    def of(cls, value) -> "AggregationParams":
        """``value`` as parameters: None (no aggregation), a method name, or parameters."""
        if value is None:
            return cls()
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            return cls(method=value)
        raise InvalidInputError(f"aggregation must be a method name {tuple(AGGREGATION_METHODS)} "
                                f"or AggregationParams, got {shown(value)}")


def guide_image(image) -> np.ndarray:
    """The guide of a 2-D image: float64, divided by its 99th percentile.

    A non-positive percentile leaves the image as it is (a flat guide is fine: the guided filter
    is then a box mean of box means, a wider smoothing).  ``image``: finite real numbers, 2-D.

    Examples
    --------
    An image of 0 and 5 has 5 as its 99th percentile; an image of zeros is left as it is:

    >>> import numpy as np
    >>> from hyperlf.costs import guide_image
    >>> image = np.zeros((8, 8)); image[:, 4:] = 5.0
    >>> np.unique(guide_image(image)).tolist()
    [0.0, 1.0]
    >>> np.unique(guide_image(np.zeros((4, 4)))).tolist()
    [0.0]
    """
    img = np.asarray(check_map(image, "the guide", 2), dtype=np.float64)
    if not np.isfinite(img).all():  # one pass, beside the percentile's sort
        raise InvalidInputError("the guide must be finite (no NaN/inf); fill or mask it first")
    p = float(np.percentile(img, 99)) if img.size else 0.0
    return img / p if p > 0 and np.isfinite(p) else img


def _guide_stats(guide: np.ndarray, n: int):
    mean = box_mean(guide, n)
    return mean, box_mean(guide * guide, n) - mean * mean


def guided_filter(guide, src, radius: int, eps: float, *, stats=None) -> np.ndarray:
    """He et al.'s guided filter of one 2-D map ``src`` by ``guide`` (both ``(H, W)``), float64.

    ``q = mean(a) I + mean(b)`` with ``a = cov(I, p) / (var(I) + eps)``, ``b = mean(p) -
    a mean(I)`` over ``(2 radius + 1)``-square boxes, replicated borders
    (:func:`hyperlf.costs.box_mean`).  ``stats``: the guide's box mean and variance, when
    filtering many maps with one guide.  Checked in O(1) (it runs per label): 2-D maps of one
    shape, ``radius`` an integer in ``1 .. map_side`` (:func:`_check_radius`), ``eps`` > 0.

    Examples
    --------
    A source that follows the guide (here twice it) keeps its edge, where a box mean of the
    same size blurs it over two columns; a constant source stays constant:

    >>> import numpy as np
    >>> from hyperlf.costs import box_mean, guided_filter
    >>> guide = np.zeros((8, 8)); guide[:, 4:] = 1.0
    >>> guided_filter(guide, 2.0 * guide, 1, 1e-4)[0].round(3).tolist()
    [0.0, 0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2.0]
    >>> box_mean(2.0 * guide, 3)[0].round(3).tolist()
    [0.0, 0.0, 0.0, 0.667, 1.333, 2.0, 2.0, 2.0]
    >>> bool(np.allclose(guided_filter(guide, np.full((8, 8), 0.7), 2, 1e-3), 0.7))
    True
    """
    guide = np.asarray(check_map(guide, "guide", 2), dtype=np.float64)
    src = check_map(src, "src", 2)
    if src.shape != guide.shape:
        raise InvalidInputError(f"src {src.shape} and guide {guide.shape} must have one shape")
    n = 2 * _check_radius(radius, guide.shape) + 1
    number(eps, "eps", positive=True)
    if stats is not None:
        try:
            ok = len(stats) == 2 and all(np.shape(a) == guide.shape for a in stats)
        except TypeError:
            ok = False
        if not ok:
            raise InvalidInputError(f"stats must be the guide's (box mean, variance), two "
                                    f"arrays of its shape {guide.shape}, got {shown(stats)}")
    mean_i, var_i = _guide_stats(guide, n) if stats is None else stats
    mean_p = box_mean(src, n)
    cov = box_mean(guide * src, n) - mean_i * mean_p
    a = cov / (var_i + eps)
    b = mean_p - a * mean_i
    return box_mean(a, n) * guide + box_mean(b, n)


def _check_radius(radius, shape) -> int:
    """The guided filter's radius: an integer ``>= 1``, at most the maps' longer side (or
    127 on smaller maps, :func:`hyperlf.costs._validate.map_side`)."""
    return integer(radius, "radius", 1, maximum=map_side(shape))


def aggregate_volume(volume, guide, params: AggregationParams | str | None = None, *,
                     valid=None, out: np.ndarray | None = None) -> np.ndarray:
    """Aggregate a cost volume ``(L, H, W)`` with the method of ``params``.

    Parameters
    ----------
    volume : array_like, shape (L, H, W)
        Lower is better.
    guide : array_like, shape (H, W)
        The image the volume is referenced to (scaled by :func:`guide_image`).
    params : AggregationParams or str, optional
        None or ``"none"``: the volume is returned as float32, unchanged.
    valid : array_like of bool, broadcastable to the volume, optional
        Valid candidates; the invalid ones get their pixel's worst valid cost again after
        filtering (:func:`hyperlf.costs.worst_fill`), as before it.
    out : ndarray, float32, shape (L, H, W), optional
        Where to write the result; it may be ``volume`` itself (slices are filtered one at a
        time), which saves a second volume in memory.

    Returns
    -------
    ndarray, float32, shape (L, H, W)

    Examples
    --------
    The guide has two flat halves; the true label is 0 on the left one and 2 on the right one,
    and the costs ``|label - truth|`` carry noise that moves some pixels' minima.  Averaged over
    each pixel's own half, every minimum is right again:

    >>> import numpy as np
    >>> from hyperlf.costs import AggregationParams, aggregate_volume
    >>> truth = np.zeros((12, 16), int); truth[:, 8:] = 2
    >>> labels = np.arange(3)[:, None, None]
    >>> noise = 1.5 * np.random.default_rng(0).random((3, 12, 16))
    >>> cost = np.abs(labels - truth) + noise
    >>> bool((cost.argmin(axis=0) == truth).all())
    False
    >>> out = aggregate_volume(cost, 1.0 + truth, AggregationParams("guided", radius=2))
    >>> out.dtype.name, bool((out.argmin(axis=0) == truth).all())
    ('float32', True)
    """
    p = AggregationParams.of(params)
    vol = np.asarray(check_map(volume, "volume (L, H, W)", 3), dtype=np.float32)
    guide = check_map(guide, "guide", 2)
    if guide.shape != vol.shape[1:]:
        raise InvalidInputError(f"volume (L, H, W) and guide (H, W) disagree: {vol.shape} vs "
                                f"{guide.shape}")
    if valid is not None:
        valid = bool_mask(valid, "valid", vol.shape, broadcast=True, of="the volume")
    if out is not None and not (isinstance(out, np.ndarray) and out.shape == vol.shape
                                and out.dtype == np.float32 and out.flags.writeable):
        raise InvalidInputError(f"out must be a writeable float32 array of shape {vol.shape}, "
                                f"got {shown(out)}")
    if p.method == "none":
        return vol
    _check_radius(p.radius, vol.shape)
    g = guide_image(guide)
    stats = _guide_stats(g, 2 * p.radius + 1)
    if out is None:
        out = np.empty_like(vol)
    for k in range(vol.shape[0]):
        out[k] = guided_filter(g, vol[k], p.radius, p.eps, stats=stats)
    if valid is not None:
        worst_fill(out, ~np.broadcast_to(np.asarray(valid, dtype=bool), out.shape))
    return out


def aggregate_pair(cost_left, cost_right, left, right, dmin: int,
                   params: AggregationParams | str | None = None):
    """Both referenced volumes of a rectified pair (:func:`hyperlf.costs.cost_volumes`), each
    aggregated with its own image as the guide, the out-of-image rule applied again.

    ``cost_right`` may be None.  Returns ``(C_L, C_R)``.

    Examples
    --------
    The left image is the right one moved 3 px to the right.  After aggregation each volume
    still finds disparity 3 clear of the borders (and of the columns ``np.roll`` wrapped
    round); left column 0, whose only valid disparity is 0, holds that cost at every label
    again.  Without ``params`` the volumes come back as they are:

    >>> import numpy as np
    >>> from hyperlf.costs import AggregationParams, aggregate_pair, cost_volumes
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> left = np.roll(right, 3, axis=1)
    >>> C_L, C_R = cost_volumes(left, right, 0, 6, metric="census")
    >>> A_L, A_R = aggregate_pair(C_L, C_R, left, right, 0, AggregationParams("guided", radius=2))
    >>> np.unique(A_L.argmin(axis=0)[:, 6:-3]).tolist()     # left columns 6 to 20
    [3]
    >>> np.unique(A_R.argmin(axis=0)[:, 3:-6]).tolist()     # right columns 3 to 17
    [3]
    >>> bool((A_L[:, :, 0] == A_L[0, :, 0]).all())
    True
    >>> aggregate_pair(C_L, C_R, left, right, 0)[0] is C_L
    True
    """
    p = AggregationParams.of(params)
    Lc, H, W = check_map(cost_left, "cost_left (L, H, W)", 3).shape
    if cost_right is not None and np.shape(check_map(cost_right, "cost_right (L, H, W)", 3)) \
            != (Lc, H, W):
        raise InvalidInputError(f"cost_right must have cost_left's shape {(Lc, H, W)}, got "
                                f"{np.shape(cost_right)}")
    for name, image in (("left", left), ("right", right)):
        if check_map(image, name, 2).shape != (H, W):
            raise InvalidInputError(f"{name} must be the (H, W) = {(H, W)} image of the "
                                    f"volumes, got shape {np.shape(image)}")
    dmin = check_dmin(dmin)
    if p.method == "none":
        return cost_left, cost_right
    dmax = dmin + Lc - 1
    cl = aggregate_volume(cost_left, left, p, valid=candidate_validity((H, W), dmin, dmax))
    cr = None if cost_right is None else aggregate_volume(
        cost_right, right, p, valid=right_validity((H, W), dmin, dmax))
    return cl, cr

