"""What ``ingest`` checks (issue 11). Broken cameras: ``--dead`` leaves a camera out (its file
may be missing) and ``depth`` matches the others; a camera that holds no signal, a dead
reference, too few live cameras and a reference view with no valid pixel are refused in one
line, before a capture is written. Filter wavelengths: read from a list or a file, refused
when they cannot be nanometres."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf import hlf
from hyperlf.calibration import read_calibration
from hyperlf.calibration.rig import make_rig
from hyperlf.cli import main
from hyperlf.errors import DataNotFoundError, HyperLFError, InvalidInputError
from hyperlf.formats import load_lightfield, read_pfm, write_image
from hyperlf.lightfield import LightField
from hyperlf.pipeline import WAVELENGTH_RANGE_NM, _wavelength_table

COLS = 3


def _write(folder, images):
    folder.mkdir(parents=True)
    for (r, c), img in images.items():
        write_image(folder / f"Cam-{r * COLS + c}.png", np.clip(img, 0, 1), bit_depth=16)
    return folder


@pytest.fixture(scope="module")
def rig_dirs(tmp_path_factory):
    """A calibrated ideal 2 x 3 rig: its calibration, its scene shots."""
    tmp = tmp_path_factory.mktemp("dead")
    rig = make_rig(2, COLS, seed=21, imperfect=0.0)
    board = _write(tmp / "board", rig.render(rig.board_pose(450.0), supersample=2))
    scene = _write(tmp / "scene", rig.render(None, supersample=2))
    b = f"{rig.board.cols},{rig.board.rows}"
    assert main(["-q", "calibrate", str(board), "--pattern", "Cam-{index}.png", "--grid",
                 f"2,{COLS}", "--board", b, "--square", str(rig.board.square), "--focal-px",
                 "300", "-o", str(tmp / "cal")]) == 0
    ref = read_calibration(tmp / "cal" / "calibration.toml").reference
    return tmp, scene, tuple(int(v) for v in ref)


def _ingest(tmp, raw, *extra, out="cap"):
    return main(["-q", "ingest", str(raw), "--calibration", str(tmp / "cal"), "--pattern",
                 "Cam-{index}.png", *extra, "-o", str(tmp / out)])


def _scene_copy(tmp, scene, name):
    raw = tmp / name
    if raw.exists():
        shutil.rmtree(raw)
    shutil.copytree(scene, raw)
    return raw


def test_a_dead_camera_needs_no_file_and_depth_matches_the_others(rig_dirs):
    tmp, scene, ref = rig_dirs
    dead = (1 - ref[0], 2 if ref[1] == 0 else 0)  # a corner camera of the other row
    raw = _scene_copy(tmp, scene, "missing")
    (raw / f"Cam-{dead[0] * COLS + dead[1]}.png").unlink()
    assert _ingest(tmp, raw, "--dead", f"{dead[0]},{dead[1]}", out="cap_dead") == 0
    lf = load_lightfield(tmp / "cap_dead")
    assert not lf.valid[dead].any() and lf.valid.sum() > 0.7 * lf.valid.size
    assert _ingest(tmp, scene, out="cap_all") == 0
    for cap in ("cap_dead", "cap_all"):
        assert main(["-q", "depth", str(tmp / cap), "--labels", "24", "-o",
                     str(tmp / f"{cap}_d")]) == 0
    d_dead = read_pfm(tmp / "cap_dead_d" / "disparity.pfm")
    d_all = read_pfm(tmp / "cap_all_d" / "disparity.pfm")
    keep = lf.valid[lf.reference]
    step = (lambda r: (r[1] - r[0]) / 23)(lf.disparity_range)
    assert np.median(np.abs(d_dead - d_all)[keep]) < 0.5 * step


def test_a_view_without_valid_pixels_is_left_out_of_matching():
    """Its image is never read: zeros or the scene give bit-identical depth."""
    rng = np.random.default_rng(0)
    H, W = 24, 32
    base = rng.random((H, W + 12)).astype(np.float32) + 0.2
    views = np.stack([np.stack([base[:, 6 + c * 2:6 + c * 2 + W] for c in range(3)])
                      for _ in range(2)])
    valid = np.ones(views.shape, bool)
    valid[0, 2] = False
    pos = np.stack(np.meshgrid(np.arange(3.0), np.arange(2.0)), -1)  # (x, y) per view
    common = dict(positions=pos, reference=(1, 1), disparity_range=(-3.0, 3.0))
    zeroed = views.copy()
    zeroed[0, 2] = 0.0
    a = hlf.depth(LightField(views=views, valid=valid, **common), n_labels=13).disparity
    b = hlf.depth(LightField(views=zeroed, valid=valid, **common), n_labels=13).disparity
    np.testing.assert_array_equal(a, b)
    valid[:] = False
    valid[1, 1] = True
    with pytest.raises(Exception, match="at least two views with data"):
        hlf.depth(LightField(views=views, valid=valid, **common), n_labels=13)


@pytest.mark.parametrize("case, message", [
    ("dead reference", "reference and cannot be dead"),
    ("one camera left", "at least two must work"),
    ("saturation 1e-9", "no valid pixel"),  # every pixel saturated (0 is refused when read)
])
def test_ingest_refuses_what_leaves_nothing_to_match(rig_dirs, capsys, case, message):
    tmp, scene, ref = rig_dirs
    others = [f"{r},{c}" for r in range(2) for c in range(COLS) if (r, c) != ref]
    extra = {"dead reference": ("--dead", f"{ref[0]},{ref[1]}"),
             "one camera left": [a for k in others for a in ("--dead", k)],
             "saturation 1e-9": ("--saturation", "1e-9")}[case]
    capsys.readouterr()
    assert _ingest(tmp, scene, *extra, out="refused") == 2, case
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert not (tmp / "refused").exists()


def test_a_camera_without_signal_is_named_with_the_fix(rig_dirs, capsys):
    tmp, scene, ref = rig_dirs
    raw = _scene_copy(tmp, scene, "black")
    write_image(raw / f"Cam-{ref[0] * COLS + ref[1]}.png", np.zeros((240, 320)), bit_depth=16)
    capsys.readouterr()
    assert _ingest(tmp, raw, out="refused") == 2
    err = capsys.readouterr().err.strip()
    k = f"{ref[0]},{ref[1]}"
    assert f"camera {k}" in err and f"--dead {k}" in err and "constant" in err
    assert _ingest(tmp, raw, "--dead", k, out="refused") == 2   # the reference: no way out
    write_image(tmp / "dark.png", np.ones((240, 320)), bit_depth=16)
    capsys.readouterr()
    assert _ingest(tmp, scene, "--dark", str(tmp / "dark.png"), out="refused") == 2
    assert "check --dark" in capsys.readouterr().err
    assert not (tmp / "refused").exists()


# ----------------------------------------------------------------------------- wavelengths
WL = [410.0 + 10 * i for i in range(6)]


def test_the_wavelengths_given_reach_the_capture(rig_dirs, tmp_path):
    tmp, scene, _ = rig_dirs
    table = tmp_path / "filters.csv"
    table.write_text("centre_nm\n" + "\n".join(f"{w:g}" for w in WL) + "\n")
    assert _ingest(tmp, scene, "--wavelengths", str(table), out="cap_wl") == 0
    np.testing.assert_array_equal(load_lightfield(tmp / "cap_wl").wavelengths,
                                  np.reshape(WL, (2, COLS)))


@pytest.mark.parametrize("spec, error, words", [
    ("0.41,0.42,0.43,0.44,0.45,0.46", InvalidInputError, "micrometres"),
    ("410,420,430", InvalidInputError, "need 6 numbers"),
    ("410,420,430,440,450,nan", InvalidInputError, "between 200 and 20000"),
    ("410,420,430,440,450,-460", InvalidInputError, "between 200 and 20000"),
    ("filters/none.csv", DataNotFoundError, "is not a file"),
    ("blue,green", InvalidInputError, "give 6 numbers"),
])
def test_wavelengths_that_cannot_be_nanometres_are_refused(spec, error, words):
    with pytest.raises(error, match=words):
        _wavelength_table(spec, (2, 3))


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"),
               max_size=60))
def test_any_wavelength_option_is_a_table_or_a_one_line_error(text):
    try:
        wl = _wavelength_table(text, (2, 3))
    except HyperLFError as e:
        assert "\n" not in str(e)
        return
    assert wl.shape == (2, 3)
    assert (wl >= WAVELENGTH_RANGE_NM[0]).all() and (wl <= WAVELENGTH_RANGE_NM[1]).all()


def test_a_missing_dark_frame_is_named_before_any_image_is_read(rig_dirs, capsys):
    tmp, scene, _ = rig_dirs
    capsys.readouterr()
    assert _ingest(tmp, scene, "--dark", str(tmp / "nope.png"), out="refused") == 4
    err = capsys.readouterr().err.strip()
    assert "--dark" in err and "is not a file" in err and len(err.splitlines()) == 1
    assert not (tmp / "refused").exists()
