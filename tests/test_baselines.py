"""Tests of hyperlf.baselines (Tao 2013, Wang 2015, Lin 2015).

Test scene: the procedural ``planes`` scene (three fronto-parallel planes at -1.5, 0 and 1.5 px,
exact ray-cast ground truth and correct occlusions) at 48 x 64 on a 3 x 3 grid, with **every view
showing the same band** (``gt_cube[:, :, b]``), i.e. an ordinary grey light field. 32 labels.

Measured on this scene (RMSE in px, 4-px border excluded) when the bounds were set:
tao2013 0.594, wang2015 0.432, lin2015 0.532; with the offsets' sign flipped 1.86, 2.07, 2.48;
a constant map at the best single disparity scores 1.13. Single cues: Tao correspondence 0.456,
defocus 0.951; Wang initial 0.481; Lin data term 0.564. The bound 0.8 leaves ~35 % margin
above the worst method and lies clearly below what a broken cue, a wrong sign or a missing
stage gives; the flipped-sign bound 1.4 is far above the correct results.
"""

from __future__ import annotations

import numpy as np
import pytest

from hyperlf import baselines as B
from hyperlf import metrics, synthesis
from hyperlf.errors import InvalidInputError
from hyperlf.lightfield import LightField

N_LABELS = 32
BOUND = {"tao2013": 0.8, "wang2015": 0.8, "lin2015": 0.8}
FLIPPED_MIN = 1.4


@pytest.fixture(scope="module")
def grey_lf() -> LightField:
    lf = synthesis.procedural_scene(**{**synthesis.SCENES["planes"], "rows": 3, "cols": 3,
                                       "height": 48, "width": 64})
    band = lf.gt_cube.shape[2] // 2
    return LightField(views=lf.gt_cube[:, :, band], positions=lf.positions,
                      reference=lf.reference, disparity_range=lf.disparity_range,
                      gt_disparity=lf.gt_disparity)


@pytest.fixture(scope="module")
def results(grey_lf):
    return {name: f(grey_lf, n_labels=N_LABELS) for name, f in B.METHODS.items()}


def _rmse(d, lf):
    return metrics.rmse(d, lf.reference_gt_disparity, border=4)


def test_registry():
    assert set(B.METHODS) == {"tao2013", "wang2015", "lin2015"}
    assert B.METHODS["tao2013"] is B.tao2013
    assert set(B.DEFAULTS) == set(B.METHODS)


@pytest.mark.parametrize("name", ["tao2013", "wang2015", "lin2015"])
def test_accuracy_and_outputs(name, results, grey_lf):
    r = results[name]
    H, W = grey_lf.image_shape
    assert isinstance(r, B.BaselineResult)
    assert r.method == name
    assert r.disparity.shape == (H, W) and r.disparity.dtype == np.float32
    assert r.confidence.shape == (H, W) and r.confidence.dtype == np.float32
    assert np.all(np.isfinite(r.disparity))
    assert r.confidence.min() >= 0 and r.confidence.max() <= 1
    assert r.labels.shape == (N_LABELS,)
    assert r.labels[0] == grey_lf.disparity_range[0] and r.labels[-1] == grey_lf.disparity_range[1]
    assert r.disparity.min() >= r.labels[0] - 1e-5 and r.disparity.max() <= r.labels[-1] + 1e-5
    assert "total" in r.timings and r.timings["total"] > 0
    assert _rmse(r.disparity, grey_lf) < BOUND[name]


def test_intermediate_stages(results, grey_lf):
    """Each cue on its own carries depth (a broken cue would be near a random map, > 1.2)."""
    tao, wang, lin = results["tao2013"], results["wang2015"], results["lin2015"]
    assert _rmse(tao.maps["depth_correspondence"], grey_lf) < 0.9
    assert _rmse(tao.maps["depth_defocus"], grey_lf) < 1.2
    assert _rmse(wang.maps["initial"], grey_lf) < 0.9
    assert _rmse(lin.maps["depth_data"], grey_lf) < 0.9
    assert wang.maps["edges"].dtype == bool and wang.maps["edges"].any()
    assert wang.maps["occlusion"].shape == grey_lf.image_shape
    # a median filter on the MRF output is the last Wang stage
    assert wang.maps["mrf"].shape == grey_lf.image_shape


@pytest.mark.parametrize("name", ["tao2013", "wang2015", "lin2015"])
def test_sign_convention(name, results, grey_lf):
    """Flipping the offsets' sign (the wrong SPEC §1 convention) makes the result clearly worse."""
    flipped = grey_lf.replace(positions=-grey_lf.positions)
    r = B.METHODS[name](flipped, n_labels=N_LABELS)
    assert _rmse(r.disparity, grey_lf) > FLIPPED_MIN
    assert _rmse(r.disparity, grey_lf) > 2 * _rmse(results[name].disparity, grey_lf)


def test_uses_offsets_not_indices(grey_lf, results):
    """Doubling every baseline halves the disparity: same shifts, same answer / 2."""
    lo, hi = grey_lf.disparity_range
    wide = grey_lf.replace(positions=2.0 * grey_lf.positions, disparity_range=(lo / 2, hi / 2))
    r = B.tao2013(wide, n_labels=N_LABELS)
    np.testing.assert_allclose(2 * r.disparity, results["tao2013"].disparity, atol=2e-3)


def test_colour_views_use_luma(grey_lf, results):
    rgb = np.repeat(grey_lf.views[..., None], 3, axis=-1)
    lf3 = grey_lf.replace(views=rgb)
    assert np.allclose(B.prepare_views(lf3), grey_lf.views, atol=1e-6)
    r = B.lin2015(lf3, n_labels=N_LABELS)
    np.testing.assert_allclose(r.disparity, results["lin2015"].disparity, atol=1e-4)


def test_shift_matches_sample_bilinear():
    from hyperlf.warp import sample_bilinear

    rng = np.random.default_rng(0)
    img = rng.random((9, 13)).astype(np.float32)
    yy, xx = np.mgrid[0:9, 0:13].astype(float)
    for sx, sy in [(0.3, -1.7), (-2.25, 0.5), (0.0, 0.0), (20.0, -20.0)]:
        ref, _ = sample_bilinear(img, np.clip(xx + sx, 0, 12), np.clip(yy + sy, 0, 8))
        np.testing.assert_allclose(B._shift(img, sx, sy), ref, atol=1e-6)


def test_peak_ratio():
    c = np.array([3.0, 1.0, 2.0, 0.5, 4.0])[:, None, None]
    # lowest 0.5, second-lowest local minimum 1.0
    assert B._peak_ratio(c)[0, 0] == pytest.approx(2.0)
    # maximise: highest 4.0 (end label), second-highest local maximum 3.0 (other end)
    assert B._peak_ratio(c, maximise=True)[0, 0] == pytest.approx(4.0 / 3.0)


def test_progress_and_params(grey_lf):
    small = grey_lf.replace(views=grey_lf.views[:, :, :16, :16], gt_disparity=None)
    r = B.lin2015(small, n_labels=8, progress=True, window=3, smooth_weight=0.0)
    assert r.disparity.shape == (16, 16)
    assert r.params["window"] == 3
    r = B.wang2015(small, n_labels=8, disparity_range=(-1, 1), median=0)
    assert r.labels[0] == -1 and r.labels[-1] == 1
    r = B.tao2013(small, n_labels=8, defocus_operator="gradient_x", irls_iterations=0)
    assert r.disparity.shape == (16, 16)


@pytest.mark.parametrize("name", ["tao2013", "wang2015", "lin2015"])
def test_validation(name, grey_lf):
    f = B.METHODS[name]
    with pytest.raises(InvalidInputError):
        f(grey_lf.views)
    with pytest.raises(InvalidInputError):
        f(grey_lf, n_labels=2)
    with pytest.raises(InvalidInputError):
        f(grey_lf, n_labels=8.5)
    with pytest.raises(InvalidInputError):
        f(grey_lf.replace(disparity_range=None))
    with pytest.raises(InvalidInputError):
        f(grey_lf, disparity_range=(1.0, -1.0))
    with pytest.raises(InvalidInputError, match="^unknown key 'no_such_parameter' in params"):
        f(grey_lf, no_such_parameter=1)
    one = LightField(views=grey_lf.views[:1, :1], disparity_range=(-1, 1))
    with pytest.raises(InvalidInputError):
        f(one)


def test_bad_parameter_values(grey_lf):
    with pytest.raises(InvalidInputError):
        B.tao2013(grey_lf, window=4)
    with pytest.raises(InvalidInputError):
        B.tao2013(grey_lf, defocus_operator="sobel")
    with pytest.raises(InvalidInputError):
        B.wang2015(grey_lf, bilateral_sigma=0)
    with pytest.raises(InvalidInputError):
        B.lin2015(grey_lf, tau=-1)
