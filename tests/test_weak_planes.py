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


def test_plane_prior_puts_the_pooled_plane_where_the_coarse_estimate_was():
    lf = _grey_capture()
    prob = hlf.prepare(lf, n_labels=17, params=hlf.DepthParams(weak_planes=True))
    w = hlf.texture_weight(prob)
    assert w.max() < 0.5
    labels = prob.labels  # -4 .. 4 in 0.5 px steps
    y, x = np.mgrid[:96, :96]
    truth = -1.0 + 0.02 * y + 0.01 * x  # disparity px
    rng = np.random.default_rng(1)
    C = (np.abs(labels[:, None, None] - truth) + 6 * rng.random((17, 96, 96))).astype(np.float32)
    prior = (np.zeros((96, 96), np.float32), np.zeros((96, 96), np.float32), 1.0, None)
    coarse, strength, width, conf = hlf.plane_prior(prob, C, w, prior)
    assert width == 1.0 and conf is None
    under = coarse != 0
    assert under.mean() > 0.8
    # the search's grid: half labels (0.25 px), slopes in steps of half a label at tile edges
    assert np.abs(coarse - truth)[under].max() < 0.5
    np.testing.assert_allclose(strength[under], 1 - w[under], rtol=1e-6)
    # off, without a weight or without a prior: the prior as it was
    off = hlf.prepare(lf, n_labels=17, params=hlf.DepthParams(weak_planes=False))
    assert hlf.plane_prior(off, C, w, prior) is prior
    assert hlf.plane_prior(prob, C, None, prior) is prior
    assert hlf.plane_prior(prob, C, w, None) is None


def test_plane_prior_pools_only_pixels_whose_labels_share_their_views(monkeypatch):
    from hyperlf import regularisers

    lf = _grey_capture()
    C = np.zeros((17, 96, 96), np.float32)
    prior = (np.zeros((96, 96), np.float32), np.zeros((96, 96), np.float32), 1.0, None)
    masks = {}

    def capture(volume, mask, **kw):
        masks[mode] = mask
        return np.full(mask.shape, np.nan, np.float32)

    monkeypatch.setattr(regularisers, "cost_planes", capture)
    for mode in ("average", "common"):
        prob = hlf.prepare(lf, n_labels=17, params=hlf.DepthParams(weak_planes=True,
                                                                    missing_views=mode))
        hlf.plane_prior(prob, C, hlf.texture_weight(prob), prior)
    # labels -4 .. 4 and views one baseline away: within 4 px of a border some views leave
    # the image at some label, so the plain average gives those labels fewer views
    inner = np.zeros((96, 96), bool)
    inner[4:92, 4:92] = True
    np.testing.assert_array_equal(masks["average"], inner)
    # every label over the views that see all of them: all pixels but the corners, which
    # no view sees at every label
    corner = np.zeros((96, 96), bool)
    for ys in (slice(0, 4), slice(92, 96)):
        for xs in (slice(0, 4), slice(92, 96)):
            corner[ys, xs] = True
    np.testing.assert_array_equal(masks["common"], ~corner)


@pytest.mark.parametrize("seed", range(2))
def test_weak_planes_leave_a_textureless_table_to_its_surroundings(seed):
    """No texture at any level: the pooled costs are noise (and the cameras' vignetting),
    the halves of each tile disagree, and the table keeps its surroundings' depth."""
    lf = _table_scene(seed)
    res = hlf.depth(lf, n_labels=25, params=hlf.DepthParams(texture_snr=2, weak_planes=True))
    err = np.abs(res.disparity[H // 2 + 8:, :] - D0)
    assert np.percentile(err, 95) < 0.25 and err.max() <= 0.55
    assert "plane_prior_s" in res.timings


@pytest.mark.parametrize("bad", [{"weak_planes": 1}, {"weak_planes": "yes"},
                                 {"plane_tile": 4}, {"plane_tile": 64.0}, {"plane_tile": True},
                                 {"plane_max_slope": 0}, {"plane_max_slope": 2.0},
                                 {"plane_max_slope": "0.1"}, {"plane_max_slope": float("nan")}])
def test_depth_params_check_the_plane_options(bad):
    with pytest.raises(InvalidInputError, match="weak_planes|plane_"):
        hlf.DepthParams(**bad)


def test_depth_and_batch_commands_take_weak_planes(tmp_path, capsys, batch_depth_args):
    from hyperlf.cli import main
    from hyperlf.formats import read_pfm, save_lightfield

    lf = _table_scene(0)
    save_lightfield(lf, tmp_path / "cap", bit_depth=32)
    assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "25", "--texture-snr", "2",
                 "--weak-planes", "-o", str(tmp_path / "d")]) == 0
    ref = hlf.depth(lf, n_labels=25, params=hlf.DepthParams(texture_snr=2, weak_planes=True))
    np.testing.assert_array_equal(read_pfm(tmp_path / "d" / "disparity.pfm"), ref.disparity)
    capsys.readouterr()
    assert main(["-q", "depth", str(tmp_path / "cap"), "--weak-planes", "--no-coarse-prior",
                 "-o", str(tmp_path / "bad")]) == 2
    assert "--weak-planes" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()

    assert "--weak-planes" not in batch_depth_args()
    assert batch_depth_args("--weak-planes")[-1] == "--weak-planes"
