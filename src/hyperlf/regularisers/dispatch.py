"""The one optimiser entry: :func:`optimise` runs WTA, SGM or graph cuts from typed parameters."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._options import flag
from ..errors import InvalidInputError
from .basic import wta
from .graphcuts import graphcut, graphcut_multiscale
from .params import OPTIMISERS, GraphCutParams, SGMParams, WTAParams
from .semiglobal import sgm

__all__ = ["OptimiseResult", "optimise"]


@dataclass(frozen=True)
class OptimiseResult:
    """Output of :func:`optimise`.

    Attributes
    ----------
    labels : ndarray, int32, shape (H, W)
        Chosen label index per pixel.
    volume : ndarray, float32, shape (L, H, W)
        The volume sub-pixel refinement and confidence must use: the SGM-aggregated volume
        for SGM, the input volume otherwise.
    """

    labels: np.ndarray
    volume: np.ndarray


def _run_wta(volume, params, guide, labels, edge_weights, init, progress):
    return wta(volume), volume


def _run_sgm(volume, params: SGMParams, guide, labels, edge_weights, init, progress):
    vol = sgm(volume, params.p1, params.p2, paths=params.paths,
              guide=guide if params.adaptive_p2 else None, impl=params.impl,
              smoothness=params.smoothness, guide_scale=params.guide_scale)
    return wta(vol), vol


def _run_graphcut(volume, params: GraphCutParams, guide, labels, edge_weights, init, progress):
    common = dict(smoothness=params.smoothness, weight=params.weight,
                  truncation=params.truncation, guide=guide, edge_sigma=params.edge_sigma,
                  max_cycles=params.max_cycles, labels=labels, progress=bool(progress) or None)
    if params.levels == 0:
        return graphcut(volume, edge_weights=edge_weights, init=init, **common), volume
    for name, given in (("edge_weights", edge_weights), ("init", init)):
        if given is not None:
            raise InvalidInputError(f"{name} is an option of plain graph cuts (GraphCutParams levels=0)")
    f = graphcut_multiscale(volume, levels=params.levels, band=params.band,
                            radius=params.radius, min_size=params.min_size, **common)
    return f, volume


_RUNNERS = {WTAParams: _run_wta, SGMParams: _run_sgm, GraphCutParams: _run_graphcut}


def optimise(volume, params, *, guide=None, labels=None, edge_weights=None, init=None,
             progress: bool = False) -> OptimiseResult:
    """Choose one label per pixel of a cost volume with the optimiser ``params`` describes.

    Parameters
    ----------
    volume : array_like, shape (L, H, W)
        Finite cost volume, lower is better (typically :func:`data_term` of a matching cost).
    params : WTAParams, SGMParams or GraphCutParams
        The optimiser and its settings (:func:`make_params` builds them from a name).
    guide : array_like, shape (H, W) or (H, W, K), optional
        Reference image: contrast-sensitive pairwise weights for graph cuts; an adaptive P2
        for SGM when ``params.adaptive_p2``; ignored by WTA.
    labels : array_like, shape (L,), optional
        Disparity of each label (default ``0..L-1``), for graph cuts' truncated-linear term.
    edge_weights : (wx (H, W-1), wy (H-1, W)), optional
        Extra pairwise factors; plain graph cuts only.
    init : array_like of int, shape (H, W), optional
        The label map plain graph cuts start from (default: winner-takes-all), e.g. an earlier
        solution of a similar volume; with few ``max_cycles`` it then only moves what the new
        volume changes.
    progress : bool
        A progress bar over graph-cut expansion moves.

    Returns
    -------
    OptimiseResult
        ``labels`` (int32 label map) and ``volume`` (for refinement and confidence).

    Raises
    ------
    InvalidInputError
        ``params`` is not an optimiser's parameters, ``edge_weights`` or ``init`` with an
        optimiser other than plain graph cuts, or any error of the optimiser itself.

    See Also
    --------
    wta, sgm, graphcut, graphcut_multiscale : The optimisers it runs; :func:`sgm` and
        :func:`graphcut` cite the papers they follow.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.regularisers import SGMParams, optimise
    >>> c = np.random.default_rng(0).random((5, 8, 9)).astype(np.float32)
    >>> res = optimise(c, SGMParams(p1=0.1, p2=0.5, impl="numpy"))
    >>> res.labels.shape, res.volume.shape
    ((8, 9), (5, 8, 9))
    """
    run = _RUNNERS.get(type(params))
    if run is None:
        raise InvalidInputError(
            f"params must be one of {', '.join(c.__name__ for c in OPTIMISERS.values())}, "
            f"got {type(params).__name__}")
    for name, given in (("edge_weights", edge_weights), ("init", init)):
        if given is not None and not isinstance(params, GraphCutParams):
            raise InvalidInputError(f"{name} is a graph-cut option, not {params.name}'s")
    progress = flag(progress, "progress")
    f, vol = run(volume, params, guide, labels, edge_weights, init, progress)
    return OptimiseResult(labels=f, volume=vol)
