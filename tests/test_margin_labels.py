"""Labels beyond the disparity range (``DepthParams.margin_labels``): the labels, the unary's
scale, the depth map on a surface at an end of the range, and the CLI option."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf import hlf, synthesis
from hyperlf.errors import InvalidInputError

from conftest import refused_while_parsing_and_handed_on


@settings(max_examples=60, deadline=None)
@given(lo=st.floats(-50, 50), span=st.floats(0.01, 100), n=st.integers(2, 80),
       k=st.integers(0, hlf.MAX_MARGIN_LABELS))
def test_margin_keeps_the_range_and_its_step(lo, span, n, k):
    inner = hlf.make_labels(lo, lo + span, n)
    labels = hlf.with_margin(inner, k)
    assert labels.size == n + 2 * k
    sl = hlf.range_labels(labels.size, k)
    assert np.array_equal(labels[sl], inner)  # the range's own labels to the bit
    step = np.diff(labels)
    assert np.allclose(step, span / (n - 1), rtol=1e-9, atol=1e-9 * span)


@pytest.mark.parametrize("labels, k, words", [
    ([0.0, 1.0], -1, "margin must be"),
    ([0.0, 1.0], hlf.MAX_MARGIN_LABELS + 1, "margin must be"),
    ([0.0, 1.0], 1.5, "margin must be"),
    ([0.0], 1, "at least 2 disparities"),
    ([0.0, np.nan], 1, "labels"),
])
def test_bad_margins_are_refused(labels, k, words):
    with pytest.raises(InvalidInputError, match=words):
        hlf.with_margin(np.array(labels), k)


def test_range_labels_refuses_a_margin_that_leaves_no_range():
    assert hlf.range_labels(5, 0) == slice(0, 5)
    with pytest.raises(InvalidInputError, match="no range inside a margin of 2"):
        hlf.range_labels(4, 2)


def test_params_refuse_a_margin_out_of_bounds():
    assert hlf.DepthParams(margin_labels=3).margin_labels == 3
    for bad in (-1, hlf.MAX_MARGIN_LABELS + 1, 2.5, "4"):
        with pytest.raises(InvalidInputError, match="params.margin_labels"):
            hlf.DepthParams(margin_labels=bad)


def test_unary_scale_leaves_the_margin_labels_out(rng):
    inner = rng.random((6, 8, 9)).astype(np.float32)
    margin = np.full((2, 8, 9), 50.0, np.float32)  # far from every surface: costly
    C = np.concatenate([margin, inner, margin])
    _, plain, _ = hlf.unary(inner, None, hlf.DepthParams())
    U, scaled, _ = hlf.unary(C, None, hlf.DepthParams(margin_labels=2))
    _, widened, _ = hlf.unary(C, None, hlf.DepthParams())
    assert scaled == pytest.approx(plain, rel=1e-6)
    assert widened > 10 * scaled  # what the margin labels would do to the scale
    # the range's labels keep their relative costs; their shift is the pixel's own minimum
    d = U[2:-2] - U[2:-2].min(axis=0)
    want = (inner - inner.min(axis=0)) / plain * hlf.DepthParams().gamma_c
    assert np.allclose(d, want, atol=1e-5)


@pytest.mark.parametrize("seed", [0, 3])
def test_a_surface_on_an_end_of_the_range_is_matched_better_with_a_margin(seed):
    # the background lies 0.1 px inside the lower end: between the end label and the next
    lf = synthesis.procedural_scene(seed=seed, rows=3, cols=3, height=64, width=80)
    gt = lf.reference_gt_disparity
    lo, hi = float(gt.min()) - 0.1, float(gt.max()) + 0.1
    far = gt < lo + 0.2
    assert far.mean() > 0.5  # the background is most of the picture

    def run(k):
        res = hlf.depth(lf, (lo, hi), n_labels=16, params=hlf.DepthParams(margin_labels=k))
        return res, np.abs(res.disparity - gt)

    plain, e0 = run(0)
    wide, e4 = run(4)
    assert np.mean(e0[far] > 0.07) > 0.9  # today: the end label, 0.1 px off
    assert np.mean(e4[far] > 0.07) < 0.5 * np.mean(e0[far] > 0.07)
    assert lo <= wide.disparity.min() and wide.disparity.max() <= hi  # clipped to the range
    assert wide.labels.size == 24 and wide.labels[4] == plain.labels[0]
    assert wide.config["n_labels"] == 16 and wide.config["params"]["margin_labels"] == 4


def test_cli_margin_labels_is_checked_and_handed_on(tmp_path, capsys, batch_depth_args,
                                                    monkeypatch):
    refused_while_parsing_and_handed_on(capsys, batch_depth_args, tmp_path / "cap",
                                        tmp_path / "out", "--margin-labels", "-1", "3")
    from hyperlf.cli import main

    code = main(["-q", "depth", str(tmp_path / "cap"), "--method", "tao2013",
                 "--margin-labels", "2", "-o", str(tmp_path / "out")])
    assert code == 2 and "--margin-labels acts on --method hlf only" in capsys.readouterr().err


@pytest.mark.parametrize("metric", ["auto", "census", "ncc"])
def test_margin_labels_change_no_cost_inside_the_range(metric):
    # the fusion's per-view scales and the unseen labels' fill are measured over the
    # range's labels: the labels beyond it leave every cost inside it as it was, but for
    # the two end labels of a census cost, averaged over the labels within half a pixel of
    # shift, which are no longer one-sided
    lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=48, width=64)
    plain = hlf.prepare(lf, n_labels=12, metric=metric)
    wide = hlf.prepare(lf, n_labels=12, metric=metric, params=hlf.DepthParams(margin_labels=3))
    assert np.array_equal(wide.labels[wide.range_labels], plain.labels)
    C0, _ = hlf.correspondence(plain)
    C3, _ = hlf.correspondence(wide)
    assert C3.shape[0] == C0.shape[0] + 6
    assert np.allclose(C3[4:-4], C0[1:-1], rtol=1e-5, atol=1e-6)
    ends_equal = np.allclose(C3[[3, -4]], C0[[0, -1]], rtol=1e-5, atol=1e-6)
    assert ends_equal == (metric == "ncc")
