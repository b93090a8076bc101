"""PNG/TIFF reading and writing: exact integer round trips, float scaling, palettes, garbage."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hyperlf.errors import DataNotFoundError, FormatError, InvalidInputError
from hyperlf.formats import read_image, to_grey, write_image

from conftest import require_dataset


@pytest.mark.parametrize("ext", [".png", ".tif"])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("shape", [(9, 7), (9, 7, 3)])
def test_integer_round_trip_exact(tmp_path, rng, ext, dtype, shape):
    a = rng.integers(0, np.iinfo(dtype).max + 1, size=shape).astype(dtype)
    write_image(tmp_path / f"a{ext}", a)
    b = read_image(tmp_path / f"a{ext}", as_float=False)
    assert b.dtype == dtype
    np.testing.assert_array_equal(a, b)  # also checks RGB order survives OpenCV's BGR
    f = read_image(tmp_path / f"a{ext}")
    assert f.dtype == np.float32
    np.testing.assert_allclose(f, a / np.iinfo(dtype).max, rtol=1e-6)
    assert os.listdir(tmp_path) == [f"a{ext}"]


@pytest.mark.parametrize("dtype,shape", [(np.uint16, (40, 30)), (np.uint8, (40, 30, 3))])
def test_lzw_tiff_read_exactly(tmp_path, rng, dtype, shape):
    """LZW TIFFs (what OpenCV and many camera programs write) need a codec tifffile lacks
    without imagecodecs; they are read through OpenCV, exactly and in RGB order."""
    import cv2
    import tifffile

    a = rng.integers(0, np.iinfo(dtype).max + 1, size=shape).astype(dtype)
    bgr = a[..., ::-1] if a.ndim == 3 else a
    assert cv2.imwrite(str(tmp_path / "l.tif"), np.ascontiguousarray(bgr))
    with tifffile.TiffFile(tmp_path / "l.tif") as tif:
        assert tif.pages[0].compression == 5  # LZW, OpenCV's default
    b = read_image(tmp_path / "l.tif", as_float=False)
    assert b.dtype == dtype
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("bits,ext", [(8, ".png"), (16, ".png"), (16, ".tiff"), (32, ".tif")])
def test_float_quantisation(tmp_path, rng, bits, ext):
    a = rng.random((6, 5, 3)).astype(np.float32)
    write_image(tmp_path / f"f{ext}", a, bit_depth=bits)
    b = read_image(tmp_path / f"f{ext}")
    tol = {8: 0.5 / 255, 16: 0.5 / 65535, 32: 0}[bits]
    assert np.max(np.abs(a - b)) <= tol + 1e-7


def test_float_clipped_and_channel_order(tmp_path):
    a = np.zeros((2, 2, 3), np.float32)
    a[..., 0] = 2.0  # red, clipped to 1
    a[..., 2] = -1.0
    write_image(tmp_path / "r.png", a, bit_depth=8)
    import cv2

    bgr = cv2.imread(str(tmp_path / "r.png"), cv2.IMREAD_UNCHANGED)
    assert bgr[0, 0].tolist() == [0, 0, 255]
    assert read_image(tmp_path / "r.png", as_float=False)[0, 0].tolist() == [255, 0, 0]


def test_write_errors(tmp_path):
    with pytest.raises(InvalidInputError):
        write_image(tmp_path / "a.jpg", np.zeros((2, 2)))
    with pytest.raises(InvalidInputError):
        write_image(tmp_path / "a.png", np.zeros((2, 2)), bit_depth=32)
    with pytest.raises(InvalidInputError):
        write_image(tmp_path / "a.png", np.full((2, 2), np.nan))
    with pytest.raises(InvalidInputError):
        write_image(tmp_path / "a.png", np.zeros((2, 2, 2)))
    assert os.listdir(tmp_path) == []


def test_channels_option_and_grey(tmp_path, rng):
    a = rng.random((4, 4, 3)).astype(np.float32)
    write_image(tmp_path / "c.tif", a, bit_depth=32)
    g = read_image(tmp_path / "c.tif", channels="grey")
    np.testing.assert_allclose(g, a @ np.array([0.2126, 0.7152, 0.0722], np.float32), rtol=1e-6)
    write_image(tmp_path / "g.png", a[..., 0], bit_depth=16)
    assert read_image(tmp_path / "g.png", channels="rgb").shape == (4, 4, 3)
    assert to_grey(np.ones((2, 3))).shape == (2,)
    with pytest.raises(InvalidInputError):
        to_grey(np.ones((2, 2)))


def test_missing_and_garbage(tmp_path):
    with pytest.raises(DataNotFoundError):
        read_image(tmp_path / "nope.png")
    for name in ("g.png", "g.tif", "g.tiff", "g.bmp"):
        (tmp_path / name).write_bytes(b"not an image at all")
        with pytest.raises(FormatError):
            read_image(tmp_path / name)


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=200), ext=st.sampled_from([".png", ".tif", ".pgm"]),
       cut=st.integers(8, 400))
def test_garbage_and_truncated_bytes(tmp_path, data, ext, cut):
    p = tmp_path / f"x{ext}"
    p.write_bytes(data)
    with pytest.raises(FormatError):
        read_image(p)
    # a valid file cut short
    q = tmp_path / f"v{ext if ext != '.pgm' else '.png'}"
    write_image(q, np.linspace(0, 1, 400).reshape(20, 20), bit_depth=16)
    full = q.read_bytes()
    if cut < len(full):
        q.write_bytes(full[:cut])
        with pytest.raises(FormatError):
            read_image(q)


def test_palette_png_reads_grey_levels():
    root = require_dataset("tsukuba")
    gt = read_image(root / "groundtruth.png", as_float=False)
    assert gt.ndim == 2 and gt.dtype == np.uint8
    assert gt.max() == 224 and 0 in gt  # grey levels, not palette indices 0..7
    left = read_image(root / "imL.png")
    assert left.shape == (288, 384, 3) and left.dtype == np.float32 and left.max() <= 1
