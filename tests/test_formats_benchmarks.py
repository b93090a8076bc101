"""HCI and Middlebury readers (synthetic folders always; real data when HYPERLF_DATA is set),
and the load/save dispatch."""

from __future__ import annotations

import os

import numpy as np
import pytest

import hyperlf
from hyperlf.errors import DataNotFoundError, FormatError, InvalidInputError
from hyperlf.formats import (StereoPair, is_hci_scene, load_lightfield, read_hci_scene,
                             read_middlebury, read_pfm, save_lightfield, write_image,
                             write_middlebury, write_pfm)

from conftest import benchmark_script, require_dataset


# ----------------------------------------------------------------------------- HCI, synthetic
def fake_hci(folder, rng, n=3, H=6, W=7, cfg=True):
    folder.mkdir()
    for i in range(n * n):
        img = np.full((H, W, 3), i, np.uint8)
        img[0, 0] = (1, 2, 3)
        write_image(folder / f"input_Cam{i:03d}.png", img)
    gt = rng.normal(size=(H, W)).astype(np.float32)
    write_pfm(folder / "gt_disp_lowres.pfm", gt)
    if cfg:
        (folder / "parameters.cfg").write_text(
            "[intrinsics]\nfocal_length_mm = 100\n\n[extrinsics]\n"
            f"num_cams_x = {n}\nnum_cams_y = {n}\nbaseline_mm = 90.0\n\n"
            "[meta]\ndisp_min = -1.5\ndisp_max = 1.5\nname = fake\n"
        )
    return gt


def test_hci_synthetic(tmp_path, rng):
    gt = fake_hci(tmp_path / "s", rng)
    assert is_hci_scene(tmp_path / "s") and not is_hci_scene(tmp_path)
    lf = read_hci_scene(tmp_path / "s")
    assert lf.views.shape == (3, 3, 6, 7, 3) and lf.reference == (1, 1)
    assert lf.views[1, 2, 3, 3, 0] == pytest.approx(5 / 255)  # Cam005 -> (1, 2)
    np.testing.assert_allclose(lf.views[0, 0, 0, 0], np.array([1, 2, 3]) / 255, rtol=1e-6)  # RGB order
    np.testing.assert_array_equal(lf.gt_disparity, gt)
    assert lf.disparity_range == (-2.5, 2.5)  # the cfg's -1.5 / 1.5, widened like the truth's
    assert lf.metadata["encoding"] == "srgb"
    assert lf.metadata["hci_parameters"]["extrinsics"]["baseline_mm"] == 90.0
    sub = read_hci_scene(tmp_path / "s", rows=[0, 1], cols=[1, 2])
    assert sub.reference == (1, 0) and sub.positions[1, 0].tolist() == [1.0, 1.0]
    assert sub.gt_disparity is not None
    off = read_hci_scene(tmp_path / "s", rows=[0], cols=[0, 1])
    assert off.gt_disparity is None and off.grid_shape == (1, 2)
    with pytest.raises(InvalidInputError):
        read_hci_scene(tmp_path / "s", rows=[5])
    assert load_lightfield(tmp_path / "s").views.shape == (3, 3, 6, 7, 3)


def test_hci_cfg_range_widened_like_the_ground_truths(tmp_path, rng):
    """The benchmark writes disp_min / disp_max as the scene's extremes rounded to 0.1 px: the
    range read from them is widened as the truth's is (whole pixels, then the margin), so that
    no surface sits on an end label."""
    gt = fake_hci(tmp_path / "s", rng, cfg=False)
    derived = read_hci_scene(tmp_path / "s").disparity_range
    lo, hi = round(float(gt.min()), 1), round(float(gt.max()), 1)
    (tmp_path / "s" / "parameters.cfg").write_text(
        f"[meta]\ndisp_min = {lo}\ndisp_max = {hi}\n")
    rmin, rmax = read_hci_scene(tmp_path / "s").disparity_range
    assert (rmin, rmax) == (np.floor(lo) - 0.5, np.ceil(hi) + 0.5)
    assert rmin <= gt.min() - 0.45 and rmax >= gt.max() + 0.45  # 0.05 px of rounding at most
    assert read_hci_scene(tmp_path / "s", disparity_margin=0).disparity_range == (
        np.floor(lo), np.ceil(hi))
    (tmp_path / "s" / "parameters.cfg").write_text("[meta]\ndisp_min = 2\ndisp_max = inf\n")
    assert read_hci_scene(tmp_path / "s").disparity_range == derived  # not finite: the truth's


def test_hci_without_cfg_and_missing_views(tmp_path, rng):
    gt = fake_hci(tmp_path / "s", rng, cfg=False)
    lf = read_hci_scene(tmp_path / "s")
    assert lf.grid_shape == (3, 3)  # square number of files
    lo, hi = lf.disparity_range
    assert lo == np.floor(gt.min()) - 0.5 and hi == np.ceil(gt.max()) + 0.5
    os.remove(tmp_path / "s" / "input_Cam004.png")
    os.remove(tmp_path / "s" / "input_Cam007.png")
    with pytest.raises(DataNotFoundError, match="input_Cam004.png, input_Cam007.png"):
        read_hci_scene(tmp_path / "s", grid=(3, 3))
    assert read_hci_scene(tmp_path / "s", grid=(3, 3), rows=[0], cols=[0, 1, 2]).grid_shape == (1, 3)
    (tmp_path / "s" / "input_Cam001.png").write_bytes(b"junk")
    with pytest.raises(FormatError, match="input_Cam001"):
        read_hci_scene(tmp_path / "s", grid=(3, 3), rows=[0])
    (tmp_path / "s" / "parameters.cfg").write_text("no section header\n")
    with pytest.raises(FormatError, match="INI"):
        read_hci_scene(tmp_path / "s")


# ----------------------------------------------------------------------------- HCI, real
@pytest.fixture(scope="module")
def antinous():
    return require_dataset("antinous")


def test_antinous_full(antinous):
    lf = read_hci_scene(antinous)
    assert lf.views.shape == (9, 9, 512, 512, 3) and lf.views.dtype == np.float32
    assert lf.gt_disparity.shape == (512, 512) and lf.reference == (4, 4)
    assert 0 <= lf.views.min() and lf.views.max() <= 1
    assert lf.disparity_range[0] < np.nanmin(lf.gt_disparity) < np.nanmax(lf.gt_disparity) < lf.disparity_range[1]
    assert lf.metadata["encoding"] == "srgb"


def test_antinous_subgrid_and_sign(antinous):
    sub = read_hci_scene(antinous, rows=range(2, 7), cols=range(2, 8))
    assert sub.views.shape[:2] == (5, 6) and sub.reference == (2, 2)
    assert sub.positions[2, 2].tolist() == [4.0, 4.0]  # Cam040
    from hyperlf.formats import read_image

    np.testing.assert_array_equal(sub.reference_view, read_image(antinous / "input_Cam040.png"))
    np.testing.assert_array_equal(sub.gt_disparity, read_pfm(antinous / "gt_disp_lowres.pfm"))
    # SPEC §1 sign: warping the right neighbour with +gt reproduces the reference better than -gt
    from hyperlf.warp import warp_to_reference

    ref, view = sub.reference_view[..., 1], sub.views[2, 3, ..., 1]
    errs = []
    for s in (1, -1):
        w, v = warp_to_reference(view, s * sub.gt_disparity, tuple(sub.offsets[2, 3]))
        errs.append(np.mean(np.abs(w - ref)[v]))
    assert errs[0] < 0.5 * errs[1]


# ----------------------------------------------------------------------------- Middlebury
SCALES = {"tsukuba": (16, 15, (288, 384)), "teddy": (4, 59, (375, 450)),
          "venus": (8, 19, (383, 434)), "art": (2, None, (555, 695))}


@pytest.mark.parametrize("name", sorted(SCALES))
def test_middlebury_real(name):
    root = require_dataset(name)
    p = read_middlebury(root)
    scale, maxd, shape = SCALES[name]
    assert p.scale == scale and p.name == name
    assert p.left.shape == p.right.shape == shape + (3,) and p.gt_disparity.shape == shape
    gt = p.gt_disparity[np.isfinite(p.gt_disparity)]
    assert gt.size > 0.5 * p.gt_disparity.size and gt.min() > 0
    if maxd is not None:
        assert p.max_disparity == maxd
        assert set(p.masks) == {"all", "nonocc", "disc"}
        assert p.masks["nonocc"].sum() <= p.masks["all"].sum()
    assert gt.max() < p.max_disparity + 1  # Venus: gt reaches 19.75 with info.txt's 19
    if name == "tsukuba":
        assert 4 <= gt.min() and gt.max() <= 15
    if name == "teddy":
        assert gt.max() < 59
    if name == "art":
        assert p.masks == {} and 100 < gt.max() < 130
    # the range Table 1 searches: to the ground truth's largest value where it is higher
    assert p.search_range == (0, {"tsukuba": 15, "teddy": 59, "venus": 20, "art": 119}[name])


@pytest.mark.parametrize("name, agree", [("tsukuba", 0.999), ("teddy", 0.99), ("venus", 0.995)])
def test_ground_truth_z_test_finds_middlebury_nonocc(name, agree):
    """The z-test of the ground truth (the right camera one baseline to the right, surfaces
    within 1 px counted as one) finds Middlebury's own non-occluded pixels: Table 1 uses it
    for Art, which comes without masks (``benchmarks/table1.py``, ``visible_mask``)."""
    from hyperlf.warp import visible_in_view

    p = read_middlebury(require_dataset(name))
    seen = visible_in_view(np.where(p.valid, p.gt_disparity, np.nan), (1.0, 0.0), margin=1.0)
    m = p.eval_mask("all")
    nonocc = p.masks["nonocc"][m]
    assert np.mean(seen[m] == nonocc) >= agree
    # not by calling nearly everything visible: it finds most of the occluded pixels too
    assert np.mean(~seen[m] & ~nonocc) >= 0.8 * np.mean(~nonocc)


@pytest.mark.parametrize("layout", ["v2", "2005"])
def test_a_middlebury_file_linked_from_outside_is_refused(tmp_path, rng, layout):
    """A scene's image or mask that is a symlink leading out of its folder is refused before
    anything is read (as for HCI scenes and captures)."""
    import os

    from hyperlf.errors import InvalidInputError
    from hyperlf.formats import StereoPair, write_middlebury

    img = rng.random((6, 8, 3)).astype(np.float32)
    scene = write_middlebury(tmp_path / "scene", StereoPair(
        left=img, right=img, gt_disparity=np.ones((6, 8), np.float32),
        masks={"nonocc": np.ones((6, 8), bool)}, scale=4.0, max_disparity=3))
    if layout == "2005":
        for old, new in (("imL", "art1"), ("imR", "art5"), ("groundtruth", "art1_true")):
            os.rename(scene / f"{old}.png", scene / f"{new}.png")
        linked = "art5.png"
    else:
        linked = "nonocc.png"
    outside = tmp_path / "elsewhere.png"
    os.rename(scene / linked, outside)
    os.symlink(outside, scene / linked)
    with pytest.raises(InvalidInputError, match=f"{linked} leads outside the folder"):
        read_middlebury(scene)


def test_middlebury_round_trip_and_errors(tmp_path, rng):
    H, W = 6, 8
    gt = rng.integers(1, 60, size=(H, W)) / 4.0
    gt[0, 0] = np.nan
    left = rng.integers(0, 256, (H, W, 3)) / 255.0
    pair = StereoPair(left=left, right=left[:, ::-1], gt_disparity=gt,
                      masks={"all": rng.random((H, W)) > 0.5}, scale=4, max_disparity=16,
                      name="toy")
    write_middlebury(tmp_path / "toy", pair)
    back = read_middlebury(tmp_path / "toy")
    np.testing.assert_allclose(back.left, left, atol=1e-7)
    np.testing.assert_array_equal(back.gt_disparity, gt.astype(np.float32))
    np.testing.assert_array_equal(back.masks["all"], pair.masks["all"])
    assert back.scale == 4 and back.max_disparity == 16 and back.name == "toy"
    assert back.eval_mask("all").sum() == (pair.masks["all"] & np.isfinite(gt)).sum()
    (tmp_path / "toy" / "info.txt").write_text("four\n")
    with pytest.raises(FormatError, match="info.txt"):
        read_middlebury(tmp_path / "toy")
    os.remove(tmp_path / "toy" / "imR.png")
    with pytest.raises(DataNotFoundError, match="imR.png"):
        read_middlebury(tmp_path / "toy")
    with pytest.raises(DataNotFoundError):
        read_middlebury(tmp_path)
    with pytest.raises(InvalidInputError):
        write_middlebury(tmp_path / "x", StereoPair(left, left, gt * 100, scale=4))


# ----------------------------------------------------------------------------- dispatch
def test_dispatch_errors(tmp_path):
    with pytest.raises(DataNotFoundError):
        load_lightfield(tmp_path / "nothing")
    with pytest.raises(FormatError, match="capture.toml"):
        load_lightfield(tmp_path)
    (tmp_path / "x.txt").write_text("hi")
    with pytest.raises(FormatError, match="HDF5"):
        hyperlf.load(tmp_path / "x.txt")
    (tmp_path / "x.h5").write_text("hi")
    with pytest.raises(FormatError):
        hyperlf.load(tmp_path / "x.h5")


def test_save_dispatch(tmp_path, rng):
    lf = hyperlf.LightField(views=rng.random((2, 2, 3, 3)), wavelengths=[[400, 500], [600, 700]])
    assert save_lightfield(lf, tmp_path / "a.h5").name == "a.h5"
    assert save_lightfield(lf, tmp_path / "cap").name == "capture.toml"
    for p in (tmp_path / "a.h5", tmp_path / "cap"):
        np.testing.assert_allclose(hyperlf.load(p).views, lf.views, atol=1e-5)
        with pytest.raises(InvalidInputError, match="overwrite=True"):
            save_lightfield(lf, p, bit_depth=8)
        save_lightfield(lf, p, bit_depth=8, overwrite=True)  # the CLI's call signature


def test_table1_pixel_classes_of_a_square_in_front_of_a_wall():
    """Table 1's failure classes from the ground truth: a square at 8 px before a wall at 2 px
    hides the 6 px of wall left of it from the right camera, the first 2 columns match outside
    the right image, and the classes split every pixel once, by the left-right check too."""
    t1 = benchmark_script("table1")
    H, W = 12, 40
    gt = np.full((H, W), 2.0, np.float32)
    gt[3:9, 20:30] = 8.0
    img = np.zeros((H, W, 3), np.float32)
    pair = StereoPair(left=img, right=img, gt_disparity=gt, name="toy")
    valid = np.zeros((H, W), bool)
    valid[:, ::2] = True
    classes = t1.pixel_classes(pair, valid)
    assert len(classes) == 6
    np.testing.assert_array_equal(sum(c.astype(int) for c in classes.values()), 1)
    hidden = classes["hidden, consistent"] | classes["hidden, filled"]
    outside = classes["match outside the image, consistent"] | \
        classes["match outside the image, filled"]
    assert outside.all(axis=0).tolist() == [True, True] + [False] * (W - 2)
    cols = np.nonzero(hidden[3:9].all(axis=0))[0]
    assert set(range(14, 20)) <= set(cols) <= set(range(13, 20))   # the z-test's 1 px margin
    assert not hidden[:3].any() and not hidden[9:].any()
    assert not (classes["visible, filled"] & valid).any()
    # a map that carries the square 3 px over the hidden wall: all bad, all too large
    est = gt.copy()
    est[3:9, 17:20] = 8.0
    b = t1.breakdown(est, valid, pair, np.ones((H, W), bool))
    hid = b["hidden, consistent"]["too_large"] + b["hidden, filled"]["too_large"]
    assert hid == pytest.approx(100 * 18 / (H * W))
    assert sum(v["bad"] for v in b.values()) == pytest.approx(100 * 18 / (H * W))


def test_table1_pixel_classes_on_art():
    """On Art (no masks of its own), the classes from its ground truth: about three quarters of
    the pixels seen by the right camera, a tenth whose match leaves its image."""
    t1 = benchmark_script("table1")
    p = read_middlebury(require_dataset("art"))
    m = p.eval_mask("all")
    classes = t1.pixel_classes(p, np.ones(m.shape, bool))
    share = {k.split(",")[0]: classes[k][m].mean() for k in classes if k.endswith("consistent")}
    assert share["visible"] == pytest.approx(0.734, abs=0.005)
    assert share["match outside the image"] == pytest.approx(0.096, abs=0.005)
    assert share["hidden"] == pytest.approx(0.170, abs=0.005)
    b = t1.breakdown(p.gt_disparity, np.ones(m.shape, bool), p, m)
    assert all(v["bad"] == 0.0 for v in b.values())


def test_rig_positions_scores_a_registration_against_the_rigs_truth():
    """benchmarks/rig_positions.py: a tilted board before a 1 x 3 rig, positions from the
    scene's parallax within a tenth of a baseline of the true centres, and the nominal grid
    (the rig's cameras are placed a little off it) within a tenth too."""
    rp = benchmark_script("rig_positions")
    r = rp.run_rig(0, (1, 3), (320, 240), rp.POSES["tilted"])
    assert r["positions_from"] == "parallax" and r["error"] < 0.1
    assert 0 < r["nominal_error"] < 0.1


def test_rig_positions_mounts_a_camera_turned():
    """benchmarks/rig_positions.py --turns: the corner camera of a 1 x 3 rig mounted upside
    down is reported turned, and the positions hold; the option's text is checked."""
    rp = benchmark_script("rig_positions")
    r = rp.run_rig(0, (1, 3), (320, 240), rp.POSES["tilted"], ("corner", 180))
    assert r["turns_found"] and r["positions_from"] == "parallax" and r["error"] < 0.1
    assert rp._turns("corner:90,reference:180") == [("corner", 90), ("reference", 180)]
    assert rp._turns("") == [None]
    for bad in ("corner", "side:90", "corner:45", "corner:x"):
        with pytest.raises(SystemExit, match="--turns must be like"):
            rp._turns(bad)


def test_middlebury_lf_renders_a_square_before_a_wall():
    """benchmarks/middlebury_lf.py: a square at 2 px per baseline before a wall at -1, the view
    one baseline to the right. Every pixel the view shares with the centre holds the centre's
    value at ``x - d`` exactly (whole-pixel shifts), and the disoccluded pixels are exactly the
    3 px of wall the square hid and the column that came in at the left border."""
    lf = benchmark_script("middlebury_lf")
    rng = np.random.default_rng(0)
    H, W = 16, 40
    image = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    gt = np.full((H, W), -1.0)
    gt[4:12, 20:30] = 2.0
    view, lost = lf.render_view(image, gt, (1.0, 0.0))
    expected = np.zeros((H, W), bool)
    expected[:, 0] = True
    expected[4:12, 28:31] = True
    np.testing.assert_array_equal(lost, expected)
    yy, xx = np.mgrid[0:H, 0:W]
    tx = (xx - gt).astype(int)
    seen = (tx >= 0) & (tx < W)
    seen[4:12, 17:20] = False   # wall that the square hides in the view
    np.testing.assert_array_equal(view[yy[seen], tx[seen]], image[seen])
    same, none = lf.render_view(image, gt, (0.0, 0.0))
    np.testing.assert_array_equal(same, image)
    assert not none.any()


def test_middlebury_lf_fills_unknown_ground_truth_from_the_background():
    """Unknown ground truth takes the farther of its row's nearest known values (a row with
    none, the nearest row's); the map then spans the asked range about 0."""
    lf = benchmark_script("middlebury_lf")
    n = np.nan
    d = np.array([[n, 5, n, n, 2, n], [n] * 6, [1, 1, 1, 1, 1, 3]])
    filled = lf.fill_rows_background(d)
    np.testing.assert_array_equal(filled, [[5, 5, 2, 2, 2, 2], [5, 5, 2, 2, 2, 2],
                                           [1, 1, 1, 1, 1, 3]])
    mapped = lf.lf_disparity(filled, 4.0)
    assert mapped.min() == pytest.approx(-2.0) and mapped.max() == pytest.approx(2.0)
    with pytest.raises(ValueError):
        lf.fill_rows_background(np.full((2, 3), np.nan))


# ----------------------------------------------------------------------------- faint thin objects
def test_faint_thin_chips_are_faint_in_the_reference_band_and_plain_elsewhere():
    """benchmarks/faint_thin.py: every chip drawn lies within the tolerance of the
    background's mean in the reference band and differs from its mean spectrum by at least
    MIN_ELSEWHERE; a library with no such chip is refused."""
    ft = benchmark_script("faint_thin")
    rng = np.random.default_rng(0)
    library = rng.random((300, 12))
    background = [3, 7]
    target = library[background].mean(axis=0)
    chips = ft.faint_chips(library, 4, background, 5, rng, tolerance=0.05)
    assert len(chips) == 5
    for c in chips:
        assert abs(library[c, 4] - target[4]) <= 0.05
        assert np.abs(library[c] - target).mean() >= ft.MIN_ELSEWHERE
    flat = np.full((10, 12), 0.5)
    with pytest.raises(ValueError, match="no chip"):
        ft.faint_chips(flat, 4, [0, 1], 2, rng, tolerance=0.05)


def test_faint_thin_changes_only_the_rings_and_sticks_chips():
    """The family's description is the random rings-and-sticks scene of its seed with new
    chips on the rings and sticks only, each within the tolerance of the background in the
    reference band; the mask of thin pixels is where the scene without them is farther."""
    from hyperlf import synthesis

    ft = benchmark_script("faint_thin")
    source = "colorchecker"   # no data needed; the benchmark draws Munsell chips
    objects, reference_nm = ft.faint_description(1, rows=3, cols=3, tolerance=0.03,
                                                 source=source)
    plain = synthesis.procedural_scene(1, rows=3, cols=3, height=16, width=16,
                                       kinds=ft.THIN_KINDS, n_objects=10,
                                       reflectance_source=source)
    assert reference_nm == float(plain.wavelengths[plain.reference])
    library = ft._library_at(np.array([reference_nm]), source)[:, 0]
    level = library[objects[0]["texture"]["chips"]].mean()
    for new, old in zip(objects, plain.metadata["objects"], strict=True):
        if "shape" not in new:
            assert new == old
            continue
        assert {k: v for k, v in new.items() if k != "texture"} == \
               {k: v for k, v in old.items() if k != "texture"}
        assert np.all(np.abs(library[new["texture"]["chips"]] - level) <= 0.03)
    lf, thin, n_thin = ft.faint_scene(1, rows=3, cols=3, height=48, width=64, source=source)
    assert n_thin == sum("shape" in o for o in objects) and thin.any() and not thin.all()
    assert lf.reference_gt_disparity[thin].min() > lf.reference_gt_disparity[~thin].min()


def test_faint_thin_plain_is_the_random_scene_as_drawn():
    """``--plain``: the random rings-and-sticks scene of the seed rendered as
    ``procedural_scene`` draws it at that size (the same views and truth), its thin pixels
    where the scene without its rings and sticks is farther."""
    from hyperlf import synthesis

    ft = benchmark_script("faint_thin")
    source = "colorchecker"
    lf, thin, n_thin = ft.faint_scene(2, rows=3, cols=3, height=48, width=64, source=source,
                                      faint=False)
    drawn = synthesis.procedural_scene(2, rows=3, cols=3, height=48, width=64,
                                       kinds=ft.THIN_KINDS, n_objects=10, supersample=2,
                                       reflectance_source=source)
    assert np.array_equal(lf.views, drawn.views)
    assert np.array_equal(lf.reference_gt_disparity, drawn.reference_gt_disparity)
    assert n_thin == sum("shape" in o for o in drawn.metadata["objects"]) > 0
    assert thin.any() and not thin.all()
    assert lf.reference_gt_disparity[thin].min() > lf.reference_gt_disparity[~thin].min()


def test_faint_thin_scores_the_thin_pixels_inside_the_border():
    """A column of thin pixels 2 px off in a 40 x 40 map: inside the 15 px border it is 10 of
    the 100 scored pixels, so the thin RMSE is 2, all of it off by more than 1 px, and the
    whole map's RMSE sqrt(0.4)."""
    ft = benchmark_script("faint_thin")
    truth = np.zeros((40, 40))
    thin = np.zeros((40, 40), bool)
    thin[:, 20] = True
    row = ft.score(truth + 2.0 * thin, truth, thin)
    assert row["thin_rmse"] == pytest.approx(2.0) and row["thin_bad1"] == 100.0
    assert row["rmse"] == pytest.approx(np.sqrt(0.4)) and row["thin_share"] == 10.0
    none = ft.score(truth, truth, np.zeros((40, 40), bool))
    assert np.isnan(none["thin_rmse"]) and none["thin_share"] == 0.0


# ----------------------------------------------------------------------------- procedural pairs
def test_procedural_pairs_weak_set_is_the_random_scene_with_long_smooth_textures():
    """benchmarks/procedural_pairs.py's ``weak`` set: the objects as the generator draws
    them (rings among them, so holes), each but the background given a smooth noise texture
    of a period in the set's range, which the rendered pair keeps; the other sets are the
    generator's scenes as before."""
    from hyperlf import synthesis

    pp = benchmark_script("procedural_pairs")
    n_objects, kinds, periods = pp.SETS["weak"]
    objects = pp.weak_objects(3, n_objects, kinds, periods)
    drawn = synthesis._random_objects(np.random.default_rng(3), n_objects, kinds, pp.RANGE)
    assert [{k: v for k, v in o.items() if k != "texture"} for o in objects] == drawn
    assert "texture" not in objects[0] and any("shape" in o for o in objects)
    for o in objects[1:]:
        assert o["texture"]["pattern"] == "noise"
        assert periods[0] <= o["texture"]["period"] <= periods[1]
    lf = pp.pair_scene(3, "weak")
    kept = [o["texture"]["period"] for o in lf.metadata["objects"][1:]]
    assert kept == [o["texture"]["period"] for o in objects[1:]]
    assert lf.metadata["objects"][0]["texture"]["period"] < periods[0]
    assert pp.SETS["plain"][2] is None and pp.SETS["thin"][2] is None
