"""`hyperlf calibrate` (issue 11): board shots in files named by a pattern -> calibration file
and pictures; one-line errors for the cases users meet (board not found in a named camera,
missing or odd-sized images, bad patterns)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from conftest import require_dataset

from hyperlf.calibration import read_calibration
from hyperlf.calibration.rig import make_rig
from hyperlf.cli import main
from hyperlf.formats import write_image


@pytest.fixture(scope="module")
def shots(tmp_path_factory):
    """Board shots of a 2 x 3 imperfect rig, one 16-bit PNG per camera, raster-numbered."""
    rig = make_rig(2, 3, seed=11, imperfect=0.5)
    images = rig.render(rig.board_pose(450.0), supersample=2)
    folder = tmp_path_factory.mktemp("shots")
    for (r, c), img in images.items():
        write_image(folder / f"Cam-{r * 3 + c}.png", np.clip(img, 0, 1), bit_depth=16)
    return folder, rig


def run(*argv):
    return main(["-q", "calibrate", *map(str, argv)])


def test_calibrate_writes_file_and_pictures_with_measured_positions(shots, tmp_path):
    folder, rig = shots
    out = tmp_path / "cal"
    assert run(folder, "--pattern", "Cam-{index}.png", "--grid", "2,3", "--board",
               f"{rig.board.cols},{rig.board.rows}", "-o", out) == 0
    assert sorted(os.listdir(out)) == [".hyperlf-result.json", "calibration.toml",
                                       "corners.png", "registered.png", "residuals.png"]
    cal = read_calibration(out / "calibration.toml")
    assert cal.mode == "plane" and cal.grid == (2, 3)
    true = rig.true_positions()
    for k, cam in cal.cameras.items():
        got = np.asarray(cam.position) - np.asarray(cal.cameras[cal.reference].position)
        want = np.asarray(true[k]) - np.asarray(true[cal.reference])
        assert np.linalg.norm(got - want) < 0.1, (k, got, want)


@pytest.mark.parametrize("case,code,words", [
    ("no fields", 2, ["{index}"]),
    ("missing camera", 4, ["camera 5", "does not exist"]),
    ("odd size", 3, ["camera 0,1"]),
    ("no board", 2, ["0,2"]),
    ("format field", 2, ["may only use"]),
])
def test_calibrate_errors_are_one_line(shots, tmp_path, capsys, case, code, words):
    folder, rig = shots
    pattern = "Cam-{index}.png"
    work = tmp_path / "shots"
    work.mkdir()
    for f in folder.iterdir():
        (work / f.name).write_bytes(f.read_bytes())
    if case == "no fields":
        pattern = "Cam.png"
    elif case == "missing camera":
        (work / "Cam-5.png").unlink()
    elif case == "odd size":
        write_image(work / "Cam-1.png", np.zeros((10, 12)), bit_depth=16)
    elif case == "no board":
        write_image(work / "Cam-2.png", np.full((rig.image_size[1], rig.image_size[0]), 0.5),
                    bit_depth=16)
    elif case == "format field":
        pattern = "Cam-{index.real}.png"
    capsys.readouterr()
    assert run(work, "--pattern", pattern, "--grid", "2,3", "--board",
               f"{rig.board.cols},{rig.board.rows}", "-o", tmp_path / "cal") == code
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)
    assert not (tmp_path / "cal").exists()


def test_calibrate_the_lab_capture(tmp_path):
    shots = require_dataset("real_arrays/msir_lab") / "calibration"
    out = tmp_path / "cal"
    assert run(shots, "--pattern", "Cam-{index}.png", "--grid", "3,3", "--board", "11,8",
               "-o", out) == 0
    cal = read_calibration(out / "calibration.toml")
    pos = cal.positions() - cal.positions()[1, 1]
    assert max(cal.reprojection_errors().values()) < 0.3
    # a 3 x 3 grid up to the mirroring the images show: every neighbour one baseline away
    assert np.allclose(np.abs(pos), [[[1, 1], [0, 1], [1, 1]], [[1, 0], [0, 0], [1, 0]],
                                     [[1, 1], [0, 1], [1, 1]]], atol=0.1)


@pytest.mark.parametrize("case,code,words", [
    ("other size", 2, ["calibration"]),
    ("missing camera", 4, ["camera 4"]),
    ("no calibration", 4, ["calibration"]),
])
def test_ingest_refuses_images_the_calibration_does_not_fit(shots, tmp_path, capsys, case,
                                                            code, words):
    folder, rig = shots
    cal = tmp_path / "cal"
    assert run(folder, "--pattern", "Cam-{index}.png", "--grid", "2,3", "--board",
               f"{rig.board.cols},{rig.board.rows}", "--focal-px", "300", "-o", cal) == 0
    raw = tmp_path / "raw"
    raw.mkdir()
    for i in range(6):
        img = np.full((24, 32) if case == "other size" else rig.image_size[::-1], 0.5)
        if not (case == "missing camera" and i == 4):
            write_image(raw / f"Cam-{i}.png", img, bit_depth=16)
    capsys.readouterr()
    argv = ["-q", "ingest", str(raw), "--calibration",
            str(tmp_path / "nope" if case == "no calibration" else cal),
            "--pattern", "Cam-{index}.png", "-o", str(tmp_path / "cap")]
    assert main(argv) == code
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)
    assert not (tmp_path / "cap").exists()
