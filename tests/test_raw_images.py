"""Raw images of a camera array (SPEC §11): the sensor's full scale, not the file's.

A 12-bit camera written as 16-bit integers never exceeds 4095; scaled by 65535 its saturated
pixels sat at 0.06 and the saturation check (0.98) never saw them.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf.calibration.raw import (SENSOR_BITS, RawScale, camera_files, read_camera_images,
                                     read_raw_image, sensor_bits)
from hyperlf.cli import main
from hyperlf.errors import DataNotFoundError, InvalidInputError
from hyperlf.formats import load_lightfield, write_image


@given(largest=st.integers(0, 65535))
def test_sensor_bits_is_the_smallest_depth_that_holds_the_largest_value(largest):
    b = sensor_bits(largest, 16)
    assert b in SENSOR_BITS and largest <= 2 ** b - 1
    smaller = [s for s in SENSOR_BITS if s < b]
    assert all(largest > 2 ** s - 1 for s in smaller)


@given(largest=st.integers(0, 255))
def test_eight_bit_files_are_eight_bit(largest):
    assert sensor_bits(largest, 8) == 8


def write_raw(folder, images):
    """``{index: uint array}`` as ``Cam-{index}.png``, values as they are."""
    folder.mkdir(exist_ok=True)
    for i, a in images.items():
        assert cv2.imwrite(str(folder / f"Cam-{i}.png"), a)
    return camera_files(folder, "Cam-{index}.png", (1, len(images)))


def test_twelve_bit_values_in_sixteen_bit_files_reach_one(tmp_path, rng):
    raw = {i: rng.integers(0, 4000, (8, 9)).astype(np.uint16) for i in range(3)}
    raw[1][2, 3] = 4095  # a saturated pixel
    files = write_raw(tmp_path / "r", raw)
    images, scale = read_camera_images(files, return_scale=True)
    assert scale == RawScale(12, 16)
    for i in range(3):
        np.testing.assert_array_equal(images[(0, i)], raw[i].astype(np.float32) / 4095)
    assert images[(0, 1)][2, 3] == 1.0
    stated, scale = read_camera_images(files, bits=16, return_scale=True)
    assert scale == RawScale(16, 16)
    np.testing.assert_array_equal(stated[(0, 0)], raw[0].astype(np.float32) / 65535)


def test_a_full_range_sixteen_bit_capture_is_unchanged(tmp_path, rng):
    raw = {i: rng.integers(0, 65536, (5, 6)).astype(np.uint16) for i in range(2)}
    raw[0][0, 0] = 65535
    images, scale = read_camera_images(write_raw(tmp_path / "r", raw), return_scale=True)
    assert scale == RawScale(16, 16)
    np.testing.assert_array_equal(images[(0, 1)], raw[1].astype(np.float32) / 65535)


def test_raw_scale_errors_are_named(tmp_path):
    files = write_raw(tmp_path / "mixed", {0: np.full((4, 4), 9, np.uint8),
                                           1: np.full((4, 4), 9, np.uint16)})
    with pytest.raises(InvalidInputError, match=r"camera 0,0 .*uint8.*camera 0,1 .*uint16"):
        read_camera_images(files)
    files = write_raw(tmp_path / "big", {0: np.full((4, 4), 3000, np.uint16),
                                         1: np.full((4, 4), 9, np.uint16)})
    with pytest.raises(InvalidInputError, match="up to 3000, more than 10-bit"):
        read_camera_images(files, bits=10)
    with pytest.raises(InvalidInputError, match="holds 8-bit values, the raw data is 16-bit"):
        read_raw_image(write_raw(tmp_path / "e", {0: np.zeros((3, 3), np.uint8),
                                                  1: np.zeros((3, 3), np.uint8)})[(0, 0)],
                       bits=16)


def test_float_files_are_taken_as_they_are(tmp_path, rng):
    a = rng.random((5, 4)).astype(np.float32) * 3
    write_image(tmp_path / "Cam-0.tif", a, bit_depth=32)
    write_image(tmp_path / "Cam-1.tif", a / 2, bit_depth=32)
    images, scale = read_camera_images(camera_files(tmp_path, "Cam-{index}.tif", (1, 2)),
                                       return_scale=True)
    assert scale == RawScale(None, None)
    np.testing.assert_array_equal(images[(0, 0)], a)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """A plane registration of a 1 x 3 synthetic rig (board shots as 16-bit PNGs)."""
    from hyperlf.calibration.rig import make_rig

    rig = make_rig(1, 3, seed=11, imperfect=0.5)
    tmp = tmp_path_factory.mktemp("raw12")
    shots = tmp / "shots"
    shots.mkdir()
    for (r, c), img in rig.render(rig.board_pose(450.0), supersample=2).items():
        write_image(shots / f"Cam-{c}.png", np.clip(img, 0, 1), bit_depth=16)
    assert main(["-q", "calibrate", str(shots), "--pattern", "Cam-{index}.png", "--grid", "1,3",
                 "--board", f"{rig.board.cols},{rig.board.rows}", "--focal-px", "300", "-o",
                 str(tmp / "cal")]) == 0
    return tmp, rig


def test_ingest_masks_a_twelve_bit_sensors_saturation_and_scales_the_dark_frame(calibrated,
                                                                             capsys):
    tmp, rig = calibrated
    w, h = rig.image_size
    raw = {i: np.full((h, w), 2000, np.uint16) for i in range(3)}
    raw[1][h // 2 - 10:h // 2 + 10, w // 2 - 10:w // 2 + 10] = 4095  # saturated patch
    for i in (0, 2):
        raw[i][0, 0] = 2001  # not constant: a constant camera is refused as dead
    write_raw(tmp / "raw", raw)
    cv2.imwrite(str(tmp / "dark.png"), np.full((h, w), 1000, np.uint16))
    capsys.readouterr()
    base = ["ingest", str(tmp / "raw"), "--calibration", str(tmp / "cal"), "--pattern",
            "Cam-{index}.png", "--dark", str(tmp / "dark.png")]
    assert main(base + ["-o", str(tmp / "cap12")]) == 0
    assert "fit in 12 of their files' 16 bits" in capsys.readouterr().err  # log on stderr
    assert main(["-q"] + base + ["--raw-bits", "16", "-o", str(tmp / "cap16")]) == 0
    lf12, lf16 = load_lightfield(tmp / "cap12"), load_lightfield(tmp / "cap16")
    ref = lf12.reference
    # the centre camera's patch: invalid at 12 bits, taken for image content at 16
    assert not lf12.valid[ref][h // 2, w // 2] and lf16.valid[ref][h // 2, w // 2]
    inside = lf12.valid[ref].copy()
    inside[h // 2 - 14:h // 2 + 14, w // 2 - 14:w // 2 + 14] = False
    v12, v16 = lf12.views[ref][inside], lf16.views[ref][inside]
    np.testing.assert_allclose(v12, 1000 / 4095, atol=1 / 65535 + 1e-6)
    np.testing.assert_allclose(v16, 1000 / 65535, atol=1 / 65535 + 1e-6)


def test_files_numbered_from_one_take_an_offset_in_the_pattern(tmp_path):
    for i in range(1, 7):
        (tmp_path / f"Cam-{i}.png").write_bytes(b"")
    files = camera_files(tmp_path, "Cam-{index+1}.png", (2, 3))
    assert files[(1, 2)].name == "Cam-6.png" and files[(0, 0)].name == "Cam-1.png"
    with pytest.raises(DataNotFoundError, match=r"Cam-1.png is there.*\{index\+1\}"):
        camera_files(tmp_path, "Cam-{index}.png", (2, 3))
    (tmp_path / "r1c2").mkdir()
    assert camera_files(tmp_path, "r{row+1}c{col+1}", (1, 2), must_exist=False)[(0, 1)].name \
        == "r1c2"
    with pytest.raises(DataNotFoundError, match="is not a folder"):
        camera_files(tmp_path / "nope", "Cam-{index}.png", (2, 3))


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"),
               max_size=40))
def test_any_pattern_expands_or_is_refused_in_one_line(pattern):
    from hyperlf.formats.patterns import expand_pattern

    try:
        name = expand_pattern(pattern, ["index", "row", "col"], index=7, row=2, col=1)
    except InvalidInputError as e:
        assert "\n" not in str(e)
        return
    assert isinstance(name, str)


def test_a_file_beyond_the_grid_is_noticed(tmp_path):
    from hyperlf.calibration.raw import beyond_grid

    for i in range(9):
        (tmp_path / f"Cam-{i}.png").write_bytes(b"")
    assert beyond_grid(tmp_path, "Cam-{index}.png", (3, 3)) is None
    assert beyond_grid(tmp_path, "Cam-{index}.png", (2, 4)).name == "Cam-8.png"
    (tmp_path / "v_0_3.png").write_bytes(b"")
    assert beyond_grid(tmp_path, "v_{row}_{col}.png", (2, 3)).name == "v_0_3.png"
