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
from hyperlf.formats import read_image, write_image


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


def test_calibrate_writes_file_and_pictures_with_measured_positions(shots, tmp_path, capsys):
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
    capsys.readouterr()
    assert main(["info", str(out)]) == 0  # the folder described: mode, cameras, errors
    text = capsys.readouterr().out
    errs = list(cal.reprojection_errors().values())
    assert ("calibration.toml: calibration (plane mode), 2 x 3 cameras, "
            f"{cal.output_size[0]} x {cal.output_size[1]} px frame") in text
    assert f"reprojection error median {np.median(errs):.3f} px (largest {max(errs):.3f})" in text
    assert "pictures    : corners.png, registered.png, residuals.png" in text


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


def test_a_camera_mounted_upside_down_is_turned_back(shots, tmp_path, capsys):
    """Its board corners come in reverse and fit the board as well, but the scene around the
    board would be registered upside down (the lab capture with one camera's images turned:
    positions 1303 baselines away, no word). The parallax matching finds it and turns it."""
    import cv2

    folder, rig = shots
    work = tmp_path / "shots"
    work.mkdir()
    for f in folder.iterdir():
        (work / f.name).write_bytes(f.read_bytes())
    img = cv2.imread(str(work / "Cam-2.png"), cv2.IMREAD_UNCHANGED)
    assert cv2.imwrite(str(work / "Cam-2.png"), np.ascontiguousarray(img[::-1, ::-1]))
    board = f"{rig.board.cols},{rig.board.rows}"
    for src, out in ((folder, "upright"), (work, "turned")):
        assert main(["calibrate", str(src), "--pattern", "Cam-{index}.png", "--grid", "2,3",
                     "--board", board, "-o", str(tmp_path / out)]) == 0
    assert "camera(s) 0,2: images upside down" in capsys.readouterr().err
    up, turned = (read_calibration(tmp_path / d / "calibration.toml")
                  for d in ("upright", "turned"))
    assert up.info["turned_cameras"] == [] and turned.info["turned_cameras"] == ["0,2"]
    np.testing.assert_allclose(turned.positions(), up.positions(), atol=0.02)
    # the turned camera's homography is the upright one's after the 180-degree turn
    W, H = rig.image_size
    pts = np.array([[10.0, 20.0], [200.0, 30.0], [150.0, 180.0]])
    back = np.c_[W - 1 - pts[:, 0], H - 1 - pts[:, 1]]          # the same pixels, turned
    def apply(Hm, p):
        q = np.c_[p, np.ones(len(p))] @ np.asarray(Hm).T
        return q[:, :2] / q[:, 2:]
    np.testing.assert_allclose(apply(turned.cameras[(0, 2)].homography, back),
                               apply(up.cameras[(0, 2)].homography, pts), atol=0.3)


def test_full_calibration_with_the_reference_turned_says_so(tmp_path, capsys):
    """Several poses (full calibration), the reference camera mounted upside down: the others
    are turned against it, so the log says that the reference may be the turned one and how
    to name another."""
    rig = make_rig(1, 3, seed=6)
    for i, pose in enumerate(rig.calibration_poses(9, n_shared=5)):
        folder = tmp_path / "poses" / f"pose{i}"
        folder.mkdir(parents=True)
        for (r, c), img in rig.render(pose, salt=i, scene=False).items():
            img = img[::-1, ::-1] if (r, c) == rig.reference else img
            write_image(folder / f"Cam-{c}.png", np.clip(img, 0, 1), bit_depth=16)
    assert main(["calibrate", str(tmp_path / "poses"), "--pattern", "Cam-{index}.png",
                 "--grid", "1,3", "--board", f"{rig.board.cols},{rig.board.rows}",
                 "-o", str(tmp_path / "cal")]) == 0
    err = capsys.readouterr().err
    assert "camera(s) 0,0, 0,2: images upside down" in err
    assert "the reference may be the one turned" in err and "--reference" in err
    cal = read_calibration(tmp_path / "cal" / "calibration.toml")
    assert cal.mode == "full" and cal.info["turned_cameras"] == ["0,0", "0,2"]
    assert max(cal.reprojection_errors().values()) < 0.2


def test_a_camera_turned_by_a_quarter_is_named_with_its_angle(tmp_path, capsys):
    """One shot per camera (plane registration), one camera mounted turned by 90 degrees:
    the log names it with the angle, and the file keeps it."""
    import dataclasses

    from hyperlf.calibration.rig import rotation_matrix

    rig = make_rig(2, 3, seed=11, imperfect=0.5)
    cam = rig.cameras[(0, 2)]
    rig.cameras[(0, 2)] = dataclasses.replace(cam, R=rotation_matrix(0, 0, 90) @ cam.R)
    for (r, c), img in rig.render(rig.board_pose(450.0), supersample=2).items():
        write_image(tmp_path / f"Cam-{r * 3 + c}.png", np.clip(img, 0, 1), bit_depth=16)
    assert main(["calibrate", str(tmp_path), "--pattern", "Cam-{index}.png", "--grid", "2,3",
                 "--board", f"{rig.board.cols},{rig.board.rows}", "-o",
                 str(tmp_path / "cal")]) == 0
    err = capsys.readouterr().err
    assert ("camera(s) 0,2: images turned by 90 degrees clockwise against the reference's "
            "(mounted turned); registered turned back") in err
    cal = read_calibration(tmp_path / "cal" / "calibration.toml")
    assert cal.info["turned_cameras"] == ["0,2"] and cal.info["camera_turns"] == {"0,2": 90}


@pytest.mark.parametrize("dc,dr", [(1, 1), (-1, 0), (0, -1), (-1, -1)])
def test_a_wrong_board_size_is_named_with_the_size_seen(shots, tmp_path, capsys, dc, dr):
    """Squares counted instead of inner corners (+1, +1), or a board stated smaller than it is
    (a detector may lock onto a part of it, differently in each camera): a one-line error
    that gives the inner corners the shots show."""
    folder, rig = shots
    capsys.readouterr()
    assert run(folder, "--pattern", "Cam-{index}.png", "--grid", "2,3", "--board",
               f"{rig.board.cols + dc},{rig.board.rows + dr}", "-o", tmp_path / "cal") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"{rig.board.cols} x {rig.board.rows} inner corners" in err, err
    assert not (tmp_path / "cal").exists()


def checkerboard(shape, origin, squares, side=16):
    """A grey image with a checkerboard of ``squares`` (cols, rows) at ``origin`` (x, y)."""
    img = np.full(shape, 0.5, np.float32)
    x0, y0 = origin
    for j in range(squares[1]):
        for i in range(squares[0]):
            img[y0 + j * side:y0 + (j + 1) * side, x0 + i * side:x0 + (i + 1) * side] = \
                0.1 if (i + j) % 2 else 0.9
    return img


def inner_corners(origin, cols, rows, side=16, first=(1, 1)):
    """Inner corners (pixel centres at integers) of :func:`checkerboard`, from corner
    ``first`` (column, row), row by row."""
    j, i = np.mgrid[first[1]:first[1] + rows, first[0]:first[0] + cols]
    return np.stack([origin[0] + i * 16 - 0.5, origin[1] + j * 16 - 0.5], -1).reshape(-1, 2)


def test_a_larger_grid_elsewhere_is_not_the_board():
    """A tiled floor beside the board (a larger grid that does not hold the board's corners)
    is no reason to refuse the board; a part of a larger board is."""
    import cv2

    from hyperlf.calibration.board import BoardSpec, check_board_size
    from hyperlf.errors import InvalidInputError

    cv2.setNumThreads(1)
    img = checkerboard((240, 420), (20, 40), (6, 5))            # the board: 5 x 4 inner corners
    img[20:200, 180:-20] = checkerboard((180, 220), (10, 10), (12, 10))[:180, :220]  # tiles
    check_board_size(img, BoardSpec(5, 4), inner_corners((20, 40), 5, 4))
    big = checkerboard((240, 320), (20, 20), (12, 9))           # 11 x 8 inner corners
    with pytest.raises(InvalidInputError, match="11 x 8 inner corners, more than --board 6,4"):
        check_board_size(big, BoardSpec(6, 4), inner_corners((20, 20), 6, 4, first=(3, 2)))
    check_board_size(big, BoardSpec(11, 8), inner_corners((20, 20), 11, 8))


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


@pytest.mark.parametrize("reference", ["0,1", "2,2"])
def test_the_lab_capture_with_the_reference_at_the_edge(tmp_path, reference):
    """Any camera may be the reference: from the top row's middle, half of the points seen in
    every view with the largest flows were wrong matches, and they used to start the
    parallax model (positions up to 14 baselines off, exit 0)."""
    shots = require_dataset("real_arrays/msir_lab") / "calibration"
    out = tmp_path / "cal"
    assert run(shots, "--pattern", "Cam-{index}.png", "--grid", "3,3", "--board", "11,8",
               "--reference", reference, "-o", out) == 0
    cal = read_calibration(out / "calibration.toml")
    pos = cal.positions() - cal.positions()[cal.reference]
    r0, c0 = cal.reference
    want = np.abs(np.stack(np.meshgrid(np.arange(3.0) - c0, np.arange(3.0) - r0), -1))
    assert np.allclose(np.abs(pos), want, atol=0.1)
    assert cal.info["parallax_rms"] < 0.5


def test_the_lab_capture_with_a_camera_turned_upside_down(tmp_path):
    """One camera of the lab's board shots turned by 180 degrees: no point is then matched in
    every view, which left the parallax model empty and the turn unfound."""
    src = require_dataset("real_arrays/msir_lab") / "calibration"
    shots = tmp_path / "shots"
    shots.mkdir()
    for i in range(9):
        img = read_image(src / f"Cam-{i}.png", as_float=False, channels="grey")
        write_image(shots / f"Cam-{i}.png", img[::-1, ::-1] if i == 5 else img)
    out = tmp_path / "cal"
    assert run(shots, "--pattern", "Cam-{index}.png", "--grid", "3,3", "--board", "11,8",
               "-o", out) == 0
    cal = read_calibration(out / "calibration.toml")
    assert cal.info["turned_cameras"] == ["1,2"] and cal.info["positions_from"] == "parallax"
    pos = cal.positions() - cal.positions()[1, 1]
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


def test_calibrate_says_when_the_board_poses_cannot_tell_near_from_far():
    """Positions from parallax take their sign (near from far) from the board poses' centres.
    When the two barely agree (a cosine of 0.14-0.26 in the registrations that came out
    turned round, against 0.76 and more in every right one, before the poses were solved at
    a short focal length), the log said nothing, and before a square-on board it even said
    the positions were fine."""
    from hyperlf.calibration.plane import SIGN_AGREEMENT_MIN
    from hyperlf.cli import _calibrate_notes

    info = {"positions_from": "parallax", "focal_determined": False}
    sure = _calibrate_notes({**info, "sign_agreement": 0.97})
    assert len(sure) == 1 and "positions are fine" in sure[0]
    notes = _calibrate_notes({**info, "sign_agreement": SIGN_AGREEMENT_MIN - 0.01})
    assert len(notes) == 2 and "swapped" in notes[0]
    assert "tilt the board by 10 degrees" in notes[0]
    assert "positions are fine" not in notes[1]
    # from the board poses alone the sign is theirs: nothing to say about it
    assert not any("swapped" in n for n in _calibrate_notes(
        {"positions_from": "board", "sign_agreement": 0.1}))
