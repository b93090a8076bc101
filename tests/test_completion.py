"""Plenoptic cube completion (SPEC §7)."""

from __future__ import annotations

import numpy as np
import pytest

from hyperlf import completion as cp
from hyperlf import metrics, synthesis
from hyperlf.errors import InvalidInputError
from hyperlf.formats.hdf5 import read_cube_h5

# Fronto-parallel planes at integer disparities with smooth ("noise") textures: every warp is an
# exact integer shift, so registered entries must equal the ground truth.
PLANES = [
    {"kind": "plane", "disparity": -1.0, "texture": {"pattern": "noise", "period": 0.08}},
    {"kind": "plane", "disparity": 2.0, "rect": [0.3, 0.3, 0.6, 0.7],
     "texture": {"pattern": "noise", "period": 0.05}},
]


@pytest.fixture(scope="module")
def planes_lf():
    return synthesis.procedural_scene(seed=1, rows=3, cols=4, height=48, width=64,
                                      objects=PLANES)


@pytest.fixture(scope="module")
def planes_result(planes_lf):
    return cp.complete(planes_lf, planes_lf.reference_gt_disparity)


def test_band_order_and_shapes(planes_lf, planes_result):
    R, C, H, W = planes_lf.views.shape
    res = planes_result
    assert res.cube.shape == (R, C, R * C, H, W) and res.cube.dtype == np.float32
    assert res.mask.shape == res.cube.shape
    assert np.all(np.diff(res.wavelengths) > 0)
    np.testing.assert_allclose(res.wavelengths, planes_lf.cube_wavelengths)
    # each view's own band is its own image, valid everywhere
    for r in range(R):
        for c in range(C):
            b = res.band_index[r, c]
            assert res.mask[r, c, b].all()
            np.testing.assert_array_equal(res.cube[r, c, b], planes_lf.views[r, c])
    assert np.isfinite(res.cube).all()


def test_propagate_disparity_matches_truth(planes_lf):
    init = cp.propagate_disparity(planes_lf, planes_lf.reference_gt_disparity)
    ok = np.isfinite(init)
    assert ok[planes_lf.reference].all()
    assert 0.8 < ok.mean() < 1.0  # holes at disocclusions and borders
    np.testing.assert_allclose(init[ok], planes_lf.gt_disparity[ok])


def test_planes_complete_near_perfect(planes_lf, planes_result):
    res = planes_result
    gt = planes_lf.gt_cube
    # disparities of every view recovered (holes filled from the background side)
    err = np.abs(res.disparities - planes_lf.gt_disparity)
    assert np.mean(err > 0.25) < 0.01
    # measured: PSNR on valid entries > 60 dB, completed ~93 %; bounds with margin
    assert metrics.psnr(res.cube, gt, mask=res.mask) > 40.0
    assert res.stats["completed_pct"] > 85.0
    assert metrics.psnr(res.cube, gt) > 28.0  # all entries, spectral fill


def test_occlusion_check_rejects_occluded_samples():
    # A bar at disparity 2 in front of a background at 0; 1 x 3 views, reference in the middle.
    objs = [{"kind": "plane", "disparity": 0.0, "texture": {"pattern": "noise", "period": 0.1}},
            {"kind": "plane", "disparity": 2.0, "rect": [0.45, 0.0, 0.55, 1.0],
             "texture": {"pattern": "noise", "period": 0.05, "chips": [5, 900]}}]
    lf = synthesis.procedural_scene(seed=3, rows=1, cols=3, height=24, width=60, objects=objs)
    gd = lf.gt_disparity
    _, bidx = cp.band_order(lf)
    v, u = (0, 0), (0, 2)  # register the right view's band into the left view
    cube, mask = cp.register_view(lf, gd, v, bidx, occlusion_tol=0.5)
    b = bidx[u]
    # pixels of v (background) whose point is hidden behind the bar in u
    H, W = lf.image_shape
    xx = np.arange(W)
    ox = lf.positions[u][0] - lf.positions[v][0]
    q = np.rint(xx[None, :] - gd[v] * ox).astype(int)
    inside = (q >= 0) & (q < W)
    du = np.take_along_axis(gd[u], np.clip(q, 0, W - 1), axis=1)
    occluded = inside & (du > gd[v] + 0.5)
    assert occluded.sum() >= H * 3
    assert not mask[b][occluded].any()           # rejected, not copied
    assert np.isnan(cube[b][occluded]).all()
    # visible entries are exact
    vis = mask[b]
    assert vis.mean() > 0.6
    np.testing.assert_allclose(cube[b][vis], lf.gt_cube[v][b][vis], atol=1e-5)
    # without the check the occluder's values are copied and wrong
    cube_n, mask_n = cp.register_view(lf, gd, v, bidx, occlusion_tol=None)
    assert mask_n[b][occluded].all()
    assert np.abs(cube_n[b][occluded] - lf.gt_cube[v][b][occluded]).mean() > 0.01
    # full pipeline: the occluded entries stay unregistered in the output mask ...
    res = cp.complete(lf, gd[lf.reference])
    assert not res.mask[v][b][occluded].any()
    # ... and are inferred from the background around them, far closer to the truth than the
    # occluder's values the naive method copies (measured 0.042 vs 0.169 mean |error|) or
    # the spectral interpolation without inference (0.203)
    inf = res.inferred
    assert inf[v][b][occluded].mean() > 0.9 and not (inf & res.mask).any()
    naive = cp.naive_completion(lf, gd[lf.reference])
    e_inf = np.abs(res.cube - lf.gt_cube)[inf].mean()
    assert e_inf < 0.5 * np.abs(naive.cube - lf.gt_cube)[inf].mean()
    plain = cp.complete(lf, gd[lf.reference], infer=False)
    assert plain.inferred is None
    assert e_inf < 0.5 * np.abs(plain.cube - lf.gt_cube)[inf].mean()
    assert res.stats["completed_pct"] > naive.stats["completed_pct"]
    assert res.stats["completed_pct"] == pytest.approx(
        res.stats["registered_pct"] + res.stats["inferred_pct"])


def test_infer_missing_numba_matches_numpy_and_respects_surfaces(rng):
    B, H, W = 4, 20, 30
    cube = rng.random((B, H, W)).astype(np.float32)
    mask = rng.random((B, H, W)) > 0.35
    disp = np.where(np.arange(W)[None, :] > 14, 3.0, 1.0) * np.ones((H, 1))
    disp[0, 0] = np.nan
    guide = 0.5 + rng.random((H, W))
    a, ia = cp.infer_missing(cube, mask, disp, guide, impl="numpy")
    b, ib = cp.infer_missing(cube, mask, disp, guide, impl="numba")
    np.testing.assert_array_equal(ia, ib)
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
    np.testing.assert_array_equal(a[mask], cube[mask])        # registered entries untouched
    assert not (ia & mask).any() and not ia[:, 0, 0].any()     # NaN disparity: no inference
    # two surfaces of constant values: a hole on the far one takes the far one's value, not
    # the near one's, even right at the boundary
    c2 = np.where(disp > 2, 0.9, 0.3)[None].astype(np.float32).repeat(2, 0)
    m2 = np.ones(c2.shape, bool)
    m2[:, 5:15, 10:15] = False                                  # far-side hole at the edge
    out, inf = cp.infer_missing(c2, m2, np.nan_to_num(disp, nan=1.0), np.ones((H, W)))
    assert inf[:, 5:15, 10:15].all()
    np.testing.assert_allclose(out[:, 5:15, 10:15], 0.3, atol=1e-3)
    with pytest.raises(InvalidInputError):
        cp.infer_missing(cube, mask, disp, guide, radius=0)
    with pytest.raises(InvalidInputError):
        cp.infer_missing(cube, mask[:2], disp, guide)
    with pytest.raises(InvalidInputError):
        cp._check_infer({"radios": 3})


def test_ours_beats_naive_with_occlusions(planes_lf, planes_result):
    gt = planes_lf.gt_cube
    ours = planes_result
    naive = cp.naive_completion(planes_lf, planes_lf.reference_gt_disparity)
    p_ours = metrics.psnr(ours.cube, gt, mask=ours.mask)
    p_naive = metrics.psnr(naive.cube, gt, mask=naive.mask)
    assert p_ours >= p_naive + 10.0
    assert metrics.psnr(ours.cube, gt) >= metrics.psnr(naive.cube, gt)
    # % completed correctly (valid and right); the naive method marks occluded copies valid,
    # so its raw % is not a fair count (see the benchmark)
    ok_ours = np.mean(ours.mask & (np.abs(ours.cube - gt) < 0.02))
    ok_naive = np.mean(naive.mask & (np.abs(naive.cube - gt) < 0.02))
    assert ok_ours >= ok_naive
    assert metrics.sam(ours.cube, gt, band_axis=2) <= metrics.sam(naive.cube, gt, band_axis=2)


def test_streaming_equals_memory(planes_lf, planes_result, tmp_path):
    path = tmp_path / "cube.h5"
    res = cp.complete(planes_lf, planes_lf.reference_gt_disparity, out_path=path)
    assert res.cube is None and res.path == path
    cube, wl, pmask = read_cube_h5(path)
    np.testing.assert_array_equal(cube, planes_result.cube)
    np.testing.assert_allclose(wl, planes_result.wavelengths)
    band_mask = cp.read_band_mask(path)
    np.testing.assert_array_equal(band_mask, planes_result.mask)
    np.testing.assert_array_equal(cp.read_band_mask(path, name="inferred_mask"),
                                  planes_result.inferred)
    np.testing.assert_array_equal(cp.read_band_mask(path, (0, 1), name="inferred_mask"),
                                  planes_result.inferred[0, 1])
    # the pixels a renderer uses: every band registered or inferred
    np.testing.assert_array_equal(pmask, (planes_result.mask | planes_result.inferred).all(axis=2))
    assert pmask.sum() > planes_result.mask.all(axis=2).sum()
    assert res.stats["completed_pct"] == pytest.approx(planes_result.stats["completed_pct"])
    assert not list(tmp_path.glob(".*scratch*"))  # scratch file removed


def test_unknown_wavelengths_complete_the_cameras_in_raster_order(planes_lf, planes_result,
                                                                  tmp_path):
    """Without wavelengths the bands are the views in raster order (the same order as the
    raster filter layout's sorted wavelengths here), every registered or inferred entry is the
    one the known-wavelength run gives, entries neither registered nor inferred stay 0
    instead of the spectral fill, and colour rendering of the streamed cube is refused by name."""
    from hyperlf import render
    from hyperlf.formats.hdf5 import open_cube_h5

    lf = planes_lf.replace(wavelengths=None)
    res = cp.complete(lf, planes_lf.reference_gt_disparity)
    R, C = lf.grid_shape
    assert np.isnan(res.wavelengths).all() and res.wavelengths.shape == (R * C,)
    np.testing.assert_array_equal(res.band_index, np.arange(R * C).reshape(R, C))
    np.testing.assert_array_equal(res.band_index, planes_result.band_index)
    np.testing.assert_array_equal(res.mask, planes_result.mask)
    np.testing.assert_array_equal(res.inferred, planes_result.inferred)
    np.testing.assert_array_equal(res.cube, planes_result.cube)  # inference reached everything
    assert res.stats["config"]["fill"] == "zero"
    known = cp.complete(planes_lf, planes_lf.reference_gt_disparity, infer=False)
    unknown = cp.complete(lf, planes_lf.reference_gt_disparity, infer=False)
    np.testing.assert_array_equal(unknown.mask, known.mask)
    assert not known.mask.all()
    np.testing.assert_array_equal(unknown.cube[known.mask], known.cube[known.mask])
    assert not unknown.cube[~known.mask].any() and known.cube[~known.mask].all()
    with pytest.raises(InvalidInputError, match="ingest --wavelengths"):
        cp.complete(lf, planes_lf.reference_gt_disparity, fill="spectral")
    cp.complete(lf, planes_lf.reference_gt_disparity, out_path=tmp_path / "u.h5")
    with open_cube_h5(tmp_path / "u.h5") as cf:
        assert np.isnan(cf.wavelengths).all()
        with pytest.raises(InvalidInputError, match="unknown"):
            render.emulate_camera(cf, views=(1, 1))


def test_band_order_follows_wavelengths_not_positions(planes_lf):
    wl = planes_lf.wavelengths[::-1, ::-1].copy()  # the last view has the shortest band
    order, index = cp.band_order(planes_lf.replace(wavelengths=wl))
    np.testing.assert_array_equal(order, np.sort(wl.ravel()))
    np.testing.assert_array_equal(index, np.arange(wl.size)[::-1].reshape(wl.shape))
    order, index = cp.band_order(planes_lf.replace(wavelengths=None))
    np.testing.assert_array_equal(index, np.arange(wl.size).reshape(wl.shape))


def test_fill_missing_spectral():
    wl = np.array([400.0, 410.0, 420.0, 430.0])
    cube = np.array([1.0, 0.0, 3.0, 0.0], dtype=np.float32)[:, None, None]
    mask = np.array([True, False, True, False])[:, None, None]
    out = cp.fill_missing(cube, mask, wl)
    np.testing.assert_allclose(out[:, 0, 0], [1.0, 2.0, 3.0, 3.0])
    np.testing.assert_allclose(cp.fill_missing(cube, mask, wl, "zero")[:, 0, 0], [1, 0, 3, 0])
    unknown = np.full(4, np.nan)
    np.testing.assert_allclose(cp.fill_missing(cube, mask, unknown, "zero")[:, 0, 0],
                               [1, 0, 3, 0])
    with pytest.raises(InvalidInputError, match="unknown"):
        cp.fill_missing(cube, mask, unknown)


def test_fill_missing_by_row_blocks_is_the_whole_fill(rng, monkeypatch):
    """The spectral fill runs a few rows at a time (memory); blocks of one row and of three
    give the very bits of one block, and every pixel is its own 1-D interpolation."""
    wl = np.sort(rng.uniform(400, 700, 7))
    cube = rng.random((7, 10, 6)).astype(np.float32)
    mask = rng.random((7, 10, 6)) < 0.5
    mask[:, 0, 0] = False  # a pixel with no valid band: 0
    whole = cp.fill_missing(cube, mask, wl, impl="numpy")
    for rows in (1, 3):
        monkeypatch.setattr(cp, "FILL_BLOCK_ENTRIES", 7 * 6 * rows)
        np.testing.assert_array_equal(cp.fill_missing(cube, mask, wl, impl="numpy"), whole)
    np.testing.assert_array_equal(whole[:, 0, 0], 0.0)
    for y, x in ((3, 2), (7, 5)):
        ok = mask[:, y, x]
        want = np.interp(wl, wl[ok], cube[ok, y, x]) if ok.any() else np.zeros(7)
        np.testing.assert_allclose(whole[:, y, x], want, rtol=1e-6)


@pytest.mark.parametrize("case", ["random", "duplicate wavelengths", "one band", "none valid",
                                  "all valid", "wide range"])
def test_fill_missing_numba_is_the_numpy_reference_bit_for_bit(rng, case):
    B = 1 if case == "one band" else 9
    wl = np.sort(rng.uniform(400, 700, B))
    if case == "duplicate wavelengths":
        wl[3] = wl[4] = wl[5]
    cube = rng.random((B, 13, 11)).astype(np.float32)
    if case == "wide range":
        cube = (cube * 10.0 ** rng.integers(-30, 30, cube.shape)).astype(np.float32)
    mask = rng.random((B, 13, 11)) < {"none valid": 0.0, "all valid": 1.0}.get(case, 0.4)
    mask[:, 0, 0] = False
    mask[:, 1, 1] = [b == B // 2 for b in range(B)]  # one valid band: copied to every band
    ref = cp.fill_missing(cube, mask, wl, impl="numpy")
    got = cp.fill_missing(cube, mask, wl, impl="numba")
    np.testing.assert_array_equal(got, ref)
    assert got.dtype == np.float32 and np.array_equal(cp.fill_missing(cube, mask, wl), got)
    np.testing.assert_array_equal(got[mask], cube[mask])
    with pytest.raises(InvalidInputError, match="impl"):
        cp.fill_missing(cube, mask, wl, impl="fortran")


def test_background_fill_and_wls():
    d = np.full((5, 9), 1.0, dtype=np.float32)
    d[:, 5:] = 3.0
    d[:, 3:5] = np.nan
    f = cp.background_fill(d)
    assert np.all(f[:, 3:5] == 1.0)
    img = np.ones((5, 9))
    z = np.where(np.isfinite(d), d, np.nan)
    out = cp.refine_disparity(img, z, np.ones_like(img), lam=0.1)
    assert np.isfinite(out).all()
    assert np.abs(out[:, :3] - 1).max() < 0.2 and np.abs(out[:, 5:] - 3).max() < 0.2


def test_wls_iterations_match_the_direct_solve(rng, monkeypatch):
    """Stage 3's WLS: the conjugate gradients give the direct solve's map (to 1e-5 px) where
    the background fill gives every hole a confidence, without the direct solve; when they do
    not converge in time, the direct solve gives the answer."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    H, W = 40, 56
    img = np.cumsum(rng.random((H, W)), axis=1)  # edges of every strength
    z = np.where(rng.random((H, W)) < 0.7, rng.random((H, W)) * 8, np.nan)
    z[10:30, 20:45] = np.nan  # a wide hole, given the fill's value and confidence
    c = np.where(np.isfinite(z), 1.0, 0.5)
    z = np.where(np.isfinite(z), z, 4.0)
    direct = spla.spsolve
    monkeypatch.setattr(cp, "_solve_spd", lambda A, b: direct(sp.csc_matrix(A), b))
    want = cp.refine_disparity(img, z, c, lam=1.0)
    monkeypatch.undo()
    used = []
    monkeypatch.setattr(spla, "spsolve", lambda *a, **k: used.append(1) or direct(*a, **k))
    np.testing.assert_allclose(cp.refine_disparity(img, z, c, lam=1.0), want, atol=1e-5)
    assert not used
    A = sp.random(60, 60, density=0.1, random_state=3)
    A = A @ A.T + sp.identity(60) * 1e-3  # symmetric positive definite, ill-conditioned
    b = rng.random(60)
    x = cp._solve_spd(A, b, maxiter=3)
    assert used and np.allclose(A @ x, b, atol=1e-8)


def test_bad_inputs(planes_lf):
    with pytest.raises(InvalidInputError):
        cp.complete(planes_lf, np.zeros((3, 3), np.float32))
    with pytest.raises(InvalidInputError):
        cp.complete(planes_lf, planes_lf.reference_gt_disparity, fill="nope")
    with pytest.raises(InvalidInputError):
        cp.complete("not a light field", None)


def test_register_view_on_threads_is_the_serial_result(planes_lf, monkeypatch):
    """The source views are warped on a thread pool, each into its own band: the same cube
    and mask as one thread, bit for bit."""
    lf = planes_lf
    _, bidx = cp.band_order(lf)
    out = {}
    for n in ("1", "3"):
        monkeypatch.setenv("HYPERLF_THREADS", n)
        out[n] = cp.register_view(lf, lf.gt_disparity, (1, 2), bidx, occlusion_tol=0.5)
    np.testing.assert_array_equal(out["1"][0], out["3"][0])
    np.testing.assert_array_equal(out["1"][1], out["3"][1])
    assert out["3"][1].any() and not out["3"][1].all()


def test_two_views_with_one_wavelength_are_named():
    from hyperlf import LightField

    wl = np.array([[500.0, 555.0, 600.0], [650.0, 555.0, 700.0]])
    lf = LightField(np.ones((2, 3, 8, 8), np.float32), wavelengths=wl)
    with pytest.raises(InvalidInputError, match=r"views \(0,1\), \(1,1\) all have 555 nm"):
        cp.band_order(lf)
    assert "6 filters (5 distinct)" in lf.describe()
