"""ENVI cubes: round trips over interleaves and axes, other data types, errors."""

from __future__ import annotations

import os

import numpy as np
import pytest

from hyperlf.errors import DataNotFoundError, FormatError, InvalidInputError
from hyperlf.formats import read_envi, write_envi


@pytest.mark.parametrize("interleave", ["bsq", "bil", "bip"])
def test_round_trip(tmp_path, rng, interleave):
    cube = rng.random((4, 5, 6)).astype(np.float32)
    wl = np.array([410.0, 420.5, 430.0, 440.0])
    hdr = write_envi(tmp_path / "cube", cube, wl, interleave=interleave)
    assert hdr == tmp_path / "cube.hdr" and (tmp_path / "cube.img").stat().st_size == 4 * cube.size
    text = hdr.read_text()
    for line in ("samples = 6", "lines = 5", "bands = 4", "header offset = 0", "data type = 4",
                 "file type = ENVI Standard", f"interleave = {interleave}", "byte order = 0",
                 "wavelength units = Nanometers", "wavelength = {410, 420.5, 430, 440}"):
        assert line in text
    for p in (hdr, tmp_path / "cube.img", tmp_path / "cube"):
        c2, wl2, h = read_envi(p)
        np.testing.assert_array_equal(cube, c2)
        np.testing.assert_array_equal(wl, wl2)
    assert sorted(os.listdir(tmp_path)) == ["cube.hdr", "cube.img"]


def test_unknown_wavelengths_write_no_wavelength_line(tmp_path, rng):
    cube = rng.random((3, 4, 5)).astype(np.float32)
    hdr = write_envi(tmp_path / "u", cube, [np.nan] * 3)
    assert "wavelength" not in hdr.read_text() and "bands = 3" in hdr.read_text()
    c2, wl2, _ = read_envi(hdr)
    np.testing.assert_array_equal(c2, cube)
    assert wl2 is None


def test_hwb_input(tmp_path, rng):
    cube = rng.random((5, 6, 3)).astype(np.float32)
    write_envi(tmp_path / "x.hdr", cube, [500, 600, 700])
    np.testing.assert_array_equal(read_envi(tmp_path / "x.hdr")[0], np.moveaxis(cube, 2, 0))
    write_envi(tmp_path / "y.hdr", cube, axes="hwb")
    assert read_envi(tmp_path / "y.hdr")[1] is None
    with pytest.raises(InvalidInputError):
        write_envi(tmp_path / "z", cube, [1, 2, 3, 4])


@pytest.mark.parametrize("code,dtype", [(1, "u1"), (2, "i2"), (4, "f4"), (5, "f8"), (12, "u2")])
@pytest.mark.parametrize("order", [0, 1])
@pytest.mark.parametrize("interleave", ["bsq", "bil", "bip"])
def test_foreign_types(tmp_path, rng, code, dtype, order, interleave):
    B, H, W = 3, 4, 5
    cube = (rng.random((B, H, W)) * 200).astype(dtype)
    data = {"bsq": cube, "bil": cube.transpose(1, 0, 2), "bip": cube.transpose(1, 2, 0)}[interleave]
    bo = "<" if order == 0 else ">"
    (tmp_path / "f.dat").write_bytes(b"\0" * 16 + np.ascontiguousarray(data).astype(bo + dtype).tobytes())
    (tmp_path / "f.hdr").write_text(
        "ENVI\ndescription = {a\n multi-line}\nsamples = 5\nlines   = 4\nbands = 3\n"
        f"header offset = 16\ndata type = {code}\ninterleave = {interleave}\nbyte order = {order}\n"
        "wavelength units = Micrometers\nwavelength = {0.5,\n 0.6, 0.7}\n"
    )
    c2, wl, h = read_envi(tmp_path / "f.hdr")
    assert c2.dtype == np.dtype(dtype)
    np.testing.assert_array_equal(c2, cube)
    np.testing.assert_allclose(wl, [500, 600, 700])


def test_errors(tmp_path, rng):
    with pytest.raises(DataNotFoundError):
        read_envi(tmp_path / "none.hdr")
    write_envi(tmp_path / "a", rng.random((2, 3, 4)).astype(np.float32))
    (tmp_path / "a.img").write_bytes(b"\0" * 10)
    with pytest.raises(FormatError, match="truncated"):
        read_envi(tmp_path / "a.hdr")
    os.remove(tmp_path / "a.img")
    with pytest.raises(DataNotFoundError):
        read_envi(tmp_path / "a.hdr")
    bad = {
        "no magic": "samples = 1\n",
        "missing": "ENVI\nsamples = 1\nlines = 1\n",
        "type": "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 7\n",
        "int": "ENVI\nsamples = x\nlines = 1\nbands = 1\ndata type = 4\n",
        "brace": "ENVI\nwavelength = {1, 2\n",
        "line": "ENVI\nwhat is this\n",
        "interleave": "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 4\ninterleave = abc\n",
    }
    (tmp_path / "b.img").write_bytes(b"\0" * 64)
    for text in bad.values():
        (tmp_path / "b.hdr").write_text(text)
        with pytest.raises(FormatError):
            read_envi(tmp_path / "b.hdr")
    with pytest.raises(InvalidInputError):
        write_envi(tmp_path / "c", rng.random((2, 3)))
    with pytest.raises(InvalidInputError):
        write_envi(tmp_path / "c", rng.random((2, 3, 4)), interleave="xyz")


def test_files_found_by_the_reader_stay_in_the_folder(tmp_path, rng):
    """A header's ``data file`` and the files found beside the named one must not lead out of
    its folder (an absolute or ``..`` name, a symlink); a file named by the caller is read."""
    cube = rng.random((2, 3, 4)).astype(np.float32)
    outside, inside = tmp_path / "outside", tmp_path / "scene"
    outside.mkdir()
    inside.mkdir()
    write_envi(outside / "c", cube)
    hdr = (outside / "c.hdr").read_text()
    for name in ("../outside/c.img", str(outside / "c.img")):
        (inside / "a.hdr").write_text(hdr + f"data file = {name}\n")
        with pytest.raises(FormatError, match="resolves outside the header's folder"):
            read_envi(inside / "a.hdr")
    (inside / "a.hdr").write_text(hdr)
    os.symlink(outside / "c.img", inside / "a.img")
    with pytest.raises(FormatError, match="copy the data file beside its header"):
        read_envi(inside / "a.hdr")
    np.testing.assert_array_equal(read_envi(inside / "a.img")[0], cube)  # named: read
    os.symlink(outside / "c.hdr", inside / "b.hdr")
    (inside / "b.img").write_bytes((outside / "c.img").read_bytes())
    with pytest.raises(FormatError, match="header .* resolves outside its folder"):
        read_envi(inside / "b.img")
    np.testing.assert_array_equal(read_envi(inside / "b.hdr")[0], cube)
    (inside / "sub").mkdir()
    (inside / "sub" / "d.img").write_bytes((outside / "c.img").read_bytes())
    (inside / "d.hdr").write_text(hdr + "data file = sub/d.img\n")
    np.testing.assert_array_equal(read_envi(inside / "d.hdr")[0], cube)


@pytest.mark.parametrize("description", [None, 5, "a}\nsamples = 2", "two\nlines", "{x"])
def test_a_description_that_would_break_the_header_is_refused(tmp_path, description):
    with pytest.raises(InvalidInputError, match="description must"):
        write_envi(tmp_path / "c", np.ones((2, 3, 4), np.float32), description=description)
    assert not list(tmp_path.iterdir())


def test_the_description_round_trips(tmp_path):
    hdr = write_envi(tmp_path / "c", np.ones((2, 3, 4), np.float32), description="bench 3, 20 C")
    assert read_envi(hdr)[2]["description"] == "bench 3, 20 C"
