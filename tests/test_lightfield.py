"""The LightField data model: validation and geometry helpers; the package's lazy import."""

import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st

from hyperlf import InvalidInputError, LightField, filter_layout, raster_wavelengths
from hyperlf.imageops import block_reduce


def _lf(**kw):
    views = kw.pop("views", np.random.default_rng(0).random((5, 6, 8, 10), dtype=np.float32))
    kw.setdefault("wavelengths", raster_wavelengths(5, 6))
    return LightField(views, **kw)


def test_defaults_follow_spec_conventions():
    lf = _lf()
    assert lf.grid_shape == (5, 6) and lf.image_shape == (8, 10)
    assert lf.reference == (2, 2)
    assert lf.wavelengths[2, 2] == 550.0  # SPEC §1 raster order
    assert tuple(lf.positions[3, 4]) == (4.0, 3.0)  # (px, py) = (c, r)
    assert tuple(lf.offsets[2, 2]) == (0.0, 0.0)
    assert lf.is_spectral and lf.channels == 1
    assert lf.views.dtype == np.float32


def test_layouts():
    k = filter_layout(2, 3, "serpentine")
    assert k.tolist() == [[0, 1, 2], [5, 4, 3]]
    r = filter_layout(5, 6, "random", seed=1)
    assert sorted(r.ravel()) == list(range(30))
    assert filter_layout(1, 3, [2, 0, 1]).tolist() == [[2, 0, 1]]
    with pytest.raises(InvalidInputError, match="exactly once"):
        filter_layout(1, 3, [0, 0, 1])
    with pytest.raises(InvalidInputError, match="unknown filter layout"):
        filter_layout(2, 2, "spiral")


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(views=np.zeros((5, 6, 8))), "shape"),
        (dict(views=np.zeros((5, 6, 0, 10))), "empty"),
        (dict(views=np.full((5, 6, 2, 2), np.nan)), "NaN"),
        (dict(wavelengths=np.ones((5, 5))), "one value per view"),
        (dict(wavelengths=-raster_wavelengths(5, 6)), "positive"),
        (dict(reference=(5, 0)), "outside the 5 x 6 grid"),
        (dict(positions=np.zeros((5, 6))), "positions"),
        (dict(disparity_range=(2, 1)), "min < max"),
        (dict(gt_disparity=np.zeros((3, 3))), "gt_disparity"),
        (dict(gt_cube=np.zeros((5, 6, 30, 8, 10))), "cube_wavelengths"),
        (dict(views=np.array([["a"]])), "shape|real"),
    ],
)
def test_bad_input_is_rejected_with_a_clear_message(kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        _lf(**kwargs)


def test_duplicate_cube_wavelengths_rejected():
    with pytest.raises(InvalidInputError, match="distinct"):
        _lf(gt_cube=np.zeros((5, 6, 2, 8, 10)), cube_wavelengths=[500, 500])


def test_colour_lightfield_and_replace():
    lf = LightField(np.zeros((3, 3, 4, 4, 3)))
    assert not lf.is_spectral and lf.channels == 3 and lf.reference == (1, 1)
    lf2 = lf.replace(reference=(0, 0))
    assert lf2.reference == (0, 0) and lf.reference == (1, 1)
    text = _lf(disparity_range=(-1, 2), gt_disparity=np.zeros((8, 10))).describe()
    assert "5 x 6" in text and "550" in text and "-1..2" in text


@settings(max_examples=50, deadline=None)
@given(rows=st.integers(1, 7), cols=st.integers(1, 7),
       lo=st.floats(300, 600), span=st.floats(0, 400))
def test_raster_wavelengths_properties(rows, cols, lo, span):
    wl = raster_wavelengths(rows, cols, lambda_min=lo, lambda_max=lo + span)
    assert wl.shape == (rows, cols)
    top = lo if rows * cols == 1 else lo + span  # a single view gets lambda_min
    assert np.isclose(wl.min(), lo) and np.isclose(wl.max(), top)
    assert np.all(np.diff(wl.ravel()) >= 0)  # raster order increases


def test_top_level_api_functions_survive_submodule_imports():
    """hyperlf.depth / stereo / complete stay functions even after their modules are imported."""
    import hyperlf
    import hyperlf.completion  # noqa: F401
    import hyperlf.hlf  # noqa: F401
    import hyperlf.twoview  # noqa: F401

    for name in ("depth", "stereo", "complete", "load", "save"):
        assert callable(getattr(hyperlf, name)), name


# ----------------------------------------------------------------------------- package import
def test_import_hyperlf_is_cheap_and_submodules_attach_lazily():
    code = (
        "import sys, hyperlf\n"
        "heavy = [m for m in ('numba', 'cv2', 'colour', 'matplotlib', 'h5py') if m in sys.modules]\n"
        "print(','.join(heavy) or 'none')\n"
        "print('hyperlf.render' in sys.modules)\n"
        "mods = [hyperlf.render, hyperlf.costs, hyperlf.regularisers, hyperlf.synthesis,\n"
        "        hyperlf.pipeline, hyperlf.formats, hyperlf.spectral, hyperlf.metrics]\n"
        "print(all(m.__name__.startswith('hyperlf.') for m in mods))\n"
        "print(callable(hyperlf.render.emulate_camera), 'render' in dir(hyperlf))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env={k: v for k, v in os.environ.items() if k != "EAGER_IMPORT"})
    assert out.stdout.split() == ["none", "False", "True", "True", "True"]


def test_top_level_api_names():
    import hyperlf

    for name in ("load", "save", "stereo", "depth", "complete", "LightField", "HyperLFError",
                 "InvalidInputError", "FormatError", "DataNotFoundError", "__version__"):
        assert name in hyperlf.__all__ and hasattr(hyperlf, name)
    with pytest.raises(AttributeError):
        hyperlf.no_such_module


def test_grid_defaults_are_the_ones_lightfield_uses():
    from hyperlf.lightfield import centre_view, grid_positions

    pos = grid_positions(2, 3)
    assert pos.shape == (2, 3, 2) and pos.dtype == np.float64
    assert pos[1, 2].tolist() == [2.0, 1.0]
    assert centre_view(5, 6) == (2, 2) and centre_view(4, 4) == (1, 1)
    lf = LightField(views=np.zeros((2, 3, 4, 5), np.float32))
    assert np.array_equal(lf.positions, pos) and lf.reference == centre_view(2, 3)


@pytest.mark.parametrize("bad", [(1.0, 1.0), (np.nan, 1.0), (0.0,), "ab", None, ("0", "2"),
                                 [0, 10 ** 400], np.zeros((2, 2))])
def test_check_disparity_range_rejects_what_is_not_an_ordered_finite_pair(bad):
    from hyperlf.lightfield import check_disparity_range

    with pytest.raises(InvalidInputError, match="disparity_range must be"):
        check_disparity_range(bad)
    assert check_disparity_range([-2, 2]) == (-2.0, 2.0)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.integers(1, 9), st.integers(1, 9), st.integers(1, 3), st.integers(0, 2**31))
def test_downscale_is_the_block_mean_with_edges_repeated(H, W, factor, seed):
    from hyperlf.lightfield import downscale

    rng = np.random.default_rng(seed)
    views = rng.uniform(0, 1, (2, 3, H, W)).astype(np.float32)
    valid = rng.uniform(size=views.shape) > 0.2
    lf = LightField(views, wavelengths=np.full((2, 3), 500.0), disparity_range=(-3, 6),
                    valid=valid, gt_disparity=np.zeros((H, W)))
    small = downscale(lf, factor)
    h, w = -(-H // factor), -(-W // factor)
    assert small.image_shape == (h, w)
    assert small.disparity_range == (-3 / factor, 6 / factor)
    assert small.reference == lf.reference
    assert small is lf if factor == 1 else small.gt_disparity is None
    for y in range(h):
        for x in range(w):
            ys = np.minimum(np.arange(y * factor, (y + 1) * factor), H - 1)
            xs = np.minimum(np.arange(x * factor, (x + 1) * factor), W - 1)
            block = views[:, :, ys][:, :, :, xs]
            np.testing.assert_allclose(small.views[:, :, y, x], block.mean(axis=(2, 3)),
                                       rtol=1e-6)
            assert np.array_equal(small.valid[:, :, y, x],
                                  valid[:, :, ys][:, :, :, xs].all(axis=(2, 3)))


@pytest.mark.parametrize("bad", [0, -2, 1.5, True, "2"])
def test_downscale_rejects_a_bad_factor(bad):
    from hyperlf.lightfield import downscale

    lf = LightField(np.ones((1, 2, 4, 4), np.float32))
    with pytest.raises(InvalidInputError, match="factor"):
        downscale(lf, bad)


@settings(max_examples=25, deadline=None, derandomize=True)
@example(2, 113).via("the mean of four depths near the pole, not the centre's")
@example(4, 113).via("the same, with the pole inside the block")
@given(st.integers(2, 4), st.integers(0, 2**31))
def test_downscale_keeps_metric_depth_and_can_keep_the_truth(factor, seed):
    """Disparities of the block grid (1/factor of the full-resolution ones) give the same metric
    depth through the moved camera matrix: the depth of an affine disparity field at a block
    centre, whatever the focal length, principal point and slant of the board plane."""
    from hyperlf.calibration.metric import depth_from_disparity
    from hyperlf.lightfield import downscale

    rng = np.random.default_rng(seed)
    H, W = 6 * factor, 8 * factor
    f = rng.uniform(50, 500)
    K = [[f, 0.0, rng.uniform(0, W)], [0.0, f, rng.uniform(0, H)], [0.0, 0.0, 1.0]]
    n = rng.normal([0, 0, 1], [0.2, 0.2, 0.0])
    geo = {"mode": "plane", "camera_matrix": K, "baseline": 1.5,
           "board_plane": [*(n / np.linalg.norm(n)), rng.uniform(20, 60)]}
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    a, bx, by = rng.uniform(-2, 2), rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05)
    disp = (a + bx * xx + by * yy).astype(np.float32)
    lf = LightField(np.ones((1, 2, H, W), np.float32), gt_disparity=disp,
                    metadata={"calibration": geo, "note": "kept"})
    small = downscale(lf, factor, truth=True)
    assert small.metadata["note"] == "kept" and lf.metadata["calibration"] is geo  # no side effect
    np.testing.assert_allclose(small.gt_disparity, block_reduce(disp, factor) / factor,
                               rtol=1e-5, atol=1e-6)
    coarse = depth_from_disparity(small.gt_disparity, small.metadata["calibration"])
    # the full-resolution depth at each block's centre: a pixel for odd factors, between
    # four for even ones (there the grid is moved by half a pixel, and the principal point
    # with it); the block's mean disparity is the affine field's value there
    off = 0.0 if factor % 2 else 0.5
    moved = {**geo, "camera_matrix": [[f, 0.0, K[0][2] - off], [0.0, f, K[1][2] - off],
                                      [0.0, 0.0, 1.0]]}
    full = depth_from_disparity((a + bx * (xx + off) + by * (yy + off)).astype(np.float32),
                                moved)
    centre = slice((factor - 1) // 2, None, factor)
    # compared as inverse depths (affine in the disparity; no depth: 0), which float32
    # disparities keep to about 1e-6 px even where the depth itself runs off to infinity
    inverse = lambda z: np.where(np.isfinite(z), 1.0 / z, 0.0)  # noqa: E731
    np.testing.assert_allclose(inverse(coarse), inverse(full[centre, centre]), rtol=1e-4,
                               atol=1e-5 / f)
    assert downscale(lf, factor).gt_disparity is None


def test_block_mean_cube_scores_like_the_block_means_of_the_whole_cube():
    from hyperlf.imageops import block_reduce
    from hyperlf.lightfield import BlockMeanCube
    from hyperlf.metrics import cube_scores

    rng = np.random.default_rng(3)
    truth = rng.random((2, 3, 4, 9, 11))
    small = block_reduce(truth, 3)
    est = small * rng.uniform(0.9, 1.1, small.shape)
    lazy = BlockMeanCube(truth, 3)
    assert lazy.shape == small.shape == (2, 3, 4, 3, 4)
    np.testing.assert_allclose(cube_scores(est, lazy), cube_scores(est, small), rtol=1e-12)


def _textured(rng, shape=(60, 80)):
    from scipy.ndimage import gaussian_filter

    g = gaussian_filter(rng.random(shape), 6)
    return (0.1 + (g - g.min()) / np.ptp(g)).astype(np.float32)


def test_capture_signature_tells_another_scene_from_another_shading(rng):
    """Exposure, vignetting and a small shift keep the signature; another scene, grid,
    reference or wavelength does not."""
    from hyperlf.lightfield import capture_signature, signature_mismatch

    def sig(view, **kw):
        return capture_signature(LightField(np.stack([view, view])[None],
                                            wavelengths=[[500.0, 600.0]], **kw))

    view = _textured(rng)
    y, x = np.mgrid[:60, :80]
    vignetting = 1 - 0.6 * (((x - 40) / 40) ** 2 + ((y - 30) / 30) ** 2) / 2
    base = sig(view)
    for same in (0.5 * view, view * vignetting, np.roll(view, 2, axis=1)):
        assert signature_mismatch(base, sig(same.astype(np.float32))) is None
    assert "another scene" in signature_mismatch(base, sig(_textured(rng)))
    assert "reference" in signature_mismatch(base, sig(view, reference=(0, 1)))
    assert signature_mismatch(base, dict(base, wavelengths=[[500.0, 610.0]])) == \
        "its wavelengths differ"
    assert signature_mismatch({"grid": "x"}, base) is None  # malformed: nothing to tell


def test_capture_signature_uses_valid_pixels_only(rng):
    from hyperlf.lightfield import capture_signature

    view = _textured(rng)
    valid = np.ones((1, 2, 60, 80), bool)
    valid[0, 0, :8] = False  # the top row of blocks: rows 0-7 (60 rows in 8, 8, 8, 8, 7, ...)
    sig = capture_signature(LightField(np.stack([view, view])[None], valid=valid,
                                       reference=(0, 0)))
    assert sig["thumbnail"][:8] == [None] * 8
    assert sig["thumbnail"][8] == pytest.approx(float(view[8:16, :10].mean()), rel=1e-6)


_LF_JUNK = (st.none() | st.booleans() | st.text(max_size=4) | st.floats() | st.integers()
            | st.lists(st.floats(), max_size=3) | st.lists(st.lists(st.integers(), max_size=3),
                                                          max_size=3)
            | st.dictionaries(st.text(max_size=2), st.none(), max_size=1)
            | st.tuples(st.floats(), st.floats())
            | st.sampled_from([np.zeros((2, 3)), np.full((2, 3), "a"), np.zeros((2, 3, 2)),
                               np.zeros((2, 3, 8, 8)), np.full((2, 3), np.nan)]))


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.sampled_from(["views", "wavelengths", "positions", "reference", "disparity_range",
                        "gt_disparity", "gt_cube", "cube_wavelengths", "metadata", "valid"]),
       _LF_JUNK)
def test_any_field_is_taken_or_refused_in_one_line(name, value):
    """Text, mappings, ragged lists and arrays of the wrong shape in any field of a light field
    end in one line of InvalidInputError (text in ``wavelengths`` was a ValueError, an
    array as ``reference`` a message over two lines)."""
    fields = {"views": np.ones((2, 3, 8, 8), np.float32), name: value}
    try:
        LightField(**fields)
    except InvalidInputError as exc:
        assert "\n" not in str(exc) and str(exc)
