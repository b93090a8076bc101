"""Typed parameters of the optimisers and the registry that names them.

Each optimiser has one frozen dataclass, validated on construction; :data:`OPTIMISERS` maps
the optimiser's name to it (choice lists come from its keys) and :func:`make_params` builds one
from a name and a dict.  :func:`hyperlf.regularisers.optimise` runs any of them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any, ClassVar

from .._options import check_fields, choice, flag, integer, mapping, number, rule
from ..errors import InvalidInputError
from .graphcuts import GRAPHCUT_SMOOTHNESS
from .semiglobal import SGM_PATHS, SGM_SMOOTHNESS

__all__ = ["WTAParams", "SGMParams", "GraphCutParams", "OPTIMISERS", "make_params",
           "params_dict"]

_IMPLS = ("auto", "numba", "numpy")


def _paths(value, label):
    return choice(integer(value, label), label, SGM_PATHS)


@dataclass(frozen=True)
class WTAParams:
    """Winner-takes-all: each pixel's lowest cost, no smoothness term (no parameters)."""

    name: ClassVar[str] = "wta"


@dataclass(frozen=True)
class SGMParams:
    """Semi-global matching (:func:`hyperlf.regularisers.sgm`).

    Parameters
    ----------
    p1, p2 : float
        Penalties in cost units per label step (``p2`` >= ``p1`` is enforced by :func:`sgm`).
    paths : {8, 4, 2}
        Path directions.
    smoothness : {"p1p2", "truncated_linear"}
        Classic P1/P2 term or ``min(p1 |Δl|, p2)``.
    adaptive_p2 : bool
        Lower P2 where the guide given to :func:`optimise` changes along the path; False
        ignores the guide.
    guide_scale : float, optional
        Scale of the guide's change (default: its mean 4-neighbour difference).
    impl : {"auto", "numba", "numpy"}
        Kernel of the path recursion.
    """

    name: ClassVar[str] = "sgm"
    p1: float = 0.5
    p2: float = 2.0
    paths: int = 8
    smoothness: str = "p1p2"
    adaptive_p2: bool = False
    guide_scale: float | None = None
    impl: str = "auto"

    def __post_init__(self):
        check_fields(self, {
            "p1": number, "p2": number, "paths": _paths,
            "smoothness": rule(choice, choices=SGM_SMOOTHNESS), "adaptive_p2": flag,
            "guide_scale": rule(number, positive=True, optional=True),
            "impl": rule(choice, choices=_IMPLS)}, f"{self.name} ")


@dataclass(frozen=True)
class GraphCutParams:
    """Alpha-expansion graph cuts (:func:`hyperlf.regularisers.graphcut`).

    Parameters
    ----------
    weight : float
        lambda, multiplies every pairwise term.
    smoothness : {"truncated_linear", "potts"}
        Pairwise term.
    truncation : float, optional
        ``T`` of the truncated-linear term, disparity units (None: not truncated).
    edge_sigma : float, optional
        Contrast scale of the guide's edge weights (default: the guide's RMS neighbour
        difference).
    max_cycles : int
        Expansion cycles (per level when coarse to fine).
    levels : int
        0: plain alpha-expansion; > 0: that many halvings, coarse to fine
        (:func:`hyperlf.regularisers.graphcut_multiscale`).
    band, radius, min_size : int
        Coarse-to-fine options (:func:`graphcut_multiscale`); unused when ``levels == 0``.
    """

    name: ClassVar[str] = "graphcut"
    weight: float = 1.0
    smoothness: str = "truncated_linear"
    truncation: float | None = 2.0
    edge_sigma: float | None = None
    max_cycles: int = 3
    levels: int = 0
    band: int = 2
    radius: int = 2
    min_size: int = 16

    def __post_init__(self):
        check_fields(self, {
            "weight": number, "smoothness": rule(choice, choices=GRAPHCUT_SMOOTHNESS),
            "truncation": rule(number, optional=True),
            "edge_sigma": rule(number, positive=True, optional=True),
            "max_cycles": integer, "levels": integer, "band": integer, "radius": integer,
            "min_size": rule(integer, minimum=1)}, f"{self.name} ")


#: Optimiser name -> its parameter dataclass (the one list of optimiser names).
OPTIMISERS: dict[str, type] = {cls.name: cls for cls in (GraphCutParams, SGMParams, WTAParams)}


def make_params(name: str, values: dict[str, Any] | None = None):
    """Parameters of the optimiser ``name`` from a dict (missing keys take the class default).

    Parameters
    ----------
    name : str
        A key of :data:`OPTIMISERS`.
    values : dict, optional
        Field values; every key must be a field of that optimiser's dataclass.

    Returns
    -------
    WTAParams, SGMParams or GraphCutParams

    Raises
    ------
    InvalidInputError
        Unknown optimiser, unknown keys (the message lists the allowed ones), invalid values.

    Examples
    --------
    >>> make_params("sgm", {"p1": 2})
    SGMParams(p1=2.0, p2=2.0, paths=8, smoothness='p1p2', adaptive_p2=False, guide_scale=None, impl='auto')
    """
    cls = OPTIMISERS.get(name) if isinstance(name, str) else None
    if cls is None:
        raise InvalidInputError(
            f"optimizer must be one of {', '.join(OPTIMISERS)}, got {name!r}")
    values = mapping(values, "params", keys=[f.name for f in fields(cls)],
                     taker=f"optimizer {name!r}") or {}
    return cls(**values)


def params_dict(params) -> dict[str, Any]:
    """The fields of an optimiser's parameters (one of :data:`OPTIMISERS`' classes) as a plain
    dict (without the name).

    Examples
    --------
    >>> params_dict(make_params("sgm", {"p1": 0.5, "p2": 2.0}))["p2"]
    2.0
    """
    if not isinstance(params, tuple(OPTIMISERS.values())):
        raise InvalidInputError(f"params must be the parameters of an optimiser (one of "
                                f"{', '.join(c.__name__ for c in OPTIMISERS.values())}), got "
                                f"{type(params).__name__}")
    return asdict(params)
