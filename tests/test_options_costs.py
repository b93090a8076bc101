"""Arguments of the cost building blocks (:mod:`hyperlf.costs`: the validity masks, the
out-of-image rule, the window statistics, RSNCC's ``rho``, BWNCC's finish, the normalisers and
the fusion, the light-field shifts and masks, the aggregation, the registry), fuzzed as in
``test_options``: each takes what it documents or refuses it with one line of a hyperlf error
before any work, never a ``TypeError``, ``ValueError``, ``IndexError``, ``OverflowError``,
``cv2.error``, numpy warning or silent NaN from deep inside."""

from __future__ import annotations

import functools
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf import costs
from hyperlf.costs import aggregation, lightfield, pair, registry
from hyperlf.errors import InvalidInputError
from test_options import JUNK, _build_or_refuse


class _Toy(registry.Cost):
    name = "toy-options"
    description = "a cost to register"
    window = 3


@functools.lru_cache(maxsize=1)
def _data():
    rng = np.random.default_rng(0)
    img = rng.random((12, 16)) + 0.5
    other = np.roll(img, 1, axis=1)
    vol = costs.cost_volume(img, other, 0, 3, metric="census")
    mask = np.ones((12, 16), bool)
    mask[3, 4] = False
    return {"img": img, "other": other, "vol": vol, "vol2": costs.cost_volume(
        img, other, 0, 3, metric="ncc"), "valid": costs.candidate_validity((12, 16), 0, 3),
            "mask": mask, "xi": rng.random((4, 12, 16)) * 2 - 1}


def _bases() -> dict:
    """Each building block with one valid call: ``name -> (function, base arguments)``; the
    arrays a function writes into are fresh at every call."""
    d = _data()
    img, other, vol = d["img"], d["other"], d["vol"]
    views = {"ref_img": img, "img": other, "offset": (-1.0, 0.0), "labels": [0.0, 0.5, 1.0]}
    mom = costs.row_moments(vol, d["valid"])
    return {
        "candidate_validity": (costs.candidate_validity, {"shape": (12, 16), "dmin": 0,
                                                          "dmax": 3}),
        "right_validity": (costs.right_validity, {"shape": (12, 16), "dmin": 0, "dmax": 3}),
        "fill_out_of_image": (costs.fill_out_of_image, {"cost": vol.copy(), "dmin": 0,
                                                        "valid": None}),
        "worst_fill": (costs.worst_fill, {"cost": vol.copy(), "invalid": ~d["valid"],
                                          "empty": "zero"}),
        "rho": (costs.rho, {"x": np.linspace(-1, 1, 5)}),
        "rsncc_rho": (costs.rsncc_rho, {"xi_i": d["xi"], "xi_g": d["xi"][::-1].copy(),
                                        "rs_tau": 1.0, "impl": "auto",
                                        "out": np.empty((4, 12, 16), np.float32)}),
        "pad_replicate": (costs.pad_replicate, {"maps": img, "r": 2}),
        "box_mean": (costs.box_mean, {"image": img, "n": 5}),
        "window_stats": (costs.window_stats, {"image": img, "n": 5}),
        "inv_sigma": (costs.inv_sigma, {"var": d["xi"][0] + 1, "tau": 1e-5}),
        "channel_stats": (costs.channel_stats, {"maps": np.stack([img, other]), "n": 5}),
        "shift_cols": (costs.shift_cols, {"a": img, "d": 2, "fill": 0.0}),
        "census_transform": (costs.census_transform, {"image": img, "window": 7}),
        "bwncc_finish": (costs.bwncc_finish, {"acc_fwd": d["xi"], "acc_bwd": d["xi"] + 0.5,
                                              "den_fwd": np.ones((1, 12, 16)),
                                              "den_bwd": np.full((4, 12, 16), 2.0),
                                              "eps": 1e-3, "return_scores": False}),
        "row_moments": (costs.row_moments, {"cost": vol, "valid": d["valid"]}),
        "moments_std": (costs.moments_std, {"n": mom[0], "mean": mom[1], "m2": mom[2]}),
        "normalise_volume": (costs.normalise_volume, {"cost": vol, "dmin": 0, "valid": None,
                                                      "sd": None, "impl": "auto",
                                                      "overwrite": False, "centre": "min"}),
        "fuse": (costs.fuse, {"volumes": [vol, d["vol2"]], "weights": None, "dmin": 0,
                              "valid": None, "scales": None, "impl": "auto",
                              "overwrite": False, "centre": "min"}),
        "light_field_window": (costs.light_field_window, {"metric": "census-rsncc",
                                                          "n_other_views": 29, "window": None,
                                                          "dense_views": 12}),
        "check_rows": (costs.check_rows, {"rows": (0, 12), "height": 12}),
        "view_shifts": (costs.view_shifts, {"offset": (1.0, 0.0), "labels": [0.0, 0.5, 1.0]}),
        "view_validity": (costs.view_validity, {"shape": (12, 16), "mask": d["mask"],
                                                "shifts": [(0.5, 0.0), (1.0, 0.5)],
                                                "rows": None}),
        "tap_validity": (costs.tap_validity, {"mask": d["mask"], "sx": 0.5, "sy": 0.0}),
        "average_over_shift": (costs.average_over_shift, {
            "cost": vol, "shifts": [(0.25 * k, 0.0) for k in range(4)], "half": 0.5,
            "valid": None, "impl": "auto"}),
        "view_costs": (costs.view_costs, {**views, "metric": "ncc", "window": None,
                                          "tau_rel": 1e-5, "eps": 1e-3, "block": 68,
                                          "ref_valid": None, "view_valid": d["mask"],
                                          "rows": None, "scales": None, "weights": None}),
        "view_moments": (costs.view_moments, {**views, "metric": "census-rsncc",
                                              "window": None, "tau_rel": 1e-5, "eps": 1e-3,
                                              "block": 68, "ref_valid": d["mask"],
                                              "view_valid": None, "rows": None}),
        "guide_image": (costs.guide_image, {"image": img}),
        "guided_filter": (costs.guided_filter, {"guide": img, "src": other, "radius": 2,
                                                "eps": 1e-3, "stats": None}),
        "aggregate_volume": (costs.aggregate_volume, {"volume": vol, "guide": img,
                                                      "params": "guided", "valid": None,
                                                      "out": None}),
        "aggregate_pair": (costs.aggregate_pair, {"cost_left": vol, "cost_right": vol,
                                                  "left": img, "right": other, "dmin": 0,
                                                  "params": "guided"}),
        "FusedCost": (costs.FusedCost, {"name": "fz", "parts": ("rsncc", "census"),
                                        "weights": None, "description": "",
                                        "view_window_part": None, "params": None,
                                        "windows": None, "part_options": None}),
        "register_cost": (costs.register_cost, {"cost": _Toy(), "replace": False}),
        "unregister_cost": (costs.unregister_cost, {"name": "ncc"}),
        "get_cost": (costs.get_cost, {"name": "ncc", "light_field": False}),
        "cost_names": (costs.cost_names, {"light_field": False}),
        "resolve_metric": (costs.resolve_metric, {"name": "auto"}),
        "fusion_weights": (costs.fusion_weights, {"name": "auto", "weights": [1, 4]}),
    }


def _call(which: str, /, **kw):
    """``name``'s valid call with ``kw`` instead, the registry restored afterwards, every
    numpy warning an error."""
    function, base = _bases()[which]
    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        warnings.simplefilter("error")
        mp.setattr(registry, "_REGISTRY", dict(registry._REGISTRY))
        return function(**{**base, **kw})


_ARGUMENTS = [(name, keyword) for name, (_, base) in _bases().items() for keyword in base]
#: The costly ones (the per-view costs, the aggregation, the fusion) get a fuzzer of their own.
_SLOW = ("view_costs", "view_moments", "aggregate_volume", "aggregate_pair", "guided_filter",
         "fuse", "normalise_volume")


def _no_new_nan(name: str, out) -> None:
    """The valid calls give finite numbers; so must any call that is not refused."""
    arrays = out if isinstance(out, tuple) else (out,)
    for a in arrays:
        if isinstance(a, np.ndarray) and a.dtype.kind == "f":
            assert np.isfinite(a).all(), name


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.sampled_from([a for a in _ARGUMENTS if a[0] not in _SLOW]), JUNK)
def test_the_building_blocks_take_any_argument_or_refuse_it_in_one_line(argument, value):
    """The validity masks, the fill, ``rho``, the window statistics, the shifts and masks of
    the views, the registry (some 700 of 1100 junk arguments were tracebacks in the
    forty-fifth session's survey: ``right_validity(None, ...)``, ``shift_cols(a, 2.5)``,
    ``pad_replicate(maps, -1)``, ``unregister_cost([1])``, ``FusedCost(parts=-1)``, ...)."""
    name, keyword = argument
    _no_new_nan(name, _build_or_refuse(lambda **kw: _call(name, **kw), **{keyword: value}))


@settings(max_examples=80, deadline=None, derandomize=True)
@given(st.sampled_from([a for a in _ARGUMENTS if a[0] in _SLOW]), JUNK)
def test_the_costly_ones_too(argument, value):
    """The per-view costs' images, offsets, labels and masks (``offset=None``, ``labels='x'``,
    ``view_valid=0``), the normaliser's ``sd=1e-300`` (infinite costs), the fusion's
    ``scales='x'``, the guided filter's ``radius=10**400`` and ``out='x'``."""
    name, keyword = argument
    _no_new_nan(name, _build_or_refuse(lambda **kw: _call(name, **kw), **{keyword: value}))


@pytest.mark.parametrize("name, kw, words", [
    ("right_validity", {"shape": None}, "shape must be an image shape (..., H, W)"),
    ("candidate_validity", {"dmax": 1e300}, "dmin and dmax must be integers"),
    ("fill_out_of_image", {"cost": np.zeros(3)}, "cost (L, H, W) must be a non-empty 3-D"),
    ("fill_out_of_image", {"valid": np.zeros((3, 3))}, "valid has shape (3, 3)"),
    ("worst_fill", {"empty": None}, "empty must be one of zero, global"),
    ("rho", {"x": 1e300}, "x must be within +-700"),
    ("rho", {"x": "x"}, "x must be a finite number, got 'x'"),
    ("rsncc_rho", {"out": [1]}, "out must be a writeable float numpy array"),
    ("rsncc_rho", {"xi_g": np.zeros(3)}, "xi_g must be a float numpy array of out's shape"),
    ("pad_replicate", {"r": -1}, "r must be an integer in 0..127"),
    ("box_mean", {"n": 4}, "n must be an odd integer >= 1, got 4"),
    ("inv_sigma", {"tau": float("nan")}, "tau must be a finite number >= 0"),
    ("channel_stats", {"n": [3, 5, 7]}, "n must be one patch size or 2"),
    ("shift_cols", {"d": 2.5}, "d must be an integer, got 2.5"),
    ("shift_cols", {"a": [1]}, "a must be a numpy array of numbers"),
    ("bwncc_finish", {"den_fwd": 1e-300, "den_bwd": 1e-300}, "the BWNCC scores acc / den "
                                                             "overflow"),
    ("bwncc_finish", {"acc_bwd": [1]}, "acc_bwd must be a float numpy array"),
    ("bwncc_finish", {"den_bwd": np.zeros(3)}, "den_bwd of shape (3,) does not fit acc_fwd's"),
    ("moments_std", {"n": np.zeros(3)}, "n, mean and m2 must have one entry per row each"),
    ("normalise_volume", {"sd": 1e-300}, "sd must be 0 or at least 1e-20"),
    ("fuse", {"scales": "x"}, "scales must give one number per volume (2)"),
    ("fuse", {"volumes": "x"}, "volumes must be a list of (L, H, W) arrays"),
    ("light_field_window", {"n_other_views": "x"}, "n_other_views must be an integer >= 0"),
    ("light_field_window", {"window": float("nan")}, "window must be an odd integer >= 1"),
    ("check_rows", {"height": np.zeros(3)}, "height must be an integer >= 0"),
    ("view_shifts", {"offset": [1]}, "offset must be two finite numbers (dx, dy)"),
    ("view_shifts", {"labels": 1e300}, "labels must be finite numbers (1-D)"),
    ("view_validity", {"mask": np.zeros((3, 3))}, "mask has shape (3, 3)"),
    ("tap_validity", {"sx": float("nan")}, "sx must be a finite number, got nan"),
    ("average_over_shift", {"half": -1}, "half must be a finite number in [0, 1e+12], got -1"),
    # an overflow in the box's weights with impl "numpy" or "numba" (the base call's "auto"
    # never drew it; found by fuzzing the other options under each mode)
    ("average_over_shift", {"half": 1e308, "impl": "numpy"}, "half must be a finite number in "
                                                            "[0, 1e+12]"),
    ("average_over_shift", {"shifts": [(0.0, 0.0), (1e300, 0.0)]}, "shifts must be finite "
                                                                   "(sx, sy) pairs of at most"),
    ("view_costs", {"offset": None}, "offset must be an array of real numbers, got None"),
    ("view_costs", {"ref_img": None}, "ref_img and img must be 2-D images of one shape"),
    ("view_moments", {"view_valid": 0}, "view_valid has shape ()"),
    ("guide_image", {"image": "x"}, "the guide must be an array of real numbers, got 'x'"),
    ("guided_filter", {"radius": 10 ** 400}, "radius must be an integer in 1..127"),
    ("aggregate_volume", {"out": "x"}, "out must be a writeable float32 array"),
    ("aggregate_pair", {"dmin": 2.5}, "dmin must be an integer"),
    ("FusedCost", {"parts": "x"}, "fz: parts must be a sequence of registered cost names"),
    ("FusedCost", {"params": [1]}, "fz: params must be a dict (or None)"),
    ("FusedCost", {"view_window_part": 2}, "view_window_part must be an integer in 0..1"),
    ("unregister_cost", {"name": [1]}, "no registered cost named [1]"),
    ("get_cost", {"light_field": np.zeros(3)}, "light_field must be True or False"),
])
def test_a_former_traceback_names_the_argument(name, kw, words):
    with pytest.raises(InvalidInputError) as exc:
        _call(name, **kw)
    assert str(exc.value).startswith(words), str(exc.value)
    assert "\n" not in str(exc.value)


def test_integral_floats_are_taken_as_integers():
    assert pair.shift_cols(np.arange(4.0), 1.0).tolist() == [0.0, 0.0, 1.0, 2.0]
    assert costs.light_field_window("ncc", 3.0, window=5.0) == 5
    assert type(costs.light_field_window("ncc", 3, window=5.0)) is int
    assert costs.check_rows((0.0, 12.0), 12.0) == (0, 12)
    assert costs.candidate_validity((2.0, 3.0), 0.0, 1.0).shape == (2, 2, 3)


def test_the_numpy_cross_term_is_private():
    """Used by the reference path of the pair NCC only, so it is not exported (checked there
    by the pair costs' own checks)."""
    assert "ncc_cross_accumulate" not in costs.__all__
    assert hasattr(pair, "_ncc_cross_accumulate")
    assert "MAX_VIEW_WINDOW" in dir(lightfield) and "guided_filter" in aggregation.__all__


@pytest.mark.parametrize("name", sorted(_bases()))
def test_every_valid_call_works(name):
    """The fuzzers replace one argument of these calls: each must run as it is, or every
    refusal above would pass for the wrong reason."""
    _no_new_nan(name, _call(name))
