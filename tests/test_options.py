"""Option values (``hyperlf._options``, the one home of those checks): every parameter class,
and every keyword option of ``twoview.stereo``, ``completion.complete`` and the rendering
functions, takes what it documents, keeps it in its canonical type, and refuses anything else
with one line of :class:`InvalidInputError` before any work, never a ``TypeError``,
``ValueError`` or ``OverflowError`` from deep inside."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import doctest
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf import _options as opt
from hyperlf.costs import AggregationParams
from hyperlf.descriptor import DescriptorParams
from hyperlf.errors import HyperLFError, InvalidInputError
from hyperlf.hlf import DepthParams
from hyperlf.regularisers import ConfidenceParams, GraphCutParams, PlaneFillParams, SGMParams

#: What a user might pass by mistake: strings, NaN, infinities, huge and negative numbers,
#: bools, containers, arrays, numpy scalars.
JUNK = (st.none() | st.booleans() | st.text(max_size=6) | st.integers()
        | st.integers(min_value=10 ** 300, max_value=10 ** 400) | st.floats()
        | st.lists(st.integers(), max_size=2) | st.dictionaries(st.text(max_size=2), st.none())
        | st.floats(width=32).map(np.float32) | st.integers(-9, 9).map(np.int64)
        | st.just(np.zeros(2)) | st.just(np.zeros((3, 3))) | st.just(np.bool_(True)))


@contextlib.contextmanager
def _in_temp_folder(warn: str | None = None, category=Warning):
    """A fresh temporary working folder for a call, yielded as a Path: the writers' relative
    paths land there, never in the checkout.  Where ``warn`` is given it is the warning
    filter's action (``"error"``, ``"ignore"``) for ``category`` inside."""
    with tempfile.TemporaryDirectory() as folder, pytest.MonkeyPatch.context() as mp, \
            warnings.catch_warnings():
        mp.chdir(folder)
        if warn is not None:
            warnings.simplefilter(warn, category)
        yield Path(folder)


def _build_or_refuse(cls, **kwargs):
    """Build or call ``cls``; a refusal must be one line of a hyperlf error (an invalid value,
    or a camera name read as a path that does not exist), never another exception."""
    try:
        return cls(**kwargs)
    except HyperLFError as exc:
        assert "\n" not in str(exc) and str(exc)
        return None


def test_the_module_examples_run():
    assert doctest.testmod(opt, optionflags=doctest.ELLIPSIS).failed == 0


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.sampled_from([f.name for f in dataclasses.fields(DepthParams)]), JUNK)
def test_depth_params_take_any_value_or_refuse_it_in_one_line(name, value):
    params = _build_or_refuse(DepthParams, **{name: value})
    if params is not None and name in ("window", "dense_views", "block", "max_cycles",
                                       "mrf_levels", "median_radius", "tile_rows",
                                       "texture_window", "visibility_rounds"):
        kept = getattr(params, name)
        assert kept is None or type(kept) is int  # an integral float is kept as an int


OTHERS = (GraphCutParams, SGMParams, AggregationParams, PlaneFillParams, ConfidenceParams,
          DescriptorParams)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.sampled_from([(cls, f.name) for cls in OTHERS for f in dataclasses.fields(cls)]),
       JUNK)
def test_the_other_parameter_classes_too(cls_name, value):
    cls, name = cls_name
    _build_or_refuse(cls, **{name: value})


@pytest.mark.parametrize("cls", (DepthParams,) + OTHERS)
def test_the_defaults_are_kept_as_they_are_written(cls):
    params = cls()
    for f in dataclasses.fields(cls):
        value = getattr(params, f.name)
        assert value == f.default and type(value) is type(f.default), f.name


@pytest.mark.parametrize("name, value, words", [
    ("window", 4, "params.window must be None or an odd integer >= 1, got 4"),
    ("block", 2.5, "params.block must be an integer >= 1"),
    ("min_selected", "3", "params.min_selected must be an integer >= 1, got '3'"),
    ("mrf_levels", 5, "params.mrf_levels must be an integer in 0..4"),
    ("max_cycles", float("inf"), "params.max_cycles must be an integer >= 0, got inf"),
    ("confidence_floor", 1.0, "params.confidence_floor must be a finite number in [0, 1)"),
    ("plane_max_slope", 0.0, "params.plane_max_slope must be a finite number in (0, 1]"),
    ("texture_snr", 0.5, "params.texture_snr must be None, 0 (off) or > 1"),
    ("lambda_r", "per_view", "params.lambda_r must be None, 'per_label', 'per_pixel' or"),
    ("median_passes", 0, "params.median_passes must be 'auto' or an integer in 1..50, got 0"),
    ("tile_rows", 100, "params.tile_rows must be a multiple of 32, got 100"),
    ("refine", 1, "params.refine must be True or False, got 1"),
    ("missing_views", ["average"], "params.missing_views must be one of average, neutral"),
    ("sgm_paths", 6, "params.sgm_paths must be one of 2, 4, 8"),
])
def test_depth_params_name_the_option_and_what_it_takes(name, value, words):
    with pytest.raises(InvalidInputError) as exc:
        DepthParams(**{name: value})
    assert str(exc.value).startswith(words)


def test_integers_and_numbers_in_their_canonical_types():
    assert opt.integer(np.int64(4), "n") == 4 and type(opt.integer(4.0, "n")) is int
    assert opt.integer(None, "n", optional=True) is None
    assert type(opt.number(np.float32(0.5), "x")) is float
    assert opt.share(1, "s") == 1.0 and opt.flag(np.bool_(False), "f") is False
    for bad in (True, 4.5, float("nan"), 10 ** 400, "4", -1, None):
        with pytest.raises(InvalidInputError, match="^n must be an integer >= 0, got "):
            opt.integer(bad, "n")
    for bad, kw in ((0, {"positive": True}), (1.0, {"below": 1}), (1.5, {"at_most": 1}),
                    (-0.1, {}), (float("inf"), {}), (True, {})):
        with pytest.raises(InvalidInputError, match="^x must be a finite number "):
            opt.number(bad, "x", **kw)
    with pytest.raises(InvalidInputError, match=r"^s must be a share in \[0, 1\], got 1.5"):
        opt.share(1.5, "s")
    with pytest.raises(InvalidInputError, match="^c must be one of a, b, got"):
        opt.choice(np.zeros(2), "c", ("a", "b"))


def test_an_unknown_camera_is_refused_before_any_matching(monkeypatch):
    from hyperlf import hlf, synthesis

    lf = synthesis.procedural_scene(seed=1, rows=2, cols=2, height=24, width=24,
                                    disparity_range=(-1.0, 1.0))
    monkeypatch.setattr(hlf, "correspondence", lambda *a, **k: pytest.fail("matched"))
    with pytest.raises(InvalidInputError, match="unknown camera 'nosuchcam'"):
        hlf.depth(lf, n_labels=8, defocus="paper", params=DepthParams(camera="nosuchcam"))


@settings(max_examples=80, deadline=None, derandomize=True)
@given(st.sampled_from(["metric", "optimizer", "occlusion", "subpixel", "params", "window",
                        "channel", "cost_params", "plane_params", "aggregation",
                        "confidence_params"]), JUNK)
def test_stereo_options_are_taken_or_refused_in_one_line(name, value):
    """``twoview.stereo``'s keyword options (``cost_params=1.5`` was a TypeError)."""
    from hyperlf import twoview

    rng = np.random.default_rng(0)
    left = rng.random((20, 28)).astype(np.float32)
    _build_or_refuse(lambda **kw: twoview.stereo(left, np.roll(left, -2, axis=1), (0, 4), **kw),
                     **{name: value})


@pytest.mark.parametrize("n", [1, 2.5, float("inf"), 10 ** 400, "8", True, None])
def test_a_label_count_is_an_integer_of_at_least_two(n):
    from hyperlf.hlf import make_labels

    with pytest.raises(InvalidInputError, match="n_labels must be an integer >= 2"):
        make_labels(-1.0, 1.0, n)


@settings(max_examples=80, deadline=None, derandomize=True)
@given(st.sampled_from(["disparity", "out_path", "metric", "optimizer", "band", "guidance", "window",
                        "params", "wls_lambda", "edge_sigma", "init_confidence",
                        "stereo_confidence", "fill_confidence", "keep_initial", "occlusion_tol",
                        "max_iter"]), JUNK)
def test_completion_takes_any_option_or_refuses_it_in_one_line(name, value):
    """``completion.complete``'s options (``band='x'``, ``max_iter=inf``, ``out_path=2.5``
    and 40-odd more were TypeErrors or ValueErrors from deep inside)."""
    from hyperlf import completion, synthesis

    lf = synthesis.procedural_scene(seed=1, rows=2, cols=2, height=12, width=12,
                                    disparity_range=(-1.0, 1.0))
    options = {"disparity": lf.gt_disparity[lf.reference], name: value}
    with _in_temp_folder():  # an out_path such as 'x' is written there
        _build_or_refuse(completion.complete, lf=lf, **options)


def test_real_arrays_and_keyword_values():
    assert opt.real_array([1, 2], "a").dtype == np.float64
    assert np.isinf(opt.real_array([1e300], "a", np.float32)).all()  # inf, for _finite to name
    for bad in ("x", {"a": 1}, [[1], [1, 2]], ["1", "b"]):
        with pytest.raises(InvalidInputError, match="^a must be an array of real numbers"):
            opt.real_array(bad, "a")
    assert opt.shown(np.zeros((3, 3))).count("\n") == 0 and len(opt.shown("x" * 99)) == 60
    checked = opt.check_values({"n": 4.0, "other": "kept"}, {"n": opt.integer, "m": opt.flag})
    assert checked == {"n": 4, "other": "kept"} and type(checked["n"]) is int


def test_array_takes_several_ndims_and_a_non_empty_rule():
    """The one array check: a tuple of allowed axis counts, emptiness refused only when asked,
    bools only where the kinds allow them, and an ndarray returned as it is."""
    a = np.zeros((2, 3))
    assert opt.array(a, "a", ndim=(2, 3)) is a
    assert opt.array(np.zeros((0, 3)), "a", ndim=2).shape == (0, 3)
    for value, words in ((np.zeros(4), "a must be a non-empty 2-D or 3-D array, got shape (4,)"),
                         (np.zeros((0, 3)), "a must be a non-empty 2-D or 3-D array, got shape "
                                            "(0, 3)"),
                         (np.ones((2, 2), bool), "a must be an array of real numbers")):
        with pytest.raises(InvalidInputError) as exc:
            opt.array(value, "a", ndim=(2, 3), kinds="iuf", empty=False)
        assert str(exc.value).startswith(words), str(exc.value)
    with pytest.raises(InvalidInputError, match="^a must be a non-empty array, got"):
        opt.array([], "a", empty=False)


def test_windows_and_bands_beyond_the_image_are_refused():
    """They asked for terabytes (a 100001 px window on a 28 px image) before any message. A
    window may reach past the image on one side (a default window on a tiny image)."""
    from hyperlf import completion, hlf, synthesis, twoview

    lf = synthesis.procedural_scene(seed=1, rows=2, cols=2, height=12, width=12,
                                    disparity_range=(-1.0, 1.0))
    left = np.random.default_rng(0).random((20, 28)).astype(np.float32)
    with pytest.raises(InvalidInputError, match="window 59 px reaches past the image on both"):
        twoview.stereo(left, left, (0, 4), window=59)
    twoview.stereo(left, left, (0, 4), window=57, optimizer="wta")
    with pytest.raises(InvalidInputError, match="params.window 27 px reaches past the views"):
        hlf.depth(lf, n_labels=8, params=DepthParams(window=27))
    truth = lf.gt_disparity[lf.reference]
    with pytest.raises(InvalidInputError, match="window 27 px reaches past the image"):
        completion.complete(lf, truth, window=27)
    with pytest.raises(InvalidInputError, match="band 13 px is wider than the 12 x 12 px"):
        completion.complete(lf, truth, band=13)


def test_parameter_objects_and_output_paths_are_refused_in_one_line(tmp_path):
    """``plane_params=np.zeros(2)`` was numpy's ambiguous-truth ValueError; ``out_path=''``
    an OSError from renaming the finished file onto the working folder."""
    from hyperlf import completion, synthesis, twoview

    left = np.random.default_rng(0).random((20, 28)).astype(np.float32)
    for name in ("plane_params", "confidence_params"):
        with pytest.raises(InvalidInputError, match=f"^{name} must be a "):
            twoview.stereo(left, left, (0, 4), **{name: np.zeros(2)})
    lf = synthesis.procedural_scene(seed=1, rows=2, cols=2, height=12, width=12,
                                    disparity_range=(-1.0, 1.0))
    for bad in ("", tmp_path):
        with pytest.raises(InvalidInputError, match="^out_path must be a file to write"):
            completion.complete(lf, lf.gt_disparity[lf.reference], out_path=bad)


def _render_calls():
    """Each public function of :mod:`hyperlf.render` on a tiny cube (or H-LF views), with
    its required arguments, as ``name -> (function, call)``; the fuzzers set one keyword."""
    from hyperlf import render

    rng = np.random.default_rng(0)
    cube = rng.random((2, 3, 4, 10, 12)).astype(np.float32)
    views = cube[:, :, 0]
    wl, view_wl = np.array([450.0, 520.0, 590.0, 650.0]), np.linspace(420, 680, 6).reshape(2, 3)
    base = {"offsets": np.stack(np.meshgrid(np.arange(3) - 1.0, np.arange(2) - 0.5), -1),
            "wavelengths": wl}
    return {
        "refocus": (render.refocus, lambda **kw: render.refocus(cube, **{**base, **kw})),
        "refocus of views": (render.refocus, lambda **kw: render.refocus(
            views, **{**base, "wavelengths": view_wl, "profile": "band:500", **kw})),
        "focal_stack": (render.focal_stack, lambda **kw: render.focal_stack(
            cube, **{**base, "disparities": (0.0, 1.0), **kw})),
        "all_focus": (render.all_focus, lambda **kw: render.all_focus(
            cube, **{**base, "disparity": np.zeros((10, 12)), **kw})),
        "emulate_camera": (render.emulate_camera, lambda **kw: render.emulate_camera(
            cube[0], **{"wavelengths": wl, **kw})),
        "spectrum_at": (render.spectrum_at, lambda **kw: render.spectrum_at(
            cube, **{"wavelengths": wl, "x": 3, "y": 4, **kw})),
        "camera_matrix": (render.camera_matrix, lambda **kw: render.camera_matrix(
            **{"camera": "CIE 1931", "wavelengths": wl, **kw})),
        "fit_ccm": (render.fit_ccm, lambda **kw: render.fit_ccm(
            **{"camera": "CIE 1931", "wavelengths": wl, **kw})),
    }


def _keywords(function, leave=("views_or_cube", "cube_or_views", "cube", "kwargs", "out_dir",
                                "path")):
    import inspect

    return [p for p in inspect.signature(function).parameters if p not in leave]


_RENDER = _render_calls()
_RENDER_OPTIONS = [(name, p) for name, (f, _) in _RENDER.items() for p in _keywords(f)]


@settings(max_examples=400, deadline=None, derandomize=True)
@given(st.sampled_from(_RENDER_OPTIONS), JUNK)
def test_rendering_takes_any_option_or_refuses_it_in_one_line(option, value):
    """Every keyword of refocusing, the focal stack, all-focus, camera emulation and the
    spectra (``white_balance`` as an array was numpy's ambiguous truth value, ``fill='x'``,
    ``aperture=10**400``, ``reference=True``, ``view=''`` and some 60 more were tracebacks)."""
    name, keyword = option
    _build_or_refuse(_RENDER[name][1], **{keyword: value})


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.sampled_from(["disparities", "fps", "formats", "output", "exposure", "annotate",
                        "stem", "bit_depth", "points", "labels", "view", "title"]), JUNK)
def test_the_sweep_and_the_spectrum_figure_too(keyword, value):
    """``formats=None``, ``stem=10**400``, ``points=None`` and ``labels=True`` were
    tracebacks; the files go into a temporary folder."""
    from hyperlf import render

    cube = np.random.default_rng(0).random((2, 3, 4, 10, 12)).astype(np.float32)
    wl = np.array([450.0, 520.0, 590.0, 650.0])
    with tempfile.TemporaryDirectory() as folder:
        if keyword in _keywords(render.focal_sweep):
            _build_or_refuse(render.focal_sweep, views_or_cube=cube, out_dir=folder,
                             **{"wavelengths": wl, "disparities": [0.0, 1.0],
                                "formats": ("gif",), keyword: value})
        if keyword in _keywords(render.save_spectrum_figure):
            _build_or_refuse(render.save_spectrum_figure, path=f"{folder}/s.png", cube=cube,
                             **{"wavelengths": wl, "points": [(2, 3)], keyword: value})


@pytest.mark.parametrize("keyword, value", [("title", "a\x00b"), ("labels", ["\U000cef6c"]),
                                            ("ylabel", "x\ny")])
def test_figure_texts_are_printable(keyword, value, tmp_path):
    """A figure's title and labels: a character no font has a glyph for (control, unassigned)
    was drawn as a box with a matplotlib warning; it is now refused by name."""
    from hyperlf import render, visualise

    cube = np.random.default_rng(0).random((1, 1, 4, 10, 12)).astype(np.float32)
    wl = np.array([450.0, 520.0, 590.0, 650.0])
    words = f"^{keyword}(\\[0\\])? must be printable text"
    with pytest.raises(InvalidInputError, match=words):
        visualise.save_spectrum_plot(tmp_path / "p.png", wl, cube[0, 0, :, 0, 0],
                                     **{keyword: value})
    if keyword != "ylabel":
        with pytest.raises(InvalidInputError, match=words):
            render.save_spectrum_figure(path=tmp_path / "s.png", cube=cube, wavelengths=wl,
                                        points=[(2, 3)], **{keyword: value})
    assert not list(tmp_path.iterdir())


@functools.lru_cache(maxsize=1)
def _completion_stage_calls():
    """:func:`completion.pairwise_disparities` and :func:`completion.refine_disparity` on a
    tiny capture, as :func:`_render_calls`."""
    from hyperlf import completion, synthesis

    lf = synthesis.procedural_scene(seed=1, rows=2, cols=2, height=12, width=16,
                                    disparity_range=(-1.0, 1.0))
    init = completion.propagate_disparity(lf, lf.gt_disparity[lf.reference])
    z = init[0, 0]
    return {
        "pairwise_disparities": (completion.pairwise_disparities, lambda **kw:
                                 completion.pairwise_disparities(**{"lf": lf, "initial": init,
                                                                    **kw})),
        "refine_disparity": (completion.refine_disparity, lambda **kw:
                             completion.refine_disparity(**{"image": lf.views[0, 0], "z": z,
                                                            "c": np.ones_like(z), **kw})),
    }


@settings(max_examples=160, deadline=None, derandomize=True)
@given(st.sampled_from([(name, p) for name, (f, _) in _completion_stage_calls().items()
                        for p in _keywords(f, leave=("lf", "progress"))]), JUNK)
def test_completion_stages_take_any_option_or_refuse_it_in_one_line(option, value):
    """The stages of completion called on their own (``guidance=None``, ``band=nan``,
    ``params='x'``, ``lam={}``, ``edge_sigma=1e300`` and some 60 more were tracebacks or
    overflows; ``wls_lambda``, ``guidance`` and the confidences are at most 1e6)."""
    import warnings

    name, keyword = option
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an overflow on the way is a failure too
        _build_or_refuse(_completion_stage_calls()[name][1], **{keyword: value})


@functools.lru_cache(maxsize=1)
def _matching_calls():
    """The pair costs with their constants, two-view stereo on given volumes, and the H-LF
    depth's checks (:func:`hlf.prepare`; ``save_intermediate`` and ``progress`` through
    :func:`hlf.depth`), as :func:`_render_calls`."""
    from hyperlf import costs, hlf, synthesis, twoview

    img = np.random.default_rng(0).random((12, 16)) + 0.5
    vol = costs.cost_volume(img, img, 0, 3, metric="census")
    lf = synthesis.procedural_scene(seed=1, rows=2, cols=2, height=12, width=12,
                                    disparity_range=(-1.0, 1.0))
    pair = {"left": img, "right": img, "dmin": 0, "dmax": 3}
    view = {"ref_img": img, "img": img, "shifts": [(0.5, 0.0), (1.0, 0.0)]}
    calls = {
        "ncc_volume": (costs.ncc_volume, pair),
        "rsncc_volume": (costs.rsncc_volume, pair),
        "bwncc_volume": (costs.bwncc_volume, pair),
        "fused_volume": (costs.fused_volume, pair),
        "census_rsncc_volume": (costs.census_rsncc_volume, pair),
        "cost_volume": (costs.cost_volume, {**pair, "metric": "census"}),
        "cost_volumes": (costs.cost_volumes, {**pair, "metric": "ncc"}),
        "compute_volumes": (twoview.compute_volumes, {**pair, "metric": "ncc"}),
        "stereo_from_volumes": (twoview.stereo_from_volumes,
                                {"cost_left": vol, "cost_right": vol, "dmin": 0,
                                 "guide_left": img}),
        "prepare": (hlf.prepare, {"lf": lf, "n_labels": 4}),
        "census_view_volume": (costs.census_view_volume, view),
        "rsncc_view_volume": (costs.rsncc_view_volume, view),
    }
    out = {name: (f, lambda f=f, base=base, **kw: f(**{**base, **kw}))
           for name, (f, base) in calls.items()}
    out["depth"] = (hlf.depth, lambda **kw: hlf.depth(lf, n_labels=4, **kw))
    return out


_MATCHING_OPTIONS = [(name, p) for name, (f, _) in _matching_calls().items()
                     for p in _keywords(f, leave=("lf", "params", "metric", "view_selection",
                                                  "occlusion_split", "disparity_range",
                                                  "bwncc_params", "rsncc_params"))
                     if name != "depth" or p in ("save_intermediate", "progress")]


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.sampled_from(_MATCHING_OPTIONS), JUNK)
def test_costs_stereo_and_depth_take_any_option_or_refuse_it_in_one_line(option, value):
    """The pair costs' constants (``tau_rel='x'``, ``rs_tau=1e300``: infinite costs,
    views of two shapes or rows beyond them in the per-view evaluators: crashes in numba,
    ``eps=0``, ``block=nan``, ``timings=2.5``), their disparity bounds (``dmax=1e300``: numpy's
    "Maximum allowed size exceeded"), ``stereo_from_volumes``' ``dmin`` and volumes, and the
    depth's ``n_labels=1e300``, ``defocus`` / ``optimizer`` as arrays and its flags (some 260
    failing cases in the forty-fourth session's survey). The memory available is taken as
    256 MiB. Overflow warnings count as failures."""
    import warnings

    from hyperlf import tiling

    name, keyword = option
    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        warnings.simplefilter("error")
        mp.setattr(tiling, "available_memory", lambda: 2 ** 28)
        _build_or_refuse(_matching_calls()[name][1], **{keyword: value})


def test_indices_and_fill_values():
    assert opt.index(np.array([1, 0]), "view", (2, 2)) == (1, 0)
    for bad in (True, "ab", (1,), (1, 2.5), (2, 0), (0, -1), None, {0: 1}):
        with pytest.raises(InvalidInputError, match=r"^view must be 2 integers within \(2, 2\)"):
            opt.index(bad, "view", (2, 2))
    assert np.isnan(opt.real(np.float32("nan"), "fill", nan=True))
    for bad in (float("nan"), float("inf"), 10 ** 400, "0", True):
        with pytest.raises(InvalidInputError, match="^fill must be a finite number, got"):
            opt.real(bad, "fill")


def _library_calls():
    """The spectra, metrics and synthetic scenes, as :func:`_render_calls`."""
    from hyperlf import imageops, metrics, spectral, synthesis, warp
    from hyperlf import regularisers as reg

    rng = np.random.default_rng(0)
    wl, truth, cube = np.array([450.0, 520.0, 590.0, 650.0]), rng.random((8, 8)), rng.random(
        (4, 8, 8))
    pair = {"estimate": truth + 0.1, "truth": truth}
    cubes = {"estimate": cube + 0.1, "truth": cube}
    spectra = {"spectra": rng.random((3, 4)), "wavelengths": wl}
    xy = {"xy": np.array([0.4, 0.4])}
    calls = {
        "procedural_scene": (synthesis.procedural_scene, {"rows": 2, "cols": 2, "height": 12,
                                                          "width": 12}),
        "band_grid": (synthesis.band_grid, {"rows": 2, "cols": 3}),
        "add_noise": (synthesis.add_noise, {"views": rng.random((2, 2, 8, 8)), "sigma": 0.01}),
        "view_disparity_from_reference": (synthesis.view_disparity_from_reference,
                                          {"gt_ref": truth, "offset": (1.0, 0.0)}),
        "cmfs": (spectral.cmfs, {"wavelengths": wl}),
        "camera_sensitivities": (spectral.camera_sensitivities,
                                 {"name_or_path": "CIE 1931", "wavelengths": wl}),
        "spectrum_to_xyz": (spectral.spectrum_to_xyz, spectra),
        "spectrum_to_rgb": (spectral.spectrum_to_rgb, spectra),
        "dominant_wavelength": (spectral.dominant_wavelength, xy),
        "dominant_wavelength_for_filters": (spectral.dominant_wavelength_for_filters,
                                            {**xy, "lambda_min": 410.0, "lambda_max": 700.0}),
        "filter_response": (spectral.filter_response, {"center_nm": 500.0, "wavelengths": wl}),
        "xyz_to_srgb": (spectral.xyz_to_srgb, {"xyz": rng.random((3, 3))}),
        "xyz_to_xy": (spectral.xyz_to_xy, {"xyz": rng.random((3, 3))}),
        "bad_pixels": (metrics.bad_pixels, {**pair, "tau": 1.0}),
        "bad_pixel_breakdown": (metrics.bad_pixel_breakdown,
                                {**pair, "tau": 1.0, "classes": {"all": truth > -1}}),
        "badpix": (metrics.badpix, pair),
        "disparity_scores": (metrics.disparity_scores, pair),
        "psnr": (metrics.psnr, pair),
        "psnr_per_band": (metrics.psnr_per_band, cubes),
        "sam": (metrics.sam, cubes),
        "range_limit_shares": (metrics.range_limit_shares,
                               {"disparity": truth, "disparity_range": (0, 2)}),
        "shift_image": (warp.shift_image, {"image": truth, "dx": 1.0, "dy": 0.5}),
        "warp_to_reference": (warp.warp_to_reference,
                              {"image": truth, "disparity": truth, "offset": (1.0, 0.0)}),
        "forward_warp_disparity": (warp.forward_warp_disparity,
                                   {"disparity": truth, "offset": (1.0, 0.0)}),
        "visible_in_view": (warp.visible_in_view, {"disparity": truth, "offset": (1.0, 0.0)}),
        "shift_map": (warp.shift_map, {"img": truth, "sx": 1.0, "sy": 0.5}),
        "sample_bilinear": (warp.sample_bilinear, {"image": truth, "x": 5 * truth,
                                                   "y": 5 * truth}),
        "normalise_intensity": (imageops.normalise_intensity, {"image": truth}),
        "gradient_magnitude": (imageops.gradient_magnitude, {"image": truth}),
        "noise_sigma": (imageops.noise_sigma, {"image": truth}),
        "texture_snr": (imageops.texture_snr, {"image": truth}),
        "edge_blur": (imageops.edge_blur, {"image": truth}),
        "block_reduce": (imageops.block_reduce, {"a": truth}),
        "graphcut": (reg.graphcut, {"cost": cube}),
        "graphcut_multiscale": (reg.graphcut_multiscale, {"cost": cube}),
        "sgm": (reg.sgm, {"cost": cube, "p1": 0.1, "p2": 1.0}),
        "fill_invalid": (reg.fill_invalid, {"cost": cube}),
        "segment": (reg.segment, {"guide": truth}),
        "edge_confidence": (reg.edge_confidence, {"disparity": truth}),
        "weighted_median": (reg.weighted_median, {"disparity": truth, "guide": truth}),
        "candidate_labels": (reg.candidate_labels, {"volume": cube, "k": 2}),
    }
    return {name: (f, lambda f=f, base=base, **kw: f(**{**base, **kw}))
            for name, (f, base) in calls.items()}


_LIBRARY = _library_calls()
_LIBRARY_OPTIONS = [(name, p) for name, (f, _) in _LIBRARY.items()
                    for p in _keywords(f, leave=("progress",))]


@settings(max_examples=1200, deadline=None, derandomize=True)
@given(st.sampled_from(_LIBRARY_OPTIONS), JUNK)
def test_spectra_metrics_and_scenes_take_any_option_or_refuse_it_in_one_line(option, value):
    """Every argument of the spectral conversions, the metrics, the synthetic scenes, the
    warps, the image operations and the regularisers (``observer=None``, ``axis=None``,
    ``band_axis=''``, ``data_range=1e300``, ``lut_size=1e300``, ``rows='x'``, ``kinds=''``,
    ``quantum_efficiency={}``, ``offset='x'``, ``fill={}``, ``factor=0``, ``paths`` as an
    array, ``seed='x'`` and some 300 more were tracebacks, divisions by zero among them). The
    memory available is taken as 256 MiB, so that a valid but huge scene (``rows=1689``:
    6.6 GB, 77 s) is refused as too large."""
    from hyperlf import tiling

    name, keyword = option
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(tiling, "available_memory", lambda: 2 ** 28)
        _build_or_refuse(_LIBRARY[name][1], **{keyword: value})


#: Explicit objects of every kind, with every texture key, a ring and a stick: the fuzzer below
#: replaces one of their values (``(key,)``, ``("texture", key)`` or ``("shape", key)``).
_OBJECTS = (
    {"kind": "plane", "disparity": 0.0, "name": "background",
     "texture": {"pattern": "noise", "period": 0.1, "chips": [1, 2],
                 "waves": [[1.0, 0.5, 0.2], [0.3, 1.0, 1.0]]}},
    {"kind": "plane", "disparity": 0.6, "rect": [0.1, 0.1, 0.5, 0.9], "gradient": [0.2, 0.1],
     "shape": {"kind": "ring", "hole": 0.5},
     "texture": {"pattern": "patches", "colors": 4, "salt": 7, "jitter": [0.1, 0.2]}},
    {"kind": "plane", "disparity": 0.4, "rect": [0.5, 0.0, 1.0, 1.0],
     "shape": {"kind": "stick", "ends": [[0.6, 0.1], [0.9, 0.9]], "width": 0.1},
     "texture": {"pattern": "stripes", "angle": 30.0}},
    {"kind": "box", "disparity": 0.8, "rect": [0.2, 0.2, 0.4, 0.4], "depth": 0.3},
    {"kind": "sphere", "disparity": 0.9, "center": [0.7, 0.6], "radius": 0.2},
)
_OBJECT_KEYS = sorted({(i, (k,)) for i, o in enumerate(_OBJECTS) for k in o}
                      | {(i, (part, k)) for i, o in enumerate(_OBJECTS)
                         for part in ("texture", "shape") for k in o.get(part, {})})


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.sampled_from(_OBJECT_KEYS), JUNK)
def test_any_object_value_is_taken_or_refused_in_one_line(where, value):
    """Junk in any key of an explicit object of ``procedural_scene`` (its texture and shape
    included) is taken or refused in one line, with no warning (an overflow warned)."""
    import warnings

    from hyperlf import synthesis

    i, key = where
    objects = [dict(o, **{p: dict(o[p]) for p in ("texture", "shape") if p in o})
               for o in _OBJECTS]
    target = objects[i] if len(key) == 1 else objects[i][key[0]]
    target[key[-1]] = value
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _build_or_refuse(synthesis.procedural_scene, rows=1, cols=2, height=12, width=12,
                         disparity_range=(-1.0, 1.0), objects=objects)


def test_a_scene_beyond_the_memory_is_refused_before_any_work(monkeypatch):
    from hyperlf import synthesis, tiling

    monkeypatch.setattr(tiling, "available_memory", lambda: 4 * 16 * 12 * 12 - 1)
    with pytest.raises(InvalidInputError, match="^a 2 x 2 scene of 12 x 12 px with 4 bands "
                                                "would need about"):
        synthesis.procedural_scene(rows=2, cols=2, height=12, width=12)
    with pytest.raises(InvalidInputError, match=f"got {synthesis.MAX_SUPERSAMPLE + 1}$"):
        synthesis.procedural_scene(rows=2, cols=2, height=12, width=12,
                                   supersample=synthesis.MAX_SUPERSAMPLE + 1)


@functools.lru_cache(maxsize=1)
def _calibration_calls():
    """Calibration on the synthetic rig's board shots, as :func:`_render_calls`."""
    from hyperlf import calibration
    from hyperlf.calibration.rig import make_rig

    rig = make_rig(seed=5)
    shots = rig.render(rig.board_pose(450.0, tilt=(4.0, -3.0, 2.0)))
    cal = calibration.register_plane(shots, rig.board)
    calls = {
        "BoardSpec": (calibration.BoardSpec, {"cols": rig.board.cols, "rows": rig.board.rows}),
        "detect_board": (calibration.detect_board, {"image": shots[(0, 0)], "board": rig.board}),
        "register_plane": (calibration.register_plane, {"shots": shots, "board": rig.board}),
        "calibrate": (calibration.calibrate, {"shots": shots, "board": rig.board}),
        "apply_calibration": (calibration.apply_calibration,
                              {"calibration": cal, "images": shots}),
        "view_maps": (calibration.view_maps, {"calibration": cal, "key": (0, 0)}),
    }
    return {name: (f, lambda f=f, base=base, **kw: f(**{**base, **kw}))
            for name, (f, base) in calls.items()}


_CALIBRATION_OPTIONS = [
    ("BoardSpec", "cols"), ("BoardSpec", "rows"), ("BoardSpec", "square"),
    ("detect_board", "image"), ("detect_board", "board"), ("detect_board", "detect_size"),
    ("detect_board", "partial"), ("register_plane", "shots"), ("register_plane", "board"),
    ("register_plane", "names"), ("register_plane", "focal_px"),
    ("register_plane", "positions_from"), ("register_plane", "work_size"),
    ("register_plane", "max_parallax"), ("register_plane", "min_parallax_px"),
    ("calibrate", "shots"), ("calibrate", "mode"), ("calibrate", "names"),
    ("apply_calibration", "calibration"), ("apply_calibration", "images"),
    ("apply_calibration", "names"), ("apply_calibration", "saturation"),
    ("view_maps", "calibration"), ("view_maps", "key")]


@settings(max_examples=150, deadline=None, derandomize=True)
@given(st.sampled_from(_CALIBRATION_OPTIONS), JUNK)
def test_calibration_takes_any_option_or_refuses_it_in_one_line(option, value):
    """The board, its detection, plane registration, calibration and its application
    (``detect_size=2`` and an 8 px shot were OpenCV assertion errors, ``names=True``,
    ``shots=None``, ``positions_from`` as an array, ``focal_px=1e300``, ``view_maps`` of an
    unknown camera and some 100 more were tracebacks)."""
    name, keyword = option
    _build_or_refuse(_calibration_calls()[name][1], **{keyword: value})


def test_a_reference_camera_outside_the_grid_is_refused_in_one_line():
    from hyperlf import calibration

    board = calibration.BoardSpec(7, 5)
    shots = {(r, c): np.zeros((40, 40)) for r in range(2) for c in range(2)}
    for bad in ((2, 0), (0, -1), True, "ab", (0.5, 0)):
        with pytest.raises(InvalidInputError, match=r"^the reference camera must be 2 integers "
                                                    r"within \(2, 2\)"):
            calibration.register_plane(shots, board, reference=bad)
