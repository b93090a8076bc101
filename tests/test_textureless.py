"""Textureless regions (issue 11 item 3): the noise estimate, the texture-to-noise ratio, and
the data-term weight that lets a region no cost can match follow its surroundings."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.ndimage import gaussian_filter

from hyperlf.errors import InvalidInputError
from hyperlf.hlf import DepthParams, depth, prepare, texture_weight
from hyperlf.imageops import noise_sigma, texture_snr
from hyperlf.lightfield import LightField


def _fractal(rng, shape):
    """Texture with about the 1/f amplitude spectrum of natural images, unit std."""
    out = np.zeros(shape)
    for scale in (0.7, 1.5, 3, 6, 12):
        g = gaussian_filter(rng.standard_normal(shape), scale)
        out += scale * g / g.std()
    return out / out.std()


# ----------------------------------------------------------------------------- noise
@pytest.mark.parametrize("sigma", [0.002, 0.01, 0.05])
def test_noise_sigma_recovers_white_noise_on_shading_and_edges(sigma):
    rng = np.random.default_rng(1)
    yy, xx = np.mgrid[0:200, 0:240]
    clean = 0.3 + 0.002 * xx + 0.1 * ((xx - 120) ** 2 + (yy - 100) ** 2) / 3e4
    clean[60:140, 80:160] += 0.4  # a bright square: edges are a minority of pixels
    img = clean + sigma * rng.standard_normal(clean.shape)
    assert noise_sigma(img) == pytest.approx(sigma, rel=0.06)


@pytest.mark.parametrize("seed", range(3))
def test_noise_sigma_tells_texture_from_noise(seed):
    """Pixel-scale texture (natural or rendered, about scale invariant) does not halve when the
    image is binned 2 x 2, white noise does: texture alone is not taken for noise."""
    rng = np.random.default_rng(seed)
    texture = 0.5 + 0.1 * _fractal(rng, (160, 200))
    assert noise_sigma(texture) < 0.001
    assert noise_sigma(texture + 0.01 * rng.standard_normal(texture.shape)) == \
        pytest.approx(0.01, rel=0.1)
    half = texture.copy()
    half[80:] = 0.5
    assert noise_sigma(half + 0.01 * rng.standard_normal(half.shape)) == \
        pytest.approx(0.01, rel=0.1)


def test_noise_sigma_of_clean_images_and_masks():
    yy, xx = np.mgrid[0:50, 0:60]
    assert noise_sigma(0.5 + 0.01 * xx + 0.02 * yy) == pytest.approx(0.0, abs=1e-12)
    assert noise_sigma(np.ones((2, 9))) == 0.0
    rng = np.random.default_rng(2)
    img = 0.5 + 0.01 * rng.standard_normal((100, 100))
    img[:, 50:] += 0.2 * rng.standard_normal((100, 50))  # heavy noise, masked out
    valid = np.zeros(img.shape, bool)
    valid[:, :48] = True
    assert noise_sigma(img, valid=valid) == pytest.approx(0.01, rel=0.08)
    assert noise_sigma(img, valid=np.zeros(img.shape, bool)) == 0.0


@pytest.mark.parametrize("amplitude", [1.0, 4.0, 10.0])
def test_texture_snr_measures_texture_in_noise_units(amplitude):
    rng = np.random.default_rng(3)
    sigma = 0.01
    noise = sigma * rng.standard_normal((120, 240))
    texture = amplitude * sigma * rng.standard_normal((120, 240))
    img = 0.5 + noise
    img[:, 120:] += texture[:, 120:]
    t = texture_snr(img, 5, sigma=sigma)
    assert np.median(t[:, :115]) < 0.5  # noise alone
    # E[var_5x5] = (1 - 1/25)(a^2 + 1) sigma^2 for white texture of std a sigma
    expected = np.sqrt(0.96 * (amplitude ** 2 + 1) - 1)
    assert np.median(t[:, 125:]) == pytest.approx(expected, rel=0.15)


def test_texture_snr_of_a_noise_free_image_is_infinite():
    assert np.isinf(texture_snr(np.full((10, 10), 0.5), 3)).all()


@given(window=st.one_of(st.integers(-3, 2), st.integers(2, 20).map(lambda k: 2 * k),
                        st.floats(3.1, 9.9).filter(lambda w: w != int(w)), st.booleans()))
@settings(max_examples=30, deadline=None, derandomize=True)
def test_texture_snr_refuses_bad_windows(window):
    with pytest.raises(InvalidInputError, match="odd integer >= 3"):
        texture_snr(np.zeros((8, 8)), window)


@pytest.mark.parametrize("bad", [{"texture_snr": -1}, {"texture_snr": float("nan")},
                                 {"texture_snr": 1}, {"texture_snr": 0.5},
                                 {"texture_window": 4}, {"texture_window": 1},
                                 {"texture_window": True}, {"texture_window": 5.5}])
def test_depth_params_check_the_texture_options(bad):
    with pytest.raises(InvalidInputError, match="texture_"):
        DepthParams(**bad)


# ----------------------------------------------------------------------------- matching
H, W, D0, BORDER = 96, 128, 1.0, 12


def _table_scene(seed, grid=(3, 3), vignetting=True, zoom=1):
    """A fronto-parallel plane at disparity ``D0``: textured above, a uniform (white-table-like)
    band over the bottom half; per-view gain (the filters), vignetting centred on each
    camera, white noise, and the outer views' borders invalid (what registration leaves).
    ``zoom`` scales the image (not the texture or the disparity)."""
    rng = np.random.default_rng(seed)
    R, C = grid
    h, w = H * zoom, W * zoom
    rr, cc = R // 2, C // 2
    pad = 8
    canvas = 0.5 + 0.15 * _fractal(rng, (h + 2 * pad, w + 2 * pad))
    canvas[pad + h // 2:, :] = 0.5
    yy, xx = np.mgrid[0:h, 0:w]
    shading = 1 - 1.4 * (((yy - h / 2) / h) ** 2 + ((xx - w / 2) / w) ** 2) if vignetting else 1
    views = np.empty((R, C, h, w))
    for r in range(R):
        for c in range(C):
            y0, x0 = pad + int(D0 * (r - rr)), pad + int(D0 * (c - cc))
            views[r, c] = rng.uniform(0.7, 1.3) * shading * canvas[y0:y0 + h, x0:x0 + w]
    views += 0.005 * rng.standard_normal(views.shape)
    valid = np.ones(views.shape, bool)
    valid[:, :cc, :, :BORDER] = valid[:, cc + 1:, :, -BORDER:] = False
    valid[:rr, :, :BORDER, :] = valid[rr + 1:, :, -BORDER:, :] = False
    return LightField(np.where(valid, views, 0).astype(np.float32),
                      np.linspace(420, 680, R * C).reshape(R, C), disparity_range=(-6.0, 6.0),
                      valid=valid, reference=(rr, cc))


@pytest.mark.parametrize("seed", range(3))
def test_a_textureless_region_follows_its_surroundings(seed):
    lf = _table_scene(seed)
    on = depth(lf, n_labels=25, params=DepthParams(texture_snr=2, coarse_prior=False))
    off = depth(lf, n_labels=25, params=DepthParams(texture_snr=0))
    inner = np.s_[H // 2 + 8:, :]
    err_on = np.abs(on.disparity[inner] - D0)
    assert np.percentile(err_on, 95) < 0.1
    # with the coarse prior (default): the half-resolution run sees the cameras' strong
    # vignetting as texture in a few rows by the bottom border (outer views invalid there)
    prior = depth(lf, n_labels=25, params=DepthParams(texture_snr=2))
    err_prior = np.abs(prior.disparity[inner] - D0)
    assert np.percentile(err_prior, 95) < 0.25 and err_prior.max() <= 0.55
    # no level saw texture there: filled in from the surroundings, so (nearly) no confidence
    # (the noise leaves some pixels a small texture weight w, and those get w times the
    # confidence floor; measured 74-83 % zeros and a mean of 0.012-0.018 over three seeds)
    assert np.mean(prior.confidence[inner] == 0) > 0.7 and prior.confidence[inner].mean() < 0.02
    assert np.median(np.abs(off.disparity[inner] - D0)) >= 0.4  # the scene needs the weight
    textured = np.s_[BORDER:H // 2 - 8, BORDER:-BORDER]
    err_tex = [np.percentile(np.abs(r.disparity[textured] - D0), 95) for r in (on, off)]
    assert err_tex[0] < 0.1 and err_tex[0] <= err_tex[1] + 0.02  # the texture is not lost
    assert on.confidence[inner].mean() < 0.5 * on.confidence[textured].mean()


@pytest.mark.parametrize("seed", range(2))
def test_a_noise_band_by_the_border_keeps_no_pull_to_a_range_limit(seed):
    """A 5 x 6 array, the band below pure noise, no shading, the texture weight off: the views
    below the reference leave the bottom rows at some labels only.  The fusion's parts are not
    centred per view (``FusedCost.view_centre``): subtracting each view's minimum over the
    labels it sees put the whole band at a range limit (error 5 px on both seeds)."""
    lf = _table_scene(seed, grid=(5, 6), vignetting=False)
    res = depth(lf, n_labels=25, params=DepthParams(texture_snr=0))
    err = np.abs(res.disparity[H // 2 + 8:] - D0)
    assert np.percentile(err, 95) < 0.1
    assert np.percentile(np.abs(res.disparity[BORDER:H // 2 - 8, BORDER:-BORDER] - D0), 95) < 0.1


def test_texture_weight_is_on_by_default_for_camera_captures_only():
    lf = _table_scene(0)
    camera = lf.replace(metadata={"calibration": {"mode": "plane"}})
    assert texture_weight(prepare(lf, n_labels=8)) is None  # synthetic: off
    w = texture_weight(prepare(camera, n_labels=8))
    on = depth(camera, n_labels=25, params=DepthParams(coarse_prior=False))
    assert np.percentile(np.abs(on.disparity[H // 2 + 8:] - D0), 95) < 0.1
    assert np.array_equal(w, texture_weight(prepare(lf, n_labels=8,
                                                    params=DepthParams(texture_snr=2))))
    assert w.dtype == np.float32 and w.shape == (H, W)
    assert np.percentile(w[H // 2 + 8:], 90) < 0.05
    assert np.percentile(w[BORDER:H // 2 - 8, BORDER:-BORDER], 90) == 1.0
    for kw in (dict(params=DepthParams(texture_snr=0)), dict(optimizer="wta")):
        assert texture_weight(prepare(camera, n_labels=8, **kw)) is None
    clean = camera.replace(views=np.full(lf.views.shape, 0.5, np.float32)
                           + np.linspace(0, 0.1, W, dtype=np.float32))
    assert texture_weight(prepare(clean, n_labels=8)) is None  # no noise: every weight 1


def test_depth_command_takes_the_texture_option(tmp_path, capsys):
    from hyperlf.cli import main
    from hyperlf.formats import read_pfm, save_lightfield

    lf = _table_scene(1).replace(metadata={"calibration": {"mode": "plane"}})
    cap = tmp_path / "cap"
    save_lightfield(lf, cap)
    maps = {}
    for value in ("0", "2", None):  # None: the default
        out = tmp_path / f"d{value}"
        extra = ["--save-intermediate"] + ([] if value is None else ["--texture-snr", value])
        assert main(["-q", "depth", str(cap), "--labels", "25", *extra, "-o", str(out)]) == 0
        maps[value] = read_pfm(out / "disparity.pfm")
    assert np.array_equal(maps["2"], maps[None])  # ingest-like capture: on by default
    weight = read_pfm(tmp_path / "dNone" / "texture_weight.pfm")
    assert (tmp_path / "dNone" / "texture_weight.png").is_file()
    assert np.percentile(weight[H // 2 + 8:], 90) < 0.05 < np.median(weight[:H // 2 - 8])
    assert not (tmp_path / "d0" / "texture_weight.pfm").exists()
    flat = np.abs(maps["2"][H // 2 + 8:] - D0)
    assert np.percentile(flat, 95) < 0.1 < np.median(np.abs(maps["0"][H // 2 + 8:] - D0))
    capsys.readouterr()
    for bad in ("1", "0.5", "-2", "inf"):
        with pytest.raises(SystemExit) as info:  # refused while parsing, exit 2
            main(["-q", "depth", str(cap), "--texture-snr", bad, "-o", str(tmp_path / "bad")])
        assert info.value.code == 2 and "--texture-snr" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


# ----------------------------------------------------------------------------- coarse prior
def _slanted_table_scene(seed, amplitude=0.01, zoom=1):
    """A textured wall at disparity 1 above a table that comes closer row by row (disparity 1
    to 4) and whose texture is faint blobs a few pixels wide, below the noise in any 5 x 5
    window: a camera-made capture (texture weight on), exact disparity per pixel.  ``zoom``
    scales the image and the blobs (not the disparities)."""
    from scipy.ndimage import map_coordinates

    rng = np.random.default_rng(seed)
    h, w, pad = H * zoom, W * zoom, 16
    canvas = 0.5 + 0.15 * _fractal(rng, (h + 2 * pad, w + 2 * pad))
    blobs = gaussian_filter(rng.standard_normal(canvas.shape), 3.0 * zoom)
    canvas[pad + h // 2:] = 0.5 + amplitude * (blobs / blobs.std())[pad + h // 2:]
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    truth = np.where(yy < h // 2, 1.0, 1.0 + 3.0 * (yy - h // 2) / (h // 2))
    views = np.empty((3, 3, h, w))
    for r in range(3):
        for c in range(3):
            views[r, c] = rng.uniform(0.8, 1.2) * map_coordinates(
                canvas, [yy + pad + truth * (r - 1), xx + pad + truth * (c - 1)], order=3,
                mode="nearest")
    views += 0.005 * rng.standard_normal(views.shape)
    lf = LightField(views.astype(np.float32), np.linspace(420, 680, 9).reshape(3, 3),
                    disparity_range=(-2.0, 6.0), metadata={"calibration": {"mode": "plane"}})
    return lf, truth


@pytest.mark.parametrize("seed", range(3))
def test_a_faint_slanted_table_follows_the_coarse_estimate(seed):
    lf, truth = _slanted_table_scene(seed)
    table, wall = np.s_[H // 2 + 6:H - 4, 6:-6], np.s_[6:H // 2 - 6, 6:-6]
    w = texture_weight(prepare(lf, n_labels=33))
    assert np.percentile(w[table], 90) < 0.1  # no data term on the table at full resolution
    res = {cp: depth(lf, n_labels=33, params=DepthParams(coarse_prior=cp))
           for cp in (False, True)}
    rmse = {cp: {k: float(np.sqrt(np.mean((r.disparity - truth)[s] ** 2)))
                 for k, s in (("table", table), ("wall", wall))} for cp, r in res.items()}
    assert rmse[False]["table"] > 1.0  # filled with one constant from the wall
    assert rmse[True]["table"] < 0.5  # the table's own slope, from the half-resolution run
    assert rmse[True]["wall"] <= rmse[False]["wall"] + 0.01
    # the confidence: (nearly) none where the wall's depth was carried over the table (a
    # pixel that the noise leaves a small texture weight w gets w times the confidence floor:
    # measured 94-99 % below 0.01), the coarse run's where the table's came from it
    conf = {cp: r.confidence for cp, r in res.items()}
    assert np.mean(conf[False][table] < 0.01) > 0.9
    assert 0.03 < np.median(conf[True][table]) < 0.25
    # the prior's pull is not counted as the pixel's own evidence: the wall's weakly textured
    # pixels are not made several times as sure as its textured ones (3.1-3.8 x when the
    # margin was read with the pull in it; 1.4-1.6 x now, the coarse run's share)
    on_wall = np.zeros(w.shape, bool)
    on_wall[wall] = True
    weak, full = on_wall & (w < 1), on_wall & (w >= 1)
    assert conf[True][weak].mean() < 2 * conf[True][full].mean()
    assert res[True].config["coarse_prior_scale"] == 2
    assert res[False].config["coarse_prior_scale"] is None
    assert "coarse_prior_s" in res[True].timings


@pytest.mark.parametrize("seed", range(4))
def test_refine_reads_the_confidence_without_the_coarse_prior(seed):
    """Graph cuts optimise the unary with the prior in it: the disparity is refined on that
    volume, the confidence is the margin of the data alone (the caller's volume untouched)."""
    from hyperlf.hlf import add_coarse_prior, prior_free_confidence, refine
    from hyperlf.regularisers import confidence

    rng = np.random.default_rng(seed)
    L, h, w = 9, 12, 14
    labels = np.linspace(-2.0, 2.0, L)
    data = rng.random((L, h, w)).astype(np.float32)
    prior = (rng.uniform(-2, 2, (h, w)).astype(np.float32),
             rng.uniform(0, 2, (h, w)).astype(np.float32), 0.5)
    U = add_coarse_prior(data.copy(), labels, *prior)
    kept = U.copy()
    lab = np.argmin(U, axis=0)
    params = DepthParams(median_radius=0)
    d_prior, c_prior = refine(U, lab, labels, params, prior=prior)
    d_plain, c_plain = refine(U, lab, labels, params)
    assert np.array_equal(U, kept)
    assert np.array_equal(d_prior, d_plain)  # the estimate itself is unchanged
    np.testing.assert_allclose(c_prior, confidence(data, lab, floor=params.confidence_floor),
                               atol=1e-5)
    assert np.array_equal(prior_free_confidence(U, lab, labels, prior, rows=5),
                          prior_free_confidence(U, lab, labels, prior))  # strips: same
    assert not np.allclose(c_plain, c_prior)  # with the pull read in, the margin differs


def test_coarse_prior_needs_the_texture_weight():
    lf, _ = _slanted_table_scene(0)
    synthetic = lf.replace(metadata={})  # texture weight off: nothing to give back
    a, b = (depth(synthetic, n_labels=17, params=DepthParams(coarse_prior=cp)) for cp in
            (True, False))
    assert np.array_equal(a.disparity, b.disparity) and a.config["coarse_prior_scale"] is None


@pytest.mark.parametrize("bad", [{"coarse_prior": "yes"}, {"coarse_prior": 1},
                                 {"coarse_prior_scale": 1}, {"coarse_prior_scale": 2.5},
                                 {"coarse_prior_width": 0}, {"coarse_prior_width": float("inf")},
                                 {"coarse_prior_levels": 0}])
def test_depth_params_check_the_coarse_prior_options(bad):
    with pytest.raises(InvalidInputError, match="coarse_prior"):
        DepthParams(**bad)


def test_depth_command_turns_the_coarse_prior_off(tmp_path, capsys):
    from hyperlf.cli import main
    from hyperlf.formats import read_pfm, save_lightfield

    lf, truth = _slanted_table_scene(1)
    save_lightfield(lf, tmp_path / "cap")
    table = np.s_[H // 2 + 6:H - 4, 6:-6]
    rmse = {}
    for extra in ((), ("--no-coarse-prior",)):
        out = tmp_path / f"d{len(extra)}"
        assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "33", *extra,
                     "-o", str(out)]) == 0
        d = read_pfm(out / "disparity.pfm")
        rmse[extra] = float(np.sqrt(np.mean((d - truth)[table] ** 2)))
    assert rmse[()] < 0.5 < 1.0 < rmse[("--no-coarse-prior",)]
    capsys.readouterr()
    assert main(["depth", str(tmp_path / "cap"), "--labels", "33", "--save-intermediate",
                 "-o", str(tmp_path / "inter")]) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("weakly textured")]
    assert len(said) == 1 and "% taken from the half-resolution estimate" in said[0]
    strength = read_pfm(tmp_path / "inter" / "coarse_prior_strength.pfm")
    assert np.median(strength[table]) > 0.5 and np.median(strength[:H // 2 - 8]) < 0.1
    assert (tmp_path / "inter" / "coarse_disparity.png").is_file()


def test_nested_coarse_levels_keep_eight_windows():
    lf, _ = _slanted_table_scene(2)
    one = depth(lf, n_labels=33)
    assert one.config["coarse_prior_levels"] == 1
    # a 96 x 128 image has room for one level (48 px >= 8 windows of 5; 24 px has not)
    two = depth(lf, n_labels=33, params=DepthParams(coarse_prior_levels=2))
    assert two.config["coarse_prior_levels"] == 1
    assert np.array_equal(one.disparity, two.disparity)
    big, truth2 = _slanted_table_scene(2, zoom=2)  # twice the size, blobs too: two levels fit
    table = np.s_[H + 12:2 * H - 8, 12:-12]
    rmse = {}
    for levels in (1, 2):
        res = depth(big, n_labels=33, params=DepthParams(coarse_prior_levels=levels))
        assert res.config["coarse_prior_levels"] == levels
        rmse[levels] = np.sqrt(np.mean((res.disparity - truth2)[table] ** 2))
    assert rmse[2] < 0.5 < 1.0 < rmse[1]  # blobs 6 px wide: textured only at 1/4


def test_depth_command_nests_the_coarse_prior(tmp_path, capsys):
    from hyperlf.cli import main
    from hyperlf.formats import read_pfm, save_lightfield

    big, truth = _slanted_table_scene(2, zoom=2)  # blobs textured only at 1/4 resolution
    save_lightfield(big, tmp_path / "cap", bit_depth=32)
    table = np.s_[H + 12:2 * H - 8, 12:-12]
    out = tmp_path / "d2"
    assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "33",
                 "--coarse-prior-levels", "2", "-o", str(out)]) == 0
    # one level (the default) leaves this table more than 1 px off (the test above)
    assert np.sqrt(np.mean((read_pfm(out / "disparity.pfm") - truth)[table] ** 2)) < 0.5
    capsys.readouterr()
    for bad in (["0"], ["9"], ["2.5"], ["two"], ["2", "--no-coarse-prior"]):
        with pytest.raises(SystemExit) as info:  # refused while parsing, exit 2
            main(["-q", "depth", str(tmp_path / "cap"), "--coarse-prior-levels", *bad,
                  "-o", str(tmp_path / "bad")])
        assert info.value.code == 2 and "--coarse-prior-levels" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_nested_coarse_levels_keep_the_label_step(monkeypatch):
    """Every nested run has the first coarse run's label count, i.e. the same step in full-
    resolution px; a uniform table then follows its wall two levels down.  Before, the
    quarter-resolution run had 7 labels, none of them the table's disparity, and its
    estimate's weak pull over the whole table outweighed the edge to the wall (the whole
    table 1 px off)."""
    from hyperlf import hlf

    lf = _table_scene(0, vignetting=False, zoom=2)  # 192 x 256: room for two levels
    lf = lf.replace(metadata={"calibration": {"mode": "plane"}})
    calls, real = [], hlf.depth

    def spy(lf_s, *a, **kw):
        calls.append((lf_s.image_shape, kw.get("n_labels")))
        return real(lf_s, *a, **kw)

    monkeypatch.setattr(hlf, "depth", spy)
    res = spy(lf, n_labels=25, params=DepthParams(coarse_prior_levels=2))
    assert res.config["coarse_prior_levels"] == 2
    assert calls == [((192, 256), 25), ((96, 128), 13), ((48, 64), 13)]
    table = np.s_[2 * (H // 2 + 8):, :]
    assert np.percentile(np.abs(res.disparity[table] - D0), 95) < 0.1


@pytest.mark.parametrize("bad", [1, 2.5, True, "13"])
def test_depth_params_check_the_coarse_labels(bad):
    with pytest.raises(InvalidInputError, match="coarse_prior_labels"):
        DepthParams(coarse_prior_labels=bad)
    assert DepthParams(coarse_prior_labels=13.0).coarse_prior_labels == 13  # kept as an int


def test_a_dense_camera_array_reuses_the_visibility_estimate(monkeypatch):
    from hyperlf import hlf, synthesis

    lf = synthesis.procedural_scene(seed=3, rows=4, cols=4, height=96, width=112,
                                    noise_sigma=0.01, reflectance_source="colorchecker")
    lf = lf.replace(metadata={"calibration": {"mode": "plane"}})
    calls = []
    real = hlf.coarse_disparity
    monkeypatch.setattr(hlf, "coarse_disparity",
                        lambda prob, **kw: calls.append(kw.get("scale")) or real(prob, **kw))
    params = DepthParams(visibility_min_size=32, visibility_rounds=1)
    res = depth(lf, n_labels=17, params=params)
    assert res.config["visibility_estimate_scale"] == res.config["coarse_prior_scale"] == 2
    assert calls == [None]  # one coarse run (the visibility round's) serves both
    noprior = depth(lf, n_labels=17, params=replace(params, coarse_prior=False))
    assert noprior.config["coarse_prior_scale"] is None


def test_batch_passes_the_coarse_prior_options_to_each_depth_run(tmp_path, batch_depth_args):
    from hyperlf.cli import main

    seen = [batch_depth_args(*extra)
            for extra in ((), ("--no-coarse-prior",), ("--coarse-prior-levels", "3"))]
    with pytest.raises(SystemExit) as info:  # contradictory: refused while parsing
        main(["-q", "batch", str(tmp_path), "--no-coarse-prior", "--coarse-prior-levels", "2",
              "-o", str(tmp_path / "o")])
    assert info.value.code == 2 and len(batch_depth_args.calls) == 3
    assert "--no-coarse-prior" not in seen[0] and seen[1][-1] == "--no-coarse-prior"
    assert "--coarse-prior-levels" not in seen[0]
    assert seen[2][seen[2].index("--coarse-prior-levels") + 1] == "3"
