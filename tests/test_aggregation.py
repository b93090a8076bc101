"""Edge-aware aggregation of cost volumes (issue 12 item 2; :mod:`hyperlf.costs.aggregation`)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf.costs import (AGGREGATION_METHODS, AggregationParams, aggregate_pair,
                           aggregate_volume, candidate_validity, guided_filter)
from hyperlf.errors import InvalidInputError


def _guided_reference(I, p, r, eps):
    """He et al.'s filter written out pixel by pixel (explicit windows clipped to the image
    with replicated borders), independent of the box-filter implementation."""
    H, W = I.shape
    n = 2 * r + 1
    Ip = np.pad(I, r, mode="edge")
    pp = np.pad(p, r, mode="edge")
    a = np.empty((H, W))
    b = np.empty((H, W))
    for y in range(H):
        for x in range(W):
            wi, wp = Ip[y:y + n, x:x + n], pp[y:y + n, x:x + n]
            cov = (wi * wp).mean() - wi.mean() * wp.mean()
            a[y, x] = cov / (wi.var() + eps)
            b[y, x] = wp.mean() - a[y, x] * wi.mean()
    ap, bp = np.pad(a, r, mode="edge"), np.pad(b, r, mode="edge")
    ma = np.array([[ap[y:y + n, x:x + n].mean() for x in range(W)] for y in range(H)])
    mb = np.array([[bp[y:y + n, x:x + n].mean() for x in range(W)] for y in range(H)])
    return ma * I + mb


def test_guided_filter_matches_the_windowed_definition():
    rng = np.random.default_rng(0)
    I, p = rng.random((9, 11)), rng.random((9, 11))
    for r, eps in ((1, 1e-3), (2, 0.1)):
        np.testing.assert_allclose(guided_filter(I, p, r, eps), _guided_reference(I, p, r, eps),
                                   atol=1e-10)


def test_guided_filter_keeps_a_step_of_the_guide_and_smooths_within_regions():
    """A cost that follows the guide's step stays a step (edge-aware), while noise inside
    each flat region is averaged away; a box mean of the same size would blur the step."""
    rng = np.random.default_rng(1)
    I = np.zeros((20, 20)); I[:, 10:] = 1.0
    p = np.where(I > 0, 2.0, 0.0) + 0.1 * rng.standard_normal(I.shape)
    q = guided_filter(I, p, 3, 1e-4)
    assert np.abs(q[:, :9].mean() - 0.0) < 0.05 and np.abs(q[:, 11:].mean() - 2.0) < 0.05
    assert q[:, 9].max() < 0.3 and q[:, 10].min() > 1.7          # the step stays at the edge
    assert q[:, 2:8].std() < 0.5 * p[:, 2:8].std()               # noise smoothed inside


def test_a_constant_volume_and_the_none_method_are_unchanged():
    rng = np.random.default_rng(2)
    guide = rng.random((12, 15))
    const = np.full((3, 12, 15), 0.7, np.float32)
    np.testing.assert_allclose(aggregate_volume(const, guide, "guided"), const, atol=1e-6)
    vol = rng.random((3, 12, 15)).astype(np.float32)
    np.testing.assert_array_equal(aggregate_volume(vol, guide, None), vol)
    np.testing.assert_array_equal(aggregate_volume(vol, guide, "none"), vol)


def test_in_place_aggregation_equals_the_copy():
    rng = np.random.default_rng(6)
    guide, vol = rng.random((12, 15)), rng.random((4, 12, 15)).astype(np.float32)
    copy = aggregate_volume(vol, guide, "guided")
    same = vol.copy()
    assert aggregate_volume(same, guide, "guided", out=same) is same
    np.testing.assert_array_equal(same, copy)
    with pytest.raises(InvalidInputError, match="out must be"):
        aggregate_volume(vol, guide, "guided", out=np.empty((4, 12, 15)))


def test_pair_aggregation_keeps_the_out_of_image_rule():
    rng = np.random.default_rng(3)
    L, R = rng.random((10, 16)), rng.random((10, 16))
    cl = rng.random((5, 10, 16)).astype(np.float32)
    valid = np.array(candidate_validity((10, 16), 0, 4))
    al, ar = aggregate_pair(cl, None, L, R, 0, AggregationParams("guided", radius=2))
    assert ar is None
    worst = np.where(valid, al, -np.inf).max(axis=0)
    np.testing.assert_array_equal(al[~valid], np.broadcast_to(worst, al.shape)[~valid])


def test_guided_aggregation_recovers_a_shift_on_a_textured_pair():
    """Through two-view stereo (WTA), on a pair with a known shift, guided aggregation keeps
    the answer (it is a smoothing of a volume whose minimum is already right)."""
    from hyperlf.twoview import stereo

    rng = np.random.default_rng(4)
    scene = rng.random((30, 60)) + 0.1
    left, right = scene[:, 5:45], scene[:, 8:48]     # left x matches right x - 3
    res = stereo(left, right, (0, 6), metric="ncc", optimizer="wta", occlusion="none",
                 aggregation=AggregationParams("guided", radius=2, eps=1e-2))
    assert np.mean(res.disparity[:, 8:] == 3) > 0.95
    assert res.extra["aggregation"] == {"method": "guided", "radius": 2, "eps": 1e-2}


def test_hlf_depth_takes_the_option_and_none_is_the_default():
    from hyperlf import synthesis
    from hyperlf.hlf import DepthParams, depth

    assert DepthParams().aggregation == "none"
    lf = synthesis.procedural_scene(seed=0, rows=2, cols=2, height=24, width=32)
    plain = depth(lf, n_labels=8, optimizer="wta")
    guided = depth(lf, n_labels=8, optimizer="wta",
                   params=DepthParams(aggregation="guided", aggregation_radius=2))
    assert "aggregation_s" in guided.timings and "aggregation_s" not in plain.timings
    assert not np.array_equal(plain.f_c, guided.f_c)


@pytest.mark.parametrize("kw, msg", [({"method": "box"}, "aggregation must be one of"),
                                     ({"radius": 0}, "aggregation_radius"),
                                     ({"radius": 2.5}, "aggregation_radius"),
                                     ({"eps": 0.0}, "aggregation_eps"),
                                     ({"eps": float("nan")}, "aggregation_eps")])
def test_bad_parameters_get_one_line(kw, msg):
    with pytest.raises(InvalidInputError, match=msg):
        AggregationParams(**kw)


@settings(max_examples=40, deadline=None)
@given(method=st.one_of(st.sampled_from(list(AGGREGATION_METHODS)), st.text(max_size=8)),
       radius=st.one_of(st.integers(-5, 80), st.floats(allow_nan=True), st.booleans()),
       eps=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-3, 3)))
def test_parameters_are_valid_or_refused_with_InvalidInputError(method, radius, eps):
    try:
        p = AggregationParams(method, radius, eps)
    except InvalidInputError as e:
        assert "\n" not in str(e)
        return
    assert p.method in AGGREGATION_METHODS and p.radius >= 1 and p.eps > 0


def test_a_mismatched_guide_is_refused():
    with pytest.raises(InvalidInputError, match="disagree"):
        aggregate_volume(np.zeros((2, 5, 6)), np.zeros((5, 7)), "guided")
