"""Optimisers shared by every matching cost: WTA, SGM, graph cuts, occlusion handling (SPEC §4, §5.4).

Conventions
-----------
* A **cost volume** is a float array ``cost[L, H, W]`` (label-major): ``L`` labels, lower is
  better. Every function here requires a *finite* volume; entries a caller considers invalid
  (e.g. out-of-image candidates ``x - d < 0``) must already carry a finite value. SPEC §4's rule
  is "the pixel's worst valid cost"; :func:`fill_invalid` applies it. A NaN or infinite entry
  raises :class:`~hyperlf.errors.InvalidInputError`. Volumes are converted to float32.
* **Labels** map to disparities through a 1-D array ``labels`` of length ``L`` (integers
  ``dmin..dmax`` or evenly spaced sub-pixel values). Where a function has no ``labels``
  argument it works in label units.
* A **label map** is an integer array ``(H, W)`` of label indices in ``[0, L)``.
* Two-view geometry is Middlebury's: left pixel ``x`` with disparity ``d`` matches right pixel
  ``x - d`` (SPEC §1).

Modules
-------
``params`` (``WTAParams``, ``SGMParams``, ``GraphCutParams``, the ``OPTIMISERS`` registry,
``make_params``), ``dispatch`` (``optimise``, the one entry that runs any of them),
``basic`` (``data_term``, ``wta``, ``fill_invalid``), ``semiglobal`` (``sgm``, ``sgm_labels``),
``graphcuts`` (``graphcut``, ``graphcut_multiscale``, ``mrf_energy``,
``edge_weights_from_guide``, ``candidate_labels``), ``postprocess`` (``left_right_check``,
``left_occlusions``, ``fill_occlusions``, ``right_cost_from_left``, ``subpixel_refine``,
``confidence``, ``edge_confidence``, ``label_saving``, ``thin_foreground``,
``enclosed_background``, ``ConfidenceParams``, ``HoleParams``,
``weighted_median``) and
``planes`` (``segment``, ``fit_plane``, ``plane_fill``, ``PlaneFillParams``: the segment-wise
slanted-plane fill;
``cost_planes``: planes fitted to a cost volume's pooled costs).  Every public name
is importable from :mod:`hyperlf.regularisers`; the numba kernels (``_kernels``) are compiled
on first use, so importing the package does not import numba (nor scikit-image, which
``segment`` imports when called).

Choosing an optimiser::

    from hyperlf.regularisers import make_params, optimise
    res = optimise(data_term(cost), make_params("sgm", {"p1": 0.5, "p2": 2.0}))
    res.labels, res.volume     # label map; volume for subpixel_refine / confidence

The MRF energy minimised by :func:`graphcut` (and evaluated by :func:`mrf_energy`) is::

    E(f) = sum_p cost[f_p, p] + sum_{(p,q) 4-neighbours} w_pq * V(f_p, f_q)

with ``V = min(|labels[a] - labels[b]|, T)`` (truncated linear, disparity units) or
``V = [a != b]`` (Potts), and ``w_pq = weight * (guide edge factor) * (explicit edge weight)``.
Subtracting the per-pixel minimum (:func:`data_term`, the paper's ``|C(f(p)) - C(f*(p))|``)
does not change the minimiser; it only shifts the energy by a constant.
"""

from __future__ import annotations

from .basic import data_term, fill_invalid, wta
from .dispatch import OptimiseResult, optimise
from .graphcuts import (GRAPHCUT_SMOOTHNESS, candidate_labels, edge_weights_from_guide,
                        graphcut, graphcut_multiscale, mrf_energy)
from .params import OPTIMISERS, GraphCutParams, SGMParams, WTAParams, make_params, params_dict
from .planes import PlaneFillParams, cost_planes, fit_plane, plane_fill, segment
from .postprocess import (ConfidenceParams, HoleParams, confidence, edge_confidence,
                          enclosed_background, fill_occlusions, label_saving,
                          left_occlusions, left_right_check,
                          right_cost_from_left, subpixel_refine, thin_foreground,
                          weighted_median)
from .semiglobal import SGM_PATHS, SGM_SMOOTHNESS, sgm, sgm_labels

__all__ = [
    "optimise",
    "OptimiseResult",
    "OPTIMISERS",
    "WTAParams",
    "SGMParams",
    "GraphCutParams",
    "make_params",
    "params_dict",
    "data_term",
    "wta",
    "fill_invalid",
    "sgm",
    "sgm_labels",
    "SGM_PATHS",
    "SGM_SMOOTHNESS",
    "edge_weights_from_guide",
    "mrf_energy",
    "graphcut",
    "candidate_labels",
    "graphcut_multiscale",
    "GRAPHCUT_SMOOTHNESS",
    "left_right_check",
    "left_occlusions",
    "PlaneFillParams",
    "segment",
    "fit_plane",
    "plane_fill",
    "cost_planes",
    "fill_occlusions",
    "right_cost_from_left",
    "subpixel_refine",
    "confidence",
    "edge_confidence",
    "thin_foreground",
    "enclosed_background",
    "label_saving",
    "ConfidenceParams",
    "HoleParams",
    "weighted_median",
]
