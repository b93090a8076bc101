"""Per-view validity masks (SPEC §11, issue 11 item 3): the data model, the formats, matching
and completion ignore pixels without data."""

import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from hyperlf import synthesis
from hyperlf.completion import (band_order, complete, naive_completion, propagate_disparity,
                                 register_view)
from hyperlf.costs import tap_validity, view_costs, view_validity
from hyperlf.errors import FormatError, InvalidInputError
from hyperlf.formats.capture import read_capture, write_capture
from hyperlf.formats.hdf5 import read_lightfield_h5, write_lightfield_h5
from hyperlf.hlf import (DepthParams, correspondence, defocus_cue, depth, edge_discount,
                         post_filter, prepare, refine, regularise, seen_pixels, thin_objects,
                         unary)
from hyperlf.imageops import fill_masked, normalise_intensity
from hyperlf.lightfield import LightField

BAND = 12  # px blanked at the array's borders (the views a registration would leave black)


def _scene(seed):
    """3 x 3 procedural scene, the border bands of the outer views and a block of the
    reference marked invalid (and blanked to 0 in ``blank``)."""
    lf = synthesis.procedural_scene(seed=seed, rows=3, cols=3, height=40, width=48,
                                    disparity_range=(-1.5, 1.5),
                                    reflectance_source="colorchecker")
    valid = np.ones(lf.views.shape, bool)
    valid[:, 0, :, :BAND] = False
    valid[:, 2, :, -BAND:] = False
    valid[0, :, :BAND, :] = False
    valid[2, :, -BAND:, :] = False
    valid[1, 1, 16:24, 18:28] = False
    blank = np.where(valid, lf.views, 0.0)
    return lf, valid, blank


def _at_limit(res):
    lab = res.labels
    half = (lab[1] - lab[0]) / 2
    d = res.disparity
    return float(((d <= lab[0] + half) | (d >= lab[-1] - half)).mean())


# ----------------------------------------------------------------------------- data model
def test_valid_is_validated_coerced_and_described():
    lf = synthesis.procedural_scene(seed=0, rows=2, cols=2, height=8, width=10)
    assert lf.valid is None and "valid mask" not in lf.describe()
    m = np.ones(lf.views.shape, np.uint8)
    m[0, 1, :4] = 0
    lfm = lf.replace(valid=m)
    assert lfm.valid.dtype == bool and lfm.valid.sum() == m.sum()
    assert "valid mask  : 87.5 % of pixels valid (per view 50.0..100.0 %)" in lfm.describe()
    with pytest.raises(InvalidInputError, match=r"valid must be one bool per view pixel"):
        lf.replace(valid=np.ones((2, 2, 8, 9), bool))
    with pytest.raises(InvalidInputError, match="bool array"):
        lf.replace(valid=np.full(lf.views.shape, "x"))
    # positional construction still works; valid is the last field
    LightField(lf.views, lf.wavelengths, lf.positions, lf.reference)


# ----------------------------------------------------------------------------- formats
def test_capture_and_hdf5_round_trip_the_masks(tmp_path):
    lf = synthesis.procedural_scene(seed=3, rows=2, cols=3, height=12, width=16)
    valid = np.random.default_rng(0).random(lf.views.shape) > 0.3
    lfm = lf.replace(valid=valid)
    man = write_capture(lfm, tmp_path / "cap")
    assert 'valid = "valid_r{row}_c{col}.png"' in man.read_text()
    np.testing.assert_array_equal(read_capture(tmp_path / "cap").valid, valid)
    write_lightfield_h5(tmp_path / "lf.h5", lfm)
    np.testing.assert_array_equal(read_lightfield_h5(tmp_path / "lf.h5").valid, valid)
    # no mask: nothing written, None read back
    man = write_capture(lf, tmp_path / "plain")
    assert "valid" not in man.read_text() and not list((tmp_path / "plain").glob("valid_*"))
    assert read_capture(tmp_path / "plain").valid is None
    write_lightfield_h5(tmp_path / "plain.h5", lf)
    assert read_lightfield_h5(tmp_path / "plain.h5").valid is None


def _capture_with_masks(tmp_path):
    lf = synthesis.procedural_scene(seed=3, rows=2, cols=2, height=12, width=16)
    man = write_capture(lf.replace(valid=np.ones(lf.views.shape, bool)), tmp_path / "cap")
    return man


@pytest.mark.parametrize("case, message", [
    ("size", r"mask valid_r0_c1.png is \(12, 15\), views are \(12, 16\)"),
    ("grey", r"mask valid_r0_c1.png holds values that are neither ~0"),
    ("single", r"valid must be a pattern with \{row\} and \{col\}"),
    ("escape", r"must be a path inside the capture folder"),
    ("field", r"valid pattern .* may only use \{row\} and \{col\}"),
])
def test_malformed_masks_are_format_errors(tmp_path, case, message):
    from hyperlf.formats.images import write_image
    man = _capture_with_masks(tmp_path)
    root = man.parent
    text = man.read_text()
    if case == "size":
        write_image(root / "valid_r0_c1.png", np.full((12, 15), 255, np.uint8))
    elif case == "grey":
        write_image(root / "valid_r0_c1.png", np.full((12, 16), 128, np.uint8))
    else:
        new = {"single": '"valid.png"', "escape": '"../valid_r{row}_c{col}.png"',
               "field": '"valid_{index}.png"'}[case]
        man.write_text(text.replace('"valid_r{row}_c{col}.png"', new))
    with pytest.raises(FormatError, match=message) as exc:
        read_capture(root)
    assert "\n" not in str(exc.value) and exc.value.exit_code == 3


def test_hdf5_mask_with_other_values_is_a_format_error(tmp_path):
    import h5py
    lf = synthesis.procedural_scene(seed=3, rows=2, cols=2, height=8, width=10)
    write_lightfield_h5(tmp_path / "lf.h5", lf.replace(valid=np.ones(lf.views.shape, bool)))
    with h5py.File(tmp_path / "lf.h5", "r+") as f:
        f["valid"][0, 0, 0, 0] = 7
    with pytest.raises(FormatError, match="values other than 0 and 1"):
        read_lightfield_h5(tmp_path / "lf.h5")


# ----------------------------------------------------------------------------- primitives
def test_normalise_and_fill_use_valid_pixels_only():
    img = np.array([[2.0, 4.0, 100.0]])
    ok = np.array([[True, True, False]])
    np.testing.assert_allclose(normalise_intensity(img, valid=ok), [[2 / 3, 4 / 3, 100 / 3]])
    np.testing.assert_array_equal(fill_masked(img, ok), [[2.0, 4.0, 4.0]])


def test_tap_validity_is_all_weighted_taps_valid():
    rng = np.random.default_rng(1)
    m = rng.random((9, 11)) > 0.2
    H, W = m.shape
    for sx, sy in [(0.0, 0.0), (1.0, -2.0), (0.5, 0.25), (-1.75, 2.5), (3.2, -0.6)]:
        got = tap_validity(m, sx, sy)
        want = np.zeros_like(m)
        for y in range(H):
            for x in range(W):
                qx, qy = min(max(x + sx, 0), W - 1), min(max(y + sy, 0), H - 1)
                x0, y0 = int(np.floor(qx)), int(np.floor(qy))
                taps = [(yy, xx) for yy, wy in ((y0, 1 - (qy - y0)), (y0 + 1, qy - y0))
                        for xx, wx in ((x0, 1 - (qx - x0)), (x0 + 1, qx - x0)) if wy * wx > 0]
                want[y, x] = all(m[yy, xx] for yy, xx in taps)
        np.testing.assert_array_equal(got, want)


def test_view_costs_mask_invalid_samples_and_reference_pixels():
    lf, valid, blank = _scene(2)
    labels = np.linspace(-2, 2, 9)
    off = lf.offsets[0, 0]
    C, ok = view_costs(blank[1, 1], blank[0, 0], off, labels, "census",
                       ref_valid=valid[1, 1], view_valid=valid[0, 0])
    shifts = [(-d * off[0], -d * off[1]) for d in labels]
    want = view_validity(blank.shape[2:], shifts, mask=valid[0, 0]) & valid[1, 1][None]
    np.testing.assert_array_equal(ok, want)
    # what lies under the mask does not matter at all
    C2, ok2 = view_costs(lf.views[1, 1], lf.views[0, 0], off, labels, "census",
                         ref_valid=valid[1, 1], view_valid=valid[0, 0])
    np.testing.assert_array_equal(C, C2)
    np.testing.assert_array_equal(ok, ok2)


# ----------------------------------------------------------------------------- depth
def test_depth_does_not_see_what_is_under_the_mask():
    lf, valid, blank = _scene(2)
    a = depth(lf.replace(views=blank, valid=valid), disparity_range=(-4, 4), n_labels=17)
    b = depth(lf.replace(valid=valid), disparity_range=(-4, 4), n_labels=17)
    np.testing.assert_array_equal(a.disparity, b.disparity)
    np.testing.assert_array_equal(a.confidence, b.confidence)


def test_masked_depth_matches_the_unblanked_scene():
    """(a) and (b) of the brief.  Measured on seeds 0..7 of this setup (ColorChecker
    reflectances, 33 labels over -4..4; RMSE on reference pixels more than 4 px from the
    blanked block; issue 11 report, re-measured in the twenty-first session):
    masked / unblanked 1.03..1.97 (the worst, seeds 1, 4 and 6, from what the reference
    block hides from the regulariser), blanked without masks / unblanked 0.76..1.86.  Seed 2 here:
    unblanked 0.402, no masks 0.437, masks 0.422, none at a range limit.  Until the fusion's
    parts were no longer centred per view (``FusedCost.view_centre``) the blanked views
    without masks scored 1.322 with 2.55 % of the pixels at a range limit; what the masks
    still buy is that black is not matched as image content: the blanked block is filled
    from its surroundings with confidence 0, not matched black on black."""
    lf, valid, blank = _scene(2)
    keep = distance_transform_edt(valid[1, 1]) > 4
    block = ~valid[1, 1]
    gt = lf.reference_gt_disparity
    kw = dict(disparity_range=(-4, 4), n_labels=33)
    rmse, limit, block_confidence = {}, {}, {}
    for name, l in (("clean", lf), ("blank", lf.replace(views=blank)),
                    ("masked", lf.replace(views=blank, valid=valid))):
        res = depth(l, **kw)
        rmse[name] = float(np.sqrt(np.mean((res.disparity - gt)[keep] ** 2)))
        limit[name] = _at_limit(res)
        block_confidence[name] = float(res.confidence[block].max())
        if name == "masked":
            assert float(res.confidence[keep].mean()) > 0.0
            lab = res.labels
            d = res.disparity[block]
            assert ((d > lab[0] + 0.25) & (d < lab[-1] - 0.25)).all()
    assert rmse["masked"] <= 1.5 * rmse["clean"]
    assert limit["masked"] == 0.0
    assert block_confidence["masked"] == 0.0 < 0.1 < block_confidence["blank"]


def test_stages_with_masks_compose_to_depth():
    lf, valid, blank = _scene(1)
    lfm = lf.replace(views=blank, valid=valid)
    kw = dict(disparity_range=(-3, 3), n_labels=13, defocus="tv", view_selection=True)
    res = depth(lfm, **kw)
    prob = prepare(lfm, **kw)
    C, n_used = correspondence(prob)
    f_c = prob.labels[np.argmin(C, axis=0)].astype(np.float32)
    D, _ = defocus_cue(prob, f_c)
    seen = seen_pixels(prob, n_used)
    assert not seen[~valid[1, 1]].any()
    U, _, _ = unary(C, D, prob.params, informative=seen)
    assert (U[:, ~seen] == 0).all()
    lab, vol = regularise(prob, U, f_c)
    disp, conf = refine(vol, lab, prob.labels, prob.params, informative=seen)
    disp = post_filter(disp, prob.In[prob.reference].astype(np.float32), prob.params)
    disp, conf, _ = thin_objects(prob, U, f_c, disp, conf, informative=seen)
    conf = edge_discount(conf, disp, prob.params)
    np.testing.assert_array_equal(disp, res.disparity)
    np.testing.assert_array_equal(conf, res.confidence)


def test_masked_depth_numpy_and_numba_agree():
    lf, valid, blank = _scene(1)
    lfm = lf.replace(views=blank, valid=valid)
    kw = dict(disparity_range=(-3, 3), n_labels=13, defocus="tv", view_selection=True,
              occlusion_split=True)
    a = depth(lfm, params=DepthParams(impl="numpy"), save_intermediate=True, **kw)
    b = depth(lfm, params=DepthParams(impl="numba"), save_intermediate=True, **kw)
    np.testing.assert_allclose(a.intermediate["C"], b.intermediate["C"], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(a.intermediate["D"], b.intermediate["D"], rtol=1e-5, atol=1e-6)
    assert np.mean(np.abs(a.disparity - b.disparity) < 1e-4) > 0.99


def test_reference_without_data_is_refused():
    lf, valid, _ = _scene(0)
    valid[1, 1] = False
    with pytest.raises(InvalidInputError, match="reference view .* has no valid pixel"):
        prepare(lf.replace(valid=valid), disparity_range=(-2, 2), n_labels=5)


# ----------------------------------------------------------------------------- completion
@pytest.mark.parametrize("run", ["complete", "naive"])
def test_completion_never_copies_invalid_pixels(run):
    """(d): a sentinel planted in the invalid pixels never reaches the cube (and, as a check
    that the test can fail, does reach it when the same views carry no mask)."""
    lf = synthesis.procedural_scene(seed=1, rows=3, cols=3, height=24, width=32)
    valid = np.ones(lf.views.shape, bool)
    valid[0, 0, :, :6] = False
    valid[2, 1, 10:16, 8:20] = False
    valid[1, 1, 4:8, 20:26] = False
    sentinel = 7.25
    planted = lf.replace(views=np.where(valid, lf.views, sentinel))
    gt = lf.gt_disparity[lf.reference]
    go = (lambda l: complete(l, gt)) if run == "complete" else (lambda l: naive_completion(l, gt))
    res = go(planted.replace(valid=valid))
    assert float(res.cube.max()) < 1.0 and not np.isclose(res.cube, sentinel).any()
    # direct registration: the view's own band is not registered where it is invalid, and
    # no band from another view's invalid pixel
    _, bidx = band_order(lf)
    disp = propagate_disparity(lf, gt)
    cube, mask = register_view(planted.replace(valid=valid), disp, (0, 0), bidx)
    assert not mask[bidx[0, 0]][~valid[0, 0]].any() and mask[bidx[0, 0]][valid[0, 0]].all()
    assert not np.isclose(cube, sentinel).any()
    unmasked = go(planted)
    assert np.isclose(unmasked.cube, sentinel).any()


def test_visibility_estimate_does_not_see_what_is_under_the_mask():
    """The half-resolution first estimate of the visibility round (a block is valid only where
    all its pixels are) leaves the result blind to the blanked content too."""
    lf = synthesis.procedural_scene(seed=3, rows=4, cols=4, height=40, width=48,
                                    disparity_range=(-1.5, 1.5),
                                    reflectance_source="colorchecker")
    valid = np.ones(lf.views.shape, bool)
    valid[:, 0, :, :BAND] = False
    valid[3, :, -BAND:, :] = False
    valid[1, 1, 17:24, 19:28] = False  # odd offsets: blocks half in, half out of the mask
    blank = np.where(valid, lf.views, 0.0)
    params = DepthParams(visibility_min_size=32)
    a = depth(lf.replace(views=blank, valid=valid), disparity_range=(-4, 4), n_labels=17,
              params=params)
    b = depth(lf.replace(valid=valid), disparity_range=(-4, 4), n_labels=17, params=params)
    assert a.config["visibility_estimate_scale"] == 2
    np.testing.assert_array_equal(a.disparity, b.disparity)
    np.testing.assert_array_equal(a.confidence, b.confidence)
