"""Every argument of the descriptor's helpers, the regularisers' building blocks, the warps'
taps, two-view stereo's fill, the metrics, the spectra and the scenes takes what it documents
or is refused with one line of :class:`InvalidInputError` before any work, never a
``TypeError``, ``ValueError``, ``IndexError`` or numpy warning from deep inside (the
forty-fifth session's survey: some 700 probes of these functions failed)."""

from __future__ import annotations

import dataclasses
import functools
import inspect
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_options import JUNK, _build_or_refuse

from hyperlf.errors import InvalidInputError


@functools.lru_cache(maxsize=1)
def _calls():
    """``name -> (function, valid keyword arguments)``, on tiny inputs."""
    from hyperlf import descriptor as D
    from hyperlf import imageops, metrics, render, spectral, synthesis, twoview, warp
    from hyperlf import regularisers as reg

    rng = np.random.default_rng(0)
    img = rng.random((12, 16)) + 0.5
    guide = rng.random((12, 16))
    disp = np.full((12, 16), 1.0)
    cvol = rng.random((5, 12, 16)).astype(np.float32)
    cube = rng.random((4, 12, 16)).astype(np.float32)
    truth = rng.random((8, 8))
    wl = np.array([450.0, 520.0, 590.0, 650.0])
    prep = D.prepare(img)
    gx, gy, M, _ = D.gradients(D.normalise(img))
    _, idx, wts = warp.bilinear_taps(np.full((4, 5), 2.5), np.full((4, 5), 3.5), (12, 16))
    valid = reg.left_right_check(disp, disp)
    calls = {
        "gradients": (D.gradients, {"In": img}),
        "bin_weights": (D.bin_weights, {"values": M}),
        "auto_sigma_w": (D.auto_sigma_w, {"M": M}),
        "edge_weights": (D.edge_weights, {"M": M}),
        "magnitude_direction": (D.magnitude_direction, {"gx": gx, "gy": gy}),
        "prepare_from_gradients": (D.prepare_from_gradients, {"gx": gx, "gy": gy}),
        "descriptor": (D.descriptor, {"image": img, "channels": slice(0, 4)}),
        "descriptor_reference": (D.descriptor_reference, {"image": img,
                                                          "channels": slice(0, 4)}),
        "iter_descriptor_blocks": (D.iter_descriptor_blocks, {"image": prep, "block": 300}),
        "PreparedDescriptor": (D.PreparedDescriptor, {
            f.name: getattr(prep, f.name) for f in dataclasses.fields(prep)
            if f.name != "cache"}),
        "params_dict": (reg.params_dict, {"params": reg.SGMParams()}),
        "data_term": (reg.data_term, {"cost": cvol}),
        "edge_weights_from_guide": (reg.edge_weights_from_guide, {"guide": guide}),
        "plane_fill": (reg.plane_fill, {"disparity": disp, "reliable": disp > 0,
                                        "guide": guide}),
        "cost_planes": (reg.cost_planes, {"volume": rng.random((4, 24, 24)),
                                          "mask": np.ones((24, 24), bool), "tile": 12,
                                          "max_slope": 0.1}),
        "fill_inconsistent": (twoview.fill_inconsistent, {
            "disp_l": disp, "disp_r": disp, "valid": valid, "occlusion": "lr-fill",
            "guide": guide}),
        "coordinate_taps": (warp.coordinate_taps, {"coord": np.array([0.5, 3.2]), "n": 8}),
        "axis_taps": (warp.axis_taps, {"n": 8, "shift": 0.5}),
        "axis_valid": (warp.axis_valid, {"n": 8, "shift": 0.5}),
        "bilinear_taps": (warp.bilinear_taps, {"x": np.full((4, 5), 2.5),
                                               "y": np.full((4, 5), 3.5), "shape": (12, 16)}),
        "gather_taps": (warp.gather_taps, {"flat": img.ravel(), "idx": idx, "wts": wts}),
        "visible_at_labels": (warp.visible_at_labels, {
            "zbuffer": warp.occlusion_zbuffer(disp, (1.0, 0.0)), "offset": (1.0, 0.0),
            "labels": np.array([0.0, 1.0]), "impl": "numpy"}),
        "occluder_excess": (warp.occluder_excess, {
            "zbuffer": warp.occlusion_zbuffer(disp, (1.0, 0.0)), "offset": (1.0, 0.0),
            "labels": np.array([0.0, 1.0]), "rows": (2, 5), "impl": "numpy"}),
        "normalise_intensity": (imageops.normalise_intensity, {"image": img}),
        "texture_snr": (imageops.texture_snr, {"image": img}),
        "srgb_to_linear": (spectral.srgb_to_linear, {"x": guide}),
        "band_index": (render.band_index, {"wavelengths": wl, "lam": 520.0}),
        "emulate_camera": (render.emulate_camera, {"cube": cube, "wavelengths": wl}),
        "spectrum_at": (render.spectrum_at, {"cube": cube, "wavelengths": wl, "x": 3, "y": 4}),
        "hci_scores": (metrics.hci_scores, {"estimate": np.zeros((40, 40)),
                                            "truth": np.full((40, 40), 0.5)}),
        "disparity_scores": (metrics.disparity_scores, {"estimate": truth + 0.1,
                                                        "truth": truth}),
        "cube_scores": (metrics.cube_scores, {"estimate": cube[None, None] + 0.1,
                                              "truth": cube[None, None]}),
        "add_noise": (synthesis.add_noise, {"views": rng.random((2, 2, 8, 8)), "sigma": 0.01}),
        "named_scene": (synthesis.named_scene, {"name": next(iter(synthesis.SCENES))}),
    }
    return calls


def _options():
    return [(name, p) for name, (f, _) in _calls().items()
            for p, v in inspect.signature(f).parameters.items()
            if v.kind not in (v.VAR_KEYWORD, v.VAR_POSITIONAL)]


def _call(_name, **kw):
    f, base = _calls()[_name]
    out = f(**{**base, **kw})
    return list(out) if inspect.isgenerator(out) else out


@pytest.mark.parametrize("name", sorted(_calls()))
def test_the_valid_calls_run(name):
    _call(name)


@settings(max_examples=500, deadline=None, derandomize=True)
@given(st.sampled_from(_options()), JUNK)
def test_every_argument_is_taken_or_refused_in_one_line(option, value):
    """Each argument of each function replaced by junk; a numpy warning (an overflow, a
    division by zero on the way) counts as a failure too."""
    name, keyword = option
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        _build_or_refuse(lambda **kw: _call(name, **kw), **{keyword: value})


@pytest.mark.parametrize("name, keyword, value, words", [
    ("gradients", "In", "x", "In must be an array of real numbers"),
    ("gradients", "method", np.zeros(2), "gradient method must be one of central, sobel"),
    ("bin_weights", "values", float("nan"), "values must be finite (no NaN or inf)"),
    ("auto_sigma_w", "M", 1e300, "M must be at most 1e+150 in magnitude"),
    ("edge_weights", "sigma_w", "x", "sigma_w must be a finite number >= 0 or None"),
    ("magnitude_direction", "gy", np.zeros(3), "gx and gy must have the same shape"),
    ("prepare_from_gradients", "params", 2.5, "params must be a DescriptorParams"),
    ("descriptor", "weighted", np.zeros(3), "weighted must be True or False"),
    ("iter_descriptor_blocks", "block", float("inf"), "block must be an integer >= 1"),
    ("iter_descriptor_blocks", "params", np.zeros(3), "params must be a DescriptorParams"),
    ("PreparedDescriptor", "M", None, "PreparedDescriptor.M must be a 2-D float array"),
    ("params_dict", "params", {}, "params must be the parameters of an optimiser"),
    ("data_term", "overwrite", np.zeros(3), "overwrite must be True or False"),
    ("edge_weights_from_guide", "edge_sigma", 1e-300, "edge_sigma must be a finite number"),
    ("plane_fill", "params", np.zeros(3), "params must be a PlaneFillParams"),
    ("cost_planes", "tile", None, "tile must be an integer >= 4"),
    ("cost_planes", "max_slope", 1e300, "max_slope must be a finite number in (0, 10000]"),
    ("cost_planes", "period", float("nan"), "period must be a finite number"),
    ("cost_planes", "min_share", "x", "min_share must be a finite number"),
    ("fill_inconsistent", "valid", None, "valid must be an array of real numbers, got None"),
    ("fill_inconsistent", "drange", 2.5, "drange must be (low, high)"),
    ("coordinate_taps", "n", float("nan"), "n must be an integer in 1..1048576"),
    ("coordinate_taps", "n", 1e300, "n must be an integer in 1..1048576"),
    ("coordinate_taps", "dtype", "x", "dtype must be numpy.float32 or numpy.float64"),
    ("axis_taps", "n", 1e300, "n must be an integer in 1..1048576"),
    ("axis_taps", "pad", -1, "pad must be an integer in 0..4096"),
    ("bilinear_taps", "shape", 0, "shape must be (H, W), two integers >= 1"),
    ("bilinear_taps", "x", np.zeros(3), "x and y must broadcast to one shape"),
    ("gather_taps", "flat", np.zeros(3), "idx holds indices beyond the 3 pixels of flat"),
    ("gather_taps", "wts", [1], "wts must be the 4 weight arrays of bilinear_taps"),
    ("visible_at_labels", "zbuffer", 2.5, "zbuffer must be an (H, W) map"),
    ("visible_at_labels", "rows", [1], "rows must be (first, end) reference rows"),
    ("visible_at_labels", "offset", None, "offset must be an array of real numbers, got None"),
    ("occluder_excess", "zbuffer", 2.5, "zbuffer must be an (H, W) map"),
    ("occluder_excess", "labels", [np.inf], "labels must be finite disparities"),
    ("normalise_intensity", "image", float("inf"), "image mean must be positive and finite"),
    ("srgb_to_linear", "x", 1e300, "sRGB values must be of a size"),
    ("band_index", "lam", "x", "a band profile needs a finite wavelength in nm"),
    ("emulate_camera", "fill", -1e300, "fill must be a number float32 holds"),
    ("emulate_camera", "exposure", 1e300,
     "an exposure gain must be a finite number in (0, 1e+30]"),
    ("spectrum_at", "x", float("nan"), "x and y must be finite pixel positions"),
    ("hci_scores", "truth", "x", "truth must be an array of real numbers"),
    ("cube_scores", "data_range", None, "data_range must be a finite number > 0"),
    ("add_noise", "sigma", 1e300, "noise sigma must be a finite number in [0, 1e+06]"),
    ("named_scene", "name", {}, "unknown scene {}"),
])
def test_former_failures_name_the_argument(name, keyword, value, words):
    """Each was a TypeError, ValueError, IndexError, an overflow or NaN from deep inside."""
    with pytest.raises(InvalidInputError) as exc:
        _call(name, **{keyword: value})
    assert str(exc.value).startswith(words), str(exc.value)
    assert "\n" not in str(exc.value)


def test_private_window_weights_and_the_iterator_refuses_at_the_call():
    """``gaussian_window`` was an internal building block (now private); the block iterator
    refuses its arguments when called, not at the first block."""
    from hyperlf import descriptor as D

    assert not hasattr(D, "gaussian_window") and "gaussian_window" not in D.__all__
    with pytest.raises(InvalidInputError, match="^impl must be one of"):
        D.iter_descriptor_blocks(np.ones((4, 4)), impl="cuda")
