"""Matching costs: one registry, two evaluators per cost (SPEC §3, §4, §5).

Every cost is a :class:`Cost` object in the registry (:mod:`hyperlf.costs.registry`), found by
name with :func:`get_cost`; two-view stereo, H-LF depth, cube completion and the command line
all read it.  A cost evaluates a rectified pair at integer disparities
(:meth:`Cost.pair_volume`, :mod:`hyperlf.costs.pair`) and, for light fields, one view against
the reference at sub-pixel shifts (:meth:`Cost.view_volume`, :mod:`hyperlf.costs.lightfield`).

Conventions
-----------
* Left pixel ``(y, x)`` with integer disparity ``d`` in ``dmin..dmax`` matches right pixel
  ``(y, x - d)``.  Every cost returns ``cost[L, H, W]`` float32, ``L = dmax - dmin + 1``,
  index ``k`` <-> ``d = dmin + k``; **lower is better**.
* **Out-of-image rule (SPEC §4), the same for every cost.**  A candidate with ``x - d < 0`` or
  ``x - d >= W`` is invalid (:func:`candidate_validity`); it gets the pixel's *worst valid* cost
  (its maximum over valid ``d``), never zero.  A pixel with no valid candidate gets 0 for every
  ``d``.  See :func:`fill_out_of_image`.
* **Border rule for windows: replicate, each view independently.**  The ``n x n`` window
  (patch) around a pixel of a view takes, for window pixels outside that view, the value of the
  nearest border pixel of *that view* (``cv2.BORDER_REPLICATE``/``mode='nearest'``).  A windowed
  cost compares the left patch around ``(y, x)`` with the right patch around ``(y, x - d)``,
  each built this way, so every patch statistic (mean, variance) is a per-view quantity computed
  once, and the cost is exactly symmetric in the two views.  Implementation: both views are
  padded by ``r = n // 2`` with replicated borders, the right padded view is shifted by ``d``
  columns, and the product (or difference) is box-filtered in "valid" mode.
* **Numerics.**  Window sums are float64 and statistics are centred on the view's (channel's)
  global mean before squaring (SPEC §3 numerics: float32 ``E[c^2] - E[c]^2`` loses the signal,
  see :func:`window_stats`).

Costs (names used by ``--metric``; :func:`cost_names`)
-----------------------------------------------------
* ``ssd``: window mean of ``(InL - InR)^2`` with ``In = I / mean(I)``; default 5 x 5; rectified
  pairs only.
* ``ncc``: ``1 - NCC`` of intensities, default 5 x 5.  NCC is 0 (cost 1) where either patch's
  variance is below ``tau_rel`` (default 1e-5) times the view's mean patch variance (flat patch).
* ``rsncc``: Shen et al. 2014 [1]_, ``rho(1 - NCC(I)) + tau * rho(1 - NCC(|grad I|))`` with
  ``rho(x) = -log(exp(-|x|) + exp(|x| - 2))`` and ``tau = 1`` (parameter ``rs_tau``).  ``grad``
  is the central difference ``(f[x+1] - f[x-1]) / 2`` of ``In`` (borders replicated), ``|grad|``
  its Euclidean magnitude.
* ``census``: Hamming distance of a census transform [2]_, default 7 x 7 (48 bits, bit set
  where a neighbour is strictly less than the centre, replicate border), packed in ``uint64``.
  Its pair volume takes ``support_gamma``: each bit weighted by adaptive support weights [4]_
  of both images (:func:`hyperlf.costs.pair.support_weights`), which the two fusions below
  ask for in two-view stereo (``part_options`` of :class:`FusedCost`).
* ``bwncc`` / ``bwncc-paper``: SPEC §3 BWNCC [3]_ on the 612-channel descriptor
  (:mod:`hyperlf.descriptor`), see :func:`bwncc_volume`.  ``bwncc`` uses
  ``DescriptorParams.default()`` with NCC patch ``n = w`` for each level's channels;
  ``bwncc-paper`` the literal ``DescriptorParams.paper()`` with ``n = 5`` for all channels.
* ``fused``: ``(norm(bwncc) + norm(census 7x7)) / 2`` (:class:`FusedCost`, :func:`fuse`,
  :func:`normalise_volume`).
* ``census-rsncc``: ``(norm(rsncc 5x5) + norm(census 7x7)) / 2``, the same fusion without the
  descriptor: census for intensity order where bands agree, RSNCC's gradient term where they
  reverse, and far cheaper than ``fused``.  Its light-field form takes RSNCC 3 x 3 on a dense
  array (:func:`light_field_window`).  Between a light field's views the fusions' ``norm``
  only scales each part (``centre="none"`` of :func:`normalise_volume`,
  :attr:`FusedCost.view_centre`): a per-pixel minimum over the labels a view sees would
  depend on how many it sees.
* ``auto``: an alias, resolved by :func:`get_cost` to :data:`AUTO_METRIC` = ``"census-rsncc"``,
  the default of two-view stereo and of H-LF depth.  Chosen on Table 1 (parameters tuned on
  Venus only, it has the lowest bad5.0 of every cost under graph cuts on the other scenes) and
  Table 2 (better than ``fused`` on most scenes and much faster); the figures are in
  BENCHMARKS.md.

``window=None`` in :func:`cost_volume` means each cost's own default (:attr:`Cost.window`: 5
for ssd/ncc/rsncc, 7 for census, per level / 5 for bwncc / bwncc-paper); an explicit ``window``
applies to every windowed cost (a fused cost passes it to no part: use ``<part>_window``).

Aggregation: any volume may be aggregated further before the optimiser, edge-aware
(:mod:`hyperlf.costs.aggregation`: ``"none"``, the default, or ``"guided"`` cost-volume
filtering), for two-view stereo and H-LF depth alike.

Implementations (``impl``): ``"numpy"`` = readable reference (loop over disparities,
``cv2.boxFilter`` float64); ``"numba"`` = parallel kernels (:mod:`hyperlf.costs._kernels`:
ncc/rsncc cross terms, census Hamming, and for bwncc a dedicated pipeline: per-block
statistics and ``1/sigma``, cross terms channel-outer over chunks of disparities inside row
bands with separable window sums and exact skipping of column tiles whose ``1/sigma`` is 0 in
either view, all sums float64, fused finish + out-of-image rule); ``"auto"`` picks numba
wherever a kernel exists.  Tests check that they agree (bwncc: to float32 rounding).

References
----------
.. [1] X. Shen, L. Xu, Q. Zhang, J. Jia, "Multi-modal and multi-spectral registration for
   natural images", ECCV 2014.
.. [2] R. Zabih, J. Woodfill, "Non-parametric local transforms for computing visual
   correspondence", ECCV 1994.
.. [3] K. Zhu, Y. Xue, Q. Fu, S. B. Kang, X. Chen, J. Yu, "Hyperspectral Light Field Stereo
   Matching" (the paper this library implements).
.. [4] K.-J. Yoon, I. S. Kweon, "Adaptive support-weight approach for correspondence search",
   IEEE TPAMI 28(4), 2006.

The modules and cost classes of this package cite these papers by author and year and point
here; the list lives only in this docstring.

Examples
--------
>>> import numpy as np
>>> from hyperlf import costs
>>> costs.get_cost("auto").name
'census-rsncc'
>>> "ssd" in costs.cost_names(light_field=True)
False
"""

from __future__ import annotations

from . import builtin as _builtin  # noqa: F401  (registers the built-in costs)
from . import aggregation, lightfield, pair, registry
from .aggregation import *  # noqa: F401,F403
from .lightfield import *  # noqa: F401,F403
from .pair import *  # noqa: F401,F403
from .registry import *  # noqa: F401,F403

# The package's public names are those of its modules (each module's ``__all__`` is the one
# list of its public names), plus the registry-driven METRIC_NAMES below.
__all__ = [*registry.__all__, "METRIC_NAMES", *lightfield.__all__, *pair.__all__,
           *aggregation.__all__]


def __getattr__(attr: str):
    # METRIC_NAMES follows the registry: every registered cost, then "auto".
    if attr == "METRIC_NAMES":
        return registry.cost_names() + ("auto",)
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")
