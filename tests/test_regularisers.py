"""Tests of hyperlf.regularisers: WTA, SGM, alpha-expansion, occlusion handling, sub-pixel."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf import regularisers as R
from hyperlf.errors import InvalidInputError


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------

def noisy_volume(gt, L, noise, rng, cap=4.0):
    """Truncated-linear data cost around the true label map plus Gaussian noise."""
    lab = np.arange(L)[:, None, None]
    c = np.minimum(np.abs(lab - gt[None]), cap) / cap + rng.normal(0.0, noise, (L,) + gt.shape)
    return c.astype(np.float32)


def step_scene(H=24, W=32, L=12):
    yy, xx = np.mgrid[0:H, 0:W]
    gt = np.full((H, W), 3)
    gt[(xx > W // 2) & (yy > 4)] = 8
    gt[(xx < 6) & (yy > H // 2)] = 5
    return gt


def batch_energy(F, cost, Vm, wx, wy):
    """Energies of many label maps F[N, H, W] (reference implementation for the tests)."""
    L, H, W = cost.shape
    yy, xx = np.mgrid[0:H, 0:W]
    e = cost[F, yy, xx].astype(np.float64).sum(axis=(1, 2))
    e += (wx * Vm[F[:, :, :-1], F[:, :, 1:]]).sum(axis=(1, 2))
    e += (wy * Vm[F[:, :-1, :], F[:, 1:, :]]).sum(axis=(1, 2))
    return e


def exact_minimum(cost, Vm, wx, wy):
    """Exact MRF minimum on a tiny grid by dynamic programming over rows (transfer matrix)."""
    L, H, W = cost.shape
    states = np.array(list(itertools.product(range(L), repeat=W)))  # (S, W)
    S = len(states)

    def row_cost(y):
        u = cost[:, y, :][states, np.arange(W)].astype(np.float64).sum(axis=1)
        if W > 1:
            u += (wx[y] * Vm[states[:, :-1], states[:, 1:]]).sum(axis=1)
        return u

    best = row_cost(0)
    for y in range(1, H):
        trans = (wy[y - 1][None, None, :] * Vm[states[:, None, :], states[None, :, :]]).sum(axis=2)
        best = (best[:, None] + trans).min(axis=0) + row_cost(y)
    assert S == L ** W
    return float(best.min())


def params_matrix(smoothness, L, labels, T):
    if smoothness == "potts":
        return 1.0 - np.eye(L)
    V = np.abs(labels[:, None] - labels[None, :])
    return V if T is None else np.minimum(V, T)


# ----------------------------------------------------------------------------------------------
# basics and validation
# ----------------------------------------------------------------------------------------------

def test_wta_and_data_term(rng):
    L, H, W = 7, 5, 6
    gt = rng.integers(0, L, (H, W))
    c = rng.random((L, H, W)).astype(np.float32) + 0.5
    c[gt, np.arange(H)[:, None], np.arange(W)[None, :]] = 0.1
    f = R.wta(c)
    assert f.dtype == np.int32 and f.shape == (H, W)
    np.testing.assert_array_equal(f, gt)
    d = R.data_term(c)
    assert d.shape == c.shape and d.min() == 0.0
    np.testing.assert_allclose(d.min(axis=0), 0.0)
    np.testing.assert_array_equal(R.wta(d), gt)
    own = c.copy()
    assert R.data_term(own, overwrite=True) is own  # in place, the same numbers
    np.testing.assert_array_equal(own, d)
    np.testing.assert_array_equal(R.data_term(c.astype(np.float64), overwrite=True), d)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_cost_is_rejected(bad):
    c = np.zeros((3, 4, 5), np.float32)
    c[1, 2, 3] = bad
    for fn in (R.wta, R.data_term, lambda x: R.sgm(x, 0.1, 1.0), R.graphcut,
               lambda x: R.subpixel_refine(x, np.zeros((4, 5), int))):
        with pytest.raises(InvalidInputError, match="NaN"):
            fn(c)
    with pytest.raises(InvalidInputError):
        R.wta(np.zeros((4, 5)))


def test_fill_invalid_uses_pixel_worst_valid_cost():
    c = np.array([[[1.0, np.nan]], [[3.0, np.inf]], [[np.nan, np.nan]]], np.float32)  # (3,1,2)
    out = R.fill_invalid(c)
    np.testing.assert_array_equal(out[:, 0, 0], [1.0, 3.0, 3.0])
    np.testing.assert_array_equal(out[:, 0, 1], [3.0, 3.0, 3.0])  # no valid entry: global worst
    assert np.isfinite(out).all()


def _fill_nan_worst_reference(C):
    """The rule hyperlf.hlf used before it called fill_invalid (kept to pin bit identity)."""
    bad = ~np.isfinite(C)
    if not bad.any():
        return C
    worst = np.where(bad, -np.inf, C).max(axis=0)
    gw = worst[np.isfinite(worst)]
    g = float(gw.max()) if gw.size else 0.0
    worst = np.where(np.isfinite(worst), worst, g).astype(np.float32)
    return np.where(bad, worst[None], C).astype(np.float32)


def test_fill_invalid_is_bit_identical_to_the_former_hlf_rule(rng):
    c = rng.random((6, 9, 11)).astype(np.float32)
    c[rng.random(c.shape) < 0.3] = np.nan
    c[:, 2, 3] = np.nan                               # a pixel with no valid entry
    out = R.fill_invalid(c)
    np.testing.assert_array_equal(out, _fill_nan_worst_reference(c))
    assert out.dtype == np.float32
    assert out[0, 2, 3] == np.nanmax(c)               # the volume's worst valid cost


def test_fill_invalid_empty_zero_and_mask():
    c = np.array([[[1.0, 2.0, np.nan]], [[3.0, 5.0, np.nan]], [[4.0, 0.5, np.nan]]], np.float32)
    invalid = np.array([[[False, False, True]], [[False, True, True]], [[True, False, True]]])
    out = R.fill_invalid(c, invalid, empty="zero")
    np.testing.assert_array_equal(out[:, 0, 0], [1.0, 3.0, 3.0])    # worst valid of the pixel
    np.testing.assert_array_equal(out[:, 0, 1], [2.0, 2.0, 0.5])    # label 1 invalid: max(2, .5)
    np.testing.assert_array_equal(out[:, 0, 2], [0.0, 0.0, 0.0])    # no valid entry: 0
    glob = R.fill_invalid(c, invalid)
    np.testing.assert_array_equal(glob[:, 0, 2], [3.0, 3.0, 3.0])   # the volume's worst valid
    np.testing.assert_array_equal(R.fill_invalid(np.full((2, 1, 1), np.nan), empty="zero"),
                                  np.zeros((2, 1, 1), np.float32))
    with pytest.raises(InvalidInputError, match="no valid entry"):
        R.fill_invalid(np.full((2, 1, 1), np.nan))
    with pytest.raises(InvalidInputError, match="empty must be one of"):
        R.fill_invalid(c, empty="nan")


@pytest.mark.parametrize("value", ["median", "share"])
def test_fill_invalid_median_and_share_follow_their_formulas(rng, value):
    """``value="median"``: an invalid entry of a pixel with valid ones gets the median ``m`` of
    those (neutral, where ``"worst"`` rules the label out); ``"share"``: ``m + s (worst - m)``
    with ``s`` the share of the pixel's entries that are valid; a pixel with none follows
    ``empty``."""
    c = rng.random((7, 5, 6)).astype(np.float32)
    invalid = rng.random(c.shape) < 0.4
    invalid[:, 1, 2] = True  # no valid entry
    invalid[:, 3, 4] = [True] + [False] * 6  # one invalid entry of seven
    c[invalid & (rng.random(c.shape) < 0.5)] = np.nan  # invalid either way
    out = R.fill_invalid(c, invalid, value=value)
    for y, x in np.ndindex(5, 6):
        ok = ~invalid[:, y, x]
        if not ok.any():
            continue
        m, worst = np.median(c[ok, y, x]), c[ok, y, x].max()
        fill = m if value == "median" else m + ok.mean() * (worst - m)
        np.testing.assert_allclose(out[:, y, x], np.where(ok, c[:, y, x], fill), rtol=1e-6)
    np.testing.assert_array_equal(out[:, 1, 2], np.nanmax(np.where(invalid, np.nan, c)))
    if value == "share":  # six of seven valid: 6/7 of the way from the median to the worst
        m, worst = np.median(c[1:, 3, 4]), c[1:, 3, 4].max()
        assert out[0, 3, 4] == pytest.approx(worst - (worst - m) / 7, rel=1e-6)
    zero = R.fill_invalid(c, invalid, value=value, empty="zero")
    np.testing.assert_array_equal(zero[:, 1, 2], 0.0)
    with pytest.raises(InvalidInputError, match="value must be one of"):
        R.fill_invalid(c, value="mean")


def test_fill_invalid_zero_matches_the_costs_rule(rng):
    from hyperlf import costs

    L, H, W, dmin = 7, 5, 6, 0
    c = rng.random((L, H, W)).astype(np.float32)
    valid = costs.candidate_validity((H, W), dmin, dmin + L - 1)
    valid = valid & (rng.random((L, H, W)) < 0.8)
    valid[:, 1, 4] = False                            # a pixel with no valid candidate
    expected = costs.fill_out_of_image(c.copy(), dmin, valid)
    np.testing.assert_array_equal(R.fill_invalid(c, ~valid, empty="zero"), expected)
    assert np.all(expected[:, 1, 4] == 0)


# ----------------------------------------------------------------------------------------------
# SGM
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("smoothness", ["p1p2", "truncated_linear"])
@pytest.mark.parametrize("paths", [8, 4])
@pytest.mark.parametrize("use_guide", [False, True])
def test_sgm_numpy_reference_matches_numba(rng, smoothness, paths, use_guide):
    L, H, W = 9, 13, 17
    c = rng.random((L, H, W)).astype(np.float32)
    guide = rng.random((H, W, 3)) if use_guide else None
    a = R.sgm(c, 0.15, 0.6, paths=paths, guide=guide, impl="numpy", smoothness=smoothness)
    b = R.sgm(c, 0.15, 0.6, paths=paths, guide=guide, impl="numba", smoothness=smoothness)
    assert a.shape == b.shape == (L, H, W) and b.dtype == np.float32
    np.testing.assert_allclose(b, a, rtol=1e-4, atol=1e-5)


@settings(max_examples=25, deadline=None)
@given(L=st.integers(1, 5), H=st.integers(1, 6), W=st.integers(1, 6), paths=st.sampled_from([2, 4, 8]),
       smoothness=st.sampled_from(["p1p2", "truncated_linear"]), seed=st.integers(0, 2**16),
       p1=st.floats(0.0, 2.0), p2=st.floats(0.0, 5.0))
def test_sgm_impls_agree_on_any_shape(L, H, W, paths, smoothness, seed, p1, p2):
    c = np.random.default_rng(seed).random((L, H, W)).astype(np.float32)
    a = R.sgm(c, p1, p2, paths=paths, impl="numpy", smoothness=smoothness)
    b = R.sgm(c, p1, p2, paths=paths, impl="numba", smoothness=smoothness)
    np.testing.assert_allclose(b, a, rtol=1e-4, atol=1e-5)
    assert np.all(a >= paths * c - 1e-4)   # each path term is >= the data cost


@settings(max_examples=30, deadline=None)
@given(L=st.integers(1, 6), H=st.integers(1, 9), W=st.integers(1, 9), seed=st.integers(0, 2**16),
       weight=st.floats(0.0, 3.0), potts=st.booleans(), guided=st.booleans())
def test_expansion_terms_kernel_is_the_numpy_reference_bit_for_bit(L, H, W, seed, weight, potts,
                                                                  guided):
    """The numba terms of an expansion move equal the numpy reference exactly, for every label
    of any labelling, on any shape (one row or column included)."""
    from hyperlf.regularisers import graphcuts as G

    rng = np.random.default_rng(seed)
    c = rng.random((L, H, W)).astype(np.float32)
    f = rng.integers(0, L, (H, W)).astype(np.intp)
    Vm = G._smoothness_matrix("potts" if potts else "truncated_linear", L,
                              np.sort(rng.random(L) * 5), 2.0)
    wx, wy = G._pair_weights(H, W, weight, rng.random((H, W)) if guided else None, None, None)
    unary_f = G.gather(c, f)
    for alpha in range(L):
        caps = [np.full((H, W), -1.0) for _ in range(4)]
        du_ref = G._move_terms_numpy(c, alpha, f, unary_f, Vm, wx, wy, caps[0], caps[1])
        du = G._move_terms(c, alpha, f, unary_f, Vm, wx, wy, caps[2], caps[3])
        np.testing.assert_array_equal(du, du_ref)
        np.testing.assert_array_equal(caps[2], caps[0])
        np.testing.assert_array_equal(caps[3], caps[1])
        if W > 1 and H > 1:
            assert (caps[0][:, :-1] >= 0).all() and (caps[1][:-1] >= 0).all()


@settings(max_examples=40, deadline=None)
@given(H=st.integers(1, 9), W=st.integers(1, 9), seed=st.integers(0, 2**16),
       share=st.floats(0.0, 1.0))
def test_restricted_terms_kernel_is_the_numpy_reference_bit_for_bit(H, W, seed, share):
    """A restricted move's graph (unary terms, pairs and their order) from the numba kernel
    equals the numpy reference exactly, for any set of active pixels (none and all included),
    and a pixel with a fixed left and upper neighbour carries both of their capacities."""
    from hyperlf.regularisers import _kernels
    from hyperlf.regularisers import graphcuts as G

    rng = np.random.default_rng(seed)
    active = rng.random((H, W)) < share
    du, capx, capy = rng.standard_normal((H, W)), rng.random((H, W)), rng.random((H, W))
    ref = G._restricted_terms_numpy(active, du, capx, capy)
    got = _kernels.restricted_terms(active, du, capx, capy)
    for a, b in zip(got, ref):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)
    d, src, dst, caps = got
    assert d.size == active.sum() and src.size == (active[:, 1:] & active[:, :-1]).sum() + \
        (active[1:] & active[:-1]).sum()
    ys, xs = np.nonzero(active)
    expect = du[ys, xs] + np.where((xs > 0) & ~active[ys, xs - 1], capx[ys, xs - 1], 0.0) + \
        np.where((ys > 0) & ~active[ys - 1, xs], capy[ys - 1, xs], 0.0)
    np.testing.assert_allclose(d, expect, rtol=1e-12, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(L=st.integers(1, 5), H=st.integers(1, 8), W=st.integers(1, 8), seed=st.integers(0, 2**16),
       share=st.floats(0.0, 1.0))
def test_move_delta_is_the_energy_difference(L, H, W, seed, share):
    """A move's energy change, from the numba kernel and from its numpy reference, equals the
    whole energy after the move less the whole energy before it, for any set of switched
    pixels, with per-pair weights and a pair term that depends on the order of its labels."""
    from hyperlf.regularisers import _kernels
    from hyperlf.regularisers import graphcuts as G

    rng = np.random.default_rng(seed)
    c = rng.random((L, H, W)).astype(np.float32)
    f = rng.integers(0, L, (H, W)).astype(np.intp)
    alpha = int(rng.integers(0, L))
    switch = (rng.random((H, W)) < share) & (f != alpha)
    Vm, wx, wy = rng.random((L, L)), rng.random((H, W - 1)), rng.random((H - 1, W))
    f_new = np.where(switch, alpha, f)
    expect = G._energy(f_new, G.gather(c, f_new), Vm, wx, wy) - \
        G._energy(f, G.gather(c, f), Vm, wx, wy)
    args = (switch, c[alpha], alpha, f, G.gather(c, f), Vm, wx, wy)
    got, ref = _kernels.move_delta(*args), G._move_delta_numpy(*args)
    assert ref == pytest.approx(expect, rel=1e-9, abs=1e-9)
    assert got == pytest.approx(ref, rel=1e-12, abs=1e-12)


@settings(max_examples=15, deadline=None)
@given(L=st.integers(1, 4), H=st.integers(1, 5), W=st.integers(1, 5), seed=st.integers(0, 2**16),
       weight=st.floats(0.0, 3.0), potts=st.booleans())
def test_graphcut_never_raises_energy_from_init(L, H, W, seed, weight, potts):
    rng = np.random.default_rng(seed)
    c = rng.random((L, H, W)).astype(np.float32)
    init = rng.integers(0, L, (H, W))
    kw = dict(smoothness="potts" if potts else "truncated_linear", weight=weight, truncation=2.0)
    f, e = R.graphcut(c, init=init, return_energy=True, **kw)
    assert e <= R.mrf_energy(init, c, **kw) + 1e-9
    assert e == pytest.approx(R.mrf_energy(f, c, **kw), rel=1e-9, abs=1e-9)


def test_sgm_zero_penalties_is_sum_of_paths(rng):
    c = rng.random((5, 6, 7)).astype(np.float32)
    np.testing.assert_allclose(R.sgm(c, 0.0, 0.0, paths=8), 8 * c, rtol=1e-6)
    np.testing.assert_allclose(R.sgm(c, 0.0, 0.0, paths=4, impl="numpy"), 4 * c, rtol=1e-6)


def test_sgm_single_path_matches_hand_recursion():
    # one row, left-to-right path only (paths=2 = both horizontal directions; compare one way)
    c = np.array([[0.0, 1.0, 0.2], [1.0, 0.0, 0.9], [0.5, 0.5, 0.0]], np.float32).T[:, None, :]
    # c[l, 0, x]: x=0 -> [0,1,0.5], x=1 -> [1,0,0.5], x=2 -> [0.2,0.9,0]
    p1, p2 = 0.3, 0.7
    Lr = [c[:, 0, 0].astype(float)]
    for x in (1, 2):
        prev = Lr[-1]
        m = prev.min()
        cur = []
        for l in range(3):
            v = min([prev[l], m + p2] + [prev[k] + p1 for k in (l - 1, l + 1) if 0 <= k < 3])
            cur.append(c[l, 0, x] + v - m)
        Lr.append(np.array(cur))
    Rr = [c[:, 0, 2].astype(float)]
    for x in (1, 0):
        prev = Rr[-1]
        m = prev.min()
        cur = []
        for l in range(3):
            v = min([prev[l], m + p2] + [prev[k] + p1 for k in (l - 1, l + 1) if 0 <= k < 3])
            cur.append(c[l, 0, x] + v - m)
        Rr.append(np.array(cur))
    expected = np.stack([Lr[x] + Rr[2 - x] for x in range(3)], axis=1)[:, None, :]
    for impl in ("numba", "numpy"):
        np.testing.assert_allclose(R.sgm(c, p1, p2, paths=2, impl=impl), expected, rtol=1e-6)


def test_sgm_beats_wta_on_noisy_piecewise_constant(rng):
    gt = step_scene()
    c = noisy_volume(gt, 12, 0.3, rng)
    err_wta = np.mean(R.wta(c) != gt)
    err_sgm = np.mean(R.sgm_labels(c, 1.0, 4.0) != gt)
    gross_wta = np.mean(np.abs(R.wta(c) - gt) > 1)
    gross_sgm = np.mean(np.abs(R.sgm_labels(c, 1.0, 4.0) - gt) > 1)
    assert err_wta > 0.3 and gross_wta > 0.1
    assert err_sgm < err_wta / 3 and gross_sgm < gross_wta / 5
    # the guided variant (guide = the true layout) is at least as good
    err_guided = np.mean(R.sgm_labels(c, 1.0, 4.0, guide=gt.astype(float)) != gt)
    assert err_guided <= err_sgm


def test_sgm_guide_lowers_p2_only_at_edges(rng):
    c = rng.random((4, 3, 8)).astype(np.float32)
    guide = np.zeros((3, 8))
    # a flat guide must give exactly the unguided result
    np.testing.assert_allclose(R.sgm(c, 0.1, 0.8, guide=guide), R.sgm(c, 0.1, 0.8), rtol=1e-6)
    with pytest.raises(InvalidInputError):
        R.sgm(c, 0.1, 0.8, paths=3)
    with pytest.raises(InvalidInputError):
        R.sgm(c, -0.1, 0.8)
    with pytest.raises(InvalidInputError):
        R.sgm(c, 0.1, 0.8, guide=np.zeros((2, 2)))


# ----------------------------------------------------------------------------------------------
# graph cuts
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("smoothness", ["truncated_linear", "potts"])
def test_graphcut_energy_not_above_wta_or_sgm(seed, smoothness):
    rng = np.random.default_rng(seed)
    L, H, W = 8, 16, 20
    if seed == 0:
        c = rng.random((L, H, W)).astype(np.float32)                      # pure noise
    else:
        c = noisy_volume(step_scene(H, W, L) % L, L, 0.3 * seed, rng)     # structured
    c = R.data_term(c)
    guide = rng.random((H, W)) if seed == 2 else None
    kw = dict(smoothness=smoothness, weight=0.4, truncation=3.0, guide=guide)
    f, e = R.graphcut(c, return_energy=True, **kw)
    assert f.dtype == np.int32 and f.shape == (H, W)
    assert e == pytest.approx(R.mrf_energy(f, c, **kw), rel=1e-12)
    for other in (R.wta(c), R.sgm_labels(c, 0.4, 1.2, guide=guide, smoothness="truncated_linear")):
        assert e <= R.mrf_energy(other, c, **kw) + 1e-9
    # started from the SGM labelling it can only improve that labelling
    s = R.sgm_labels(c, 0.4, 1.2)
    _, e2 = R.graphcut(c, init=s, return_energy=True, **kw)
    assert e2 <= R.mrf_energy(s, c, **kw) + 1e-9


def test_graphcut_potts_two_regions_exact_split(rng):
    H, W, L = 20, 30, 4
    gt = np.zeros((H, W), int)
    gt[:, 12:] = 2
    c = noisy_volume(gt, L, 0.45, rng, cap=1.0)
    assert np.mean(R.wta(c) != gt) > 0.1
    f = R.graphcut(c, smoothness="potts", weight=2.0)
    np.testing.assert_array_equal(f, gt)


def test_graphcut_edge_weights_place_the_boundary(rng):
    # ambiguous data everywhere except two anchoring columns; a cheap cut column decides the split
    H, W, L = 6, 10, 2
    c = np.full((L, H, W), 0.5, np.float32)
    c[0, :, 0] = 0.0
    c[1, :, 0] = 5.0
    c[1, :, -1] = 0.0
    c[0, :, -1] = 5.0
    wx = np.ones((H, W - 1))
    wx[:, 6] = 0.05               # cheap between x=6 and x=7
    wy = np.ones((H - 1, W))
    f = R.graphcut(c, smoothness="potts", weight=1.0, edge_weights=(wx, wy))
    expected = np.zeros((H, W), int)
    expected[:, 7:] = 1
    np.testing.assert_array_equal(f, expected)
    # the same split from a guide image with an edge there
    guide = np.zeros((H, W))
    guide[:, 7:] = 1.0
    f2 = R.graphcut(c, smoothness="potts", weight=1.0, guide=guide, edge_sigma=0.2)
    np.testing.assert_array_equal(f2, expected)


def test_mrf_energy_matches_hand_computation():
    c = np.zeros((3, 2, 2), np.float32)
    c[1] = [[1.0, 2.0], [3.0, 4.0]]
    c[2] = 0.5
    f = np.array([[0, 1], [2, 2]])
    lv = np.array([0.0, 0.5, 3.0])
    wx = np.array([[1.0], [2.0]])
    wy = np.array([[1.0, 0.5]])
    unary = 0 + 2.0 + 0.5 + 0.5
    # horizontal: (0,1) -> |0-0.5|=0.5 * 1 ; (2,2) -> 0; vertical: (0,2)-> min(3,T=2)=2 * 1 ; (1,2)->2*0.5
    pair = 0.5 * 1 + 0 + 2 * 1 + 2 * 0.5
    e = R.mrf_energy(f, c, weight=3.0, truncation=2.0, edge_weights=(wx, wy), labels_values=lv)
    assert e == pytest.approx(unary + 3.0 * pair)
    e_potts = R.mrf_energy(f, c, smoothness="potts", weight=3.0, edge_weights=(wx, wy))
    assert e_potts == pytest.approx(unary + 3.0 * (1 * 1 + 0 + 1 * 1 + 0.5 * 1))


@pytest.mark.parametrize("case", range(4))
def test_alpha_expansion_local_optimum_and_bound_on_tiny_grid(case):
    rng = np.random.default_rng(100 + case)
    L, H, W = 3, 4, 4
    smoothness = "potts" if case % 2 == 0 else "truncated_linear"
    lv = np.array([0.0, 1.0, 2.5])
    T = 2.0
    c = rng.random((L, H, W)).astype(np.float32)
    weight = 0.35 + 0.2 * case
    wx = weight * np.ones((H, W - 1))
    wy = weight * np.ones((H - 1, W))
    Vm = params_matrix(smoothness, L, lv, T)
    f, e = R.graphcut(c, smoothness=smoothness, weight=weight, truncation=T, labels=lv,
                      max_cycles=10, return_energy=True)
    e_opt = exact_minimum(c, Vm, wx, wy)
    assert e >= e_opt - 1e-9
    if smoothness == "potts":
        assert e <= 2.0 * e_opt + 1e-9       # BVZ bound for Potts (c = 1)
    # local optimum: no expansion move (all 2^16 of them, for every alpha) lowers the energy
    subsets = ((np.arange(2 ** (H * W))[:, None] >> np.arange(H * W)) & 1).astype(bool)
    subsets = subsets.reshape(-1, H, W)
    for alpha in range(L):
        F = np.where(subsets, alpha, f[None])
        assert batch_energy(F, c, Vm, wx, wy).min() >= e - 1e-9


def test_alpha_expansion_equals_optimum_in_easy_case(rng):
    L, H, W = 3, 4, 4
    gt = np.array([[0, 0, 2, 2], [0, 0, 2, 2], [1, 1, 2, 2], [1, 1, 2, 2]])
    c = noisy_volume(gt, L, 0.1, rng, cap=1.0)
    Vm = params_matrix("potts", L, None, None)
    w = 0.3
    f, e = R.graphcut(c, smoothness="potts", weight=w, return_energy=True)
    e_opt = exact_minimum(c, Vm, w * np.ones((H, W - 1)), w * np.ones((H - 1, W)))
    assert e == pytest.approx(e_opt, abs=1e-9)
    np.testing.assert_array_equal(f, gt)


def test_graphcut_progress_and_options(rng):
    c = rng.random((5, 6, 7)).astype(np.float32)
    calls = []
    f = R.graphcut(c, progress=lambda *a: calls.append(a), order="random", seed=3, max_cycles=3)
    assert calls[0][0] == 0 and len(calls) >= 2
    energies = [a[2] for a in calls]
    assert all(b <= a + 1e-12 for a, b in zip(energies, energies[1:]))
    np.testing.assert_array_equal(R.graphcut(c, max_cycles=0), R.wta(c))
    init = np.zeros((6, 7), int)
    np.testing.assert_array_equal(R.graphcut(c, max_cycles=0, init=init), init)
    assert f.shape == (6, 7)
    with pytest.raises(InvalidInputError):
        R.graphcut(c, smoothness="quadratic")
    with pytest.raises(InvalidInputError):
        R.graphcut(c, init=np.full((6, 7), 5))
    with pytest.raises(InvalidInputError):
        R.graphcut(c, edge_weights=(np.ones((6, 7)), np.ones((5, 7))))


@settings(max_examples=20, deadline=None)
@given(L=st.integers(2, 5), H=st.integers(1, 6), W=st.integers(1, 6), seed=st.integers(0, 2**16),
       weight=st.floats(0.0, 2.0), potts=st.booleans())
def test_restricted_moves_with_every_label_allowed_are_plain_alpha_expansion(L, H, W, seed,
                                                                              weight, potts):
    rng = np.random.default_rng(seed)
    c = rng.random((L, H, W)).astype(np.float32)
    kw = dict(smoothness="potts" if potts else "truncated_linear", weight=weight, truncation=2.0)
    f0, e0 = R.graphcut(c, return_energy=True, **kw)
    f1, e1 = R.graphcut(c, candidates=np.ones(c.shape, bool), return_energy=True, **kw)
    np.testing.assert_array_equal(f0, f1)
    assert e1 == pytest.approx(e0, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("case", range(3))
def test_restricted_move_is_exact_over_its_variables(case):
    """One cycle with a random candidate mask: for every alpha the result is at least as good as
    every expansion that switches only allowed pixels (brute force on a 3 x 4 grid)."""
    rng = np.random.default_rng(7 + case)
    L, H, W = 3, 3, 4
    c = rng.random((L, H, W)).astype(np.float32)
    cand = rng.random((L, H, W)) < 0.6
    w = 0.3 + 0.2 * case
    Vm = params_matrix("truncated_linear", L, np.arange(L, dtype=float), 1.5)
    wx, wy = w * np.ones((H, W - 1)), w * np.ones((H - 1, W))
    f, e = R.graphcut(c, weight=w, truncation=1.5, candidates=cand, max_cycles=20,
                      return_energy=True)
    assert e <= R.mrf_energy(R.wta(c), c, weight=w, truncation=1.5) + 1e-9
    subsets = ((np.arange(2 ** (H * W))[:, None] >> np.arange(H * W)) & 1).astype(bool)
    subsets = subsets.reshape(-1, H, W)
    for alpha in range(L):
        allowed = subsets & cand[alpha][None]
        F = np.where(allowed, alpha, f[None])
        assert batch_energy(F, c, Vm, wx, wy).min() >= e - 1e-9
    # a pixel only ever takes its initial (WTA) label or an allowed one
    moved = f != R.wta(c)
    assert np.all(np.take_along_axis(cand, f[None].astype(np.intp), 0)[0][moved])


def test_candidate_labels_top_k_and_spread():
    c = np.zeros((6, 1, 2), np.float32)
    c[:, 0, 0] = [5, 0, 1, 5, 5, 5]          # best labels 1, 2
    c[:, 0, 1] = [5, 5, 5, 5, 1, 0]          # best labels 5, 4
    m = R.candidate_labels(c, 2, spread=0)
    np.testing.assert_array_equal(np.flatnonzero(m[:, 0, 0]), [1, 2])
    np.testing.assert_array_equal(np.flatnonzero(m[:, 0, 1]), [4, 5])
    m = R.candidate_labels(c, 2, spread=1)
    np.testing.assert_array_equal(np.flatnonzero(m[:, 0, 0]), [0, 1, 2, 3])
    np.testing.assert_array_equal(np.flatnonzero(m[:, 0, 1]), [3, 4, 5])
    assert R.candidate_labels(c, 9).all()
    for bad in (0, 1.5, True):
        with pytest.raises(InvalidInputError):
            R.candidate_labels(c, bad)
    with pytest.raises(InvalidInputError):
        R.graphcut(c, candidates=np.ones((6, 1, 3), bool))


def test_multiscale_graphcut_close_to_plain_on_a_piecewise_scene(rng):
    H, W, L = 64, 80, 24
    yy, xx = np.mgrid[0:H, 0:W]
    gt = np.full((H, W), 4)
    gt[(xx > 30) & (yy > 10)] = 15
    gt[(xx < 20) & (yy > 40)] = 9
    gt[(xx > 50) & (yy < 30)] = 21
    c = noisy_volume(gt, L, 0.5, rng)
    kw = dict(weight=0.5, truncation=4.0, max_cycles=3)
    f0, e0 = R.graphcut(c, return_energy=True, **kw)
    f2, e2 = R.graphcut_multiscale(c, levels=2, min_size=8, return_energy=True, **kw)
    assert e2 == pytest.approx(R.mrf_energy(f2, c, weight=0.5, truncation=4.0), rel=1e-12)
    assert e2 <= 1.02 * e0
    assert np.mean(f2 != gt) <= np.mean(f0 != gt) + 0.01
    assert np.mean(f2 != gt) < 0.05
    # levels=0, or a problem too small to halve, is plain alpha-expansion
    np.testing.assert_array_equal(R.graphcut_multiscale(c, levels=0, **kw), f0)
    np.testing.assert_array_equal(R.graphcut_multiscale(c, levels=3, min_size=64, **kw), f0)
    with pytest.raises(InvalidInputError):
        R.graphcut_multiscale(c, levels=-1)


# ----------------------------------------------------------------------------------------------
# occlusion handling
# ----------------------------------------------------------------------------------------------

def two_layer_scene(H=5, W=40):
    """Background d=2, foreground [15, 25) at d=6 in the left view; maps for both views."""
    dl = np.full((H, W), 2.0)
    dl[:, 15:25] = 6.0
    dr = np.full((H, W), 2.0)
    dr[:, 9:19] = 6.0                  # the foreground seen from the right: x - 6
    occluded = np.zeros((H, W), bool)
    occluded[:, 11:15] = True          # background pixels hidden behind the foreground
    occluded[:, :2] = True             # x - d < 0: outside the right image
    return dl, dr, occluded


def test_left_right_check_and_background_fill():
    dl, dr, occluded = two_layer_scene()
    valid = R.left_right_check(dl, dr, tol=1.0)
    np.testing.assert_array_equal(valid, ~occluded)
    corrupted = np.where(occluded, 9.0, dl)     # garbage where occluded
    filled = R.fill_occlusions(corrupted, valid)
    np.testing.assert_array_equal(filled, dl)   # background side (d = 2) wins
    # tolerance: a 0.4 px error (same right pixel after rounding) passes at tol 1, not at 0.3
    noisy = dl + 0.4 * (~occluded)
    assert np.array_equal(R.left_right_check(noisy, dr, tol=1.0), ~occluded)
    assert not R.left_right_check(noisy, dr, tol=0.3).any()
    # NaN disparities are never valid
    dl_nan = dl.copy()
    dl_nan[0, 20] = np.nan
    assert not R.left_right_check(dl_nan, dr)[0, 20]


def test_fill_occlusions_edge_cases():
    d = np.array([[5.0, 1.0, 7.0, 3.0], [4.0, 4.0, 4.0, 4.0]])
    valid = np.array([[False, True, False, True], [False, False, False, False]])
    out = R.fill_occlusions(d, valid)
    np.testing.assert_array_equal(out, [[1.0, 1.0, 1.0, 3.0], [1.0, 1.0, 1.0, 1.0]])
    with pytest.raises(InvalidInputError):
        R.fill_occlusions(d, np.zeros_like(valid))


def test_right_cost_from_left_shifts_and_fills(rng):
    L, H, W = 5, 3, 9
    lv = np.arange(-1, 4).astype(float)            # d = -1..3
    c = rng.random((L, H, W)).astype(np.float32)
    cr = R.right_cost_from_left(c, labels=lv)
    valid = np.zeros((L, H, W), bool)
    for l, d in enumerate(lv.astype(int)):
        for x in range(W):
            if 0 <= x + d < W:
                assert cr[l, :, x].tolist() == c[l, :, x + d].tolist()
                valid[l, :, x] = True
    worst = np.where(valid, cr, -np.inf).max(axis=0)
    np.testing.assert_array_equal(cr[~valid], np.broadcast_to(worst, cr.shape)[~valid])
    # sub-pixel labels interpolate linearly
    cr_half = R.right_cost_from_left(c[:2], labels=np.array([0.0, 0.5]))
    np.testing.assert_allclose(cr_half[1, :, :-1], 0.5 * (c[1, :, :-1] + c[1, :, 1:]), rtol=1e-6)
    # a right pixel no label reaches gets the worst cost of the whole volume
    far = R.right_cost_from_left(c[:2], labels=np.array([W, W + 1.5]))
    assert (far == c[:2].max()).all()


def test_right_map_from_same_volume_passes_lr_check():
    # an absolute-difference cost from a synthetic pair whose true disparity is d everywhere
    rng = np.random.default_rng(7)
    H, W, d = 6, 30, 3
    full = rng.random((H, W + d))
    left, right = full[:, :W], full[:, d:W + d]   # Middlebury: left(x) == right(x - d)
    L = 6
    c = np.empty((L, H, W), np.float32)
    for k in range(L):
        shifted = np.full((H, W), np.nan)
        shifted[:, k:] = right[:, :W - k]
        c[k] = np.abs(left - shifted)
    c = R.fill_invalid(c)
    dl = R.wta(c).astype(float)
    dr = R.wta(R.right_cost_from_left(c)).astype(float)
    valid = R.left_right_check(dl, dr)
    assert np.all(dl[:, d:] == d) and np.all(dr[:, : W - d] == d)
    assert valid[:, d:].all()


# ----------------------------------------------------------------------------------------------
# sub-pixel and confidence
# ----------------------------------------------------------------------------------------------

def test_subpixel_refine_recovers_parabola_vertex():
    lv = np.arange(-3.0, 3.01, 0.5)               # 13 labels, step 0.5
    H, W = 4, 5
    true = np.linspace(-2.2, 2.3, H * W).reshape(H, W)
    c = (2.0 * (lv[:, None, None] - true[None]) ** 2 + 1.0).astype(np.float64)
    f = R.wta(c)
    out = R.subpixel_refine(c.astype(np.float32), f, lv)
    np.testing.assert_allclose(out, true, atol=2e-4)
    # at the ends of the label range: no refinement
    c_end = (lv[:, None, None] + 3.4) ** 2 * np.ones((1, 1, 1))
    f_end = R.wta(c_end)
    assert f_end[0, 0] == 0
    assert R.subpixel_refine(c_end.astype(np.float32), f_end, lv)[0, 0] == -3.0
    with pytest.raises(InvalidInputError, match="evenly"):
        R.subpixel_refine(c.astype(np.float32), f, lv ** 3)


def test_confidence_range_and_ordering():
    L = 10
    lab = np.arange(L)[:, None, None]
    sharp = np.minimum(np.abs(lab - 4), 1.0) * np.ones((1, 1, 1))
    flat = np.zeros((L, 1, 1))
    ambiguous = sharp.copy()
    ambiguous[8] = 0.0
    c = np.concatenate([sharp, flat, ambiguous], axis=2).astype(np.float32)
    conf = R.confidence(c)
    assert conf.shape == (1, 3) and conf.min() >= 0 and conf.max() <= 1
    assert conf[0, 0] == pytest.approx(1.0)
    assert conf[0, 1] == 0.0 and conf[0, 2] == 0.0


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), floor=st.sampled_from([0.0, 0.05, 0.1, 0.5, 0.99]))
def test_confidence_floor_lifts_the_margin_and_keeps_flat_curves_at_zero(seed, floor):
    rng = np.random.default_rng(seed)
    c = rng.random((7, 4, 5)).astype(np.float32)
    c[:, 0, 0] = 0.3  # a flat curve: no data
    f = rng.integers(0, 7, (4, 5))
    margin = R.confidence(c, f)
    out = R.confidence(c, f, floor=floor)
    expected = floor + (1 - floor) * margin.astype(np.float64)
    expected[0, 0] = 0.0
    np.testing.assert_allclose(out, expected, atol=1e-6)
    assert out.dtype == np.float32 and out[0, 0] == 0


@pytest.mark.parametrize("bad", [-0.1, 1.0, float("nan"), None])
def test_confidence_floor_and_its_params_refuse_bad_values(bad):
    c = np.random.default_rng(0).random((5, 3, 3)).astype(np.float32)
    with pytest.raises(InvalidInputError, match="floor"):
        R.confidence(c, floor=bad)
    with pytest.raises(InvalidInputError, match="floor"):
        R.ConfidenceParams(floor=bad)
    for kw in (dict(edge_px=-1.0), dict(edge_jump=0.0), dict(edge_px=float("inf"))):
        with pytest.raises(InvalidInputError, match="confidence edge_"):
            R.ConfidenceParams(**kw)


# ----------------------------------------------------------------------------------------------
# guided weighted median
# ----------------------------------------------------------------------------------------------

def test_weighted_median_numba_matches_numpy(rng):
    d = rng.random((23, 31)) * 4.0
    g = 0.5 + rng.random((23, 31))
    for r, s in ((1, 0.2), (3, 0.05), (4, 1.0)):
        np.testing.assert_array_equal(R.weighted_median(d, g, r, s, impl="numba"),
                                      R.weighted_median(d, g, r, s, impl="numpy"))
    np.testing.assert_array_equal(R.weighted_median(d, g, 0), d.astype(np.float32))
    # a mask filters only its pixels, with the same medians there, in both implementations
    mask = rng.random(d.shape) < 0.3
    full = R.weighted_median(d, g, 2, 0.1)
    for impl in ("numba", "numpy"):
        part = R.weighted_median(d, g, 2, 0.1, impl=impl, mask=mask)
        np.testing.assert_array_equal(part[mask], full[mask])
        np.testing.assert_array_equal(part[~mask], d.astype(np.float32)[~mask])
    np.testing.assert_array_equal(R.weighted_median(d, g, 2, 0.1, mask=np.ones(d.shape, bool)),
                                  full)
    with pytest.raises(InvalidInputError, match="mask has shape"):
        R.weighted_median(d, g, 2, mask=np.ones((2, 2), bool))
    with pytest.raises(InvalidInputError):
        R.weighted_median(d, g[:, :5], 2)
    with pytest.raises(InvalidInputError):
        R.weighted_median(d, g, 2, sigma=0.0)
    with pytest.raises(InvalidInputError):
        R.weighted_median(np.where(d > 3, np.nan, d), g, 2)


def test_weighted_median_snaps_fattened_edges_and_keeps_ramps():
    H, W = 20, 40
    xx = np.broadcast_to(np.arange(W, dtype=float), (H, W))
    guide = np.where(xx >= 20, 1.0, 0.3)             # image edge between x = 19 and 20
    disp = np.where(xx >= 18, 5.0, 1.0)              # foreground fattened by 2 px
    out = R.weighted_median(disp, guide, 4, 0.05)
    np.testing.assert_array_equal(out[:, :20], 1.0)
    np.testing.assert_array_equal(out[:, 20:], 5.0)
    # beyond about radius / 2 the wrong side holds the majority and the median cannot help
    out = R.weighted_median(np.where(xx >= 17, 5.0, 1.0), guide, 4, 0.05)
    assert (out[:, 19] == 5.0).all()
    ramp = 0.1 * xx + 0.05 * np.arange(H)[:, None]   # a slanted plane, textured guide
    tex = 1.0 + 0.3 * np.sin(xx) * np.cos(np.arange(H)[:, None])
    out = R.weighted_median(ramp, np.ones((H, W)), 3, 0.05)
    np.testing.assert_allclose(out[3:-3, 3:-3], ramp[3:-3, 3:-3], atol=1e-6)
    assert np.isfinite(R.weighted_median(ramp, tex, 3, 0.05)).all()


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), width=st.sampled_from([0.5, 2.0, 4.0]),
       jump=st.sampled_from([0.25, 0.5, 1.5]))
def test_edge_confidence_is_the_distance_to_the_depth_edges(seed, width, jump):
    rng = np.random.default_rng(seed)
    d = np.repeat(np.repeat(rng.integers(0, 3, (4, 5)).astype(float), 4, 0), 3, 1)
    d += rng.random(d.shape) * 0.1  # noise below every jump
    H, W = d.shape
    edge = np.zeros((H, W), bool)
    for y, x in itertools.product(range(H), range(W)):
        win = d[max(y - 1, 0):y + 2, max(x - 1, 0):x + 2]
        edge[y, x] = win.max() - win.min() > jump
    ys, xs = np.nonzero(edge)
    out = R.edge_confidence(d, width=width, jump=jump)
    assert out.dtype == np.float32 and out.shape == d.shape
    for y, x in itertools.product(range(H), range(W)):
        dist = np.hypot(ys - y, xs - x).min() if ys.size else np.inf
        assert out[y, x] == pytest.approx(min(1.0, dist / width), abs=1e-6)


def test_edge_confidence_options_and_unknowns():
    d = np.zeros((5, 6))
    d[:, 3:] = 1.0
    np.testing.assert_array_equal(R.edge_confidence(d, width=0), np.ones((5, 6), np.float32))
    np.testing.assert_array_equal(R.edge_confidence(np.zeros((5, 6))), np.ones((5, 6)))
    assert (R.edge_confidence(d, jump=2.0) == 1).all()  # the step is below the jump
    d2 = np.zeros((5, 6))
    d2[2, 2] = np.nan  # unknown: an edge
    out = R.edge_confidence(d2, width=2.0)
    assert out[2, 2] == 0 and out[2, 3] == pytest.approx(0.5) and out[2, 4] == 1
    for bad in (dict(width=-1), dict(width=np.inf), dict(jump=0), dict(jump="a")):
        with pytest.raises(InvalidInputError):
            R.edge_confidence(d, **bad)
    with pytest.raises(InvalidInputError, match="H, W"):
        R.edge_confidence(np.zeros(5))
