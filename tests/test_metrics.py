"""Evaluation metrics against hand-computed values."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf import InvalidInputError
from hyperlf import metrics as m


def test_disparity_metrics_known_values():
    gt = np.zeros((4, 4))
    est = np.zeros((4, 4))
    est[0, 0] = 3.0  # one pixel off by 3
    est[1, 1] = 0.05  # below BadPix threshold
    assert m.bad_pixels(est, gt, 2.0) == pytest.approx(100 / 16)
    assert m.rmse(est, gt) == pytest.approx(np.sqrt((9 + 0.0025) / 16))
    assert m.mse_x100(est, gt) == pytest.approx(100 * (9 + 0.0025) / 16)
    s = m.disparity_scores(est, gt)
    assert s.badpix_007 == pytest.approx(100 / 16) and s.n_pixels == 16 and s.mask == "all"


def test_unknown_truth_and_masks_and_border():
    gt = np.zeros((40, 40))
    gt[0, :] = np.nan
    est = np.ones((40, 40))
    est[20, 20] = 0.0
    assert m.evaluation_mask(gt).sum() == 40 * 39
    # HCI border excludes 15 px on every side: 10 x 10 interior, one pixel correct
    assert m.badpix(est, gt) == pytest.approx(99.0)
    mask = np.zeros((40, 40), bool)
    mask[20, 20] = True
    assert m.rmse(est, gt, mask=mask) == 0.0
    with pytest.raises(InvalidInputError, match="no pixel"):
        m.rmse(est, gt, mask=np.zeros((40, 40), bool))


def test_missing_estimate_counts_as_bad():
    gt = np.zeros((2, 2))
    est = np.array([[np.nan, 0.0], [0.0, 0.0]])
    assert m.bad_pixels(est, gt, 1.0) == 25.0
    assert m.rmse(est, gt) == np.inf


def test_shape_mismatch():
    with pytest.raises(InvalidInputError, match="shape") as exc:
        m.rmse(np.zeros((2, 2)), np.zeros((3, 3)))
    assert "reference_gt_disparity" not in str(exc.value)
    # a light field's per-view truth given for the reference's map: the message says which
    with pytest.raises(InvalidInputError, match="compare with its reference_gt_disparity"):
        m.rmse(np.zeros((2, 2)), np.zeros((3, 3, 2, 2)))


def test_psnr_and_sam():
    rng = np.random.default_rng(0)
    gt = rng.random((3, 5, 6))
    assert m.psnr(gt, gt) == np.inf
    assert m.psnr(gt + 0.1, gt) == pytest.approx(20.0)
    per_band = m.psnr_per_band(gt + 0.1, gt)
    assert per_band.shape == (3,) and np.allclose(per_band, 20.0)
    # scaling a spectrum does not change its angle; orthogonal spectra are 90 degrees apart
    assert m.sam(2.5 * gt, gt) == pytest.approx(0.0, abs=1e-5)
    a = np.zeros((2, 1, 1)); a[0] = 1
    b = np.zeros((2, 1, 1)); b[1] = 1
    assert m.sam(a, b) == pytest.approx(90.0)
    assert m.completion_ratio(np.array([True, False, True, True])) == 75.0


def test_hci_scores_skip_maps_inside_the_border():
    from hyperlf import metrics

    gt = np.zeros((40, 50))
    est = gt + 0.1
    sc = metrics.hci_scores(est, gt)
    assert sc.border == metrics.HCI_BORDER and sc.n_pixels == 10 * 20
    assert abs(sc.rmse - 0.1) < 1e-12
    assert metrics.hci_scores(est[:30], gt[:30]) is None


def test_cube_scores_stream_the_whole_cube_values(tmp_path):
    from hyperlf import synthesis
    from hyperlf.formats import open_gt_cube, save_lightfield

    rng = np.random.default_rng(7)
    gt = rng.random((2, 3, 6, 5, 4))
    est = np.clip(gt + 0.05 * rng.standard_normal(gt.shape), 0, None)
    psnr, sam = m.cube_scores(est, gt)
    assert psnr == pytest.approx(m.psnr(est, gt), rel=1e-12)
    assert sam == pytest.approx(m.sam(est, gt, band_axis=2), rel=1e-12)
    assert m.cube_scores(gt, gt)[0] == float("inf")
    with pytest.raises(InvalidInputError, match="one shape"):
        m.cube_scores(est[:, :2], gt)
    # lazily from disk: a capture folder and an HDF5 light field, each read view by view
    lf = synthesis.procedural_scene(seed=2, rows=2, cols=2, height=10, width=12)
    cap = save_lightfield(lf, tmp_path / "cap").parent
    h5 = save_lightfield(lf, tmp_path / "lf.h5")
    for path in (cap, h5):
        with open_gt_cube(path) as cube:
            assert cube.shape == lf.gt_cube.shape
            np.testing.assert_array_equal(cube[1, 0], lf.gt_cube[1, 0])
            assert m.cube_scores(lf.gt_cube * 0.5, cube)[0] == pytest.approx(
                m.psnr(lf.gt_cube * 0.5, lf.gt_cube), rel=1e-9)
    plain = save_lightfield(lf.replace(gt_cube=None, cube_wavelengths=None), tmp_path / "p")
    with open_gt_cube(plain.parent) as cube:
        assert cube is None
    with open_gt_cube(tmp_path / "nothing-here") as cube:
        assert cube is None
    (tmp_path / "junk.h5").write_bytes(b"not hdf5")
    from hyperlf.errors import FormatError
    with pytest.raises(FormatError, match="not a readable HDF5 file"):
        with open_gt_cube(tmp_path / "junk.h5"):
            pass


def test_bad_pixel_breakdown_finds_a_fattened_foreground_where_it_is():
    """A foreground square carried 3 px over its background on its left side: the breakdown
    puts exactly those pixels in the class beside the square, all of them too large."""
    gt = np.full((20, 30), 2.0)
    gt[5:15, 12:22] = 12.0
    est = gt.copy()
    est[5:15, 9:12] = 12.0                 # 30 px fattened
    est[0, 0] = np.nan                     # one missing estimate
    strip = np.zeros(gt.shape, bool)
    strip[:, 6:12] = True
    b = m.bad_pixel_breakdown(est, gt, 5.0, {"strip": strip, "rest": ~strip})
    n = gt.size
    assert b["strip"].share == pytest.approx(100 * 120 / n)
    assert b["strip"].too_large == pytest.approx(100 * 30 / n)
    assert b["strip"].too_small == 0.0 and b["strip"].missing == 0.0
    assert b["rest"].missing == pytest.approx(100 / n) and b["rest"].too_large == 0.0
    assert b["strip"].bad + b["rest"].bad == pytest.approx(m.bad_pixels(est, gt, 5.0))
    # the mask counts: evaluated on the strip alone, the fattened pixels are a quarter
    only = m.bad_pixel_breakdown(est, gt, 5.0, {"strip": strip}, mask=strip)
    assert only["strip"].share == 100.0 and only["strip"].too_large == pytest.approx(25.0)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**16), tau=st.floats(0.0, 3.0), holes=st.floats(0.0, 0.3))
def test_bad_pixel_breakdown_of_a_partition_adds_up_to_bad_pixels(seed, tau, holes):
    rng = np.random.default_rng(seed)
    gt = rng.normal(0, 2, (9, 11))
    gt[rng.random(gt.shape) < 0.1] = np.nan               # unknown truth is never counted
    est = gt + rng.normal(0, 3, gt.shape)
    est[rng.random(gt.shape) < holes] = np.nan
    mask = rng.random(gt.shape) < 0.9
    if not (mask & np.isfinite(gt)).any():
        mask[:] = True
        gt[0, 0] = 0.0
    label = rng.integers(0, 3, gt.shape)
    b = m.bad_pixel_breakdown(est, gt, tau, {str(k): label == k for k in range(3)}, mask=mask)
    assert list(b) == ["0", "1", "2"]
    assert sum(v.share for v in b.values()) == pytest.approx(100.0)
    assert sum(v.bad for v in b.values()) == pytest.approx(m.bad_pixels(est, gt, tau, mask=mask))
    for v in b.values():
        assert v.bad == pytest.approx(v.too_large + v.too_small + v.missing)
        assert 0.0 <= v.bad <= v.share + 1e-9


@pytest.mark.parametrize("classes, match", [
    ([np.ones((2, 2), bool)], "classes must be a dict"),
    ({"a": np.ones((3, 2), bool)}, "class 'a' has shape"),
    ({1: np.ones((2, 2), bool)}, "class's name must be text"),
    ({"a": "x"}, "class 'a'"),
])
def test_bad_pixel_breakdown_refuses_bad_classes_in_one_line(classes, match):
    with pytest.raises(InvalidInputError, match=match):
        m.bad_pixel_breakdown(np.zeros((2, 2)), np.zeros((2, 2)), 1.0, classes)
