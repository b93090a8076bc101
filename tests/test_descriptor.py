"""Tests of the spectral-invariant descriptor (SPEC §2, §3)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from hyperlf.descriptor import (
    DescriptorParams,
    auto_sigma_w,
    bin_weights,
    descriptor,
    descriptor_reference,
    edge_weights,
    gradients,
    iter_descriptor_blocks,
    magnitude_direction,
    normalise,
    prepare,
    prepare_from_gradients,
)
from hyperlf.errors import InvalidInputError

VARIANTS = {"default": DescriptorParams.default(), "paper": DescriptorParams.paper()}


def _images():
    """Random and structured test images (name -> array)."""
    rng = np.random.default_rng(7)
    H, W = 23, 31
    yy, xx = np.mgrid[0:H, 0:W]
    imgs = {
        "random": rng.random((H, W)),
        "random_f32": rng.random((H, W)).astype(np.float32),
        "step": (xx > 12).astype(float) * 0.8 + 0.1,
        "ramp": 0.2 + xx / W * 0.5,
        "checker": ((xx // 3 + yy // 3) % 2) * 0.5 + 0.25,
        "disc": (np.hypot(xx - 15, yy - 11) < 7).astype(float) + 0.3,
        "uint8": np.round(255 * (0.5 + 0.4 * np.sin(xx / 3.0) * np.cos(yy / 5.0))).astype(np.uint8),
        "constant": np.full((H, W), 0.4),
        "bright": 50.0 * rng.random((H, W)) ** 4,  # large magnitudes, past the last M bin
        "tiny_1x1": np.array([[0.5]]),
        "tiny_2x3": rng.random((2, 3)) + 0.1,
        "thin_1x17": rng.random((1, 17)) + 0.1,
    }
    return imgs


IMAGES = _images()


def _levels(d, params):
    """(n_levels, 3, K, H, W) view of a full descriptor."""
    return d.reshape(params.n_levels, 3, params.n_bins, *d.shape[1:])


# ------------------------------------------------------------------------------- params ----


def test_params_variants_and_channel_layout():
    p = DescriptorParams.default()
    q = DescriptorParams.paper()
    assert p.n_channels == 612 and q.n_channels == 612
    assert (p.gradient, p.sigma_w, p.beta) == ("sobel", "auto", 0.5)
    assert (q.gradient, q.sigma_w, q.beta) == ("central", 0.16, 0.5)
    assert p.bin_width == 1 / 64 and p.overlap == 1 / 16 and p.n_bins == 68
    assert p.windows == (3, 5, 9) and p.sigma_g(9) == 4.5
    lv = p.channel_levels
    assert lv.shape == (612,)
    assert (lv[:204] == 3).all() and (lv[204:408] == 5).all() and (lv[408:] == 9).all()
    assert (p.channel_hist[:68] == 0).all() and (p.channel_hist[68:136] == 1).all()
    assert (p.channel_hist[136:204] == 2).all() and p.channel_bin[205] == 1
    r = DescriptorParams(windows=[5], n_bins=10)
    assert r.windows == (5,) and r.n_channels == 30
    assert DescriptorParams.paper(windows=(3,)).gradient == "central"


@pytest.mark.parametrize("kw", [
    dict(windows=(4,)), dict(windows=()), dict(overlap=0.5), dict(overlap=-0.1),
    dict(bin_width=0), dict(n_bins=0), dict(beta=0.6), dict(sigma_w=0.0), dict(sigma_w="median"), dict(sigma_w=None),
    dict(sigma_w="0.1"),
    dict(gradient="scharr"), dict(presmooth_sigma=-1), dict(sigma_g_factor=0),
])
def test_params_validation(kw):
    with pytest.raises(InvalidInputError):
        DescriptorParams(**kw)


def test_bad_images_raise():
    for bad in (np.zeros((4, 4)), np.full((3, 3), np.nan), np.ones((2, 3, 4)), np.ones((0, 3))):
        with pytest.raises(InvalidInputError):
            descriptor(bad)
    with pytest.raises(InvalidInputError):
        descriptor(np.ones((4, 4)), impl="cuda")
    with pytest.raises(InvalidInputError):
        descriptor(np.ones((4, 4)), channels=[612])


# --------------------------------------------------------------------------------- bins ----


def _brute_bins(v, p):
    starts = np.arange(p.n_bins) * p.bin_step
    inside = [k for k in range(p.n_bins) if starts[k] <= v < starts[k] + p.bin_width]
    if v >= starts[-1] + p.bin_width:
        inside = [p.n_bins - 1]
    return inside


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.floats(0, 1.2), st.integers(0, 1100).map(lambda i: i / 1024.0),
                 st.integers(0, 1100).map(lambda i: np.nextafter(i / 1024.0, 0.0))))
def test_bin_membership_matches_definition(v):
    p = DescriptorParams()
    i0, w0, i1, w1 = bin_weights(np.array([v]), p)
    got = [int(i0[0])] + ([int(i1[0])] if i1[0] >= 0 else [])
    assert got == _brute_bins(v, p)
    assert w0[0] == 1.0 and w1[0] == (1.0 if i1[0] >= 0 else 0.0)


def test_bin_membership_examples():
    p = DescriptorParams()
    v = np.array([0.0, 15 / 1024, 15.5 / 1024, 16 / 1024, 0.5, 1005.5 / 1024, 1020.5 / 1024,
                  1021 / 1024, 1.0, 7.0])
    i0, w0, i1, w1 = bin_weights(v, p)
    assert i0.tolist() == [0, 0, 0, 1, 34, 66, 67, 67, 67, 67]
    assert i1.tolist() == [-1, 1, 1, -1, -1, 67, -1, -1, -1, -1]
    assert w1.tolist() == [0, 1, 1, 0, 0, 1, 0, 0, 0, 0]
    # the overlap is o*s = 1/1024 wide: about 1/15 of uniform values are in two bins
    u = np.random.default_rng(1).random(200_000) * p.n_bins * p.bin_step
    frac = (bin_weights(u, p)[2] >= 0).mean()
    assert abs(frac - 1 / 15) < 0.005


# ---------------------------------------------------------------------------- gradients ----


def test_gradients_central_and_sobel_on_ramp():
    In = np.tile(np.arange(6, dtype=float), (5, 1))  # In = x
    gx, gy, M, T = gradients(In, "central")
    assert np.allclose(gx[:, 1:-1], 1.0) and np.allclose(gx[:, [0, -1]], 0.5)  # replicated
    assert np.allclose(gy, 0) and np.allclose(T, 0)
    gx, gy, M, T = gradients(In, "sobel")  # Sobel/4: (1,2,1)-weighted f[x+1] - f[x-1], / 4
    assert np.allclose(gx[:, 1:-1], 2.0) and np.allclose(gx[:, [0, -1]], 1.0)
    gx, gy, M, T = gradients(In.T, "central")  # In = y: direction pi/2 -> Theta 0.5
    assert np.allclose(gy[1:-1], 1.0) and np.allclose(T[1:-1], 0.5)
    with pytest.raises(InvalidInputError):
        gradients(In, "roberts")


def test_direction_mod_pi_is_sign_invariant_exactly():
    rng = np.random.default_rng(3)
    gx = rng.normal(size=1000)
    gy = rng.normal(size=1000)
    gx[:50] = 0.0
    gy[25:75] = 0.0
    gy[75:80] = -0.0
    gx[80:85] = -0.0
    gy[85:90] = 1e-300  # atan2 close to pi for gx < 0
    gx[85:90] = -1.0
    M, T = magnitude_direction(gx, gy)
    M2, T2 = magnitude_direction(-gx, -gy)
    assert np.array_equal(T, T2) and np.array_equal(M, M2)
    assert T.min() >= 0 and T.max() < 1
    ref = np.mod(np.arctan2(gy, gx), np.pi) / np.pi
    ref = np.where(ref >= 1, 0, ref)
    d = np.abs(T - ref)
    assert np.minimum(d, 1 - d).max() < 1e-12  # same value (mod 1) as the literal formula


def test_normalise():
    I = np.random.default_rng(0).random((4, 5)).astype(np.float32)
    In = normalise(I)
    assert In.dtype == np.float64 and abs(In.mean() - 1) < 1e-12


# ------------------------------------------------------------------------------ weights ----


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_edge_weights(variant):
    p = VARIANTS[variant]
    prep = prepare(IMAGES["random"], p)
    a1, a3 = prep.a1, prep.a3
    assert a1.min() >= 0 and a1.max() <= p.beta
    assert np.allclose(a1 + a1 + a3, 1.0)
    if variant == "paper":
        assert prep.sigma_w == 0.16
    else:
        # sigma_w = median(M^2)/ln 2: the median pixel gets a3 = 1/2
        assert prep.sigma_w == pytest.approx(np.median(prep.M ** 2) / math.log(2))
        assert np.median(a3) == pytest.approx(0.5, abs=1e-9)
        assert np.allclose(a3, 1 - np.exp(-prep.M ** 2 / prep.sigma_w))


def test_auto_sigma_w_fallbacks():
    M = np.zeros(10)
    assert auto_sigma_w(M) == 0.0
    a1, a3, sw = edge_weights(M, DescriptorParams(beta=0.3))
    assert np.allclose(a1, 0.3) and np.allclose(a3, 0.4)
    M[:3] = [1.0, 2.0, 3.0]  # median of M^2 is 0: use the non-zero ones
    assert auto_sigma_w(M) == pytest.approx(4.0 / math.log(2))


# --------------------------------------------------------------------------------- sums ----


@pytest.mark.parametrize("variant", list(VARIANTS))
@pytest.mark.parametrize("name", list(IMAGES))
def test_sums_and_numba_matches_reference(variant, name):
    p = VARIANTS[variant]
    img = IMAGES[name]
    ref = descriptor_reference(img, p)
    fast = descriptor(img, p, impl="numba")
    assert fast.dtype == np.float32 and fast.shape == (612,) + img.shape
    assert np.abs(fast - ref).max() <= 1e-5
    lv = _levels(fast, p)
    assert np.abs(lv.sum(axis=(1, 2)) - 1.0).max() < 1e-5  # every D_p(w) sums to 1
    assert np.abs(fast.sum(axis=0) - 3.0).max() < 3e-5  # H_p sums to 3
    assert fast.min() >= 0
    # unweighted histograms: h1, h2 sum to 1 everywhere, h3 to 1 where non-empty else 0
    h = _levels(descriptor(img, p, weighted=False), p)
    s = h.sum(axis=2)
    assert np.abs(s[:, :2] - 1).max() < 1e-5
    assert np.all((np.abs(s[:, 2] - 1) < 1e-5) | (s[:, 2] == 0))
    if name == "constant":
        assert (s[:, 2] == 0).all()


def test_degenerate_sum_with_small_beta():
    p = DescriptorParams(beta=0.25)
    d = _levels(descriptor(np.full((5, 6), 0.3), p), p)
    assert np.allclose(d.sum(axis=(1, 2)), 0.5)  # flat window: h3 empty, a3 = 1 - 2 beta
    d = _levels(descriptor(IMAGES["random"], p), p)
    assert np.allclose(d.sum(axis=(1, 2)), 1.0, atol=1e-5)


def test_reference_matches_literal_per_pixel_loops():
    """Window sums with replicated borders, written as literally as possible."""
    p = DescriptorParams.paper(windows=(5,), n_bins=68)
    img = IMAGES["uint8"][:6, :7].astype(float) + np.random.default_rng(2).random((6, 7))
    prep = prepare(img, p)
    H, W = img.shape
    d = descriptor_reference(img, p)
    K = p.n_bins
    starts = np.arange(K) * p.bin_step

    def member(v):
        m = (starts <= v) & (v < starts + p.bin_width)
        if v >= starts[-1] + p.bin_width:
            m[-1] = True
        return m.astype(float)

    sg = p.sigma_g(5)
    for y in range(H):
        for x in range(W):
            h = np.zeros((3, K))
            for v in range(y - 2, y + 3):
                for u in range(x - 2, x + 3):
                    yy, xx = min(max(v, 0), H - 1), min(max(u, 0), W - 1)
                    G = math.exp(-((v - y) ** 2 + (u - x) ** 2) / (2 * sg * sg))
                    h[0] += G * member(prep.M[yy, xx])
                    h[1] += G * member(prep.Theta[yy, xx])
                    h[2] += G * prep.M[yy, xx] * member(prep.Theta[yy, xx])
            h /= np.where(h.sum(1, keepdims=True) > 0, h.sum(1, keepdims=True), 1)
            a1 = 0.5 * math.exp(-prep.M[y, x] ** 2 / 0.16)
            want = np.concatenate([a1 * h[0], a1 * h[1], (1 - 2 * a1) * h[2]])
            assert np.abs(d[:, y, x] - want).max() < 1e-6


# -------------------------------------------------------------------------- invariances ----


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_gain_invariance(variant):
    p = VARIANTS[variant]
    img = IMAGES["random"]
    d = descriptor(img, p)
    assert np.array_equal(descriptor(4.0 * img, p), d)  # power of two: bit-exact
    assert np.abs(descriptor(3.7 * img, p) - d).max() <= 1e-6
    assert np.abs(descriptor(0.013 * img.astype(np.float32), p) - d).max() <= 1e-6


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_gradient_sign_invariance(variant):
    """(gx, gy) -> (-gx, -gy) leaves M and Theta mod pi, hence the whole descriptor, unchanged."""
    p = VARIANTS[variant]
    rng = np.random.default_rng(5)
    gx = np.round(rng.normal(size=(17, 19)) * 20) / 256  # includes exact zeros
    gy = np.round(rng.normal(size=(17, 19)) * 20) / 256
    a = descriptor(prepare_from_gradients(gx, gy, p))
    b = descriptor(prepare_from_gradients(-gx, -gy, p))
    assert np.array_equal(a, b)


def _dyadic_image(rng, H=16, W=16):
    """Integer image with mean exactly 32 (pairs r, 64 - r), so all arithmetic is exact."""
    r = rng.integers(0, 65, size=H * W // 2)
    v = np.concatenate([r, 64 - r]).astype(float)
    rng.shuffle(v)
    return v.reshape(H, W)


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_contrast_reversal(variant):
    """I -> c - I: In' = -k In + const with k = mean / (c - mean).

    Directions (mod pi) are unchanged, so h2 and the normalised h3 are too; M scales by k, so
    h1 changes unless k = 1.  With sigma_w = "auto" the weights a1..a3 are also unchanged; for
    c = 2 mean (k = 1, In' = 2 - In) the whole descriptor is unchanged.  The dyadic image makes
    every step exact, so the checks are bit-exact.
    """
    p = VARIANTS[variant]
    img = _dyadic_image(np.random.default_rng(11))
    assert img.mean() == 32.0
    K = p.n_bins
    h = _levels(descriptor(img, p, weighted=False), p)
    h_rev = _levels(descriptor(96.0 - img, p, weighted=False), p)  # k = 32 / 64 = 1/2
    assert np.array_equal(h[:, 1:], h_rev[:, 1:])  # h2, h3
    assert not np.array_equal(h[:, 0], h_rev[:, 0])  # h1 sees the magnitude scale
    d = _levels(descriptor(img, p), p)
    d_rev = _levels(descriptor(96.0 - img, p), p)
    if p.sigma_w == "auto":
        assert np.array_equal(d[:, 1:], d_rev[:, 1:])
    else:
        assert not np.array_equal(d[:, 1:], d_rev[:, 1:])
    # k = 1: full invariance
    assert np.array_equal(descriptor(img, p), descriptor(64.0 - img, p))
    # and, not exact in floating point but to rounding, for an arbitrary image
    x = IMAGES["random"]
    a = descriptor(x, p)
    b = descriptor(2 * x.mean() - x, p)
    assert np.mean(np.abs(a - b) > 1e-5) < 1e-3  # only rare bin-edge flips, if any
    assert K == 68


# ----------------------------------------------------------------------- channel subsets ----


@pytest.mark.parametrize("impl", ["numba", "numpy"])
def test_channel_subsets_and_blocks(impl):
    p = DescriptorParams.default()
    img = IMAGES["disc"]
    full = descriptor(img, p, impl=impl)
    assert np.array_equal(descriptor(img, p, channels=slice(100, 300), impl=impl), full[100:300])
    idx = np.array([611, 0, 5, 5, 300, -1])
    assert np.array_equal(descriptor(img, p, channels=idx, impl=impl), full[idx])
    assert descriptor(img, p, channels=[], impl=impl).shape == (0,) + img.shape
    prep = prepare(img, p)
    for block, nblocks in ((50, 13), (68, 9), (64, 10), (204, 3), (1000, 1)):
        got = []
        for sl, blk in iter_descriptor_blocks(prep, block=block, impl=impl):
            assert blk.shape[0] == sl.stop - sl.start <= block
            assert np.array_equal(blk, full[sl])
            got.append(sl)
        assert got[0].start == 0 and got[-1].stop == 612 and len(got) == nblocks
        assert all(a.stop == b.start for a, b in zip(got, got[1:]))
    with pytest.raises(InvalidInputError):
        next(iter_descriptor_blocks(img, p, block=0))


def test_prepared_params_mismatch():
    prep = prepare(IMAGES["random"], DescriptorParams.default())
    with pytest.raises(InvalidInputError):
        descriptor(prep, DescriptorParams.paper())


def test_presmoothing_and_custom_levels():
    p = DescriptorParams(windows=(3, 7), presmooth_sigma=0.8, n_bins=20, bin_width=0.06)
    img = IMAGES["uint8"]
    a = descriptor(img, p)
    assert a.shape == (120,) + img.shape
    assert np.abs(a - descriptor_reference(img, p)).max() <= 1e-5
    assert np.abs(_levels(a, p).sum(axis=(1, 2)) - 1).max() < 1e-5
