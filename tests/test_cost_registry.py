"""The cost registry (hyperlf.costs.registry): a toy cost registered from outside the library
runs through two-view stereo and H-LF depth; names and errors come from one place."""

from __future__ import annotations

import argparse

import cv2
import numpy as np
import pytest

import hyperlf
from hyperlf import costs, hlf, synthesis, twoview
from hyperlf.costs import Cost, box_mean, fill_out_of_image, shift_cols
from hyperlf.errors import InvalidInputError
from hyperlf.imageops import normalise_intensity
from hyperlf.warp import shift_map


class SAD(Cost):
    """The toy of docs/developers.md: window mean of ``|In_left - In_right|``, ``In = I / mean(I)``."""

    name = "sad"
    description = "sum of absolute differences of mean-normalised intensities"
    window = 5
    params = {"graphcut": {"weight": 2.0, "truncation": 4.0}, "sgm": {"p1": 1.0, "p2": 8.0}}

    def pair_volume(self, left, right, dmin, dmax, *, window=None, impl="auto", **options):
        n = self.window if window is None else window
        a = normalise_intensity(np.asarray(left, np.float64))
        b = normalise_intensity(np.asarray(right, np.float64))
        vol = np.stack([box_mean(np.abs(a - shift_cols(b, d)), n) for d in range(dmin, dmax + 1)])
        return fill_out_of_image(vol.astype(np.float32), dmin)

    def view_volume(self, ref_img, img, shifts, *, window=None, valid=None, **options):
        n = self.window if window is None else window
        a = normalise_intensity(ref_img)
        b = normalise_intensity(img)
        return np.stack([box_mean(np.abs(a - shift_map(b, sx, sy, 0)[0]), n)
                         for sx, sy in shifts]).astype(np.float32)


@pytest.fixture
def sad():
    with costs.registered_cost(SAD()) as cost:
        yield cost
    assert "sad" not in costs.cost_names()


def _pair():
    """Textured rectified pair: background disparity 3, a square at 7 (left x = right x - d)."""
    rng = np.random.default_rng(0)
    tex = cv2.GaussianBlur(rng.random((40, 72)), (0, 0), 1.0) + 0.2
    gt = np.full((40, 64), 3.0)
    gt[10:30, 20:44] = 7.0
    right = tex[:, 8:72]
    xs = np.arange(64)[None, :] + 8 - gt.astype(int)
    left = np.take_along_axis(tex, xs, axis=1)
    return left, right, gt


def test_toy_cost_is_registered_and_listed(sad):
    assert costs.get_cost("SAD") is sad
    assert "sad" in costs.cost_names() and "sad" in costs.cost_names(light_field=True)
    assert "sad" in costs.METRIC_NAMES and "sad" in costs.METRICS
    assert twoview.default_params("sad", "graphcut")["weight"] == 2.0
    assert twoview.default_window("sad", "sgm") is None
    with pytest.raises(InvalidInputError, match="already registered"):
        costs.register_cost(SAD())


def test_toy_cost_two_view_stereo(sad):
    left, right, gt = _pair()
    res = hyperlf.stereo(left, right, (0, 10), metric="sad")
    assert res.metric == "sad" and res.params["weight"] == 2.0
    bad1 = np.mean(np.abs(res.disparity - gt)[:, 10:] > 1)    # columns with both views' support
    assert bad1 < 0.15, bad1
    # the registry's right-referenced volume is the shift of the left one
    cl, cr = costs.cost_volumes(left, right, 0, 10, "sad")
    np.testing.assert_array_equal(cl, costs.cost_volume(left, right, 0, 10, metric="sad"))
    assert cr.shape == cl.shape


def test_toy_cost_hlf_depth(sad):
    lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=32, width=40)
    gt = lf.reference_gt_disparity
    res = hyperlf.depth(lf, n_labels=16, metric="sad")
    assert res.config["metric"] == "sad"
    err = np.abs(res.disparity - gt)
    assert np.median(err) < 0.3, np.median(err)                # label step 4 / 15 = 0.27
    assert np.mean(err > 0.5) < 0.2, np.mean(err > 0.5)
    ref = np.abs(hyperlf.depth(lf, n_labels=16, metric="ncc").disparity - gt)
    assert np.mean(err > 0.5) <= np.mean(ref > 0.5) + 0.05     # as good as the built-in NCC


def test_toy_view_volume_matches_pair_volume_at_integer_shifts(sad):
    left, right, _ = _pair()
    labels = np.arange(0, 6, dtype=np.float64)
    C, valid = costs.view_costs(left, right, (1.0, 0.0), labels, "sad")
    P = costs.cost_volume(left, right, 0, 5, metric="sad")
    np.testing.assert_allclose(C[:, 3:-3, 8:-3], P[:, 3:-3, 8:-3], atol=1e-6)


def test_unregister_and_errors():
    with costs.registered_cost(SAD()):
        pass
    with pytest.raises(InvalidInputError, match="unknown metric 'sad'; choose one of ssd, ncc"):
        costs.get_cost("sad")
    with pytest.raises(InvalidInputError, match="census-rsncc, auto"):
        hyperlf.stereo(np.ones((8, 16)), np.ones((8, 16)), (0, 3), metric="sad")
    with pytest.raises(InvalidInputError, match="not available for H-LF matching"):
        costs.get_cost("ssd", light_field=True)
    with pytest.raises(InvalidInputError, match="not available for light fields"):
        costs.get_cost("ssd").view_volume(np.ones((4, 4)), np.ones((4, 4)), [(0.0, 0.0)])
    with pytest.raises(InvalidInputError, match="'auto'"):
        costs.register_cost(type("Auto", (SAD,), {"name": "auto"})())
    with pytest.raises(InvalidInputError):
        costs.unregister_cost("auto")
    cost = costs.register_cost(SAD())
    assert costs.unregister_cost("sad") is cost
    with pytest.raises(InvalidInputError, match="no registered cost"):
        costs.unregister_cost("sad")


@pytest.mark.parametrize("metric, words", [
    ("census", "metric 'census' has no option 'sigma': its options are those of "
               "hyperlf.costs.census_volume"),
    ("auto", "metric 'census-rsncc' has no option 'sigma': its options are those of "
             "hyperlf.costs.rsncc_volume; a fusion also takes weights and rsncc_window, "
             "census_window, and passes the rest to its first part"),
])
def test_an_unknown_cost_option_is_named_with_where_the_options_are(metric, words):
    """It was the TypeError's own words ("rsncc_volume() got an unexpected keyword argument")."""
    left = np.random.default_rng(0).random((12, 20))
    with pytest.raises(InvalidInputError) as exc:
        costs.cost_volume(left, left, 0, 3, metric=metric, sigma=2.0)
    assert str(exc.value) == words
    assert callable(getattr(costs, words.split("hyperlf.costs.")[1].split(";")[0]))
    for odd in ("", "a\nb"):  # any text may be a keyword; the message stays one line
        with pytest.raises(InvalidInputError) as exc:
            costs.cost_volume(left, left, 0, 3, metric=metric, **{odd: 1})
        assert f"has no option {odd!r}:" in str(exc.value) and "\n" not in str(exc.value)


def test_auto_and_builtin_names():
    assert costs.get_cost("auto").name == costs.AUTO_METRIC == "census-rsncc"
    assert costs.cost_names() == ("ssd", "ncc", "rsncc", "census", "bwncc", "bwncc-paper",
                                  "fused", "census-rsncc")
    assert costs.METRIC_NAMES == costs.cost_names() + ("auto",)
    assert set(hlf.CORR_METRICS) == set(costs.cost_names(light_field=True))
    assert "ssd" not in costs.cost_names(light_field=True)


def _metric_choices(parser: argparse.ArgumentParser, command: str):
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    act = next(a for a in sub.choices[command]._actions if a.dest == "metric")
    return act.choices


def test_registry_names_are_the_cli_names():
    from hyperlf.cli import build_parser
    choices = _metric_choices(build_parser(), "stereo")
    assert set(choices) == set(costs.METRIC_NAMES)
