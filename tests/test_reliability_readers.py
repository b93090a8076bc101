"""Readers facing hostile files (issue 10, reader cases of items 6 and 8).

Every bad file ends in ONE hyperlf error whose message is one line, raised before anything large
is decoded or allocated: decompression bombs (PNG/TIFF whose header declares a huge image), HDF5
files with groups, corrupt chunks or bad metadata, HCI ``parameters.cfg`` with absurd camera
counts, ENVI/PFM headers that promise more data than the file holds. Hypothesis fuzzing feeds
mutated valid files to the HDF5, HCI and ENVI readers.
"""

from __future__ import annotations

import struct
import time
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest
import tifffile
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hyperlf import LightField, raster_wavelengths
from hyperlf.errors import HyperLFError, FormatError
from hyperlf.formats import (open_cube_h5, read_cube_h5, read_envi, read_hci_scene, read_image,
                             read_lightfield_h5, read_pfm, write_cube_h5, write_envi,
                             write_image, write_lightfield_h5)
from hyperlf.formats import hdf5, images

# Derandomized so that CI runs the same mutations every time.  A mutated version-1 HDF5 file
# once sent libhdf5 into an endless loop (a variable-length string read through a corrupted
# global heap); since version 2 hyperlf stores no text in the heap and reads version-1 text in a
# child process with a time limit (test_corrupt_heap_of_a_version_1_file_is_an_error_not_a_hang).
FUZZ = settings(max_examples=60, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])


def one_line_error(call, kind=HyperLFError) -> str:
    """Run ``call``; it must raise ``kind`` (a hyperlf error) with a one-line message."""
    with pytest.raises(kind) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg and msg, msg
    return msg


def read_or_hyperlf_error(call):
    """``call()`` either returns or raises a one-line hyperlf error; anything else fails."""
    try:
        return call()
    except HyperLFError as exc:
        assert "\n" not in str(exc), str(exc)
        return None


# ----------------------------------------------------------------------------- PNG / TIFF
def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_of_zeros(path: Path, w: int, h: int, depth=16, colour=2, rows=None) -> Path:
    """A PNG of zeros; ``rows`` < h writes only that many rows (a header-only bomb)."""
    per_px = {0: 1, 2: 3}[colour] * depth // 8
    row = b"\x00" * (1 + w * per_px)
    co = zlib.compressobj(9)
    idat = b"".join(co.compress(row) for _ in range(h if rows is None else rows)) + co.flush()
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", idat)
                     + _chunk(b"IEND", b""))
    return path


def test_png_declaring_a_huge_image_is_refused_from_its_header(tmp_path):
    # 16000 x 16000 RGB 16-bit: 1.5 GB stored, 4.6 GB with the float32 copy
    p = png_of_zeros(tmp_path / "bomb.png", 16000, 16000, rows=10)
    assert p.stat().st_size < 10_000
    t0 = time.perf_counter()
    msg = one_line_error(lambda: read_image(p), FormatError)
    assert time.perf_counter() - t0 < 1.0
    assert "16000 x 16000" in msg and "GB" in msg and images.MAX_IMAGE_BYTES_ENV in msg


def test_real_png_bomb_is_refused_before_decoding(tmp_path, monkeypatch):
    p = png_of_zeros(tmp_path / "bomb.png", 3000, 3000)  # 54 MB stored + float copy, ~80 KB file
    assert p.stat().st_size < 200_000
    monkeypatch.setenv(images.MAX_IMAGE_BYTES_ENV, str(20_000_000))
    msg = one_line_error(lambda: read_image(p), FormatError)
    assert "3000 x 3000" in msg and "20 MB" in msg
    monkeypatch.setenv(images.MAX_IMAGE_BYTES_ENV, str(10**9))
    assert read_image(p, as_float=False).shape == (3000, 3000, 3)


def test_bad_limit_in_the_environment_is_one_line(tmp_path, monkeypatch):
    p = write_image(tmp_path / "ok.png", np.zeros((4, 5)))
    monkeypatch.setenv(images.MAX_IMAGE_BYTES_ENV, "lots")
    one_line_error(lambda: read_image(p))


def tiff_declaring(path: Path, w: int, h: int) -> Path:
    """A small TIFF whose ImageWidth/ImageLength tags are patched to ``w`` x ``h``."""
    tifffile.imwrite(path, np.zeros((8, 8), np.uint16))
    with tifffile.TiffFile(path, mode="r+b") as tif:
        tif.pages[0].tags["ImageWidth"].overwrite(w)
        tif.pages[0].tags["ImageLength"].overwrite(h)
    return path


def test_tiff_declaring_a_huge_image_is_refused_from_its_header(tmp_path):
    p = tiff_declaring(tmp_path / "bomb.tif", 200_000, 100_000)
    msg = one_line_error(lambda: read_image(p), FormatError)
    assert "200000 x 100000" in msg and "GB" in msg and images.MAX_IMAGE_BYTES_ENV in msg


def test_real_tiff_bomb_is_refused_before_decoding(tmp_path, monkeypatch):
    p = tmp_path / "bomb.tif"
    tifffile.imwrite(p, np.zeros((2048, 2048), np.uint16), compression="zlib")
    assert p.stat().st_size < 100_000
    monkeypatch.setenv(images.MAX_IMAGE_BYTES_ENV, str(10_000_000))
    assert "2048 x 2048" in one_line_error(lambda: read_image(p), FormatError)


def test_folder_given_as_an_image_says_it_is_a_folder(tmp_path):
    msg = one_line_error(lambda: read_image(tmp_path), FormatError)
    assert "folder" in msg and "does not exist" not in msg


def _png_variants(p: Path) -> dict[str, bytes]:
    b = p.read_bytes()
    idat = b.index(b"IDAT") + 20
    return {"flipped IDAT byte": b[:idat] + bytes([b[idat] ^ 0xFF]) + b[idat + 1:],
            "bad IHDR CRC": b[:29] + b"\0\0\0\0" + b[33:],
            "no IEND": b[:-12], "truncated": b[: len(b) // 2],
            "bad zlib data, good CRC": _recrc_idat(b)}


def _recrc_idat(b: bytes) -> bytes:
    i = b.index(b"IDAT")
    n = struct.unpack(">I", b[i - 4: i])[0]
    data = bytearray(b[i + 4: i + 4 + n])
    data[n // 2] ^= 0xFF
    return b[: i + 4] + bytes(data) + struct.pack(">I", zlib.crc32(b"IDAT" + data)) + b[i + 8 + n:]


def test_corrupt_png_prints_only_hyperlfs_line(tmp_path, capfd, rng):
    src = write_image(tmp_path / "ok.png", rng.random((40, 50, 3)), bit_depth=16)
    for name, data in _png_variants(src).items():
        bad = tmp_path / "bad.png"
        bad.write_bytes(data)
        one_line_error(lambda: read_image(bad), FormatError)
        out, err = capfd.readouterr()
        assert out == "" and err == "", (name, err)


# ----------------------------------------------------------------------------- HDF5
def small_lf(rng, R=2, C=2, H=5, W=6, B=3) -> LightField:
    return LightField(views=rng.random((R, C, H, W)), wavelengths=raster_wavelengths(R, C),
                      gt_cube=rng.random((R, C, B, H, W)), cube_wavelengths=[450, 550, 650],
                      disparity_range=(-1.0, 2.0))


@pytest.fixture
def lf_file(tmp_path, rng) -> Path:
    return write_lightfield_h5(tmp_path / "lf.h5", small_lf(rng))


@pytest.fixture
def cube_file(tmp_path, rng) -> Path:
    return write_cube_h5(tmp_path / "c.h5", rng.random((2, 2, 3, 5, 6)), [450, 550, 650],
                         mask=rng.random((2, 2, 5, 6)) > 0.5)


def replace(path: Path, name: str, make) -> Path:
    """Replace dataset ``/name`` of ``path`` by ``make(file)``'s object."""
    with h5py.File(path, "r+") as f:
        del f[name]
        make(f, name)
    return path


def read_cube_everything(p):
    with open_cube_h5(p) as cf:
        [cf.view(r, c) for r in range(cf.shape[0]) for c in range(cf.shape[1])]
    return read_cube_h5(p)


@pytest.mark.parametrize("name", ["cube", "wavelengths", "mask"])
def test_cube_dataset_that_is_a_group(cube_file, name):
    replace(cube_file, name, lambda f, n: f.create_group(n))
    assert f"'/{name}'" in one_line_error(lambda: read_cube_everything(cube_file), FormatError)


@pytest.mark.parametrize("name", ["views", "positions", "gt_cube"])
def test_lightfield_dataset_that_is_a_group(lf_file, name):
    replace(lf_file, name, lambda f, n: f.create_group(n))
    assert f"'/{name}'" in one_line_error(lambda: read_lightfield_h5(lf_file), FormatError)


def flip_chunk_bytes(path: Path, name: str) -> Path:
    """Flip bytes in the middle of the first stored chunk of ``/name`` (gzip-compressed)."""
    with h5py.File(path, "r") as f:
        info = f[name].id.get_chunk_info(0)
    with open(path, "r+b") as fh:
        fh.seek(info.byte_offset + info.size // 2)
        chunk = fh.read(8)
        fh.seek(info.byte_offset + info.size // 2)
        fh.write(bytes(v ^ 0xFF for v in chunk))
    return path


def test_corrupt_gzip_chunk_in_a_cube_file(cube_file):
    flip_chunk_bytes(cube_file, "cube")
    with open_cube_h5(cube_file) as cf:
        msg = one_line_error(lambda: cf.view(0, 0), FormatError)
    assert "corrupt" in msg
    one_line_error(lambda: read_cube_h5(cube_file), FormatError)


@pytest.mark.parametrize("name", ["views", "gt_cube"])
def test_corrupt_gzip_chunk_in_a_lightfield_file(lf_file, name):
    flip_chunk_bytes(lf_file, name)
    assert "corrupt" in one_line_error(lambda: read_lightfield_h5(lf_file), FormatError)


BAD_PAIRS = [np.array([b"a", b"b"]), np.array([np.nan, 1.0]), np.array([1, 2, 3]),
             np.array([[0, 1], [1, 0]]), np.array([1.5, 0.0]), "0, 1", np.array([1e20, 0.0])]


@pytest.mark.parametrize("value", BAD_PAIRS, ids=repr)
def test_bad_reference_attribute(lf_file, value):
    with h5py.File(lf_file, "r+") as f:
        f.attrs["reference"] = value
    assert "reference" in one_line_error(lambda: read_lightfield_h5(lf_file), FormatError)


@pytest.mark.parametrize("value", BAD_PAIRS[:4] + ["0, 1", np.array([np.inf, 1.0])], ids=repr)
def test_bad_disparity_range_attribute(lf_file, value):
    with h5py.File(lf_file, "r+") as f:
        f.attrs["disparity_range"] = value
    assert "disparity" in one_line_error(lambda: read_lightfield_h5(lf_file), FormatError)


@pytest.mark.parametrize("value", [np.full((2, 2, 2), b"x"), np.full((2, 2, 2), np.nan),
                                   np.zeros((2, 2, 3)), np.zeros(4), np.zeros((2, 2, 2), complex)],
                         ids=["strings", "nan", "3 coords", "flat", "complex"])
def test_bad_positions_dataset(lf_file, value):
    replace(lf_file, "positions", lambda f, n: f.create_dataset(n, data=value))
    assert "positions" in one_line_error(lambda: read_lightfield_h5(lf_file), FormatError)


def test_cube_of_strings_is_reported_as_such(cube_file):
    replace(cube_file, "cube", lambda f, n: f.create_dataset(n, data=np.full((2, 2, 3, 5, 6), b"ab")))
    msg = one_line_error(lambda: read_cube_everything(cube_file), FormatError)
    assert "number" in msg and "positions" not in msg


def test_lightfield_views_of_strings_are_reported_as_such(lf_file):
    replace(lf_file, "views", lambda f, n: f.create_dataset(n, data=np.full((2, 2, 5, 6), b"ab")))
    msg = one_line_error(lambda: read_lightfield_h5(lf_file), FormatError)
    assert "number" in msg and "positions" not in msg


@pytest.mark.parametrize("name", ["wavelengths", "cube_wavelengths"])
def test_lightfield_wavelengths_of_strings(lf_file, name):
    shape = (2, 2) if name == "wavelengths" else (3,)
    replace(lf_file, name, lambda f, n: f.create_dataset(n, data=np.full(shape, b"nm")))
    assert name in one_line_error(lambda: read_lightfield_h5(lf_file), FormatError)


def test_cube_wavelengths_of_strings(cube_file):
    replace(cube_file, "wavelengths", lambda f, n: f.create_dataset(n, data=np.full(3, b"nm")))
    assert "wavelengths" in one_line_error(lambda: read_cube_everything(cube_file), FormatError)


def test_huge_declared_dataset_is_refused_before_allocating(lf_file):
    # a chunked dataset that was never written: tiny on disk, 4 PB when read
    replace(lf_file, "views", lambda f, n: f.create_dataset(
        n, shape=(1000, 1000, 10**6, 1000), dtype=np.float32, chunks=(1, 1, 8, 8)))
    msg = one_line_error(lambda: read_lightfield_h5(lf_file), FormatError)
    assert "'/views'" in msg and "GB" in msg


@pytest.mark.parametrize("value", [np.array([b"a", b"b"]), np.array([1, 2]), 3])
def test_odd_format_and_metadata_attributes(cube_file, lf_file, value):
    for p in (cube_file, lf_file):
        with h5py.File(p, "r+") as f:
            f.attrs["metadata"] = value
        read_or_hyperlf_error(lambda: read_cube_everything(p) if p == cube_file
                              else read_lightfield_h5(p))
        with h5py.File(p, "r+") as f:
            f.attrs["format"] = value
        one_line_error(lambda: read_cube_everything(p) if p == cube_file
                       else read_lightfield_h5(p), FormatError)


# ----------------------------------------------------------------------------- text attributes
DATA = Path(__file__).parent / "data"


def heap_attributes(path) -> list[str]:
    """Names of the root attributes of ``path`` stored as variable-length data (global heap)."""
    with h5py.File(path, "r") as f:
        return [n for n in f.attrs if hdf5._uses_heap(f, n)]


def test_new_files_keep_their_text_out_of_the_heap(cube_file, lf_file):
    assert heap_attributes(cube_file) == [] and heap_attributes(lf_file) == []
    with h5py.File(cube_file, "r") as f:
        assert f.attrs["version"] == hdf5.VERSION == 2


def as_version_1(path: Path) -> Path:
    """Rewrite ``path``'s text attributes as variable-length strings, as version 1 wrote them."""
    with h5py.File(path, "r+") as f:
        text = {n: f.attrs[n].decode() for n in ("format", "metadata")}
        for n, v in text.items():
            del f.attrs[n]
            f.attrs[n] = v  # a Python str: h5py stores a variable-length string
        f.attrs["version"] = 1
    assert sorted(heap_attributes(path)) == ["format", "metadata"]
    return path


def test_version_1_files_still_read(tmp_path, rng):
    lf = small_lf(rng)
    lf.metadata["note"] = "zürich"
    back = read_lightfield_h5(as_version_1(write_lightfield_h5(tmp_path / "lf.h5", lf)))
    assert back.metadata["note"] == "zürich"
    np.testing.assert_array_equal(back.views, lf.views)
    cube = rng.random((2, 2, 3, 5, 6))
    p = as_version_1(write_cube_h5(tmp_path / "c.h5", cube, [450, 550, 650],
                                   metadata={"scene": "x"}))
    with open_cube_h5(p) as cf:
        assert cf.metadata == {"scene": "x"}
        np.testing.assert_allclose(cf.view(1, 0), cube[1, 0], rtol=1e-6)


def test_corrupt_heap_of_a_version_1_file_is_an_error_not_a_hang(tmp_path, monkeypatch):
    # a mutated cube file on which libhdf5 loops forever reading the 'format' string in-process
    monkeypatch.setattr(hdf5, "HEAP_READ_TIMEOUT_S", 3.0)
    p = tmp_path / "c.h5"
    p.write_bytes((DATA / "cube_v1_corrupt_heap.h5").read_bytes())
    assert "did not finish in 3 s" in one_line_error(lambda: read_cube_h5(p), FormatError)


def test_a_child_that_cannot_read_the_attribute_is_one_line(lf_file):
    msg = one_line_error(lambda: hdf5._read_heap_attr(lf_file, "no such attribute"),
                         FormatError)
    assert "'no such attribute'" in msg and "corrupt" in msg


def test_metadata_larger_than_an_object_header_message(tmp_path, rng):
    lf = small_lf(rng)
    lf.metadata["calibration"] = {"residuals": [float(v) for v in rng.random(20000)]}
    back = read_lightfield_h5(write_lightfield_h5(tmp_path / "lf.h5", lf))
    assert back.metadata["calibration"] == lf.metadata["calibration"]


def test_numbers_stored_as_variable_length_data_are_refused_unread(lf_file):
    with h5py.File(lf_file, "r+") as f:
        del f.attrs["reference"]
        rows = np.empty(2, dtype=object)
        rows[0], rows[1] = np.array([1]), np.array([2])
        f.attrs.create("reference", rows, dtype=h5py.vlen_dtype(np.int64))
    assert "reference" in one_line_error(lambda: read_lightfield_h5(lf_file), FormatError)


# ----------------------------------------------------------------------------- HCI
def hci_scene(folder: Path, cfg: str | None, n=2) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n * n):
        write_image(folder / f"input_Cam{i:03d}.png", np.full((4, 5, 3), i / 10), bit_depth=8)
    if cfg is not None:
        (folder / "parameters.cfg").write_text(cfg)
    return folder


@pytest.mark.parametrize("nx, ny", [(10**12, 10**12), (-3, 3), ("many", 2), (2, 0), (3.5, 2),
                                    (40, 40)])
def test_hci_absurd_camera_counts_are_refused_at_once(tmp_path, nx, ny):
    folder = hci_scene(tmp_path / "s", f"[extrinsics]\nnum_cams_x = {nx}\nnum_cams_y = {ny}\n")
    t0 = time.perf_counter()
    msg = one_line_error(lambda: read_hci_scene(folder), FormatError)
    assert time.perf_counter() - t0 < 1.0 and "num_cams" in msg


def test_hci_grid_keyword_too_large_is_refused_at_once(tmp_path):
    folder = hci_scene(tmp_path / "s", None)
    one_line_error(lambda: read_hci_scene(folder, grid=(10**9, 10**9)))


def test_hci_sane_camera_counts_still_read(tmp_path):
    folder = hci_scene(tmp_path / "s", "[extrinsics]\nnum_cams_x = 2\nnum_cams_y = 2\n")
    assert read_hci_scene(folder).grid_shape == (2, 2)


# ----------------------------------------------------------------------------- ENVI / PFM
@pytest.mark.parametrize("sizes", [(10**9, 10**9, 10**9), (10**30, 1, 1), (4, 5, 10**12)])
def test_envi_header_with_absurd_sizes(tmp_path, rng, sizes):
    hdr = write_envi(tmp_path / "c", rng.random((3, 4, 5)).astype(np.float32))
    W, H, B = sizes
    text = hdr.read_text().replace("samples = 5", f"samples = {W}")
    hdr.write_text(text.replace("lines = 4", f"lines = {H}").replace("bands = 3", f"bands = {B}"))
    assert "too small" in one_line_error(lambda: read_envi(hdr), FormatError)


@pytest.mark.parametrize("w, h", [(10**9, 10**9), (10**40, 1), (1, 4)])
def test_pfm_header_declaring_more_than_the_file_holds(tmp_path, w, h):
    p = tmp_path / "x.pfm"
    p.write_bytes(f"Pf\n{w} {h}\n-1\n".encode() + b"\0" * 12)
    one_line_error(lambda: read_pfm(p), FormatError)


# ----------------------------------------------------------------------------- fuzzing
def mutate(data: bytes, edits) -> bytes:
    b = bytearray(data)
    for pos, val in edits:
        b[pos % len(b)] = val
    return bytes(b)


EDITS = st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255)), min_size=1, max_size=12)


@pytest.fixture(scope="module")
def valid_h5(tmp_path_factory):
    d = tmp_path_factory.mktemp("h5")
    rng = np.random.default_rng(3)
    lf = write_lightfield_h5(d / "lf.h5", small_lf(rng), compression="gzip")
    cube = write_cube_h5(d / "c.h5", rng.random((2, 2, 3, 5, 6)), [450, 550, 650],
                         mask=rng.random((2, 2, 5, 6)) > 0.5)
    return {"lf": lf.read_bytes(), "cube": cube.read_bytes()}


@FUZZ
@given(edits=EDITS)
def test_fuzz_mutated_lightfield_h5(tmp_path, valid_h5, edits):
    p = tmp_path / "lf.h5"
    p.write_bytes(mutate(valid_h5["lf"], edits))
    lf = read_or_hyperlf_error(lambda: read_lightfield_h5(p))
    assert lf is None or isinstance(lf, LightField)


@FUZZ
@given(edits=EDITS)
def test_fuzz_mutated_cube_h5(tmp_path, valid_h5, edits):
    p = tmp_path / "c.h5"
    p.write_bytes(mutate(valid_h5["cube"], edits))
    read_or_hyperlf_error(lambda: read_cube_everything(p))


@FUZZ
@given(data=st.binary(max_size=3000), prefix=st.booleans())
def test_fuzz_random_bytes_as_h5(tmp_path, data, prefix):
    p = tmp_path / "r.h5"
    p.write_bytes((b"\x89HDF\r\n\x1a\n" if prefix else b"") + data)
    read_or_hyperlf_error(lambda: read_lightfield_h5(p))
    read_or_hyperlf_error(lambda: read_cube_everything(p))


CFG_VALUE = st.one_of(st.integers(-10**15, 10**15), st.floats(allow_nan=True),
                      st.text(max_size=12).filter(lambda s: "\n" not in s and "\r" not in s))
CFG_KEY = st.sampled_from(["num_cams_x", "num_cams_y", "disp_min", "disp_max", "baseline_mm"])


@pytest.fixture(scope="module")
def hci_folder(tmp_path_factory):
    return hci_scene(tmp_path_factory.mktemp("hci") / "s", None, n=3)


@FUZZ
@given(entries=st.lists(st.tuples(st.sampled_from(["extrinsics", "meta", "intrinsics"]),
                                  CFG_KEY, CFG_VALUE), max_size=8),
       junk=st.binary(max_size=40))
def test_fuzz_hci_parameters_cfg(hci_folder, entries, junk):
    sections: dict[str, list[str]] = {}
    for sec, key, val in entries:
        sections.setdefault(sec, []).append(f"{key} = {val}")
    text = "".join(f"[{s}]\n" + "\n".join(lines) + "\n" for s, lines in sections.items())
    (hci_folder / "parameters.cfg").write_bytes(text.encode() + junk)
    lf = read_or_hyperlf_error(lambda: read_hci_scene(hci_folder))
    assert lf is None or isinstance(lf, LightField)


@FUZZ
@given(which=st.integers(0, 8), data=st.binary(max_size=300))
def test_fuzz_hci_view_files(tmp_path, which, data):
    folder = hci_scene(tmp_path / "f", None, n=3)
    (folder / f"input_Cam{which:03d}.png").write_bytes(data)
    read_or_hyperlf_error(lambda: read_hci_scene(folder))


@pytest.fixture(scope="module")
def envi_pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("envi")
    hdr = write_envi(d / "c", np.random.default_rng(1).random((3, 4, 5)).astype(np.float32),
                     wavelengths=[450, 550, 650])
    return hdr.read_text(), (d / "c.img").read_bytes()


@FUZZ
@given(edits=st.lists(st.tuples(st.integers(0, 10**4), st.characters(max_codepoint=0x2FF)),
                      min_size=1, max_size=10))
def test_fuzz_envi_header(tmp_path, envi_pair, edits):
    text = list(envi_pair[0])
    for pos, ch in edits:
        text[pos % len(text)] = ch
    (tmp_path / "c.hdr").write_text("".join(text), encoding="utf-8", errors="surrogatepass")
    (tmp_path / "c.img").write_bytes(envi_pair[1])
    read_or_hyperlf_error(lambda: read_envi(tmp_path / "c.hdr"))


@FUZZ
@given(lines=st.lists(st.tuples(st.sampled_from(["samples", "lines", "bands", "data type",
                                                 "byte order", "header offset", "interleave",
                                                 "data file", "wavelength", "wavelength units"]),
                                st.text(max_size=25)), max_size=10))
def test_fuzz_envi_header_values(tmp_path, envi_pair, lines):
    extra = "".join(f"\n{k} = {v}" for k, v in lines)
    (tmp_path / "c.hdr").write_text(envi_pair[0] + extra, encoding="utf-8", errors="surrogatepass")
    (tmp_path / "c.img").write_bytes(envi_pair[1])
    read_or_hyperlf_error(lambda: read_envi(tmp_path / "c.hdr"))
