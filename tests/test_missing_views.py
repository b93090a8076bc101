"""Views that cannot see a sample (issue 11, item 3): averaging over the views that do see it
pulls textureless pixels to the range limits, where fewer, noisier costs are averaged;
``missing_views="neutral"`` removes that bias, and ``"common"`` averages every label of a
pixel over the same views."""

from __future__ import annotations

import numpy as np
import pytest

from hyperlf import hlf
from hyperlf.errors import InvalidInputError
from hyperlf.lightfield import LightField

from conftest import refused_while_parsing_and_handed_on


def at_limits(mode: str) -> float:
    """Fraction of pixels at a range limit on a textureless scene (flat grey + noise): with no
    information every label is as likely, so 2 of 17 labels = 11.8 % is the unbiased answer."""
    rng = np.random.default_rng(0)
    views = 0.5 + 0.01 * rng.standard_normal((3, 3, 40, 48)).astype(np.float32)
    lf = LightField(views=views, disparity_range=(-8.0, 8.0))
    params = hlf.DepthParams(missing_views=mode, median_radius=0)
    d = hlf.depth(lf, n_labels=17, metric="ncc", optimizer="wta", params=params).disparity
    return float(np.mean(np.abs(np.abs(d) - 8.0) < 1e-3))


def test_neutral_missing_views_remove_the_pull_to_the_range_limits():
    unbiased = 2 / 17
    average, neutral = at_limits("average"), at_limits("neutral")
    assert abs(neutral - unbiased) < 0.025, neutral
    assert average > neutral + 0.03, (average, neutral)


def test_common_views_average_every_label_over_the_same_views():
    rng = np.random.default_rng(1)
    views = 0.5 + 0.05 * rng.standard_normal((3, 3, 40, 48)).astype(np.float32)
    lf = LightField(views=views, disparity_range=(-8.0, 8.0))
    counts = {}
    for mode in ("average", "common"):
        prob = hlf.prepare(lf, n_labels=17, metric="ncc",
                           params=hlf.DepthParams(missing_views=mode))
        counts[mode] = hlf.correspondence(prob)[1]
    average, common = counts["average"], counts["common"]
    y, x = np.mgrid[:40, :48]
    corner = ((x < 8) | (x > 39)) & ((y < 8) | (y > 31))  # no view sees every label: all kept
    np.testing.assert_array_equal(common[:, corner], average[:, corner])
    assert (common[:, ~corner] == common[:1, ~corner]).all()  # the same count at every label
    assert (average[:, ~corner] != average[:1, ~corner]).any()  # which the plain mean lacks
    np.testing.assert_array_equal(common[:, 20, 24], 8)  # the middle: every view
    np.testing.assert_array_equal(common[:, 36, 24], 2)  # near the bottom: the two beside it


def _flat_problem(valid=None):
    views = np.full((3, 3, 40, 48), 0.5, np.float32)
    lf = LightField(views=views, disparity_range=(-8.0, 8.0), valid=valid)
    return lf, hlf.prepare(lf, n_labels=17, metric="ncc",
                           params=hlf.DepthParams(missing_views="common"))


def test_views_at_every_label_follow_the_geometry():
    lf, prob = _flat_problem()
    y, x = np.mgrid[:40, :48]
    # labels -8..8: view v sees p at every label iff p - d o_v stays inside for |d| <= 8
    inside_x, inside_y = (x >= 8) & (x <= 39), (y >= 8) & (y <= 31)
    corner = ~inside_x & ~inside_y  # no view sees these at every label: all views kept
    for v, m in prob.every_label.items():
        dx, dy = lf.offsets[v]
        expect = (inside_x if dx else True) & (inside_y if dy else True)
        np.testing.assert_array_equal(m, expect | corner, err_msg=str(v))
    assert hlf.prepare(lf, n_labels=17, metric="ncc").every_label is None


def test_views_at_every_label_respect_validity_masks():
    valid = np.ones((3, 3, 40, 48), bool)
    valid[1, 2, :, 30] = False  # a dead column in the view right of the reference
    _, prob = _flat_problem(valid)
    m = prob.every_label[(1, 2)]
    # that view samples x - d for d in -8..8: the dead column is on the line of x = 22..38
    assert not m[20, 22:39].any() and m[20, 8:22].all() and m[20, 39]


def test_neutral_keeps_labels_every_view_sees():
    C = np.array([[[1.0]], [[2.0]], [[3.0]]], np.float32)
    n = np.array([[[4]], [[4]], [[2]]])
    out = hlf.neutral_missing_views(C, n)
    np.testing.assert_allclose(out[:2, 0, 0], [1.0, 2.0])
    np.testing.assert_allclose(out[2, 0, 0], (3.0 * 2 + 2 * 2.0) / 4)  # median 2.0 fills in
    assert np.isnan(hlf.neutral_missing_views(C, np.zeros_like(n))).all()


def test_missing_views_option_is_checked():
    with pytest.raises(InvalidInputError, match="missing_views"):
        hlf.DepthParams(missing_views="ignore")


def _check_depth_option(tmp_path, capsys, batch_depth_args, lf, option, modes, bad):
    """``depth OPTION MODE`` writes the library's map under ``DepthParams(name=MODE)`` for
    each of the two ``modes``, and the two maps differ; ``bad`` is refused while parsing
    (exit 2, nothing written); ``batch`` hands the option on only when given."""
    from hyperlf.cli import main
    from hyperlf.formats import read_pfm, save_lightfield

    name = option.lstrip("-").replace("-", "_")
    save_lightfield(lf, tmp_path / "cap", bit_depth=32)
    maps = {}
    for mode in modes:
        assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "17", "--metric", "ncc",
                     "--optimizer", "wta", "--median-radius", "0", option, mode,
                     "-o", str(tmp_path / mode)]) == 0
        maps[mode] = read_pfm(tmp_path / mode / "disparity.pfm")
        params = hlf.DepthParams(**{name: mode}, median_radius=0)
        np.testing.assert_array_equal(
            maps[mode], hlf.depth(lf, n_labels=17, metric="ncc", optimizer="wta",
                                  params=params).disparity)
    assert (maps[modes[0]] != maps[modes[1]]).any()
    refused_while_parsing_and_handed_on(capsys, batch_depth_args, tmp_path / "cap",
                                        tmp_path / "bad", option, bad, modes[1])


def test_depth_and_batch_commands_take_missing_views(tmp_path, capsys, batch_depth_args):
    lf, _ = _flat_problem()
    rng = np.random.default_rng(2)
    lf.views[:] += 0.05 * rng.standard_normal(lf.views.shape).astype(np.float32)
    _check_depth_option(tmp_path, capsys, batch_depth_args, lf, "--missing-views",
                        ("average", "common"), "ignore")


def _row_plane() -> LightField:
    """A textured plane at d = 6 seen by a 1 x 3 row whose reference is its left end: the
    reference's left strip is seen by no view at the larger disparities."""
    from scipy.ndimage import gaussian_filter

    big = gaussian_filter(np.random.default_rng(2).random((24, 80)), 1.2).astype(np.float32)
    views = np.stack([big[:, 6 * k:6 * k + 48] for k in range(3)])[None]
    return LightField(views=views, disparity_range=(0.0, 8.0), reference=(0, 0))


def test_labels_no_view_sees_get_the_pixels_worst_median_or_graded_cost():
    """``unseen_labels``: near the left edge of a reference at the end of a 1 x 3 array no view
    sees the larger disparities; those entries get the pixel's worst cost (the label ruled
    out), the median of its other costs (left to the regulariser), or between the two by the
    share of labels seen (the default)."""
    lf = _row_plane()
    assert hlf.DepthParams().unseen_labels == "share"

    def share(c):  # c: the seen costs of one pixel, out of 17 labels
        return np.median(c) + c.size / 17 * (c.max() - np.median(c))

    for mode, rule in (("worst", np.max), ("median", np.median), ("share", share)):
        prob = hlf.prepare(lf, n_labels=17, params=hlf.DepthParams(unseen_labels=mode))
        C, n_used = hlf.correspondence(prob)
        unseen = n_used == 0
        assert unseen[:, :, :4].all(axis=(1, 2)).sum() >= 8 and not unseen[:, :, 16:].any()
        for y, x in zip(*np.nonzero(unseen.any(axis=0))):
            seen = ~unseen[:, y, x]
            np.testing.assert_allclose(C[~seen, y, x], rule(C[seen, y, x]), rtol=1e-6)
    with pytest.raises(InvalidInputError, match="unseen_labels"):
        hlf.DepthParams(unseen_labels="mean")


def test_depth_and_batch_commands_take_unseen_labels(tmp_path, capsys, batch_depth_args):
    _check_depth_option(tmp_path, capsys, batch_depth_args, _row_plane(), "--unseen-labels",
                        ("worst", "median"), "mean")


def test_share_keeps_a_foreground_depth_out_of_the_background_rows_above_it():
    """A 2 x 3 procedural scene whose side views lose their top 12 rows (as rectification
    cuts them): above an object at 5.1 px that starts at row 7, the background rows are seen
    only at the background's depth.  ``"median"`` lets the object spread over them;
    ``"share"`` keeps them as ``"worst"`` does (BENCHMARKS.md, thirtieth session)."""
    import dataclasses

    from hyperlf import synthesis

    lf = synthesis.procedural_scene(seed=2, rows=2, cols=3, height=48, width=64,
                                    disparity_range=(1.0, 6.0),
                                    reflectance_source="colorchecker")
    valid = np.ones(lf.views.shape, bool)
    valid[0, 0, :12] = valid[0, 2, :12] = False
    lf = dataclasses.replace(lf, valid=valid)
    err = {}
    for mode in ("share", "worst", "median"):
        r = hlf.depth(lf, n_labels=25, params=hlf.DepthParams(unseen_labels=mode))
        err[mode] = float(np.abs(r.disparity - lf.reference_gt_disparity)[:12].mean())
    assert err["share"] < 0.4 and err["share"] <= err["worst"] + 0.02, err  # 0.309 each
    assert err["median"] > 0.5, err  # 0.601: the object spread
