"""The stages of hyperlf.hlf.depth run alone give what depth gives, and each does its job."""

import numpy as np
import pytest

from hyperlf import synthesis
from hyperlf.errors import InvalidInputError
from hyperlf.hlf import (DepthParams, correspondence, defocus_cue, depth, edge_discount,
                         post_filter, prepare, refine, regularise, thin_objects, unary)


@pytest.fixture(scope="module")
def lf():
    return synthesis.procedural_scene(seed=2, rows=3, cols=3, height=32, width=40,
                                      disparity_range=(-1.5, 1.5))


@pytest.mark.parametrize("kw", [{}, {"view_selection": True, "occlusion_split": True},
                                {"defocus": "tv", "optimizer": "sgm"}])
def test_stages_compose_to_depth(lf, kw):
    res = depth(lf, n_labels=12, **kw)
    prob = prepare(lf, n_labels=12, **kw)
    C, _ = correspondence(prob)
    f_c = prob.labels[np.argmin(C, axis=0)].astype(np.float32)
    D, _ = defocus_cue(prob, f_c)
    assert (D is None) == (kw.get("defocus", "off") == "off")
    U, _, _ = unary(C, D, prob.params)
    lab, vol = regularise(prob, U, f_c)
    disp, conf = refine(vol, lab, prob.labels, prob.params)
    disp = post_filter(disp, prob.In[prob.reference].astype(np.float32), prob.params)
    disp, conf, _ = thin_objects(prob, U, f_c, disp, conf)
    conf = edge_discount(conf, disp, prob.params)
    np.testing.assert_array_equal(disp, res.disparity)
    np.testing.assert_array_equal(conf, res.confidence)
    np.testing.assert_array_equal(f_c, res.f_c)
    assert {"prepare_s", "correspondence_s", "selection_split_s", "defocus_s", "mrf_s",
            "refine_s", "median_s", "thin_objects_s", "total_s"} <= set(res.timings)


def test_prepare_validates_before_work(lf):
    with pytest.raises(InvalidInputError, match="defocus"):
        prepare(lf, defocus="sometimes")
    with pytest.raises(InvalidInputError, match="optimizer"):
        prepare(lf, optimizer="annealing")
    prob = prepare(lf, n_labels=5, disparity_range=(-1, 1))
    np.testing.assert_allclose(prob.labels, [-1, -0.5, 0, 0.5, 1])
    assert prob.reference not in prob.others and len(prob.others) == 8
    for v in prob.views:  # In = I / mean(I)
        assert prob.In[v].mean() == pytest.approx(1.0)
    assert prob.Mbar is None and not prob.edges.any()


def test_correspondence_finds_the_true_disparity(lf):
    prob = prepare(lf, n_labels=13, metric="ncc")
    C, n_used = correspondence(prob)
    f_c = prob.labels[np.argmin(C, axis=0)]
    gt = lf.gt_disparity[lf.reference]
    inner = (slice(4, -4), slice(4, -4))
    assert np.median(np.abs(f_c - gt)[inner]) <= 0.25 + 1e-9  # one label step is 0.25
    assert n_used.max() <= len(prob.others)


def test_unary_normalises_each_term():
    rng = np.random.default_rng(0)
    C = rng.random((6, 8, 9)).astype(np.float32) * 5
    U, sC, sD = unary(C, None, DepthParams(gamma_c=0.5))
    assert sD is None and U.dtype == np.float32 and U.flags["C_CONTIGUOUS"]
    np.testing.assert_allclose(U.min(axis=0), 0, atol=1e-7)  # per-pixel minimum removed
    np.testing.assert_allclose(np.median(U.max(axis=0)), 0.5, rtol=1e-6)  # gamma_c x median range 1


def test_post_filter_off_and_on():
    d = np.zeros((20, 20), np.float32)
    d[:, 10:] = 2.0
    d[5, 5] = 9.0  # an outlier in a flat guide region
    g = np.zeros((20, 20), np.float32)
    assert post_filter(d, g, DepthParams(median_radius=0)) is d
    out = post_filter(d, g, DepthParams(median_radius=2))
    assert out[5, 5] == 0.0


def test_mrf_levels_run_graph_cuts_coarse_to_fine(monkeypatch):
    from hyperlf.regularisers import dispatch

    calls = []
    real = dispatch.graphcut_multiscale
    monkeypatch.setattr(dispatch, "graphcut_multiscale",
                        lambda *a, **k: calls.append(k["levels"]) or real(*a, **k))
    lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=64, width=64)
    gt = lf.reference_gt_disparity
    plain = depth(lf, n_labels=24)
    assert calls == []
    c2f = depth(lf, n_labels=24, params=DepthParams(mrf_levels=2))
    assert calls == [2] and c2f.config["params"]["mrf_levels"] == 2
    err = lambda d: float(np.sqrt(np.mean((d - gt)[8:-8, 8:-8] ** 2)))  # noqa: E731
    assert err(c2f.disparity) < 1.5 * err(plain.disparity) + 0.05
    # occlusion edge weights need the plain moves: taken whatever mrf_levels says
    calls.clear()
    ow = DepthParams(occlusion_weight=0.5)
    np.testing.assert_array_equal(
        depth(lf, n_labels=24, params=DepthParams(occlusion_weight=0.5, mrf_levels=2)).disparity,
        depth(lf, n_labels=24, params=ow).disparity)
    assert calls == []
    for bad in (-1, 5, 1.5, True):
        with pytest.raises(InvalidInputError, match="mrf_levels"):
            DepthParams(mrf_levels=bad)
