"""Slanted planes of the pooled costs as the coarse prior's target on weakly textured pixels
(``DepthParams.weak_planes``, :func:`hyperlf.hlf.plane_prior`; issue 11)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from hyperlf import hlf
from hyperlf.errors import InvalidInputError
from hyperlf.lightfield import LightField

sys.path.insert(0, str(Path(__file__).parent))
from test_textureless import D0, H, _table_scene  # noqa: E402


def _grey_capture(size=96, seed=0):
    """A 3 x 3 capture of flat grey and noise, made from camera images: no texture at any
    level, so the weight and the coarse levels' coverage are 0 everywhere."""
    rng = np.random.default_rng(seed)
    views = 0.5 + 0.005 * rng.standard_normal((3, 3, size, size))
    return LightField(views.astype(np.float32), disparity_range=(-4.0, 4.0),
                      metadata={"calibration": {"mode": "plane"}})


def _flat_prior(size=96):
    return (np.zeros((size, size), np.float32), np.zeros((size, size), np.float32), 1.0, None)


def test_plane_prior_carries_the_coarse_levels_plane_up(monkeypatch):
    """The planes are fitted at the coarse prior's scale (2: 48 x 48 px, labels -2 .. 2 in
    0.25 px steps) and become full-resolution disparities: twice the coarse level's, on each
    2 x 2 block."""
    lf = _grey_capture()
    prob = hlf.prepare(lf, n_labels=17, params=hlf.DepthParams(weak_planes=True))
    w = hlf.texture_weight(prob)
    assert w.max() < 0.5
    y, x = np.mgrid[:48, :48]
    truth = -0.5 + 0.01 * y + 0.005 * x  # coarse-level disparity px
    rng = np.random.default_rng(1)
    levels = []

    def level_volume(level, **kw):
        levels.append(level)
        labels = level.labels[:, None, None]
        C = np.abs(labels - truth) + 6 * rng.random((labels.size, 48, 48))
        return C.astype(np.float32), None

    monkeypatch.setattr(hlf, "correspondence", level_volume)
    coarse, strength, width, conf = hlf.plane_prior(prob, w, _flat_prior())
    (level,) = levels
    assert level.lf.image_shape == (48, 48) and level.params.missing_views == "common"
    np.testing.assert_allclose(level.labels, np.linspace(-2, 2, 17))
    assert width == 1.0 and conf is None
    under = coarse != 0
    assert under.mean() > 0.8
    full = 2 * np.repeat(np.repeat(truth, 2, 0), 2, 1)
    # the search's grid: half labels (0.125 px there), slopes in half-label steps at tile edges
    assert np.abs(coarse - full)[under].max() < 0.5
    np.testing.assert_allclose(strength[under], 1 - w[under], rtol=1e-6)


def test_plane_prior_is_off_without_its_option_a_weight_or_a_prior(monkeypatch):
    lf = _grey_capture()
    prob = hlf.prepare(lf, n_labels=17, params=hlf.DepthParams(weak_planes=True))
    w, prior = hlf.texture_weight(prob), _flat_prior()
    off = hlf.prepare(lf, n_labels=17, params=hlf.DepthParams(weak_planes=False))
    monkeypatch.setattr(hlf, "correspondence", None)  # none of these computes a volume
    assert hlf.plane_prior(off, w, prior) is prior
    assert hlf.plane_prior(prob, None, prior) is prior
    assert hlf.plane_prior(prob, w, None) is None
    small = hlf.prepare(_grey_capture(24), n_labels=17, params=hlf.DepthParams(weak_planes=True))
    tiny = _flat_prior(24)  # a coarse level of 12 px is too small
    assert hlf.plane_prior(small, hlf.texture_weight(small), tiny) is tiny


def test_a_prior_given_below_the_coarse_levels_size_is_kept():
    """At 40 px the planes are fitted (20 px), but no coarse prior level fits (a level keeps 8
    texture windows): a prior given there is taken as it is, not a TypeError."""
    small = hlf.prepare(_grey_capture(40), n_labels=17,
                        params=hlf.DepthParams(weak_planes=True))
    prior = _flat_prior(40)
    out = hlf.plane_prior(small, hlf.texture_weight(small), prior)
    assert np.array_equal(out[0], prior[0]) and np.array_equal(out[1], prior[1])
    assert out[2:] == prior[2:]


def test_plane_prior_pools_only_pixels_whose_labels_share_their_views(monkeypatch):
    from hyperlf import regularisers

    lf = _grey_capture()
    masks = {}

    def capture(volume, mask, **kw):
        masks[mode] = mask
        return np.full(mask.shape, np.nan, np.float32)

    monkeypatch.setattr(regularisers, "cost_planes", capture)
    for mode in ("average", "common"):
        prob = hlf.prepare(lf, n_labels=17, params=hlf.DepthParams(weak_planes=True,
                                                                    missing_views=mode))
        hlf.plane_prior(prob, hlf.texture_weight(prob), _flat_prior())
    # the coarse level (48 x 48, labels -2 .. 2, views one baseline away) averages every
    # label over the views that see all of them, whatever the main pass does: all pixels but
    # the corners, which no view sees at every label
    corner = np.zeros((48, 48), bool)
    for ys in (slice(0, 2), slice(46, 48)):
        for xs in (slice(0, 2), slice(46, 48)):
            corner[ys, xs] = True
    np.testing.assert_array_equal(masks["average"], ~corner)
    np.testing.assert_array_equal(masks["common"], ~corner)


def test_plane_prior_passes_the_carry_on(monkeypatch):
    from hyperlf import regularisers

    seen = []

    def capture(volume, mask, **kw):
        seen.append(kw["carry"])
        return np.full(mask.shape, np.nan, np.float32)

    monkeypatch.setattr(regularisers, "cost_planes", capture)
    for carry in (None, 0, 1.5):
        prob = hlf.prepare(_grey_capture(), n_labels=17, params=hlf.DepthParams(plane_carry=carry))
        hlf.plane_prior(prob, hlf.texture_weight(prob), _flat_prior())
    assert seen == [None, 0.0, 1.5] and hlf.DepthParams().plane_carry == 2.0


def test_specks_are_small_islands_of_texture_in_weak_surroundings():
    weak = np.ones((60, 60), bool)
    weak[10:14, 10:14] = False  # a speck of 4 x 4 px amid weak pixels
    weak[30:, 30:] = False  # a textured object of 30 x 30 px in the corner
    specks = hlf._specks(weak, 15)
    assert specks[10:14, 10:14].all() and specks.sum() == 16 + specks[30:, 30:].sum()
    # of the object only pixels near its convex corner, where more than half of the 15 px
    # square is weak (along a straight edge at most 7 of its 15 rows are)
    assert specks[30:, 30:].sum() < 30 and not specks[37:, :].any()
    assert not hlf._specks(weak, 0).any()
    assert not (hlf._specks(weak, 15) & weak).any()


def test_plane_prior_pulls_specks_to_the_plane(monkeypatch):
    """A pixel that the coarse levels saw textured (``g >= 0.5``) keeps ``d_coarse``, unless it
    is a speck in weakly textured surroundings (``plane_specks``)."""
    lf = _grey_capture()
    g = np.zeros((96, 96), np.float32)
    g[40:44, 40:44] = 1.0  # a speck
    g[:, 80:] = 1.0  # a textured region
    monkeypatch.setattr(hlf, "_coverage", lambda prob, levels: g)
    monkeypatch.setattr(hlf, "_coarse_planes", lambda prob, s, **kw: np.full(g.shape, 2.5,
                                                                            np.float32))
    for window, speck_target in ((15, 2.5), (0, 0.0)):
        prob = hlf.prepare(lf, n_labels=17, params=hlf.DepthParams(plane_specks=window))
        w = hlf.texture_weight(prob)
        coarse, strength, _, _ = hlf.plane_prior(prob, w, _flat_prior())
        assert (coarse[g == 0] == 2.5).all() and (coarse[40:44, 40:44] == speck_target).all()
        assert (coarse[:, 88:] == 0).all()  # inside the textured region: d_coarse
        np.testing.assert_allclose(strength[40:44, 40:44], 1 - w[40:44, 40:44] if window
                                   else 0.0, rtol=1e-6)


@pytest.mark.parametrize("seed", range(2))
def test_weak_planes_leave_a_textureless_table_to_its_surroundings(seed):
    """No texture at any level: the pooled costs are noise (and the cameras' vignetting),
    no tile's plane is accepted, and the table keeps its surroundings' depth."""
    lf = _table_scene(seed)
    res = hlf.depth(lf, n_labels=25, params=hlf.DepthParams(texture_snr=2, weak_planes=True))
    err = np.abs(res.disparity[H // 2 + 8:, :] - D0)
    assert np.percentile(err, 95) < 0.25 and err.max() <= 0.55
    assert "plane_prior_s" in res.timings


@pytest.mark.parametrize("bad", [{"weak_planes": 1}, {"weak_planes": "yes"},
                                 {"plane_tile": 4}, {"plane_tile": 64.5}, {"plane_tile": True},
                                 {"plane_max_slope": 0}, {"plane_max_slope": 2.0},
                                 {"plane_max_slope": "0.1"}, {"plane_max_slope": float("nan")},
                                 {"plane_specks": -1}, {"plane_specks": 15.5},
                                 {"plane_specks": True}, {"plane_carry": -1.0},
                                 {"plane_carry": float("nan")}, {"plane_carry": float("inf")},
                                 {"plane_carry": "2"}, {"plane_carry": True}])
def test_depth_params_check_the_plane_options(bad):
    with pytest.raises(InvalidInputError, match="weak_planes|plane_"):
        hlf.DepthParams(**bad)


def test_weak_planes_are_on_by_default():
    assert hlf.DepthParams().weak_planes is True


def test_depth_and_batch_commands_take_weak_planes(tmp_path, capsys, batch_depth_args):
    from hyperlf.cli import main
    from hyperlf.formats import read_pfm, save_lightfield

    lf = _table_scene(0)
    save_lightfield(lf, tmp_path / "cap", bit_depth=32)
    for flag, on in (("--weak-planes", True), ("--no-weak-planes", False)):
        out = tmp_path / flag
        assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "25", "--texture-snr",
                     "2", flag, "-o", str(out)]) == 0
        ref = hlf.depth(lf, n_labels=25, params=hlf.DepthParams(texture_snr=2, weak_planes=on))
        np.testing.assert_array_equal(read_pfm(out / "disparity.pfm"), ref.disparity)
    capsys.readouterr()
    assert main(["-q", "depth", str(tmp_path / "cap"), "--weak-planes", "--no-coarse-prior",
                 "-o", str(tmp_path / "bad")]) == 2
    assert "--weak-planes" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
    # without the coarse prior the default's planes have nothing to act on: no refusal
    assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "9", "--no-coarse-prior",
                 "-o", str(tmp_path / "plain")]) == 0

    assert not {"--weak-planes", "--no-weak-planes"} & set(batch_depth_args())
    assert batch_depth_args("--weak-planes")[-1] == "--weak-planes"
    assert batch_depth_args("--no-weak-planes")[-1] == "--no-weak-planes"
