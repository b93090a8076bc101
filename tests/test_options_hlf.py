"""The stages of :func:`hyperlf.hlf.depth` and their building blocks, called on their own: every
argument takes what it documents or is refused with one line of :class:`InvalidInputError`
before any work (a stage given something that is not a :class:`hyperlf.hlf.DepthProblem`, a
map or volume of another shape, a non-finite cost, junk options), never an
``AttributeError``, ``TypeError``, ``IndexError``, numba typing error or NaN from deep inside
(some 1100 failing probes in the forty-fifth session's survey)."""

from __future__ import annotations

import dataclasses
import functools
import inspect
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf import hlf, synthesis
from hyperlf.errors import InvalidInputError

from test_options import JUNK, _build_or_refuse


@functools.lru_cache(maxsize=1)
def _stage_calls():
    """One valid call per public function of :mod:`hyperlf.hlf` (beyond ``depth``,
    ``prepare`` and ``post_filter``, fuzzed in ``test_options``), as ``name -> (function,
    keyword arguments)``, on a 3 x 3 scene of 32 x 40 px with 6 labels."""
    lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=32, width=40)
    prob = hlf.prepare(lf, n_labels=6, metric="ncc")  # the cheapest cost
    sel = hlf.prepare(lf, n_labels=6, view_selection=True)
    spectral = hlf.prepare(lf, n_labels=6, defocus="gaussian")
    textured = hlf.prepare(lf, n_labels=6, params=hlf.DepthParams(texture_snr=2.0))
    C, n_used = hlf.correspondence(prob)
    f_c = prob.labels[np.argmin(C, axis=0)].astype(np.float32)
    U, _, _ = hlf.unary(C, None, prob.params)
    lab, vol = hlf.regularise(prob, U, f_c)
    disp, conf = hlf.refine(vol, lab, prob.labels, prob.params)
    w = hlf.texture_weight(textured)
    prior = (f_c, (1 - w).astype(np.float32), 0.5, conf)
    H, W = lf.image_shape
    v = prob.others[0]
    Cv = C.copy()
    valid = np.ones(C.shape, bool)
    views = np.stack([spectral.In[u] for u in spectral.views])
    wl = np.array([lf.wavelengths[u] for u in spectral.views], float)
    offsets = np.array([prob.offsets[u] for u in spectral.views], float)
    acc = lambda: hlf._new_accumulators(*C.shape, 0)  # noqa: E731
    aggregation = {"Cv": Cv, "valid": valid, "Mq": sel.Mbar, "Mbar": sel.Mbar,
                   "M_ref": sel.M_ref, "use_selection": True, "edge_idx": None,
                   "edge_side": None}
    return {
        "correspondence": (hlf.correspondence, {"prob": prob, "sees": hlf.visible_views(
            prob, disp), "strips": [(0, H)], "timings": {}, "store": None, "progress": False}),
        "defocus_cue": (hlf.defocus_cue, {"prob": spectral, "f_c": f_c}),
        "neutral_missing_views": (hlf.neutral_missing_views, {"C": C, "n_used": n_used}),
        "views_at_every_label": (hlf.views_at_every_label, {"prob": prob}),
        "texture_weight": (hlf.texture_weight, {"prob": textured}),
        "coarse_prior": (hlf.coarse_prior, {"prob": textured, "weight": w, "start": None,
                                            "progress": False}),
        "plane_prior": (hlf.plane_prior, {"prob": textured, "weight": w, "prior": prior,
                                          "progress": False}),
        "add_coarse_prior": (lambda **kw: hlf.add_coarse_prior(**{"U": U.copy(), **kw}), {
            "labels": prob.labels, "coarse": f_c, "strength": prior[1], "width": 0.5}),
        "unary": (hlf.unary, {"C": C, "D": C, "params": prob.params, "informative": None,
                              "weight": w}),
        "regularise": (hlf.regularise, {"prob": prob, "U": U, "f_c": f_c, "init": lab}),
        "refine": (hlf.refine, {"volume": vol, "labels_map": lab, "labels": prob.labels,
                                "params": prob.params, "informative": None, "weight": w,
                                "prior": prior}),
        "prior_free_confidence": (hlf.prior_free_confidence, {
            "volume": vol, "labels_map": lab, "labels": prob.labels, "prior": prior,
            "rows": 8, "floor": 0.1}),
        "edge_discount": (hlf.edge_discount, {"conf": conf, "disparity": disp,
                                              "params": prob.params}),
        "median_passes": (hlf.median_passes, {"guide": prob.ref_img, "params": prob.params,
                                              "valid": None}),
        "guide_noise": (hlf.guide_noise, {"guide": prob.ref_img, "valid": None}),
        "seen_pixels": (hlf.seen_pixels, {"prob": prob, "n_used": n_used}),
        "visible_views": (hlf.visible_views, {"prob": prob, "disparity": disp}),
        "LabelVisibility": (hlf.LabelVisibility, {"prob": prob, "disparity": disp,
                                                  "nearest": True}),
        "visibility": (hlf.visibility, {"prob": prob, "disparity": disp, "last": False}),
        "occluder_margins": (hlf.occluder_margins, {"margin": 0.5, "largest": 8.0}),
        "make_labels": (hlf.make_labels, {"dmin": -1.0, "dmax": 1.0, "n_labels": 5}),
        "with_margin": (hlf.with_margin, {"labels": np.array([-1.0, 0.0, 1.0]), "margin": 2}),
        "range_labels": (hlf.range_labels, {"n": 7, "margin": 2}),
        "selection_masks": (hlf.selection_masks, {"M_ref": sel.M_ref, "Mq": sel.Mbar,
                                                  "valid": valid, "Mbar": sel.Mbar}),
        "aggregate_view": (lambda **kw: hlf.aggregate_view(**{"acc": acc(), **kw}),
                           {**aggregation, "impl": "auto"}),
        "aggregate_view_reference": (lambda **kw: hlf.aggregate_view_reference(
            **{"acc": acc(), **kw}), aggregation),
        "half_plane_sides": (hlf.half_plane_sides, {"gx": [1.0, 0.5], "gy": [0.0, 2.0],
                                                    "offsets": offsets}),
        "reference_edges": (hlf.reference_edges, {"ref_img": prob.ref_img, "sigma": 1.0,
                                                  "low": None, "high": None, "dilate": 1}),
        "defocus_cost": (hlf.defocus_cost, {
            "P": views, "valid": True, "wl": wl, "lam_r": 550.0, "prior": "gaussian",
            "sigma_d": 96.5, "p_eps": 1e-6, "impl": "auto"}),
        "defocus_cost_reference": (hlf.defocus_cost_reference, {
            "P": views, "valid": True, "wl": wl, "lam_r": np.full((H, W), 550.0),
            "prior": "gaussian", "sigma_d": 96.5, "p_eps": 1e-6}),
        "defocus_volume": (hlf.defocus_volume, {
            "In_views": views, "offsets": offsets, "wl": wl, "labels": prob.labels[:3],
            "prior": "gaussian", "lambda_r": "per_pixel", "f_c": f_c, "camera": "CIE 1931",
            "sigma_d": 96.5, "achromatic_radius": 0.01, "p_eps": 1e-6, "impl": "auto",
            "valid": None}),
        "normalise_unary": (hlf.normalise_unary, {"X": C, "enabled": True, "mask": None}),
        "DepthResult": (hlf.DepthResult, {"disparity": disp, "confidence": conf, "f_c": f_c,
                                          "f_d": None, "labels": prob.labels}),
        "DepthProblem": (hlf.DepthProblem, {f.name: getattr(prob, f.name)
                                            for f in dataclasses.fields(prob)}),
    }


def _arguments(name, function, base):
    if name in ("DepthResult", "DepthProblem"):
        return [f.name for f in dataclasses.fields(function)]
    target = function.__init__ if isinstance(function, type) else function
    names = [p for p in inspect.signature(target).parameters if p not in ("self", "kw")]
    return names or list(base)


_OPTIONS = [(name, arg) for name, (f, base) in _stage_calls().items()
            for arg in _arguments(name, f, base)]


def _call(name, **kw):
    function, base = _stage_calls()[name]
    return function(**{**base, **kw})


def test_every_public_name_has_a_valid_call_here():
    fuzzed_elsewhere = {"depth", "prepare", "post_filter", "DepthParams", "view_costs",
                        "shift_map"}
    names = {n for n in hlf.__all__ if callable(getattr(hlf, n))} - fuzzed_elsewhere
    assert names <= set(_stage_calls())
    for name in _stage_calls():
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            _call(name)


def _no_nan_where_the_valid_call_has_none(name, out):
    """A call that takes a value gives no NaN or inf where the valid call gives none."""
    def arrays(x):
        if isinstance(x, np.ndarray) and x.dtype.kind == "f":
            yield x
        elif isinstance(x, (tuple, list)):
            for y in x:
                yield from arrays(y)
        elif isinstance(x, dict):
            for y in x.values():
                yield from arrays(y)
    if name in ("median_passes", "DepthResult", "DepthProblem"):  # NaN: blur not measured
        return
    if all(np.isfinite(a).all() for a in arrays(_valid_output(name))):
        assert all(np.isfinite(a).all() for a in arrays(out)), name


@functools.lru_cache(maxsize=None)
def _valid_output(name):
    return _call(name)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.sampled_from(_OPTIONS), JUNK)
def test_the_stages_take_any_argument_or_refuse_it_in_one_line(option, value):
    """Each argument of every stage and helper replaced by junk (``prob=None``: an
    AttributeError, ``sees={}``: a KeyError, ``store={}``: a numba typing error,
    ``edge_idx=-1``: a TypeError, ``timings=2.5``, ``lam_r=nan``: NaN costs, ...)."""
    name, keyword = option
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an overflow or invalid value on the way fails too
        out = _build_or_refuse(lambda **kw: _call(name, **kw), **{keyword: value})
    if out is not None:
        _no_nan_where_the_valid_call_has_none(name, out)


@pytest.mark.parametrize("name, keyword, value, words", [
    ("correspondence", "prob", None, "prob must be a DepthProblem (from hyperlf.hlf.prepare), "
                                     "got NoneType"),
    ("regularise", "prob", np.zeros(3), "prob must be a DepthProblem"),
    ("correspondence", "sees", {}, "sees must be None, a LabelVisibility or a dict of bool"),
    ("correspondence", "store", {}, "store must be None or a ViewCostStore, got dict"),
    ("correspondence", "timings", 2.5, "timings must be None or a dict"),
    ("correspondence", "strips", 2.5, "strips must be None or a list of row ranges"),
    ("unary", "C", np.zeros((3, 3)), "C must be a 3-D array (an L x H x W volume)"),
    ("unary", "weight", np.zeros(3), "weight must have shape (32, 40) (an H x W map)"),
    ("refine", "params", "x", "params must be a DepthParams (or None for its defaults)"),
    ("refine", "prior", 2.5, "prior must be None or the tuple of coarse_prior"),
    ("prior_free_confidence", "rows", 0, "rows must be an integer >= 1, got 0"),
    ("add_coarse_prior", "width", 0, "width must be a finite number in [1e-09, 1e+09]"),
    ("edge_discount", "conf", np.nan, "conf must have shape (32, 40) (an H x W map), got nan"),
    ("visible_views", "disparity", np.zeros((3, 3)), "disparity must have shape (32, 40)"),
    ("regularise", "init", np.full((32, 40), 9), "init must hold label indices in 0..5"),
    ("neutral_missing_views", "n_used", np.zeros(3), "n_used must have shape (6, 32, 40)"),
    ("aggregate_view", "edge_idx", [-1], "edge_idx must hold flat pixel indices"),
    ("aggregate_view", "valid", np.zeros(3), "valid has shape (3,), which does not match Cv"),
    ("aggregate_view", "use_selection", 1, "use_selection must be True or False, got 1"),
    ("half_plane_sides", "offsets", np.zeros(3), "offsets must be view offsets (dx, dy)"),
    ("half_plane_sides", "gx", np.nan, "gx must be a 1-D array"),
    ("reference_edges", "sigma", 1e300, "sigma must be a finite number in [0, 100]"),
    ("defocus_cost", "lam_r", np.nan, "lam_r must be a finite number in (0, 1e+06]"),
    ("defocus_cost", "wl", np.zeros(3), "wl must have shape (9,) (one per view)"),
    ("defocus_cost", "sigma_d", 1e-300, "sigma_d must be a finite number in [0.001, 1e+06]"),
    ("defocus_cost_reference", "p_eps", 0, "p_eps must be a finite number > 0, got 0"),
    ("defocus_volume", "lambda_r", "x", "lambda_r must be 'per_label', 'per_pixel' or a"),
    ("defocus_volume", "f_c", np.zeros(3), "f_c must have shape (32, 40)"),
    ("make_labels", "dmin", "x", "dmin must be a finite number, got 'x'"),
    ("make_labels", "n_labels", 1e300, "1e+300 labels would need about"),
    ("with_margin", "margin", -1, "margin must be"),
    ("with_margin", "labels", np.array([0.0]), "labels must hold at least 2 disparities"),
    ("range_labels", "n", 4, "4 labels hold no range inside a margin of 2"),
    ("normalise_unary", "X", np.full((2, 3, 3), np.nan), "X must be finite (no NaN or inf)"),
    ("selection_masks", "Mq", np.zeros((2, 1, 1)), "M_ref (32, 40), Mq (2, 1, 1) and Mbar"),
    ("DepthResult", "disparity", None, "disparity must be an array of real numbers, got None"),
    ("DepthResult", "f_c", np.zeros(3), "f_c must have shape (32, 40)"),
    ("DepthProblem", "labels", "x", "labels must be an array of real numbers, got 'x'"),
])
def test_a_former_failure_is_refused_naming_the_argument(name, keyword, value, words):
    extra = {"edge_side": [0]} if keyword == "edge_idx" else {}  # edges need both
    with pytest.raises(InvalidInputError) as exc:
        _call(name, **{keyword: value, **extra})
    assert str(exc.value).startswith(words), str(exc.value)
    assert "\n" not in str(exc.value)


def test_a_non_finite_volume_is_refused_by_the_stages():
    C = _stage_calls()["unary"][1]["C"].copy()
    C[2, 5, 7] = np.inf
    with pytest.raises(InvalidInputError, match="^C must be finite"):
        _call("unary", C=C)
    with pytest.raises(InvalidInputError, match="^D must be finite"):
        _call("unary", D=C)
    with pytest.raises(InvalidInputError, match="^U must be finite"):
        _call("regularise", U=C)
    with pytest.raises(InvalidInputError, match="^volume must be finite"):
        _call("refine", volume=C)


def test_a_wide_dilation_is_taken_as_the_image():
    """``dilate`` beyond the image's longer side asked for a kernel of that size (10**9 px:
    a MemoryError); it dilates the same as the image's side."""
    ref = _stage_calls()["reference_edges"][1]["ref_img"]
    edges, _ = hlf.reference_edges(ref, dilate=10 ** 9)
    same, _ = hlf.reference_edges(ref, dilate=max(ref.shape))
    np.testing.assert_array_equal(edges, same)
