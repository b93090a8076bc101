"""Tests of hyperlf.warp, including the SPEC §1 sign convention checked on real HCI data."""

from __future__ import annotations

import numpy as np
import pytest

from hyperlf.errors import InvalidInputError
from hyperlf.warp import (axis_taps, axis_valid, bilinear_taps, coordinate_taps,
                          forward_warp_disparity, gather_taps, sample_bilinear, shift_image,
                          shift_map, warp_to_reference)

from conftest import require_dataset


# ----------------------------------------------------------------------------- unit tests
def test_sample_bilinear_exact_on_linear_ramp_and_masks_outside():
    H, W = 6, 8
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    img = 2.0 * xx + 3.0 * yy + 1.0
    x = np.array([0.0, 2.25, 6.5, 7.0, -0.5, 7.5, 3.0])
    y = np.array([0.0, 1.75, 4.5, 5.0, 2.0, 2.0, 5.5])
    vals, valid = sample_bilinear(img, x, y)
    assert valid.tolist() == [True, True, True, True, False, False, False]
    np.testing.assert_allclose(vals[valid], 2 * x[valid] + 3 * y[valid] + 1, atol=1e-5)
    assert np.all(np.isnan(vals[~valid]))  # invalid samples carry the fill, never zero
    vals0, _ = sample_bilinear(img, x, y, fill=-7.0)
    assert np.all(vals0[~valid] == -7.0)


def test_sample_bilinear_channels():
    img = np.random.default_rng(0).random((5, 7, 3))
    vals, valid = sample_bilinear(img, np.array([1.0, 2.5]), np.array([3.0, 0.5]))
    assert vals.shape == (2, 3) and valid.all()
    np.testing.assert_allclose(vals[0], img[3, 1], atol=1e-6)
    expect = (img[0, 2] + img[0, 3] + img[1, 2] + img[1, 3]) / 4
    np.testing.assert_allclose(vals[1], expect, atol=1e-6)


def test_shift_image_integer_and_subpixel():
    rng = np.random.default_rng(1)
    img = rng.random((10, 12))
    out, valid = shift_image(img, 2, -1)  # out(x, y) = img(x + 2, y - 1)
    np.testing.assert_allclose(out[1:, :-2], img[:-1, 2:], atol=1e-6)
    assert not valid[0].any() and not valid[:, -2:].any()
    assert valid[1:, :-2].all()
    assert np.isnan(out[~valid]).all()
    half, hv = shift_image(img, 0.5, 0.0)
    np.testing.assert_allclose(half[:, :-1], (img[:, :-1] + img[:, 1:]) / 2, atol=1e-6)
    assert hv[:, :-1].all() and not hv[:, -1].any()


def test_warp_to_reference_sign_convention_synthetic():
    # reference texture T; a view at offset (dx, dy) sees T(x + d dx, y + d dy) at (x, y)
    # when the scene is a fronto plane of disparity d (SPEC §1).
    H, W, d = 20, 24, 1.5
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)

    def tex(x, y):
        return np.sin(0.3 * x) + np.cos(0.25 * y) + 0.1 * x

    ref = tex(xx, yy)
    for dx, dy in [(1, 0), (0, 2), (-1, 1)]:
        view = tex(xx + d * dx, yy + d * dy)
        warped, valid = warp_to_reference(view, d, (dx, dy))
        err = np.abs(warped - ref)[valid]
        assert valid.mean() > 0.6
        assert err.max() < 0.03
        wrong, wv = warp_to_reference(view, -d, (dx, dy))
        assert np.abs(wrong - ref)[wv].mean() > 5 * err.mean() + 0.05
    # NaN disparity marks pixels invalid
    dmap = np.full((H, W), d)
    dmap[3, 4] = np.nan
    _, v = warp_to_reference(ref, dmap, (1, 0))
    assert not v[3, 4]


def test_forward_warp_disparity_zbuffer_larger_wins():
    H, W = 5, 12
    d = np.zeros((H, W))
    d[:, 6] = 3.0              # a near column; background at 0
    out = forward_warp_disparity(d, (1, 0))
    # near column lands at x = 6 - 3 = 3 and must hide the background pixel landing there
    assert np.all(out[:, 3] == 3.0)
    # the column's old place is disoccluded: nothing lands at x = 6
    assert np.all(np.isnan(out[:, 6]))
    assert out.dtype == np.float32
    # opposite direction: lands at x = 9
    out2 = forward_warp_disparity(d, (-1, 0))
    assert np.all(out2[:, 9] == 3.0) and np.all(np.isnan(out2[:, 6]))
    # vertical offset and out-of-image targets
    dv = np.zeros((8, 4))
    dv[1, :] = 2.0
    outv = forward_warp_disparity(dv, (0, 1))      # row 1 -> row -1: leaves the image
    assert np.all(np.isnan(outv[1])) and not np.any(outv == 2.0)
    # z-buffer when two values compete for one pixel: the larger one wins
    dz = np.zeros((1, 6))
    dz[0, 2], dz[0, 4] = 1.0, 3.0                  # 2 - 1 = 1 and 4 - 3 = 1
    outz = forward_warp_disparity(dz, (1, 0))
    assert outz[0, 1] == 3.0


def test_forward_warp_zero_offset_is_identity_and_nan_input():
    d = np.random.default_rng(3).normal(size=(6, 7))
    d[2, 2] = np.nan
    out = forward_warp_disparity(d, (0, 0))
    np.testing.assert_allclose(out[np.isfinite(d)], d[np.isfinite(d)].astype(np.float32))
    assert np.isnan(out[2, 2])


def _ramp(H=6, W=8, dtype=np.float64):
    """An exact linear ramp: bilinear interpolation reproduces it at every coordinate."""
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    return (2.0 * xx + 3.0 * yy + 1.0).astype(dtype)


def test_coordinate_taps_hand_computed():
    i0, i1, f, valid = coordinate_taps([-2.0, -1e-7, 0.0, 1.25, 2.999, 3.0, 3.0 + 1e-7, 4.5,
                                        np.nan, np.inf], 4)
    assert i0.tolist() == [0, 0, 0, 1, 2, 2, 2, 2, 0, 0]
    assert i1.tolist() == [1, 1, 1, 2, 3, 3, 3, 3, 1, 1]
    np.testing.assert_allclose(f, [0, 0, 0, 0.25, 0.999, 1, 1, 1, 0, 0], atol=1e-12)
    assert valid.tolist() == [False, True, True, True, True, True, True, False, False, False]
    assert i0.dtype == np.intp and f.dtype == np.float64
    # one-pixel axis: both taps are pixel 0
    i0, i1, f, valid = coordinate_taps([0.0, 0.5], 1)
    assert i0.tolist() == [0, 0] and i1.tolist() == [0, 0] and valid.tolist() == [True, False]
    # weight precision: computed in float64, then cast
    _, _, f32, _ = coordinate_taps([0.1], 4, dtype=np.float32)
    assert f32.dtype == np.float32 and f32[0] == np.float32(0.1)


def test_axis_taps_and_valid_are_the_shifted_grid():
    i0, i1, f = axis_taps(5, 0.5, pad=1)
    c0, c1, cf, _ = coordinate_taps(np.arange(-1, 6) + 0.5, 5)
    assert i0.tolist() == c0.tolist() and i1.tolist() == c1.tolist()
    np.testing.assert_array_equal(f, cf)
    assert axis_valid(5, 0.5).tolist() == [True, True, True, True, False]
    assert axis_valid(5, -1.0).tolist() == [False, True, True, True, True]


@pytest.mark.parametrize("edge", ["mask", "clamp"])
def test_sample_bilinear_edge_rules_on_a_ramp(edge):
    img = _ramp()
    x = np.array([0.0, 2.25, 7.0, -0.5, 9.0, 3.0, np.nan])
    y = np.array([0.0, 1.75, 5.0, 2.0, -3.0, 5.5, 1.0])
    vals, valid = sample_bilinear(img, x, y, fill=-7.0, edge=edge)
    assert valid.tolist() == [True, True, True, False, False, False, False]
    if edge == "mask":
        expect = np.where(valid, 2 * x + 3 * y + 1, -7.0)
    else:  # replicated border: the ramp at the clamped coordinate; NaN coordinates get fill
        expect = 2 * np.clip(x, 0, 7) + 3 * np.clip(y, 0, 5) + 1
        expect[-1] = -7.0
    np.testing.assert_allclose(vals, expect, atol=1e-12)


def test_sample_bilinear_dtypes():
    img = _ramp(dtype=np.float32)
    x, y = np.array([0.5, 3.25]), np.array([1.0, 2.5])
    v64, _ = sample_bilinear(img, x, y)
    v32, _ = sample_bilinear(img, x, y, dtype=np.float32)
    assert v64.dtype == np.float32 and v32.dtype == np.float32
    np.testing.assert_allclose(v32, 2 * x + 3 * y + 1, rtol=1e-6)
    assert sample_bilinear(_ramp(), x, y)[0].dtype == np.float64
    assert sample_bilinear(_ramp().astype(np.uint8), x, y)[0].dtype == np.float32
    with pytest.raises(InvalidInputError):
        sample_bilinear(img, x, y, edge="wrap")


@pytest.mark.parametrize("sx, sy", [(0.0, 0.0), (0.3, -1.7), (-2.5, 0.25), (10.0, 0.0),
                                    (-1.0, -2.0), (1.0, 3.0)])
def test_shift_map_matches_the_general_sampler(rng, sx, sy):
    img = rng.random((7, 9))
    yy, xx = np.mgrid[0:7, 0:9].astype(np.float64)
    for edge in ("mask", "clamp"):
        want, wv = sample_bilinear(img, xx + sx, yy + sy, fill=-1.0, edge=edge)
        # x then y is the general sampler's operation order: bit-identical
        got, gv = shift_map(img, sx, sy, edge=edge, fill=-1.0, order="xy")
        np.testing.assert_array_equal(gv, wv)
        np.testing.assert_array_equal(got, want)
        # y then x rounds differently, but only in the last bits
        got_yx, _ = shift_map(img, sx, sy, edge=edge, fill=-1.0)
        np.testing.assert_allclose(got_yx, want, rtol=0, atol=1e-14)


def test_shift_map_edge_rules_on_a_ramp():
    img = _ramp()
    out, valid = shift_map(img, 1.5, -0.5, edge="clamp")
    yy, xx = np.mgrid[0:6, 0:8].astype(np.float64)
    np.testing.assert_allclose(out, 2 * np.clip(xx + 1.5, 0, 7) + 3 * np.clip(yy - 0.5, 0, 5) + 1,
                               atol=1e-12)
    assert valid.tolist() == ((xx + 1.5 <= 7) & (yy - 0.5 >= 0)).tolist()
    masked, mv = shift_map(img, 1.5, -0.5, edge="mask")
    np.testing.assert_array_equal(mv, valid)
    np.testing.assert_array_equal(masked[valid], out[valid])
    assert np.isnan(masked[~valid]).all()
    # padded grid: one pixel around, clamped to the border
    padded, pv = shift_map(img, 0.0, 0.0, pad=1)
    assert padded.shape == (8, 10) and pv.shape == (6, 8) and pv.all()
    np.testing.assert_array_equal(padded[1:-1, 1:-1], img)
    np.testing.assert_array_equal(padded[0, 1:-1], img[0])
    np.testing.assert_array_equal(padded[1:-1, -1], img[:, -1])
    with pytest.raises(InvalidInputError):
        shift_map(img, 0.0, 0.0, pad=1, edge="mask")


def test_shift_map_dtype_channels_and_skip_zero(rng):
    img = rng.random((2, 6, 7)).astype(np.float32)          # a (K, H, W) stack
    out64, _ = shift_map(img, 0.4, -0.3)
    assert out64.dtype == np.float64
    out32, _ = shift_map(img, 0.4, -0.3, dtype=np.float32)
    assert out32.dtype == np.float32
    np.testing.assert_allclose(out32, out64, atol=1e-6)
    for k in range(2):                                       # leading axes carried along
        np.testing.assert_array_equal(out64[k], shift_map(img[k], 0.4, -0.3)[0])
    last = np.ascontiguousarray(np.moveaxis(img, 0, -1))     # (H, W, K)
    for sx, sy in ((0.4, -0.3), (-2.0, -1.0), (3.0, 0.5)):
        want, wv = shift_map(img, sx, sy, edge="mask", fill=0.0, dtype=np.float32, order="xy")
        got, gv = shift_map(last, sx, sy, edge="mask", fill=0.0, dtype=np.float32, order="xy",
                            channel_axis=-1)
        np.testing.assert_array_equal(gv, wv)
        np.testing.assert_array_equal(got, np.moveaxis(want, 0, -1))
        fast, fv = shift_map(last, sx, sy, edge="mask", fill=0.0, dtype=np.float32, order="xy",
                             channel_axis=-1, skip_zero=True)
        np.testing.assert_array_equal(fv, gv)
        np.testing.assert_array_equal(fast, got)  # finite image: skipping changes nothing
    # skip_zero only where every weight is 0: a negative integer shift
    np.testing.assert_array_equal(shift_map(img[0], -2.0, -1.0, skip_zero=True)[0][1:, 2:],
                                  img[0][:-1, :-2])


def test_bilinear_taps_hand_computed_and_gather():
    valid, idx, wts = bilinear_taps(np.array([0.5, 2.0, -1.0]), np.array([1.25, 0.0, 0.0]),
                                    (3, 3))
    assert valid.tolist() == [True, True, False]
    assert [int(i[0]) for i in idx] == [3, 4, 6, 7]
    np.testing.assert_allclose([w[0] for w in wts], [0.375, 0.375, 0.125, 0.125])
    assert [int(i[1]) for i in idx] == [1, 2, 4, 5]              # x = 2: pair (1, 2), f = 1
    np.testing.assert_allclose([w[1] for w in wts], [0, 1, 0, 0])
    img = _ramp()
    rng = np.random.default_rng(4)
    x, y = rng.uniform(-1, 8, 50), rng.uniform(-1, 6, 50)
    valid, idx, wts = bilinear_taps(x, y, img.shape)
    want, wv = sample_bilinear(img, x, y)
    np.testing.assert_array_equal(valid, wv)
    got = gather_taps(img.ravel(), idx, wts)
    np.testing.assert_allclose(got[valid], want[valid], atol=1e-12)
    np.testing.assert_allclose(got[valid], (2 * x + 3 * y + 1)[valid], atol=1e-12)


# ----------------------------------------------------------------------------- real data
def _valid_mask(gt: np.ndarray, ok: np.ndarray, border: int = 15) -> np.ndarray:
    """Valid warped pixels away from the image border and from ground-truth depth edges."""
    from scipy import ndimage

    gy, gx = np.gradient(gt)
    edges = ndimage.binary_dilation(np.hypot(gx, gy) > 0.05, iterations=3)
    m = ok & ~edges
    m[:border] = m[-border:] = False
    m[:, :border] = m[:, -border:] = False
    return m


@pytest.fixture(scope="module")
def antinous():
    folder = require_dataset("antinous")
    from hyperlf.formats import read_hci_scene

    return read_hci_scene(folder)


@pytest.mark.parametrize("dr, dc", [(0, 1), (0, 2), (1, 0), (2, 0), (1, 1), (2, 2), (-1, -2),
                                     (2, -1)])
def test_hci_ground_truth_warp_sign(antinous, dr, dc):
    """SPEC §1: warping a view with the HCI ground truth reproduces the reference view.

    Measured on antinous (mean abs error on [0, 1] sRGB values, valid pixels away from the
    border and depth edges): correct sign 0.0017-0.0037 at distances 1-2, opposite sign
    0.010-0.022 (about 6x worse).
    """
    lf = antinous
    r0, c0 = lf.reference
    assert (r0, c0) == (4, 4)  # input_Cam040
    gt = lf.gt_disparity
    ref = lf.views[r0, c0]
    offset = tuple(lf.positions[r0 + dr, c0 + dc] - lf.positions[r0, c0])
    view = lf.views[r0 + dr, c0 + dc]
    warped, ok = warp_to_reference(view, gt, offset)
    m = _valid_mask(gt, ok)
    err = float(np.abs(warped - ref)[m].mean())
    wrong, okw = warp_to_reference(view, -gt, offset)
    err_wrong = float(np.abs(wrong - ref)[_valid_mask(gt, okw)].mean())
    assert m.mean() > 0.5
    assert err < 0.01, f"correct-sign warp error {err:.4f}"
    assert err_wrong > 3 * err, f"opposite sign {err_wrong:.4f} vs correct {err:.4f}"
