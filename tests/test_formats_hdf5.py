"""HDF5 light fields and cubes: round trips, streaming writer, lazy access, atomicity, errors."""

from __future__ import annotations

import os
import zlib

import h5py
import numpy as np
import pytest

import hyperlf
from hyperlf import LightField, raster_wavelengths
from hyperlf.errors import DataNotFoundError, FormatError, InvalidInputError
from hyperlf.formats import (CubeWriter, open_cube_h5, read_cube_h5, read_lightfield_h5,
                             write_cube_h5, write_lightfield_h5)
from hyperlf._parallel import threads
from hyperlf.formats._h5chunks import read_images, write_images
from hyperlf.formats.hdf5 import ChunkedImages


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
    with pytest.raises(InvalidInputError, match="is a cube file .* not a light field"):
        read_lightfield_h5(tmp_path / "cube.h5")
    write_lightfield_h5(tmp_path / "lf.h5", full_lf(rng))
    with pytest.raises(InvalidInputError,
                       match="is a light field file, not a cube: complete it"):
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


# ----------------------------------------------------------------------------- parallel chunks
def _chunks(ds, lead=()):
    """The stored bytes of every image chunk below the indices ``lead``."""
    keys = np.ndindex(*ds.shape[len(lead):-2])
    return [ds.id.read_direct_chunk(tuple(lead) + tuple(k) + (0, 0)) for k in keys]


@pytest.mark.parametrize("n_threads", ["1", "3"])  # 1: libhdf5's filters, the reference
@pytest.mark.parametrize("dtype,shuffle", [("<f4", True), ("<f4", False), (">f4", True),
                                           ("bool", True), ("uint8", True), ("<u2", True),
                                           ("<f8", True), ("<c16", True)])
def test_parallel_chunks_are_the_bytes_hdf5_writes(tmp_path, rng, monkeypatch, n_threads, dtype,
                                                   shuffle):
    """The chunks write_images compresses itself are byte for byte what libhdf5's shuffle and
    deflate filters store, so any HDF5 reader reads them."""
    monkeypatch.setenv("HYPERLF_THREADS", n_threads)
    data = (rng.random((2, 5, 17, 23)) * (3 if dtype == "bool" else 300)).astype(dtype)
    data[0, 1] = 0  # a run that compresses well next to noise
    opts = dict(chunks=(1, 1, 1, 17, 23), compression="gzip", compression_opts=4, shuffle=shuffle)
    with h5py.File(tmp_path / "f.h5", "w") as f:
        ours = f.create_dataset("ours", shape=(3,) + data.shape, dtype=dtype, **opts)
        theirs = f.create_dataset("theirs", shape=(3,) + data.shape, dtype=dtype, **opts)
        write_images(ours, (1,), data)
        theirs[1] = data
        assert _chunks(ours, (1,)) == _chunks(theirs, (1,))
        np.testing.assert_array_equal(ours[()], theirs[()])
        np.testing.assert_array_equal(ours[1], data)
        back = read_images(theirs, (1,))  # and read back in parallel
        assert back.dtype == theirs.dtype and back.shape == data.shape
        # and spelled as h5py's own read spells it: 'float32', not '<f4' (big-endian stays)
        assert repr(back.dtype) == repr(theirs[1].dtype)
        np.testing.assert_array_equal(back, data)
        np.testing.assert_array_equal(read_images(theirs, (1, 1, 3)), data[1, 3])
        np.testing.assert_array_equal(read_images(theirs), theirs[()])  # chunks never written
        np.testing.assert_array_equal(read_images(theirs, (-2,)), data)  # h5py's own path


@pytest.mark.parametrize("stored", [b"not zlib", zlib.compress(b"short"),
                                    zlib.compress(bytes(10_000))])
def test_a_chunk_that_does_not_inflate_to_its_image_is_refused(tmp_path, monkeypatch, stored):
    """A corrupt chunk, one too short and one too long (a decompression bomb is cut off at the
    image's size) are errors, and the readers call the file corrupt."""
    monkeypatch.setenv("HYPERLF_THREADS", "2")
    path = tmp_path / "c.h5"
    write_cube_h5(path, np.ones((1, 2, 3, 8, 9), np.float32), np.array([450.0, 550, 650]))
    with h5py.File(path, "r+") as f:
        f["cube"].id.write_direct_chunk((0, 1, 2, 0, 0), stored)
        with pytest.raises((ValueError, zlib.error)):
            read_images(f["cube"], (0, 1))
    with pytest.raises(FormatError, match="corrupt"):
        read_cube_h5(path)
    with open_cube_h5(path) as cf:
        assert cf.view(0, 0).tolist() == np.ones((3, 8, 9)).tolist()
        with pytest.raises(FormatError, match="corrupt"):
            cf.view(0, 1)
        views = ChunkedImages(cf.cube)  # what cube_scores reads
        assert views.shape == (1, 2, 3, 8, 9) and len(views) == 1 and views.ndim == 5
        np.testing.assert_array_equal(views[0, 0], np.ones((3, 8, 9)))
        np.testing.assert_array_equal(views[0, 1, 1], np.ones((8, 9)))
        with pytest.raises(FormatError, match=r"'/?cube'.*corrupt"):
            views[0, 1]


def test_other_layouts_are_written_plainly(tmp_path, rng):
    data = rng.random((4, 6, 8)).astype(np.float32)
    with h5py.File(tmp_path / "f.h5", "w") as f:
        for name, opts in [("lzf", dict(chunks=(1, 1, 6, 8), compression="lzf")),
                           ("plain", {}), ("halves", dict(chunks=(1, 1, 3, 8), compression="gzip")),
                           ("checksum", dict(chunks=(1, 1, 6, 8), compression="gzip",
                                             fletcher32=True))]:
            ds = f.create_dataset(name, shape=(2,) + data.shape, dtype=np.float32, **opts)
            write_images(ds, (1,), data)
            np.testing.assert_array_equal(ds[1], data)
            np.testing.assert_array_equal(read_images(ds, (1,)), data)
        with pytest.raises((TypeError, ValueError)):  # h5py's own check of a wrong shape
            write_images(f["plain"], (1,), data[:2])


@pytest.mark.parametrize("value,expected", [("2", 2), ("16", 16), ("0", None), ("-1", None),
                                            ("x", None), ("", None), (" 3 ", 3)])
def test_the_thread_setting_the_hdf5_pool_reads(monkeypatch, value, expected):
    monkeypatch.setenv("HYPERLF_THREADS", value)
    assert threads() == (expected or len(os.sched_getaffinity(0)))


def test_lightfield_and_cube_files_keep_their_bytes(tmp_path, rng, monkeypatch):
    """The writers' files hold the same chunks whether compressed in one thread or many."""
    lf = LightField(views=rng.random((2, 3, 9, 11)).astype(np.float32),
                    positions=np.stack(np.meshgrid(np.arange(3.0), np.arange(2.0))[::-1], -1),
                    wavelengths=raster_wavelengths(2, 3), reference=(0, 1),
                    valid=rng.random((2, 3, 9, 11)) > 0.2,
                    gt_cube=rng.random((2, 3, 6, 9, 11)).astype(np.float32),
                    cube_wavelengths=np.linspace(420, 670, 6))
    files = {}
    for n in ("1", "4"):
        monkeypatch.setenv("HYPERLF_THREADS", n)
        files[n] = write_lightfield_h5(tmp_path / f"lf{n}.h5", lf)
    with h5py.File(files["1"]) as a, h5py.File(files["4"]) as b:
        for name in ("views", "gt_cube", "valid"):
            assert _chunks(a[name]) == _chunks(b[name])
    back = read_lightfield_h5(files["4"])
    np.testing.assert_array_equal(back.views, lf.views)
    np.testing.assert_array_equal(back.gt_cube, lf.gt_cube)
    np.testing.assert_array_equal(back.valid, lf.valid)


def test_datasets_explain_themselves_to_plain_h5py(tmp_path):
    """Axes, units and meaning are attributes of every dataset hyperlf writes."""
    from hyperlf.synthesis import procedural_scene

    lf = procedural_scene(seed=1, rows=2, cols=2, height=12, width=16)
    path = write_lightfield_h5(tmp_path / "lf.h5", lf)
    with h5py.File(path, "r") as f:
        assert f["wavelengths"].attrs["unit"] == b"nm"
        assert f["positions"].attrs["unit"] == b"baselines"
        assert f["gt_disparity"].attrs["unit"] == b"px per baseline"
        assert f["views"].attrs["axes"].startswith(b"row, col, y, x")
