"""Capture folders: round trips, manifest validation, atomic/incomplete writes."""

from __future__ import annotations

import os
import string
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hyperlf
from hyperlf import LightField, raster_wavelengths
from hyperlf.errors import DataNotFoundError, FormatError, InvalidInputError
from hyperlf.formats import read_capture, write_capture, write_image
from hyperlf.formats.capture import MANIFEST

try:
    import tomllib
except ImportError:  # pragma: no cover
    import tomli as tomllib

FAST = settings(max_examples=60, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])


def make_lf(rng, R=3, C=4, H=10, W=12, B=5, gt_views=False):
    views = rng.random((R, C, H, W)).astype(np.float32)
    pos = np.stack(np.meshgrid(np.arange(C) * 1.1, np.arange(R) * 0.9), -1)
    gt = rng.normal(size=(R, C, H, W) if gt_views else (H, W)).astype(np.float32)
    gt.flat[3] = np.nan
    return LightField(
        views=views, wavelengths=raster_wavelengths(R, C), positions=pos, reference=(1, 2),
        disparity_range=(-1.5, 2.0), gt_disparity=gt,
        gt_cube=rng.random((R, C, B, H, W)).astype(np.float32),
        cube_wavelengths=np.linspace(400, 700, B),
        metadata={"scene": "test", "seed": np.int64(3), "params": {"a": 1.5, "b": [1, 2]},
                  "none": None, "calibration": {"focal_px": 1000.0}},
    )


def assert_same(a: LightField, b: LightField, tol):
    assert b.views.shape == a.views.shape
    assert np.max(np.abs(a.views - b.views)) <= tol
    np.testing.assert_array_equal(a.wavelengths, b.wavelengths)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.reference == b.reference and a.disparity_range == b.disparity_range
    np.testing.assert_array_equal(a.gt_disparity, b.gt_disparity)
    np.testing.assert_array_equal(a.gt_cube, b.gt_cube)
    np.testing.assert_array_equal(a.cube_wavelengths, b.cube_wavelengths)


@pytest.mark.parametrize("bit_depth,tol", [(16, 0.5 / 65535 + 1e-7), (8, 0.5 / 255 + 1e-7), (32, 0)])
def test_round_trip(tmp_path, rng, bit_depth, tol):
    lf = make_lf(rng)
    man = write_capture(lf, tmp_path / "cap", bit_depth=bit_depth)
    assert man.name == MANIFEST
    back = read_capture(tmp_path / "cap")
    assert_same(lf, back, tol)
    assert back.metadata["scene"] == "test" and back.metadata["seed"] == 3
    assert back.metadata["params"] == {"a": 1.5, "b": [1, 2]}
    assert back.metadata["calibration"] == {"focal_px": 1000.0}
    assert "none" not in back.metadata
    assert not [f for f in os.listdir(tmp_path / "cap") if ".partial-" in f]


def test_round_trip_per_view_gt_rgb_and_tiff(tmp_path, rng):
    lf = make_lf(rng, gt_views=True)
    write_capture(lf, tmp_path / "a", image_format="tiff")
    assert_same(lf, read_capture(tmp_path / "a"), 0.5 / 65535 + 1e-7)
    rgb = LightField(views=rng.random((2, 3, 5, 6, 3)), metadata={"encoding": "srgb"})
    hyperlf.save(rgb, tmp_path / "rgb")
    back = hyperlf.load(tmp_path / "rgb")
    assert back.views.shape == (2, 3, 5, 6, 3) and back.wavelengths is None
    assert back.metadata["encoding"] == "srgb"


def test_overwrite_rules(tmp_path, rng):
    lf = make_lf(rng, R=2, C=3)
    write_capture(lf, tmp_path / "c")
    with pytest.raises(InvalidInputError, match="overwrite=True"):
        write_capture(lf, tmp_path / "c")
    small = LightField(views=rng.random((1, 2, 10, 12)), wavelengths=[[500, 600]])
    write_capture(small, tmp_path / "c", overwrite=True)
    back = read_capture(tmp_path / "c")
    assert back.grid_shape == (1, 2) and back.gt_disparity is None
    # files of the old capture that the new one does not use are gone
    assert sorted(os.listdir(tmp_path / "c")) == ["capture.toml", "view_r0_c0.png", "view_r0_c1.png"]


def test_views_outside_unit_range_need_float(tmp_path, rng):
    lf = LightField(views=rng.random((1, 2, 4, 4)) * 3)
    with pytest.raises(InvalidInputError, match="bit_depth=32"):
        write_capture(lf, tmp_path / "c")
    write_capture(lf, tmp_path / "d", bit_depth=32)
    np.testing.assert_array_equal(read_capture(tmp_path / "d").views, lf.views)


def test_interrupted_write_leaves_no_manifest(tmp_path, rng, monkeypatch):
    import hyperlf.formats.capture as cap

    calls = []

    def flaky(path, array, bit_depth=16):
        calls.append(path)
        if len(calls) == 4:
            raise KeyboardInterrupt  # killed mid-capture
        return write_image(path, array, bit_depth=bit_depth)

    monkeypatch.setattr(cap, "write_image", flaky)
    with pytest.raises(KeyboardInterrupt):
        write_capture(make_lf(rng), tmp_path / "c")
    files = os.listdir(tmp_path / "c")
    assert MANIFEST not in files and not [f for f in files if ".partial-" in f]
    with pytest.raises(DataNotFoundError, match="not finished"):
        read_capture(tmp_path / "c")
    with pytest.raises(DataNotFoundError):
        hyperlf.load(tmp_path / "c")


# ----------------------------------------------------------------------------- validation
def write_manifest(folder: Path, doc: dict) -> None:
    (folder / MANIFEST).write_text(tomli_w.dumps(doc))


@pytest.fixture
def capdir(tmp_path, rng):
    """A valid 2 x 2 capture with 8-bit grey views; returns (folder, manifest dict)."""
    folder = tmp_path / "cap"
    write_capture(LightField(views=rng.random((2, 2, 6, 5)), wavelengths=[[450, 500], [550, 600]]),
                  folder, bit_depth=8)
    return folder, tomllib.loads((folder / MANIFEST).read_text())


def mutate(doc, fn):
    import copy

    d = copy.deepcopy(doc)
    fn(d)
    return d


CASES = {
    "format": (lambda d: d.update(format="other"), FormatError, "format"),
    "version": (lambda d: d.update(version=99), FormatError, "upgrade"),
    "grid missing": (lambda d: d.pop("grid"), FormatError, "grid"),
    "grid type": (lambda d: d.update(grid="2x2"), FormatError, "grid"),
    "grid bigger": (lambda d: d.update(grid=[3, 2]), FormatError, r"\(2, 0\), \(2, 1\)"),
    "view outside": (lambda d: d.update(grid=[1, 2]), FormatError, "outside grid"),
    "duplicate": (lambda d: d["view"].__setitem__(1, dict(d["view"][0])), FormatError, "twice"),
    "ref outside": (lambda d: d.update(reference=[2, 0]), FormatError, "reference"),
    "wl negative": (lambda d: d["view"][2].update(wavelength=-5.0), FormatError, "positive"),
    "wl type": (lambda d: d["view"][2].update(wavelength="red"), FormatError, "wavelength"),
    "wl partial": (lambda d: d["view"][2].pop("wavelength"), FormatError, "all or none"),
    "file missing": (lambda d: d["view"][1].update(file="gone.png"), DataNotFoundError, "gone.png"),
    "file escape": (lambda d: d["view"][1].update(file="../x.png"), FormatError, "inside"),
    "position": (lambda d: d["view"][1].update(position=[1]), FormatError, "position"),
    "range": (lambda d: d.update(disparity_range=[3, 1]), FormatError, "min < max"),
    "bit depth": (lambda d: d.update(bit_depth=12), FormatError, "bit_depth"),
    "no views": (lambda d: d.pop("view"), FormatError, r"\[\[view\]\]"),
    "metadata": (lambda d: d.update(metadata=3), FormatError, "table"),
    "gt missing": (lambda d: d.update(gt_disparity="gt.pfm"), DataNotFoundError, "gt.pfm"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_manifest_errors(capdir, case):
    folder, doc = capdir
    fn, exc, msg = CASES[case]
    write_manifest(folder, mutate(doc, fn))
    with pytest.raises(exc, match=msg) as info:
        read_capture(folder)
    assert "\n" not in str(info.value)


def test_size_mismatch_and_colour_views(capdir, rng):
    folder, doc = capdir
    write_image(folder / "view_r1_c1.png", rng.random((7, 5)), bit_depth=8)
    with pytest.raises(FormatError, match=r"view \(1, 1\)"):
        read_capture(folder)
    write_image(folder / "view_r1_c1.png", rng.random((6, 5, 3)), bit_depth=8)
    with pytest.raises(FormatError, match="to_grey"):
        read_capture(folder)
    grey = rng.random((6, 5))
    write_image(folder / "view_r1_c1.png", np.repeat(grey[..., None], 3, 2), bit_depth=8)
    assert read_capture(folder).views.shape == (2, 2, 6, 5)  # grey stored as RGB is fine
    (folder / "view_r1_c1.png").write_bytes(b"garbage")
    with pytest.raises(FormatError):
        read_capture(folder)


def test_missing_manifest_and_folder(tmp_path):
    with pytest.raises(DataNotFoundError):
        read_capture(tmp_path / "none")
    with pytest.raises(DataNotFoundError, match=MANIFEST):
        read_capture(tmp_path)


toml_scalars = st.one_of(st.integers(-3, 40), st.floats(allow_nan=False, width=32),
                         st.text(max_size=5), st.booleans())
toml_values = st.recursive(toml_scalars, lambda ch: st.lists(ch, max_size=3)
                           | st.dictionaries(st.sampled_from(["row", "col", "file", "x"]), ch, max_size=3),
                           max_leaves=6)
keys = st.sampled_from(["format", "version", "grid", "reference", "disparity_range", "bit_depth",
                        "channels", "view", "gt_disparity", "gt_cube", "metadata", "calibration"])


@FAST
@given(changes=st.dictionaries(keys, toml_values, min_size=1, max_size=3),
       drop=st.lists(keys, max_size=2))
def test_random_manifest_edits_raise_hyperlf_errors(capdir, changes, drop):
    folder, doc = capdir
    d = dict(doc)
    d.update(changes)
    for k in drop:
        d.pop(k, None)
    write_manifest(folder, d)
    before = sorted(os.listdir(folder))
    try:
        lf = read_capture(folder)
    except (FormatError, DataNotFoundError) as exc:
        assert "\n" not in str(exc)  # one line saying what and where
    else:  # an edit the reader accepts still describes the manifest's grid
        assert lf.grid_shape == tuple(d["grid"])
    assert sorted(os.listdir(folder)) == before


@FAST
@given(text=st.text(alphabet=string.printable, max_size=120))
def test_random_text_manifest(capdir, text):
    folder, _ = capdir
    (folder / MANIFEST).write_text(text)
    before = sorted(os.listdir(folder))
    with pytest.raises((FormatError, DataNotFoundError)):
        read_capture(folder)
    assert sorted(os.listdir(folder)) == before


def test_binary_manifest(capdir):
    folder, _ = capdir
    (folder / MANIFEST).write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(FormatError, match="UTF-8"):
        read_capture(folder)


def test_formats_package_exports_every_module_api():
    import hyperlf.formats as formats
    from hyperlf.formats import capture, envi, hci, hdf5, images, middlebury, pfm

    for module in (capture, envi, hci, hdf5, images, middlebury, pfm):
        for name in module.__all__:
            assert name in formats.__all__
            assert getattr(formats, name) is getattr(module, name)
    assert {"load_lightfield", "save_lightfield"} <= set(formats.__all__)


def test_a_light_field_loads_without_its_cube(tmp_path):
    """``cube=False`` (what ``hyperlf depth`` uses) leaves the ground-truth cube on disk and
    keeps everything else, for capture folders and HDF5 files alike."""
    from hyperlf.formats import load_lightfield, save_lightfield
    from hyperlf.synthesis import procedural_scene

    lf = procedural_scene(seed=1, rows=2, cols=3, height=12, width=16)
    for target in (tmp_path / "cap", tmp_path / "lf.h5"):
        save_lightfield(lf, target)
        full, lean = load_lightfield(target), load_lightfield(target, cube=False)
        assert full.gt_cube is not None and lean.gt_cube is None
        assert lean.cube_wavelengths is None
        np.testing.assert_array_equal(lean.views, full.views)
        np.testing.assert_array_equal(lean.gt_disparity, full.gt_disparity)


def test_what_save_returns_loads_again(tmp_path):
    """save_lightfield returns a folder's capture.toml; load_lightfield takes it back."""
    import hyperlf
    from hyperlf.synthesis import procedural_scene

    lf = procedural_scene(seed=2, rows=2, cols=2, height=12, width=16)
    back = hyperlf.load(hyperlf.save(lf, tmp_path / "cap"))
    np.testing.assert_allclose(back.views, lf.views, atol=1 / 65535)
