"""HDF5 light fields and cubes: round trips, streaming writer, lazy access, atomicity, errors."""

from __future__ import annotations

import os

import h5py
import numpy as np
import pytest

import hyperlf
from hyperlf import LightField, raster_wavelengths
from hyperlf.errors import DataNotFoundError, FormatError, InvalidInputError
from hyperlf.formats import (CubeWriter, open_cube_h5, read_cube_h5, read_lightfield_h5,
                             write_cube_h5, write_lightfield_h5)


def full_lf(rng, R=2, C=3, H=8, W=9, B=4):
    return LightField(
        views=rng.random((R, C, H, W)), wavelengths=raster_wavelengths(R, C),
        positions=rng.normal(size=(R, C, 2)), reference=(1, 0), disparity_range=(-2.0, 3.5),
        gt_disparity=rng.normal(size=(R, C, H, W)), gt_cube=rng.random((R, C, B, H, W)),
        cube_wavelengths=np.linspace(410, 700, B),
        metadata={"scene": "x", "n": np.int32(4), "arr": np.arange(3), "nested": {"k": [1.5]}},
    )


@pytest.mark.parametrize("compression", ["gzip", "lzf", None])
def test_lightfield_round_trip(tmp_path, rng, compression):
    lf = full_lf(rng)
    write_lightfield_h5(tmp_path / "lf.h5", lf, compression=compression)
    b = read_lightfield_h5(tmp_path / "lf.h5")
    for name in ("views", "wavelengths", "positions", "gt_disparity", "gt_cube", "cube_wavelengths"):
        np.testing.assert_array_equal(getattr(lf, name), getattr(b, name), err_msg=name)
    assert b.reference == (1, 0) and b.disparity_range == (-2.0, 3.5)
    assert b.metadata == {"scene": "x", "n": 4, "arr": [0, 1, 2], "nested": {"k": [1.5]}}
    with h5py.File(tmp_path / "lf.h5") as f:
        assert f["views"].chunks == (1, 1, 8, 9)
        assert f["gt_cube"].chunks == (1, 1, 1, 8, 9)
    assert os.listdir(tmp_path) == ["lf.h5"]


def test_minimal_rgb_lightfield_via_save_load(tmp_path, rng):
    lf = LightField(views=rng.random((1, 2, 4, 5, 3)))
    hyperlf.save(lf, tmp_path / "x.hdf5")
    b = hyperlf.load(tmp_path / "x.hdf5")
    np.testing.assert_array_equal(lf.views, b.views)
    assert b.wavelengths is None and b.gt_disparity is None and b.disparity_range is None


def test_cube_round_trip_and_lazy(tmp_path, rng):
    cube = rng.random((2, 3, 4, 5, 6)).astype(np.float32)
    mask = rng.random((2, 3, 5, 6)) > 0.3
    wl = [400, 450, 500, 550]
    write_cube_h5(tmp_path / "c.h5", cube, wl, mask=mask)
    c2, wl2, m2 = read_cube_h5(tmp_path / "c.h5")
    np.testing.assert_array_equal(cube, c2)
    np.testing.assert_array_equal(wl, wl2)
    np.testing.assert_array_equal(mask, m2)
    with open_cube_h5(tmp_path / "c.h5") as cf:
        assert cf.shape == (2, 3, 4, 5, 6)
        assert isinstance(cf.cube, h5py.Dataset) and cf.cube.chunks == (1, 1, 1, 5, 6)
        np.testing.assert_array_equal(cf.view(1, 2), cube[1, 2])
        np.testing.assert_array_equal(cf.cube[0, 1, 2], cube[0, 1, 2])
    write_cube_h5(tmp_path / "n.h5", cube, wl)
    assert read_cube_h5(tmp_path / "n.h5")[2] is None


def test_cube_with_unknown_wavelengths(tmp_path, rng):
    """A cube completed from a capture without wavelengths stores them all NaN; a mix of
    known and NaN is refused."""
    cube = rng.random((1, 2, 3, 4, 5)).astype(np.float32)
    write_cube_h5(tmp_path / "u.h5", cube, [np.nan] * 3)
    c2, wl2, _ = read_cube_h5(tmp_path / "u.h5")
    np.testing.assert_array_equal(c2, cube)
    assert wl2.shape == (3,) and np.isnan(wl2).all()
    with pytest.raises(InvalidInputError, match="all NaN when unknown"):
        write_cube_h5(tmp_path / "m.h5", cube, [500.0, np.nan, 600.0])
    assert not (tmp_path / "m.h5").exists()


def test_cube_description_and_format(tmp_path, rng):
    """``describe`` (hyperlf info): size, wavelengths and the mask's share of True pixels;
    ``h5_format`` tells a cube file from a light field file and from anything else."""
    from hyperlf.formats.hdf5 import CUBE_FORMAT, LF_FORMAT, h5_format

    cube = rng.random((2, 3, 4, 5, 6)).astype(np.float32)
    mask = np.zeros((2, 3, 5, 6), bool)
    mask[:, :, :2] = True  # 2 of 5 rows
    write_cube_h5(tmp_path / "c.h5", cube, [400, 450, 500, 550], mask=mask)
    with open_cube_h5(tmp_path / "c.h5") as cf:
        text = cf.describe()
    assert "2 x 3 views x 4 bands of 6 x 5 px" in text
    assert "4, 400..550 nm" in text and "40.0 % of the pixels (valid)" in text
    assert "registered" not in text and "inferred" not in text
    write_lightfield_h5(tmp_path / "lf.h5", full_lf(rng))
    (tmp_path / "t.h5").write_text("not hdf5")
    assert h5_format(tmp_path / "c.h5") == CUBE_FORMAT
    assert h5_format(tmp_path / "lf.h5") == LF_FORMAT
    assert h5_format(tmp_path / "t.h5") is None and h5_format(tmp_path) is None


def test_streaming_writer(tmp_path, rng):
    R, C, B, H, W = 2, 2, 3, 4, 5
    cube = rng.random((R, C, B, H, W)).astype(np.float32)
    with CubeWriter(tmp_path / "s.h5", (R, C, B, H, W), [500, 600, 700]) as w:
        assert not (tmp_path / "s.h5").exists()  # nothing at the target until complete
        for r in range(R):
            for c in range(C):
                w.write_view(r, c, cube[r, c], mask_rc=np.ones((H, W), bool) if r else None)
    c2, _, m2 = read_cube_h5(tmp_path / "s.h5")
    np.testing.assert_array_equal(cube, c2)
    assert m2.all()  # views without a mask count as valid
    assert os.listdir(tmp_path) == ["s.h5"]


def test_streaming_writer_incomplete_or_failing(tmp_path, rng):
    with pytest.raises(InvalidInputError, match=r"never written: \(1, 1\)"):
        with CubeWriter(tmp_path / "s.h5", (2, 2, 1, 3, 3), [500]) as w:
            for rc in [(0, 0), (0, 1), (1, 0)]:
                w.write_view(*rc, np.zeros((1, 3, 3)))
    with pytest.raises(KeyboardInterrupt):
        with CubeWriter(tmp_path / "s.h5", (1, 1, 1, 3, 3), [500]) as w:
            raise KeyboardInterrupt
    with pytest.raises(InvalidInputError):
        with CubeWriter(tmp_path / "s.h5", (1, 1, 1, 3, 3), [500]) as w:
            w.write_view(0, 0, np.zeros((2, 3, 3)))
    with pytest.raises(InvalidInputError):
        CubeWriter(tmp_path / "s.h5", (1, 1, 2, 3, 3), [500])
    assert os.listdir(tmp_path) == []


def test_interrupted_lightfield_write(tmp_path, rng, monkeypatch):
    lf = full_lf(rng)
    orig = h5py.Group.create_dataset

    def boom(self, name, *a, **k):
        if name == "gt_cube":
            raise KeyboardInterrupt
        return orig(self, name, *a, **k)

    monkeypatch.setattr(h5py.Group, "create_dataset", boom)
    with pytest.raises(KeyboardInterrupt):
        write_lightfield_h5(tmp_path / "lf.h5", lf)
    assert os.listdir(tmp_path) == []


def test_read_errors(tmp_path, rng):
    with pytest.raises(DataNotFoundError):
        read_lightfield_h5(tmp_path / "none.h5")
    (tmp_path / "bad.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"garbage" * 10)
    with pytest.raises(FormatError, match="HDF5"):
        read_lightfield_h5(tmp_path / "bad.h5")
    with pytest.raises(FormatError):
        read_cube_h5(tmp_path / "bad.h5")
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["x"] = 1
    with pytest.raises(FormatError, match="format attribute"):
        read_lightfield_h5(tmp_path / "other.h5")
    write_cube_h5(tmp_path / "cube.h5", rng.random((1, 1, 1, 2, 2)), [500])
    with pytest.raises(FormatError, match="is a cube file .* not a light field"):
        read_lightfield_h5(tmp_path / "cube.h5")
    write_lightfield_h5(tmp_path / "lf.h5", full_lf(rng))
    with pytest.raises(FormatError, match="is a light field file, not a cube: complete it"):
        read_cube_h5(tmp_path / "lf.h5")
    with h5py.File(tmp_path / "lf.h5", "a") as f:
        del f["views"]
    with pytest.raises(FormatError, match="/views"):
        read_lightfield_h5(tmp_path / "lf.h5")
    write_lightfield_h5(tmp_path / "lf2.h5", full_lf(rng))
    with h5py.File(tmp_path / "lf2.h5", "a") as f:
        f.attrs["reference"] = [7, 7]
    with pytest.raises(FormatError, match="outside"):
        read_lightfield_h5(tmp_path / "lf2.h5")
