"""The built-in costs, registered on import of :mod:`hyperlf.costs`.

Default windows and optimiser parameters for two-view stereo were tuned on **Venus only**
(SPEC §4), red vs blue, left-right check + background fill, by ``benchmarks/table1.py --tune``
(graph cuts weight {1,2,4,8} x truncation {2,4,8} with the coarse-to-fine solver; SGM p1
{0.5,1,2} x p2 {4,8,16}; windows {5,9} for ssd/ncc/rsncc, {5,7} for census; criterion Venus
bad5.0, ties by bad2.0), then fixed for every other scene.  ``--tune`` prints the ``windows``
and ``params`` to paste here; the scores behind them are in BENCHMARKS.md.  The papers behind
the costs are listed in :mod:`hyperlf.costs` (References).
"""

from __future__ import annotations

from . import lightfield as _lf
from . import pair as _pair
from .registry import Cost, FusedCost, register_cost

__all__ = ["SSD", "NCC", "RSNCC", "Census", "BWNCC"]


def _graphcut(weight: float, truncation: float) -> dict:
    return {"smoothness": "truncated_linear", "weight": weight, "truncation": truncation,
            "edge_sigma": None, "max_cycles": 3, "levels": 2}


def _sgm(p1: float, p2: float) -> dict:
    return {"p1": p1, "p2": p2, "paths": 8, "smoothness": "p1p2"}


class _FunctionCost(Cost):
    """A built-in cost whose rectified-pair volume is one function of :mod:`hyperlf.costs.pair`
    called as ``pair_function(left, right, dmin, dmax, window, impl=impl, **options)``."""

    pair_function = None

    def pair_volume(self, left, right, dmin, dmax, *, window=None, impl="auto", **options):
        return type(self).pair_function(left, right, dmin, dmax, self.window_for(window),
                                        impl=impl, **options)


class SSD(Cost):
    """Window mean of ``(InL - InR)^2`` with ``In = I / mean(I)`` (rectified pairs only)."""

    name = "ssd"
    description = "sum of squared differences of mean-normalised intensities (pairs only)"
    window = 5
    windows = {"graphcut": 9}
    params = {"graphcut": _graphcut(8.0, 8.0), "sgm": _sgm(1.0, 16.0)}

    def pair_volume(self, left, right, dmin, dmax, *, window=None, impl="auto", **options):
        return _pair.ssd_volume(left, right, dmin, dmax, self.window_for(window), **options)


class NCC(_FunctionCost):
    """``1 - NCC`` of intensities; NCC is 0 (cost 1) where either patch's variance is below
    ``tau_rel`` (default 1e-5) times the view's mean patch variance (flat patch)."""

    name = "ncc"
    description = "1 - normalised cross-correlation of intensities"
    window = 5
    windows = {"graphcut": 5, "sgm": 5, "wta": 5}
    params = {"graphcut": _graphcut(8.0, 4.0), "sgm": _sgm(2.0, 16.0)}
    pair_function = _pair.ncc_volume

    def view_volume(self, ref_img, img, shifts, *, window=None, valid=None, tau_rel=1e-5,
                    rows=None, **options):
        return _lf.ncc_view_volume(ref_img, img, shifts, self.window_for(window), tau_rel,
                                   rows=rows)


class RSNCC(_FunctionCost):
    """Robust selective NCC (Shen et al. 2014, :mod:`hyperlf.costs` References [1]):
    ``rho(1 - NCC(In)) + tau rho(1 - NCC(|grad In|))``.

    ``rho(x) = -log(exp(-|x|) + exp(|x| - 2))``, ``tau = 1`` (option ``rs_tau``, alias
    ``tau``); ``grad`` is the central difference of ``In`` (borders replicated), ``|grad|``
    its Euclidean magnitude.
    """

    name = "rsncc"
    description = "robust selective NCC of intensities and gradient magnitudes (Shen et al. 2014)"
    window = 5
    windows = {"graphcut": 5}
    dense_window = 3
    params = {"graphcut": _graphcut(8.0, 4.0), "sgm": _sgm(2.0, 16.0)}
    pair_function = _pair.rsncc_volume

    def pair_volume(self, left, right, dmin, dmax, *, window=None, impl="auto", tau=None,
                    **options):
        if tau is not None:
            options["rs_tau"] = tau
        return super().pair_volume(left, right, dmin, dmax, window=window, impl=impl, **options)

    def view_volume(self, ref_img, img, shifts, *, window=None, valid=None, tau_rel=1e-5,
                    rs_tau=1.0, rows=None, impl="auto", **options):
        return _lf.rsncc_view_volume(ref_img, img, shifts, self.window_for(window), tau_rel,
                                     rs_tau, rows=rows, impl=impl)


#: The adaptive support weights of the fusions' census part in two-view stereo: ``gamma`` as a
#: share of each image's 1st-99th percentile range.  Venus (the tuning scene) and six
#: procedural cross-spectral pairs took it for the fusions; Venus refused it for census alone
#: under graph cuts (BENCHMARKS.md, thirty-third session).
SUPPORT_GAMMA = 0.1


class Census(_FunctionCost):
    """Hamming distance of census codes (Zabih & Woodfill 1994, :mod:`hyperlf.costs`
    References [2]): one bit per neighbour of the window (48 bits at 7 x 7), set where the
    neighbour is strictly less than the centre, replicate border.

    Between a light field's views the costs at sub-pixel shifts are averaged over
    ``shift_average`` px of shift (:func:`hyperlf.costs.lightfield.average_over_shift`):
    census is exact only at whole-pixel shifts, and without it the disparities snap to them
    where every view shifts by a whole pixel at the same labels (sparse arrays).

    The pair volume takes ``support_gamma``: adaptive support weights (Yoon & Kweon 2006) of
    both images on each bit, so that a window across a depth edge is matched by its centre's
    side (:func:`hyperlf.costs.pair.census_volume`; default None, every bit counts once).  The
    fusions ask for it in their census part (:data:`SUPPORT_GAMMA`); census alone does not.
    """

    name = "census"
    description = "Hamming distance of census transforms (Zabih & Woodfill 1994)"
    window = 7
    windows = {"graphcut": 7, "sgm": 5, "wta": 5}
    params = {"graphcut": _graphcut(4.0, 8.0), "sgm": _sgm(2.0, 16.0)}
    pair_function = _pair.census_volume
    #: Half-width (px of shift) of the average over labels in :meth:`view_volume`.
    shift_average = 0.5


    def view_volume(self, ref_img, img, shifts, *, window=None, valid=None, rows=None,
                    **options):
        C = _lf.census_view_volume(ref_img, img, shifts, self.window_for(window), rows=rows)
        return _lf.average_over_shift(C, shifts, self.shift_average, valid=valid)


class BWNCC(Cost):
    """BWNCC on the spectral-invariant descriptor (Zhu et al., :mod:`hyperlf.costs`
    References [3]; SPEC §3, :mod:`hyperlf.descriptor`).

    ``paper=False`` (``bwncc``): ``DescriptorParams.default()`` with NCC patch ``n = w`` for
    each level's channels; ``paper=True`` (``bwncc-paper``): the literal
    ``DescriptorParams.paper()`` with ``n = 5`` for all channels.  An explicit window sets
    ``n`` for all channels.
    """

    window = None

    def __init__(self, *, paper: bool = False, params: dict | None = None):
        self.paper = bool(paper)
        self.name = "bwncc-paper" if paper else "bwncc"
        self.description = ("BWNCC on the literal descriptor of the paper (Zhu et al.)" if paper
                            else "bidirectional weighted NCC on the spectral-invariant descriptor")
        self.windows = {}
        self.params = dict(params or {})

    def pair_volume(self, left, right, dmin, dmax, *, window=None, impl="auto", **options):
        return _pair.bwncc_volume(left, right, dmin, dmax, "paper" if self.paper else "default",
                                  window=window, impl=impl, **options)

    def view_volume(self, ref_img, img, shifts, *, window=None, valid=None, tau_rel=1e-5,
                    eps=1e-3, block=68, cache=None, rows=None, **options):
        return _lf.bwncc_view_volume(ref_img, img, shifts, paper=self.paper, window=window,
                                     tau_rel=tau_rel, eps=eps, block=block, cache=cache,
                                     rows=rows)


def _register_builtin() -> None:
    for cost in (
        SSD(), NCC(), RSNCC(), Census(),
        BWNCC(params={"graphcut": _graphcut(4.0, 8.0), "sgm": _sgm(2.0, 16.0)}),
        BWNCC(paper=True, params={"graphcut": _graphcut(2.0, 8.0), "sgm": _sgm(2.0, 16.0)}),
        FusedCost("fused", ("bwncc", "census"),
                  description="(norm(bwncc) + norm(census 7x7)) / 2",
                  params={"graphcut": _graphcut(4.0, 8.0), "sgm": _sgm(2.0, 16.0)},
                  part_options={"census": {"support_gamma": SUPPORT_GAMMA}}),
        FusedCost("census-rsncc", ("rsncc", "census"), view_window_part=0,
                  description="(norm(rsncc 5x5) + norm(census 7x7)) / 2: census for intensity "
                              "order, RSNCC's gradient term where bands reverse contrast",
                  params={"graphcut": _graphcut(2.0, 4.0), "sgm": _sgm(2.0, 16.0)},
                  part_options={"census": {"support_gamma": SUPPORT_GAMMA}}),
    ):
        register_cost(cost, replace=True)


_register_builtin()
