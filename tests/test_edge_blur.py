"""How soft a view's edges are (imageops.edge_blur), and the post-filter passes it sets
(hlf.median_passes): blurred views carry the foreground further over the background."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.ndimage import gaussian_filter

from hyperlf.errors import InvalidInputError
from hyperlf.hlf import (MAX_MEDIAN_PASSES, NOISE_MIN_SIDE, DepthParams, guide_noise,
                         median_passes, post_filter)
from hyperlf.imageops import edge_blur
from hyperlf.regularisers import weighted_median


def _steps(seed=0, size=16, n=16):
    """Piecewise-constant blocks of random grey levels: step edges of every contrast."""
    return np.kron(np.random.default_rng(seed).random((n, n)), np.ones((size, size)))


@pytest.mark.parametrize("sigma", [1.0, 1.5, 2.0, 3.0])
def test_edge_blur_recovers_a_known_gaussian_blur(sigma):
    """Blurs add in quadrature: what the sharp steps read (the differences' own width) and
    the known blur."""
    img = _steps()
    own = edge_blur(img)
    assert 0.6 < own < 0.9
    assert edge_blur(gaussian_filter(img, sigma)) == pytest.approx(np.hypot(own, sigma),
                                                                   rel=0.05)


def test_edge_blur_grows_with_blur_and_ignores_contrast_and_offset():
    img = _steps(seed=1)
    sharp, soft = edge_blur(img), edge_blur(gaussian_filter(img, 1.0))
    assert sharp < 0.9 < 1.2 < soft           # the rule's one-pass and two-pass sides
    assert edge_blur(5.0 * img + 3.0) == pytest.approx(sharp, rel=1e-9)


def test_edge_blur_counts_no_edge_at_the_border_of_missing_data():
    img = gaussian_filter(_steps(seed=2), 2.0)
    valid = np.ones(img.shape, bool)
    valid[:, 6::32] = valid[:, 7::32] = valid[:, 8::32] = False   # dead columns, zeros
    cut = img.copy()
    cut[~valid] = 0.0                         # hard steps where the data ends
    assert edge_blur(cut) < 1.5               # counted, they read sharper
    assert edge_blur(cut, valid=valid) == pytest.approx(edge_blur(img), rel=0.02)


@pytest.mark.parametrize("kw", [{"reblur": 0.0}, {"reblur": -1.0}, {"share": 0.0},
                                {"share": 1.5}, {"reblur": float("nan")}])
def test_edge_blur_refuses_meaningless_options(kw):
    with pytest.raises(InvalidInputError, match="edge_blur"):
        edge_blur(_steps(), **kw)


def test_edge_blur_is_nan_without_edges():
    assert np.isnan(edge_blur(np.full((64, 64), 0.3)))
    assert np.isnan(edge_blur(np.ones((40, 40)), valid=np.zeros((40, 40), bool)))


def test_passes_follow_the_blur():
    img = _steps(seed=3)
    p = DepthParams()
    assert median_passes(img, p)[0] == 1
    for sigma, expected in ((1.0, 2), (2.0, 4)):       # ceil((blur - 0.8) / 0.4)
        n, blur = median_passes(gaussian_filter(img, sigma), p)[:2]
        assert n == expected == int(np.ceil((blur - 0.8) / 0.4))
    forced = median_passes(gaussian_filter(img, 2.0), DepthParams(median_passes=1))
    assert (forced.passes, forced.noise_passes) == (1, 0)
    assert np.isnan(forced.edge_blur_px) and np.isnan(forced.noise)
    assert median_passes(np.full((32, 32), 0.5), p)[0] == 1     # nothing to tell: one


@pytest.mark.parametrize("relative, step, expected", [(0.0, 0.01, 0), (0.005, 0.01, 0),
                                                      (0.015, 0.01, 1), (0.035, 0.01, 3),
                                                      (0.035, 0.02, 1), (0.035, None, 0)])
def test_noise_adds_passes(relative, step, expected):
    """White noise of a known share of the mean adds one pass per median_noise_step of it, on
    top of the blur rule's; the noise is measured within 10 %."""
    img = 0.3 + 0.2 * gaussian_filter(np.random.default_rng(5).random((256, 256)), 2.0)
    noisy = img + relative * img.mean() * np.random.default_rng(6).standard_normal(img.shape)
    blur_only = median_passes(noisy, DepthParams(median_noise_step=None))
    got = median_passes(noisy, DepthParams(median_noise_step=step))
    assert got.noise_passes == expected
    assert got.passes == blur_only.passes + expected
    assert got.edge_blur_px == blur_only.edge_blur_px
    if step is None:
        assert np.isnan(got.noise)
    else:
        assert got.noise == pytest.approx(relative, abs=0.1 * relative + 1e-3)
        assert guide_noise(noisy) == got.noise
        assert guide_noise(noisy * 7.0) == pytest.approx(got.noise)      # scale-free


def test_small_guides_add_no_passes_for_noise():
    """Below NOISE_MIN_SIDE the noise is not read: small renders' aliased texture passes for
    it (a clean 40 x 48 procedural scene reads 8 % of its mean)."""
    from hyperlf import synthesis
    from hyperlf.costs.lightfield import normalise_intensity

    lf = synthesis.procedural_scene(seed=1, rows=3, cols=4, height=40, width=48)
    guide = normalise_intensity(lf.reference_view)
    assert guide_noise(guide) > 0.05                         # what the estimator reads
    got = median_passes(guide, DepthParams())
    assert got.noise_passes == 0 and np.isnan(got.noise) and got.passes == 1
    img = 0.3 + 0.2 * gaussian_filter(np.random.default_rng(5).random((NOISE_MIN_SIDE,) * 2),
                                      2.0)
    noisy = img + 0.02 * img.mean() * np.random.default_rng(6).standard_normal(img.shape)
    assert median_passes(noisy, DepthParams()).noise_passes >= 1
    assert median_passes(noisy[:-1], DepthParams()).noise_passes == 0


def test_a_noise_step_near_zero_gives_at_most_the_most_passes():
    img = 0.3 + 0.2 * gaussian_filter(np.random.default_rng(5).random((NOISE_MIN_SIDE,) * 2),
                                      2.0)
    noisy = img + 0.02 * img.mean() * np.random.default_rng(6).standard_normal(img.shape)
    for step in (5e-324, 1e-300):
        got = median_passes(noisy, DepthParams(median_noise_step=step))
        assert got.noise_passes == MAX_MEDIAN_PASSES == got.passes


def test_guide_noise_of_an_empty_or_dark_guide_is_zero():
    assert guide_noise(np.zeros((16, 16))) == 0.0
    assert guide_noise(np.ones((16, 16)), valid=np.zeros((16, 16), bool)) == 0.0


def test_post_filter_runs_the_passes():
    rng = np.random.default_rng(4)
    d = rng.normal(size=(30, 40)).astype(np.float32)
    g = gaussian_filter(_steps(seed=4, size=5, n=8)[:30, :40], 1.0).astype(np.float32)
    p = DepthParams(median_radius=2)
    twice = weighted_median(weighted_median(d, g, 2, p.median_sigma), g, 2, p.median_sigma)
    np.testing.assert_array_equal(post_filter(d, g, p, passes=2), twice)
    np.testing.assert_array_equal(post_filter(d, g, DepthParams(median_radius=2,
                                                                median_passes=2)), twice)
    assert post_filter(d, g, DepthParams(median_radius=0, median_passes=3)) is d


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.integers(-3, 5), st.floats(allow_nan=True), st.text(max_size=6),
                 st.booleans(), st.none()))
def test_median_passes_option_is_checked(value):
    ok = value == "auto" or (isinstance(value, (int, float)) and not isinstance(value, bool)
                             and np.isfinite(value) and value == int(value)
                             and 1 <= value <= MAX_MEDIAN_PASSES)
    if ok:
        assert DepthParams(median_passes=value).median_passes == value
    else:
        with pytest.raises(InvalidInputError, match="median_passes"):
            DepthParams(median_passes=value)


@pytest.mark.parametrize("name, value", [("median_blur_step", 0.0), ("median_blur_step", -1.0),
                                         ("median_blur_sharp", -0.1), ("median_noise_step", 0.0),
                                         ("median_noise_step", -0.01),
                                         ("median_noise_step", float("nan"))])
def test_blur_rule_constants_are_checked(name, value):
    with pytest.raises(InvalidInputError, match=name):
        DepthParams(**{name: value})


def test_depth_says_when_soft_edges_get_more_passes(tmp_path, capsys):
    """A blurred capture through the CLI: more passes, and the log says why."""
    from hyperlf import synthesis
    from hyperlf.cli import main
    from hyperlf.formats import save_lightfield

    lf = synthesis.procedural_scene(seed=3, rows=3, cols=3, height=64, width=64)
    v = lf.views.astype(np.float64)
    soft = lf.replace(views=np.stack([[gaussian_filter(v[r, c], 2.0) for c in range(3)]
                                      for r in range(3)]).astype(lf.views.dtype))
    save_lightfield(soft, tmp_path / "cap")
    assert main(["depth", str(tmp_path / "cap"), "--labels", "8", "-o",
                 str(tmp_path / "d")]) == 0
    import re

    said = re.search(r"soft image edges \(blur ([0-9.]+) px\) pull the depth edges off them: "
                     r"the weighted median ran (\d+) times", capsys.readouterr().err)
    assert said, "no word of the soft edges"
    blur, passes = float(said[1]), int(said[2])
    assert blur > 1.2 and passes == int(np.ceil((blur - 0.8) / 0.4)) >= 2
    # --median-passes overrides the rule: once, as the library's median_passes=1 does
    from hyperlf.formats import load_lightfield, read_pfm
    from hyperlf.hlf import depth

    assert main(["depth", str(tmp_path / "cap"), "--labels", "8", "--median-passes", "1",
                 "-o", str(tmp_path / "once")]) == 0
    assert "soft image edges" not in capsys.readouterr().err
    once = read_pfm(tmp_path / "once" / "disparity.pfm")
    auto = read_pfm(tmp_path / "d" / "disparity.pfm")
    lib = depth(load_lightfield(tmp_path / "cap"), n_labels=8,
                params=DepthParams(median_passes=1)).disparity
    assert not np.array_equal(once, auto)
    np.testing.assert_allclose(once, lib, atol=1e-6)


def test_depth_says_when_noisy_views_get_more_passes(tmp_path, capsys):
    """Soft, noisy views through the CLI: the log gives the noise and the passes, the result's
    config what the views were read as, and the passes add up."""
    from hyperlf import synthesis
    from hyperlf.cli import main
    from hyperlf.formats import load_lightfield, save_lightfield
    from hyperlf.hlf import depth

    lf = synthesis.procedural_scene(seed=3, rows=3, cols=3, height=128, width=128)
    v = lf.views.astype(np.float64)
    soft = np.stack([[gaussian_filter(v[r, c], 2.0) for c in range(3)] for r in range(3)])
    noisy = soft + 0.03 * soft.mean() * np.random.default_rng(0).standard_normal(soft.shape)
    save_lightfield(lf.replace(views=noisy.astype(lf.views.dtype)), tmp_path / "cap")
    assert main(["depth", str(tmp_path / "cap"), "--labels", "8", "-o",
                 str(tmp_path / "d")]) == 0
    import re

    err = capsys.readouterr().err
    said = re.search(r"noise \(([0-9.]+) % of the signal\) leaves blotches: the weighted "
                     r"median ran (\d+) times", err)
    assert said, err
    noise, passes = float(said[1]) / 100, int(said[2])
    config = depth(load_lightfield(tmp_path / "cap"), n_labels=8).config
    assert config["view_noise"] == pytest.approx(noise, abs=5e-4)
    assert 0.02 < config["view_noise"] < 0.03                 # 3 % added, read a little low
    assert config["median_noise_passes"] == int(config["view_noise"] / 0.01) >= 2
    assert config["median_passes"] == passes
    blur_passes = passes - config["median_noise_passes"]
    assert blur_passes == max(1, int(np.ceil((config["edge_blur_px"] - 0.8) / 0.4)))
    assert ("soft image edges" in err) == (blur_passes > 1)
