"""Slanted planes: the segment-wise plane fill and the occlusion / mismatch split of two-view
stereo (issue 12 item 3), and planes fitted to pooled costs (issue 11)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf import regularisers as reg
from hyperlf.errors import InvalidInputError
from hyperlf.regularisers import cost_planes
from hyperlf.twoview import fill_inconsistent, stereo

H, W = 60, 90


def two_surfaces(seed=0):
    """A guide with two regions (left: dark, right: bright, a little noise) and two slanted
    planes on them, with their own slopes."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[:H, :W].astype(np.float64)
    right = x >= 45
    guide = np.where(right, 0.8, 0.2) + 0.01 * rng.standard_normal((H, W))
    truth = np.where(right, -0.05 * x - 0.1 * y + 26.0, -0.08 * x + 0.04 * y + 12.0)
    return guide, truth, right


def test_fit_plane_exact_and_robust_to_outliers():
    rng = np.random.default_rng(1)
    x, y = rng.uniform(0, 100, 400), rng.uniform(0, 80, 400)
    d = 0.3 * x - 0.2 * y + 7.0 + 0.05 * rng.standard_normal(400)
    bad = rng.random(400) < 0.25                       # a quarter gross outliers
    d[bad] += rng.uniform(5, 40, bad.sum())
    a, b, c = reg.fit_plane(x, y, d)
    assert abs(a - 0.3) < 0.01 and abs(b + 0.2) < 0.01 and abs(c - 7.0) < 0.3


def test_fit_plane_needs_three_points():
    with pytest.raises(InvalidInputError):
        reg.fit_plane([0, 1], [0, 1], [1, 2])


def test_plane_fill_gives_each_hole_its_own_surface():
    guide, truth, right = two_surfaces()
    ok = np.ones((H, W), bool)
    ok[20:35, 10:30] = False        # a hole in the left surface
    ok[25:45, 55:80] = False        # one in the right surface
    d = np.where(ok, truth, 99.0)   # what the hole held is never read
    out, rep = reg.plane_fill(d, ok, guide)
    assert rep.sum() == (~ok).sum()
    assert np.abs(out - truth)[~ok].max() < 1e-3
    assert np.array_equal(out[ok], d[ok].astype(np.float32))


def test_plane_fill_refuses_a_region_that_is_not_one_plane():
    guide, truth, right = two_surfaces()
    flat_guide = np.full((H, W), 0.5)                 # one region spans both surfaces
    ok = np.ones((H, W), bool)
    ok[20:35, 40:50] = False
    out, rep = reg.plane_fill(truth, ok, flat_guide)
    assert not rep.any()                              # 4-6 px apart: no plane holds 80 %
    assert np.array_equal(out, truth.astype(np.float32))


def test_plane_fill_needs_support_and_respects_targets():
    guide, truth, right = two_surfaces()
    ok = np.ones((H, W), bool)
    ok[:, :45] = False                                # the left surface has no trusted pixel
    ok[10:20, 60:70] = False
    targets = ~ok & right
    targets[10:15] = False                            # only part of the hole may change
    out, rep = reg.plane_fill(truth, ok, guide, targets=targets)
    assert np.array_equal(rep, targets)
    few = reg.PlaneFillParams(min_reliable=0.99)      # 100 of 2700 right pixels untrusted
    _, rep = reg.plane_fill(truth, ok, guide, params=few)
    assert not rep.any()


def _or_nan(lo, hi):
    return st.one_of(st.floats(lo, hi), st.just(float("nan")))


@given(scale=_or_nan(-10, 2000), min_size=st.integers(-3, 300), share=_or_nan(-0.5, 1.5),
       tol=_or_nan(-1, 5))
@settings(max_examples=60, deadline=None)
def test_plane_fill_params_accept_exactly_the_documented_ranges(scale, min_size, share, tol):
    ok = (scale > 0 and np.isfinite(scale) and min_size >= 1 and 0 <= share <= 1
          and tol > 0 and np.isfinite(tol))
    kwargs = dict(scale=scale, min_size=min_size, min_reliable=share, inlier_tol=tol)
    if ok:
        assert reg.PlaneFillParams(**kwargs).min_size == min_size
    else:
        with pytest.raises(InvalidInputError):
            reg.PlaneFillParams(**kwargs)


def _layered_right_map(db, df, x0, x1, rows, shape):
    """Right-view disparity of a background at ``db`` with a fronto-parallel square at ``df``
    covering left columns ``x0..x1-1`` on ``rows`` (Middlebury: right ``x_r`` sees left
    ``x_r + d``)."""
    h, w = shape
    dr = np.full(shape, float(db))
    xs = np.arange(w)
    front = (xs + df >= x0) & (xs + df < x1)
    dr[rows, :] = np.where(front, df, db)
    return dr


def test_left_occlusions_match_the_geometry():
    db, df, x0, x1, rows = 2, 9, 40, 70, slice(10, 30)
    dr = _layered_right_map(db, df, x0, x1, rows, (H, W))
    occ = reg.left_occlusions(dr)
    expect = np.zeros((H, W), bool)
    expect[:, :db] = True                            # outside the right image
    expect[rows, x0 - (df - db):x0] = True          # hidden behind the square
    assert np.array_equal(occ, expect)


def test_left_occlusions_nan_sees_nothing():
    dr = np.full((2, 5), 1.0)
    dr[0, 2] = np.nan
    occ = reg.left_occlusions(dr)
    assert occ[0, 3] and not occ[1, 3] and occ[:, 0].all()


def test_lr_plane_fills_mismatches_with_the_plane_and_occlusions_with_the_background():
    guide, truth, right = two_surfaces()
    disp_r = np.zeros((H, W))                        # right x_r sees left x_r + d ...
    disp_r[:, :3] = 3.0                              # ... so nobody sees left x = 0, 1, 2
    occluded = reg.left_occlusions(disp_r)
    assert np.array_equal(np.flatnonzero(occluded.any(axis=0)), [0, 1, 2])
    block = np.zeros((H, W), bool)
    block[25:40, 55:75] = True                       # mismatches on the right surface
    assert not (block & occluded).any()
    valid = ~block & ~occluded                       # hidden pixels fail the check too
    raw = np.where(valid, truth, 0.0)                # the raw map is wrong there
    parts = reg.PlaneFillParams(median_radius=0)       # the planes and the fill alone
    plane, rep = fill_inconsistent(raw, disp_r, valid, "lr-plane", guide, parts)
    fill, rep0 = fill_inconsistent(raw, disp_r, valid, "lr-fill", guide)
    assert np.array_equal(rep, block) and not rep0.any()
    assert np.abs(plane - truth)[block].max() < 1e-3
    # the row fill copies a constant into a slanted surface: off by more than 1/2 px here
    assert np.abs(fill - truth)[block].max() > 0.5
    # the pixels the right view cannot see keep the background fill
    assert np.array_equal(plane[occluded], fill[occluded])
    assert np.array_equal(plane[valid], raw[valid])


def test_lr_plane_median_removes_a_fill_streak_and_keeps_consistent_pixels():
    # a background at 5 px, a hidden band (columns 30-39) in front of a surface at 15 px; on
    # row 20 a wrong pixel at 15 px passed the check just left of the band, so the row fill
    # (the lower of the two nearest consistent values) copies 15 into the band: a streak
    x = np.mgrid[:H, :W][1]
    guide = np.where(x >= 40, 0.8, 0.3)
    truth = np.where(x >= 40, 15.0, 5.0)
    valid = ~((x >= 30) & (x < 40))
    raw = truth.copy()
    raw[20, 29] = 15.0
    raw[~valid] = 15.0
    disp_r = np.full((H, W), 5.0)                    # only the hidden band is unseen ...
    disp_r[:, 25:] = 15.0                            # ... by the surface at 15 px
    without, _ = fill_inconsistent(raw, disp_r, valid, "lr-plane", guide,
                                   reg.PlaneFillParams(median_radius=0))
    assert np.all(without[20, 30:40] == 15.0) and np.all(without[19, 30:40] == 5.0)
    with_median, _ = fill_inconsistent(raw, disp_r, valid, "lr-plane", guide)
    assert np.all(with_median[~valid] == 5.0)        # the band is background on every row
    assert np.array_equal(with_median[valid], raw[valid])   # consistent pixels untouched
    fill, _ = fill_inconsistent(raw, disp_r, valid, "lr-fill", guide)
    assert np.array_equal(fill, without)             # the paper's fill has no median


def test_stereo_lr_plane_is_the_default_and_records_its_share():
    rng = np.random.default_rng(0)
    scene = rng.random((40, 80)) + 0.1
    left, right = scene[:, 2:62], scene[:, 6:66]     # left x matches right x - 4
    res = stereo(left, right, (0, 8), optimizer="wta")
    assert res.occlusion == "lr-plane"
    assert 0.0 <= res.extra["plane_filled"] <= 1.0
    assert np.median(res.disparity) == 4.0
    with pytest.raises(InvalidInputError, match="occlusion must be one of"):
        stereo(left, right, (0, 8), occlusion="plane")


def test_plane_fill_rejects_mismatched_shapes():
    guide, truth, _ = two_surfaces()
    ok = np.ones((H, W), bool)
    with pytest.raises(InvalidInputError, match="shape"):
        reg.plane_fill(truth, ok, guide[:, :-1])
    with pytest.raises(InvalidInputError, match="shape"):
        reg.plane_fill(truth, ok[:-1], guide)
    with pytest.raises(InvalidInputError, match="finite"):
        reg.segment(np.full((4, 4), np.nan))


def test_stereo_from_volumes_lr_plane_needs_the_left_image():
    from hyperlf.twoview import compute_volumes, stereo_from_volumes

    rng = np.random.default_rng(2)
    a = rng.random((20, 30)) + 0.1
    cl, cr = compute_volumes(a, a, 0, 3, "census")
    with pytest.raises(InvalidInputError, match="lr-fill"):
        stereo_from_volumes(cl, cr, 0, "wta", "lr-plane")
    res = stereo_from_volumes(cl, cr, 0, "wta", "lr-fill")
    assert res.extra["plane_filled"] == 0.0


# ----------------------------------------------------------------- planes of pooled costs
def _slanted_volume(seed, noise, L=16, shape=(96, 96), truth=None):
    """Costs ``|l - truth| + noise`` over ``L`` labels: each pixel's own minimum is lost in
    the noise at ``noise`` >> 1, the pooled one is not."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[:shape[0], :shape[1]]
    if truth is None:
        truth = 5.0 + 0.04 * y + 0.02 * x
    labels = np.arange(L)[:, None, None]
    return np.abs(labels - truth) + noise * rng.random((L, *shape)), truth


@pytest.mark.parametrize("seed", range(3))
def test_cost_planes_recover_a_slanted_plane_that_no_pixel_shows(seed):
    C, truth = _slanted_volume(seed, noise=12.0)
    own = np.argmin(C, axis=0)
    assert np.mean(np.abs(own - truth) > 2) > 0.2  # each pixel alone: often far off
    plane = cost_planes(C, np.ones(truth.shape, bool), tile=48, max_slope=0.1)
    assert np.isfinite(plane).mean() > 0.8
    # the search's grid: half labels, slopes in steps of 1/48 (half a label at the tile's edge)
    assert np.nanmax(np.abs(plane - truth)) < 0.8


def test_cost_planes_search_no_steeper_than_twice_the_label_range_across_a_tile():
    """The largest slope taken (1e4 labels per px) searches as many steps as 2 (L - 1)
    across the tile: the same planes, and not a grid of 10^11 slope pairs (the junk test
    of the forty-fourth session's survey hung there)."""
    rng = np.random.default_rng(5)
    C = rng.random((4, 24, 24))
    mask = np.ones((24, 24), bool)
    steep = cost_planes(C, mask, tile=12, max_slope=1e4)
    np.testing.assert_array_equal(steep, cost_planes(C, mask, tile=12, max_slope=6 / 12))
    C, truth = _slanted_volume(2, noise=1.0, L=8, shape=(48, 48),
                               truth=3.0 + 0.05 * np.mgrid[:48, :48][0])
    mask = np.ones((48, 48), bool)
    steep = cost_planes(C, mask, tile=24, max_slope=1e4)
    assert np.isfinite(steep).mean() > 0.5 and np.nanmax(np.abs(steep - truth)) < 0.8
    np.testing.assert_array_equal(steep, cost_planes(C, mask, tile=24, max_slope=14 / 24))


def test_cost_planes_refuse_noise_and_unbracketed_minima():
    rng = np.random.default_rng(4)
    noise = rng.random((16, 96, 96))
    plane = cost_planes(noise, np.ones((96, 96), bool), tile=48, max_slope=0.1)
    assert np.isnan(plane).mean() > 0.9
    edge, _ = _slanted_volume(0, noise=1.0, truth=np.full((96, 96), 0.2))  # at the range's end
    assert np.isnan(cost_planes(edge, np.ones((96, 96), bool), tile=48, max_slope=0.1)).all()
    C, truth = _slanted_volume(1, noise=1.0)
    mask = np.zeros((96, 96), bool)
    mask[:, :30] = True  # only tiles with 30 % of their pixels masked are fitted
    plane = cost_planes(C, mask, tile=48, max_slope=0.1)
    assert np.isnan(plane[:, 72:]).all() and np.isfinite(plane[:, :24]).all()


@pytest.mark.parametrize("seed", [0, 1, 4])
def test_a_refused_tile_takes_the_plane_next_to_it(seed):
    """Where no surface shows (a textureless corner), the tiles are refused; with ``carry``
    they continue the plane of the overlapping accepted tiles, whose samples do not contradict
    it, instead of staying without one."""
    C, truth = _slanted_volume(seed, noise=6.0, shape=(96, 144))
    C[:, :, :40] = 6.0 * np.random.default_rng(100 + seed).random((16, 96, 40))
    mask = np.ones(truth.shape, bool)
    assert np.isnan(cost_planes(C, mask, tile=48, max_slope=0.1, carry=None)[:, :24]).all()
    plane = cost_planes(C, mask, tile=48, max_slope=0.1)
    err = np.abs(plane - truth)[:, :24]
    # one tile's plane moved by up to a tile: slopes in steps of 1/48, c in half labels
    assert np.isfinite(err).all() and err.mean() < 1.0 and err.max() < 1.5
    assert np.nanmax(np.abs(plane - truth)[:, 48:]) < 0.8


def test_a_refused_tile_keeps_no_plane_its_costs_contradict():
    """Of the overlapping tiles' planes, a refused tile takes one its samples do not contradict
    (a surface they show at another depth does), the cheapest of those; none when all are
    contradicted."""
    from hyperlf.regularisers.planes import _carried_plane, _standardised, _tile_samples

    C, _ = _slanted_volume(0, noise=6.0, shape=(48, 48), truth=np.full((48, 48), 4.0))
    P, dx, dy = _tile_samples(C, np.ones((48, 48), bool), 0, 0, 48, 1000, 1.0)
    np.testing.assert_allclose(P, _standardised(C.reshape(16, -1).T[::2].astype(float)))
    own = (0.0, 0.0, 4.0)
    other = {(0, 24): (0.0, 0.0, 9.0)}  # another surface, 5 labels away
    assert _carried_plane(P, dx, dy, own, (0, 0), other, 48, 2.0) is None
    near = {(0, 24): (0.0, 0.0, 4.5), (24, 0): (0.0, 0.0, 9.0), (24, 24): (0.0, 0.0, 4.0)}
    assert _carried_plane(P, dx, dy, own, (0, 0), near, 48, 2.0) == (0.0, 0.0, 4.0)
    # 1152 samples at noise 6 pin the depth to well under half a label: 4.5 is contradicted
    # at 2 standard errors; allowed more, the cheaper of 4.5 and 4.0 is taken
    assert _carried_plane(P, dx, dy, own, (0, 0), {(0, 24): (0.0, 0.0, 4.5)}, 48, 2.0) is None
    for order in (near, dict(reversed(near.items()))):
        assert _carried_plane(P, dx, dy, own, (0, 0), order, 48, 30.0) == (0.0, 0.0, 4.0)
    far = {(0, 48): (0.0, 0.0, 4.0)}  # a tile that does not overlap it
    assert _carried_plane(P, dx, dy, own, (0, 0), far, 48, 2.0) is None


def test_cost_planes_ignore_a_bias_of_one_pixel_period():
    """Half-pixel shifts cost less in pure noise (bilinear sampling halves its variance): with
    labels every half pixel, a bias that alternates must neither become a plane nor move
    one."""
    rng = np.random.default_rng(5)
    bias = 3.0 * (np.arange(16) % 2)[:, None, None]
    mask = np.ones((96, 96), bool)
    noise = cost_planes(10 * rng.random((16, 96, 96)) - bias, mask, tile=48, max_slope=0.1,
                        period=2.0)
    assert np.isnan(noise).mean() > 0.9
    C, truth = _slanted_volume(0, noise=10.0)
    plane = cost_planes(C - bias, mask, tile=48, max_slope=0.1, period=2.0)
    assert np.isfinite(plane).mean() > 0.8 and np.nanmax(np.abs(plane - truth)) < 0.8


def test_plane_scores_numba_matches_numpy():
    from hyperlf.regularisers import _kernels
    from hyperlf.regularisers.planes import _plane_scores_numpy

    rng = np.random.default_rng(6)
    P = rng.standard_normal((200, 12))
    dx, dy = rng.uniform(-20, 20, 200), rng.uniform(-20, 20, 200)
    A, B, c = np.linspace(-0.2, 0.2, 5), np.linspace(-0.3, 0.3, 7), np.arange(0, 11.5, 0.5)
    ref = _plane_scores_numpy(P, dx, dy, A, B, c, 180)
    out = np.empty_like(ref)
    _kernels.plane_scores(P, dx, dy, A, B, c, 180.0, out)
    assert np.isinf(ref).any() and np.isfinite(ref).any()
    np.testing.assert_allclose(out, ref, rtol=1e-10, atol=1e-12)
    assert (np.isinf(out) == np.isinf(ref)).all()


def test_cost_planes_check_their_input():
    with pytest.raises(InvalidInputError):
        cost_planes(np.zeros((4, 8, 8)), np.ones((8, 9), bool), tile=8, max_slope=0.1)
    with pytest.raises(InvalidInputError):
        cost_planes(np.zeros((4, 8, 8)), np.ones((8, 8), bool), tile=2, max_slope=0.1)
    with pytest.raises(InvalidInputError):
        cost_planes(np.zeros((4, 8, 8)), np.ones((8, 8), bool), tile=8, max_slope=0.1,
                    carry=-1.0)
