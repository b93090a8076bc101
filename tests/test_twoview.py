"""Tests of the two-view stereo pipeline (hyperlf.twoview, SPEC §4)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from hyperlf import costs
from hyperlf import regularisers as reg
from hyperlf.errors import InvalidInputError
from hyperlf.twoview import (StereoResult, compute_volumes, default_params, default_window,
                            select_channels, stereo)

from conftest import sparsification

DB, DF = 2, 8                      # background / foreground disparity
SQ = (16, 48, 36, 68)              # foreground square (y0, y1, x0, x1) in the left view
H, W = 64, 96


def _texture(rng, h, w, sigma=1.2):
    t = ndimage.gaussian_filter(rng.random((h, w)), sigma)
    return (t - t.min()) / (t.max() - t.min())


def two_layer(seed=0):
    """Left/right scene textures (in [0, 1]) and the left ground truth.

    Left pixel ``x`` shows the background point ``x`` (disparity DB) or, inside SQ, the
    foreground point ``x`` (disparity DF); right pixel ``x_r`` shows the point ``x_r + d`` of the
    front-most layer.  The left pixels ``x0 - (DF - DB) <= x < x0`` of the square's rows are
    occluded in the right view.
    """
    rng = np.random.default_rng(seed)
    pad = 20
    B = _texture(rng, H, W + 2 * pad)
    F = _texture(rng, H, W + 2 * pad)
    y0, y1, x0, x1 = SQ
    xs = np.arange(W)
    L = B[:, xs + pad].copy()
    R = B[:, xs + DB + pad].copy()
    gt = np.full((H, W), float(DB))
    L[y0:y1, x0:x1] = F[y0:y1, x0 + pad:x1 + pad]
    gt[y0:y1, x0:x1] = DF
    inF = (xs + DF >= x0) & (xs + DF < x1)
    R[y0:y1, inF] = F[y0:y1][:, xs[inF] + DF + pad]
    return L, R, gt


def cross_spectral(seed=0):
    """Right = a non-monotonic remap of the scene texture (contrast flips where t < 0.5)."""
    L, R, gt = two_layer(seed)
    return 0.1 + L, 0.1 + 4.0 * (R - 0.5) ** 2, gt


INTERIOR = (slice(4, H - 4), slice(12, W - 4))


@pytest.fixture(scope="module")
def cross_result():
    # Moderate smoothing, pinned: this checks the graph-cut + occlusion pipeline, not the
    # Venus-tuned defaults (weight 4-8, truncation 4-8), which over-smooth small scenes like
    # this one just as they can over-smooth Tsukuba's lamp (see BENCHMARKS.md).
    L, R, gt = cross_spectral()
    params = {"weight": 1.0, "truncation": 2.0}
    return stereo(L, R, (0, 12), metric="bwncc", optimizer="graphcut", occlusion="lr-fill",
                  params=params), gt


def test_cross_spectral_graphcut_recovers_two_layers(cross_result):
    res, gt = cross_result
    assert isinstance(res, StereoResult)
    assert res.disparity.dtype == np.float32 and res.disparity.shape == (H, W)
    err = np.abs(res.disparity - gt)[INTERIOR]
    assert 100.0 * np.mean(err > 1.0) < 5.0
    assert np.isfinite(res.disparity).all()
    assert set(res.timings) == {"cost", "optimiser", "total"}
    assert res.metric == "bwncc" and res.optimizer == "graphcut"
    assert res.confidence.shape == (H, W) and 0 <= res.confidence.min() <= res.confidence.max() <= 1
    assert not res.confidence[~res.valid].any()


def test_intensity_costs_fail_on_non_monotonic_remap():
    """A sanity check of the test pair itself: NCC is not invariant to the remap."""
    L, R, gt = cross_spectral()
    res = stereo(L, R, (0, 12), metric="ncc", optimizer="sgm")
    err = np.abs(res.disparity - gt)[INTERIOR]
    assert 100.0 * np.mean(err > 1.0) > 20.0


def test_occlusion_fill_uses_background(cross_result):
    res, gt = cross_result
    y0, y1, x0, x1 = SQ
    strip = (slice(y0 + 3, y1 - 3), slice(x0 - (DF - DB), x0))
    # The occluded strip is mostly rejected by the LR check ...
    assert res.valid[strip].mean() < 0.5
    assert res.valid.mean() > 0.85
    # ... and filled with the background (lower) disparity, not the foreground.
    assert np.mean(np.abs(res.disparity[strip] - DB) <= 1.0) > 0.9
    # without occlusion handling nothing is marked invalid
    L, R, _ = cross_spectral()
    res2 = stereo(L, R, (0, 12), metric="bwncc", optimizer="wta", occlusion="none")
    assert res2.valid.all() and res2.right_disparity is None
    np.testing.assert_array_equal(res2.disparity, res2.raw)


@pytest.mark.parametrize("optimizer", ["wta", "sgm", "graphcut"])
def test_every_optimizer_runs_same_spectrum(optimizer):
    L, R, gt = two_layer(seed=1)
    res = stereo(0.1 + L, 0.1 + R, (0, 12), metric="census", optimizer=optimizer,
                 params={"max_cycles": 2} if optimizer == "graphcut" else None)
    assert res.disparity.shape == (H, W)
    assert res.right_disparity is not None and res.valid.dtype == bool
    err = np.abs(res.disparity - gt)[INTERIOR]
    limit = 25.0 if optimizer == "wta" else 5.0
    assert 100.0 * np.mean(err > 1.0) < limit
    assert res.params == {**default_params("census", optimizer),
                          **({"max_cycles": 2} if optimizer == "graphcut" else {})}


def test_subpixel_and_params():
    L, R, gt = two_layer(seed=2)
    res = stereo(0.1 + L, 0.1 + R, (0, 12), metric="ncc", optimizer="sgm", subpixel=True,
                 params={"p1": 0.3, "p2": 3.0})
    assert res.params["p1"] == 0.3 and res.params["p2"] == 3.0
    assert not np.allclose(res.raw, np.round(res.raw))          # some fractional values
    assert np.all(np.abs(res.raw - np.round(res.raw)) <= 0.5 + 1e-6)


def test_channel_selection_red_vs_blue():
    L, R, _ = cross_spectral()
    rng = np.random.default_rng(5)
    left = rng.random((H, W, 3)).astype(np.float32)
    right = rng.random((H, W, 3)).astype(np.float32)
    left[:, :, 0] = L
    right[:, :, 2] = R
    a, b = select_channels(left, right, (0, 2))
    np.testing.assert_array_equal(a, L.astype(np.float32))
    np.testing.assert_array_equal(b, R.astype(np.float32))
    r1 = stereo(left, right, (0, 12), metric="census", optimizer="sgm", channel=(0, 2))
    r2 = stereo(L.astype(np.float32), R.astype(np.float32), (0, 12), metric="census",
                optimizer="sgm")
    np.testing.assert_array_equal(r1.disparity, r2.disparity)
    # single int selects the same channel of both
    a, b = select_channels(left, right, 1)
    np.testing.assert_array_equal(a, left[:, :, 1])
    np.testing.assert_array_equal(b, right[:, :, 1])


@pytest.mark.parametrize("metric", ["ncc", "census", "ssd"])
def test_right_volume_is_exact(metric):
    """C_R from right_cost_from_left equals the volume computed with the right view as
    reference (mirrored inputs), on every entry whose partner is inside the image."""
    L, R, _ = two_layer(seed=3)
    L, R = 0.1 + L, 0.1 + R
    dmin, dmax = 0, 10
    _, cr = compute_volumes(L, R, dmin, dmax, metric)
    mirrored = costs.cost_volume(R[:, ::-1].copy(), L[:, ::-1].copy(), dmin, dmax, metric=metric)
    direct = mirrored[:, :, ::-1]
    d = np.arange(dmin, dmax + 1)[:, None, None]
    x = np.arange(W)[None, None, :]
    ok = np.broadcast_to(x + d < W, cr.shape)
    np.testing.assert_allclose(cr[ok], direct[ok], rtol=1e-4, atol=1e-4)


@pytest.mark.parametrize("metric", ["fused", "census-rsncc"])
def test_fused_right_volume_is_refused_per_right_pixel(metric):
    """Fusions normalise per pixel, so their right volume is fused again from the shifted raw
    parts (not a shift of the fused left volume); out-of-image entries carry the worst cost."""
    L, R, _ = cross_spectral()
    dmin, dmax = 0, 6
    cl, cr = compute_volumes(L[:32, :48], R[:32, :48], dmin, dmax, metric)
    np.testing.assert_allclose(cl, costs.cost_volume(L[:32, :48], R[:32, :48], dmin, dmax,
                                                     metric), rtol=1e-6, atol=1e-6)
    assert cl.shape == cr.shape == (7, 32, 48)
    assert np.isfinite(cr).all()
    naive = reg.right_cost_from_left(cl, np.arange(dmin, dmax + 1))
    assert not np.allclose(naive, cr)
    d = np.arange(dmin, dmax + 1)[:, None, None]
    x = np.arange(48)[None, None, :]
    ok = np.broadcast_to(x + d < 48, cr.shape)
    worst = np.where(ok, cr, -np.inf).max(axis=0)
    np.testing.assert_allclose(np.where(ok, worst[None], cr), np.broadcast_to(worst, cr.shape),
                               rtol=1e-6)


def test_input_validation():
    L, R, _ = two_layer()
    with pytest.raises(InvalidInputError, match="same size"):
        stereo(L, R[:, :-1], (0, 8))
    bad = L.copy()
    bad[3, 3] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        stereo(bad, R, (0, 8))
    with pytest.raises(InvalidInputError, match="dmin < dmax"):
        stereo(L, R, (8, 8))
    with pytest.raises(InvalidInputError, match="dmin < dmax"):
        stereo(L, R, (9, 3))
    with pytest.raises(InvalidInputError, match="wider than the image"):
        stereo(L, R, (0, W))
    with pytest.raises(InvalidInputError, match="integers"):
        stereo(L, R, (0, 2.5))
    with pytest.raises(InvalidInputError, match="pair"):
        stereo(L, R, 5)
    with pytest.raises(InvalidInputError, match="optimizer"):
        stereo(L, R, (0, 8), optimizer="bp")
    with pytest.raises(InvalidInputError, match="occlusion"):
        stereo(L, R, (0, 8), occlusion="median")
    with pytest.raises(InvalidInputError, match="metric"):
        stereo(L, R, (0, 8), metric="sad")
    with pytest.raises(InvalidInputError, match="^unknown key 'weight' in params"):
        stereo(L, R, (0, 8), optimizer="sgm", params={"weight": 2.0})
    with pytest.raises(InvalidInputError, match="channel"):
        stereo(np.dstack([L] * 3), np.dstack([R] * 3), (0, 8), channel=(0, 3))
    with pytest.raises(InvalidInputError, match="2-D"):
        stereo(L, R, (0, 8), channel=1)
    with pytest.raises(InvalidInputError, match="shape"):
        stereo(L[None, None], R[None, None], (0, 8))
    with pytest.raises(InvalidInputError, match="ConfidenceParams"):
        stereo(L, R, (0, 8), confidence_params={"floor": 0.1})


def test_default_params_table():
    for metric in costs.cost_names():
        cost = costs.get_cost(metric)
        assert metric in costs.METRICS and set(cost.params) <= {"sgm", "graphcut"}
        for opt, p in cost.params.items():
            if opt == "sgm":
                assert p["p2"] >= p["p1"] > 0
            else:
                assert p["weight"] > 0 and p["max_cycles"] >= 1
    auto = default_params("auto", "graphcut")
    assert auto == {**auto, **costs.get_cost(costs.AUTO_METRIC).params["graphcut"]}
    assert auto["levels"] >= 0          # every graph-cut default says how coarse-to-fine it runs
    assert default_params("ncc", "wta") == {}
    # windows: per optimiser where tuned, else the cost's own default (None)
    assert default_window("ssd", "graphcut") == 9 and default_window("ssd", "sgm") is None
    assert default_window("census", "graphcut") == 7 and default_window("census", "wta") == 5
    assert default_window("auto", "graphcut") is None


@pytest.mark.parametrize("metric", ["auto", "census", "fused"])
def test_volumes_made_in_place_give_the_same_bits(metric):
    """The fused costs fuse each side in the memory of its parts, and ``stereo`` makes the
    data terms in its own volumes: the volumes and the disparities of fresh copies, bit for
    bit; a caller's volumes are written over only when it says ``overwrite=True``."""
    from hyperlf.costs import fuse, get_cost
    from hyperlf.costs.registry import FusedCost, _right_from_left
    from hyperlf.twoview import stereo_from_volumes

    L, R, _ = cross_spectral(3)
    cl, cr = compute_volumes(L, R, 0, 12, metric)
    cost = get_cost(metric)
    if isinstance(cost, FusedCost):  # the reference: every part kept, every fusion fresh
        parts = [get_cost(p).pair_volume(L, R, 0, 12, window=get_cost(p).window,
                                         **cost.part_options.get(p, {})) for p in cost.parts]
        np.testing.assert_array_equal(cl, fuse(parts, cost.weights, 0))
        vr = costs.right_validity(cl.shape[1:], 0, 12)
        right = [_right_from_left(v, 0) for v in parts]
        np.testing.assert_array_equal(cr, fuse(right, cost.weights, 0, valid=vr))
    keep_l, keep_r = cl.copy(), cr.copy()
    fresh = stereo_from_volumes(cl, cr, 0, "graphcut", "lr-plane", guide_left=L, guide_right=R,
                                metric=metric)
    np.testing.assert_array_equal(cl, keep_l)
    np.testing.assert_array_equal(cr, keep_r)
    mine = stereo_from_volumes(cl, cr, 0, "graphcut", "lr-plane", guide_left=L, guide_right=R,
                               metric=metric, overwrite=True)
    np.testing.assert_array_equal(mine.disparity, fresh.disparity)
    np.testing.assert_array_equal(mine.confidence, fresh.confidence)
    assert not np.array_equal(cl, keep_l)  # now the data term
    np.testing.assert_array_equal(stereo(L, R, (0, 12), metric=metric).disparity,
                                  fresh.disparity)


def test_confidence_ranks_the_consistent_pixels_first_and_the_depth_edges_last():
    """The default confidence (:class:`hyperlf.regularisers.ConfidenceParams`: the margin from
    a floor of 0.1 up on the consistent pixels, scaled by the distance to the map's depth
    edges) against the cost margin alone, on small procedural cross-spectral pairs: the
    disparities are the same, the inconsistent pixels and the depth edges get 0, and the most
    confident pixels hold fewer of the bad ones (measured: ratio 0.45-0.72 on seven of the
    eight pair / texture-library cases, 1.07 on one; 0.29-0.91 on the twelve procedural tuning
    pairs at 400 x 300, with bad5.0; BENCHMARKS.md, fortieth session)."""
    from hyperlf import synthesis
    from hyperlf.twoview import stereo_from_volumes

    ratios = []
    for seed in range(4):
        lf = synthesis.procedural_scene(seed, rows=1, cols=2, height=120, width=160,
                                        disparity_range=(0.0, 24.0), lambda_min=460.0,
                                        lambda_max=630.0, layout=[1, 0], n_objects=6,
                                        supersample=1)
        gt, left, right = lf.gt_disparity[0, 0], lf.views[0, 0], lf.views[0, 1]
        cl, cr = compute_volumes(left, right, 0, 25, "auto")
        new = stereo_from_volumes(cl, cr, 0, guide_left=left, guide_right=right)
        old = stereo_from_volumes(cl, cr, 0, guide_left=left, guide_right=right,
                                  confidence_params=reg.ConfidenceParams(floor=0, edge_px=0))
        np.testing.assert_array_equal(new.disparity, old.disparity)
        assert not new.confidence[~new.valid].any()
        assert not new.confidence[reg.edge_confidence(new.disparity, jump=1.5) == 0].any()
        assert (new.confidence[new.valid] > 0).mean() > (old.confidence[old.valid] > 0).mean()
        bad = np.abs(new.disparity - gt) > 2
        ratios.append(sparsification(new.confidence, bad) / sparsification(old.confidence, bad))
    assert np.mean(ratios) < 0.85, ratios


def test_stereo_from_volumes_refuses_bad_inputs_before_any_solve(monkeypatch, rng):
    """A right volume, a guide or a fill that cannot work is refused before the left map is
    solved (seconds to minutes on a real pair), and a guide is named."""
    from hyperlf import twoview

    def solve(*args, **kwargs):
        raise AssertionError("solved before the inputs were checked")

    monkeypatch.setattr(twoview, "_optimise", solve)
    cl = rng.random((4, 12, 16)).astype(np.float32)
    g = rng.random((12, 16))
    bad = {"needs the right-referenced volume": dict(cost_right=None),
           "needs guide_left": dict(cost_right=cl, occlusion="lr-plane"),
           "cost_right shape": dict(cost_right=cl[:, :5], guide_left=g),
           "guide_right must be an image": dict(cost_right=cl, guide_left=g,
                                                 guide_right=np.zeros((3, 3))),
           "guide_left image contains NaN": dict(cost_right=cl, guide_left=g * np.nan)}
    for words, kw in bad.items():
        with pytest.raises(InvalidInputError, match=words):
            twoview.stereo_from_volumes(cl, dmin=0, **{"occlusion": "lr-fill", **kw})
