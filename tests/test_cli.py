"""The command-line tool: help, exit codes, and the demo/synth/info/convert chain."""

import argparse
import subprocess
import sys

import numpy as np
import pytest

from hyperlf.cli import main


def test_help_teaches(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for word in ("demo", "synth", "info", "convert", "examples"):
        assert word in out


def test_help_does_not_import_the_numerical_stack():
    # `--help` builds every subcommand's parser (the `--method` choices come from
    # hyperlf.baselines); scipy was 0.4 of its 0.8 s before the baselines imported it lazily.
    code = ("import sys\nfrom hyperlf.cli import main\n"
            "try:\n    main(['depth', '--help'])\nexcept SystemExit:\n    pass\n"
            "print('LOADED', ' '.join(m for m in ('scipy', 'numba', 'cv2', 'h5py', 'matplotlib')"
            " if m in sys.modules) or 'none')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "tao2013" in out  # the choices were built
    assert out.strip().splitlines()[-1] == "LOADED none"


def test_synth_help_names_every_named_scene(capsys):
    from hyperlf.synthesis import SCENES

    with pytest.raises(SystemExit):
        main(["synth", "procedural", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    listed = out.split("a named scene:")[1].split("(default")[0]
    assert sorted(n.strip() for n in listed.split(",")) == sorted(SCENES)


@pytest.mark.parametrize("command, titles", [
    ("depth", ["matching", "regularisation and post-filter", "weakly textured regions",
               "views that cannot see a pixel", "time and memory", "outputs"]),
    ("batch", ["cluster", "depth of each capture (see 'hyperlf depth --help')", "outputs"]),
])
def test_long_commands_group_their_options(command, titles):
    """depth's thirty options came as one flat list; each now sits under a title, and a new
    option has to be put under one too: only -h and -q stay in the untitled group."""
    from hyperlf.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    groups = sub.choices[command]._action_groups
    assert [g.title for g in groups[2:]] == titles
    untitled = [o for a in groups[1]._group_actions for o in a.option_strings]
    assert sorted(untitled) == ["--help", "--quiet", "-h", "-q"]
    assert all(g._group_actions for g in groups[2:])

def test_no_command_prints_help_and_fails(capsys):
    assert main([]) == 2
    assert "usage" in capsys.readouterr().out


def test_bad_argument_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["synth", "procedural", "-o", "x", "--grid", "5,zero"])
    assert exc.value.code == 2
    assert "expected two integers" in capsys.readouterr().err


@pytest.mark.parametrize("extra", ["--downscale=4", "a\nb"])
def test_an_unknown_argument_is_named_by_its_command(tmp_path, capsys, extra):
    """argparse reported a command's unknown argument as the top parser's ('hyperlf: error:
    ... see hyperlf --help'), and a newline in it on a second line."""
    with pytest.raises(SystemExit) as exc:
        main(["refocus", str(tmp_path), "-o", str(tmp_path / "r"), extra])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1
    assert err.startswith("hyperlf refocus: error: unrecognized arguments: ")
    assert err.rstrip().endswith("see 'hyperlf refocus --help'")
    assert not (tmp_path / "r").exists()


def test_missing_input_exit_code_and_one_line(tmp_path, capsys):
    code = main(["info", str(tmp_path / "nothing-here")])
    err = capsys.readouterr().err.strip()
    assert code in (3, 4)
    assert err.startswith("hyperlf info: error:") and "\n" not in err


def test_synth_info_convert_chain(tmp_path, capsys):
    cap = tmp_path / "scene"
    assert main(["-q", "synth", "procedural", "--seed", "1", "--size", "40,48", "--grid", "3,4",
                 "-o", str(cap)]) == 0
    assert (cap / "capture.toml").is_file()
    assert list(cap.glob("**/*views.png")), "synth must write a picture of the views"
    assert main(["info", str(cap)]) == 0
    out = capsys.readouterr().out
    assert "3 x 4 views" in out and "48 x 40 px" in out
    h5 = tmp_path / "scene.h5"
    assert main(["-q", "convert", str(cap), "-o", str(h5)]) == 0
    import hyperlf

    a, b = hyperlf.load(cap), hyperlf.load(h5)
    assert np.array_equal(a.views, b.views) and np.array_equal(a.wavelengths, b.wavelengths)
    # refuses to overwrite without --overwrite, with a clear error
    assert main(["-q", "synth", "procedural", "--size", "40,48", "--grid", "3,4",
                 "-o", str(cap)]) != 0


def test_pfm_to_png_conversion(tmp_path):
    from hyperlf.formats import read_image, read_pfm, write_pfm

    d = np.linspace(-1, 2, 30 * 20, dtype=np.float32).reshape(20, 30)
    write_pfm(tmp_path / "d.pfm", d)
    assert main(["-q", "convert", str(tmp_path / "d.pfm"), "-o", str(tmp_path / "d.png")]) == 0
    img = read_image(tmp_path / "d.png", as_float=True)
    assert img.shape == (20, 30) and img.min() == 0 and img.max() == 1
    assert (tmp_path / "d_colour.png").is_file()
    # and back: the mapping beside the image gives the values to 16-bit precision
    assert main(["-q", "convert", str(tmp_path / "d.png"), "-o", str(tmp_path / "b.pfm")]) == 0
    np.testing.assert_allclose(read_pfm(tmp_path / "b.pfm"), d, atol=3 / 65535 / 2 + 1e-6)
    assert main(["-q", "convert", str(tmp_path / "d.pfm"), "--bit-depth", "8", "-o",
                 str(tmp_path / "e.png")]) == 0
    assert read_image(tmp_path / "e.png", as_float=False).dtype == np.uint8
    assert main(["-q", "convert", str(tmp_path / "e.png"), "-o", str(tmp_path / "e.pfm")]) == 0
    np.testing.assert_allclose(read_pfm(tmp_path / "e.pfm"), d, atol=3 / 255 / 2 + 1e-6)
    # depth's disparity_16bit.png, through its disparity_16bit.txt
    (tmp_path / "q").mkdir()
    from hyperlf.pipeline import save_disparity_outputs
    save_disparity_outputs(tmp_path / "q", d, "d")
    assert main(["-q", "convert", str(tmp_path / "q" / "disparity_16bit.png"), "-o",
                 str(tmp_path / "q.pfm")]) == 0
    np.testing.assert_allclose(read_pfm(tmp_path / "q.pfm"), d, atol=1 / 512 + 1e-6)


def test_a_light_field_does_not_become_a_folder_named_like_a_file(tmp_path, capsys):
    cap = tmp_path / "s"
    assert main(["-q", "synth", "procedural", "--size", "24,28", "--grid", "2,2", "-o", str(cap),
                 "--no-pictures"]) == 0
    capsys.readouterr()
    assert main(["-q", "convert", str(cap), "-o", str(tmp_path / "v1.png")]) == 2
    assert "a capture folder or a .h5 file, not a .png file" in capsys.readouterr().err
    assert not (tmp_path / "v1.png").exists()


def test_demo_runs_and_writes_pictures(tmp_path):
    out = tmp_path / "demo"
    proc = subprocess.run([sys.executable, "-m", "hyperlf.cli", "demo", "-o", str(out),
                           "--size", "48,64"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    for name in ("views.png", "gt_disparity.png", "reference_srgb.png", "gt_disparity.pfm"):
        assert (out / name).is_file(), name
    assert (out / "capture" / "capture.toml").is_file()
    # every path it names is where the file ends up, not the hidden folder it was written in
    assert ".hyperlf-" not in proc.stderr and f"wrote {out / 'report.html'}" in proc.stderr
    assert "\r" not in proc.stderr  # no progress bars into a pipe or a log: stage lines only
    from hyperlf.formats import describe  # 'hyperlf info': the capture inside in one line
    text = describe(out)
    assert "capture/    : a capture, " in text and "gt_disparity_r0_c0" not in text


def test_render_refocus_spectrum_on_a_capture_cube(tmp_path, capfd):
    cap = tmp_path / "planes"
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "40,48",
                 "--grid", "3,4", "-o", str(cap), "--no-pictures"]) == 0
    assert main(["-q", "render", str(cap), "--white", "D65", "-o", str(tmp_path / "r")]) == 0
    assert (tmp_path / "r" / "rgb_reference.png").is_file()
    capfd.readouterr()
    assert main(["refocus", str(cap), "--sweep=-1,1,3", "-o", str(tmp_path / "f")]) == 0
    assert len(list((tmp_path / "f").glob("refocus_*.png"))) == 3
    # GIF everywhere, MP4 for desktop players, WebM (VP9) for browsers; each one listed, and
    # OpenCV's notice about the WebM's fourcc tag kept off stderr
    err = capfd.readouterr().err.splitlines()
    for name in ("refocus.gif", "refocus.mp4", "refocus.webm"):
        assert (tmp_path / "f" / name).is_file() and f"wrote {tmp_path / 'f' / name}" in err
    assert not [line for line in err if "OpenCV" in line]
    assert (tmp_path / "f" / "refocus_frames.csv").read_text().splitlines() == [
        "frame,file,disparity", "0,refocus_000.png,-1", "1,refocus_001.png,0",
        "2,refocus_002.png,1"]
    assert main(["-q", "refocus", str(cap), "--profile", "band:9999", "-o",
                 str(tmp_path / "g")]) == 2  # no such band: a clear usage error
    assert main(["-q", "spectrum", str(cap), "--at", "10,12", "-o",
                 str(tmp_path / "s.png")]) == 0
    rows = (tmp_path / "s.csv").read_text().splitlines()
    assert rows[0] == "wavelength_nm,value" and len(rows) == 1 + 12


def test_stereo_command_writes_disparity_products(tmp_path, monkeypatch):
    from hyperlf import visualise
    from hyperlf.formats import read_pfm, write_image

    labels, real = [], visualise.save_disparity_png
    monkeypatch.setattr(visualise, "save_disparity_png",
                        lambda *a, **kw: labels.append(kw.get("label")) or real(*a, **kw))

    rng = np.random.default_rng(3)
    tex = rng.random((40, 74)).astype(np.float32)
    left = tex[:, 10:70]
    right = tex[:, 14:74]  # left x shows texture column x + 10 = right column (x - 4) + 14
    write_image(tmp_path / "l.png", left, bit_depth=16)
    write_image(tmp_path / "r.png", 1.0 - 0.8 * right, bit_depth=16)  # contrast-reversed band
    out = tmp_path / "out"
    assert main(["-q", "stereo", str(tmp_path / "l.png"), str(tmp_path / "r.png"),
                 "--disparity-range", "0,8", "--metric", "bwncc", "--optimizer", "sgm",
                 "-o", str(out)]) == 0
    d = read_pfm(out / "disparity.pfm")
    assert np.mean(np.abs(d[5:-5, 12:-5] - 4) < 0.5) > 0.95
    for name in ("disparity_16bit.png", "disparity_16bit.txt", "disparity.png", "confidence.png",
                 "confidence.pfm"):
        assert (out / name).is_file(), name
    assert labels == ["disparity (px)", "confidence"]  # a pair's disparity is in px
    assert main(["-q", "stereo", str(tmp_path / "l.png"), str(tmp_path / "r.png"),
                 "-o", str(out)]) == 2  # no range given: usage error with a hint


def _scene_folder(folder, shift=4, dmax=7):
    """A v2 Middlebury scene folder: a textured pair shifted by ``shift`` px, ground truth
    ``shift`` with an unknown band, and an evaluation mask without its first rows."""
    from hyperlf.formats import StereoPair, write_middlebury

    rng = np.random.default_rng(5)
    tex = np.repeat(rng.random((40, 70 + shift))[..., None], 3, axis=2).astype(np.float32)
    gt = np.full((40, 70), float(shift), np.float32)
    gt[:, :3] = np.nan
    mask = np.ones((40, 70), bool)
    mask[:5] = False
    return write_middlebury(folder, StereoPair(
        left=tex[:, shift:shift + 70], right=tex[:, :70], gt_disparity=gt,
        masks={"all": mask}, scale=8.0, max_disparity=dmax))


def test_stereo_of_a_scene_folder_takes_its_range_and_scores_its_map(tmp_path, capsys,
                                                                      monkeypatch):
    """A Middlebury scene folder given alone: matched over its own range, scored against its
    ground truth on its evaluation mask, with an error picture."""
    from hyperlf import twoview
    from hyperlf.formats import read_pfm

    scene = _scene_folder(tmp_path / "scene")
    seen = {}
    real = twoview.stereo

    def spy(left, right, disparity_range, **kw):
        seen["range"] = disparity_range
        return real(left, right, disparity_range, **kw)

    monkeypatch.setattr(twoview, "stereo", spy)
    capsys.readouterr()
    assert main(["stereo", str(scene), "-o", str(tmp_path / "o")]) == 0
    assert seen["range"] == (0, 7)
    d = read_pfm(tmp_path / "o" / "disparity.pfm")
    bad = np.abs(d - 4) > 5
    bad[:5] = False  # outside the mask
    bad[:, :3] = False  # no ground truth
    want = 100 * bad.sum() / (35 * 67)
    err = capsys.readouterr().err
    line = next(ln for ln in err.splitlines() if "against the ground truth" in ln)
    assert f"(all, {35 * 67} px): bad5.0 {want:.2f} %" in line
    assert (tmp_path / "o" / "disparity_error.png").is_file()
    assert main(["-q", "stereo", str(scene), "--disparity-range", "0,5",
                 "-o", str(tmp_path / "p")]) == 0
    assert seen["range"] == (0, 5)


def test_stereo_of_a_scene_folder_without_ground_truth_is_not_scored(tmp_path, capsys):
    from hyperlf.formats import StereoPair, write_middlebury

    img = np.random.default_rng(0).random((20, 30, 3)).astype(np.float32)
    scene = write_middlebury(tmp_path / "scene", StereoPair(
        left=img, right=img, gt_disparity=np.full((20, 30), np.nan, np.float32), scale=4.0,
        max_disparity=3))
    capsys.readouterr()
    assert main(["stereo", str(scene), "-o", str(tmp_path / "o")]) == 0
    assert "the scene has no pixel with ground truth; its map is not scored" in \
        capsys.readouterr().err
    assert (tmp_path / "o" / "disparity.pfm").is_file()


@pytest.mark.parametrize("inputs, words", [
    (lambda s: [s, s / "imR.png"], "is a folder: give a Middlebury scene folder alone"),
    (lambda s: [s / "imL.png"], "give the right image after"),
    (lambda s: [s.parent], "is not a Middlebury scene"),
])
def test_stereo_refuses_a_scene_folder_with_a_right_image_or_an_image_alone(
        tmp_path, capsys, inputs, words):
    scene = _scene_folder(tmp_path / "scene")
    capsys.readouterr()
    code = main(["-q", "stereo", *map(str, inputs(scene)), "-o", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code in (2, 4) and words in err and "\n" not in err
    assert not (tmp_path / "o").exists()


def test_stereo_of_tsukubas_folder_reproduces_table_1(tmp_path, capsys):
    """The command on the scene folder gives Table 1's figures (``auto``, graph cuts, red
    vs blue; BENCHMARKS.md)."""
    from conftest import require_dataset

    scene = require_dataset("middlebury/tsukuba")
    capsys.readouterr()
    assert main(["stereo", str(scene), "--channel", "0,2", "-o", str(tmp_path / "o")]) == 0
    assert "bad5.0 1.64 %, bad2.0 2.80 %, bad1.0 3.88 %" in capsys.readouterr().err


def test_refocus_refuses_a_sweep_the_memory_cannot_hold(tmp_path, capsys, monkeypatch):
    """Every frame of a sweep is held until the animations are written: 100000 frames ran the
    machine out of memory; a sweep above the memory available is refused in one line."""
    from hyperlf import cli, tiling

    cap = tmp_path / "planes"
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "40,48",
                 "--grid", "2,2", "-o", str(cap), "--no-pictures"]) == 0
    monkeypatch.setattr(tiling, "available_memory",
                        lambda: cli.SWEEP_BYTES_AT_LEAST * 40 * 48 * 5)
    capsys.readouterr()
    assert main(["-q", "refocus", str(cap), "--sweep=-1,1,6", "-o", str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--sweep with 6 frames of 48 x 40 px" in err[0]
    assert "fewer frames" in err[0] and not (tmp_path / "f").exists()
    assert main(["-q", "refocus", str(cap), "--sweep=-1,1,5", "-o", str(tmp_path / "g")]) == 0


def test_stereo_refuses_a_range_the_memory_cannot_hold_before_any_work(tmp_path, capsys,
                                                                       monkeypatch):
    """Cost volumes of 16 B per pixel and disparity at least: a pair and range above the memory
    available is refused at once (one line, exit 2, nothing written), a smaller one runs."""
    from hyperlf import tiling
    from hyperlf.formats import write_image

    tex = np.random.default_rng(5).random((30, 50)).astype(np.float32)
    write_image(tmp_path / "l.png", tex[:, 3:43], bit_depth=16)
    write_image(tmp_path / "r.png", tex[:, 6:46], bit_depth=16)
    need = 16 * 11 * 30 * 40  # --disparity-range 0,10 on 40 x 30 px
    monkeypatch.setattr(tiling, "available_memory", lambda: need - 1)
    args = ["stereo", str(tmp_path / "l.png"), str(tmp_path / "r.png"), "--optimizer", "wta"]
    assert main([*args, "--disparity-range", "0,10", "-o", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--disparity-range 0,10 on 40 x 30 px" in err[0]
    assert "narrow the range" in err[0] and not (tmp_path / "a").exists()
    assert main(["-q", *args, "--disparity-range", "0,9", "-o", str(tmp_path / "b")]) == 0


@pytest.mark.parametrize("extra, want", [(["--occlusion", "lr-fill"], "lr-fill"),
                                         (["--occlusion", "none"], "none"),
                                         (["--no-occlusion"], "none"), ([], "lr-plane")])
def test_stereo_command_occlusion_modes(tmp_path, extra, want, monkeypatch):
    import hyperlf.twoview as tv
    from hyperlf.formats import write_image

    seen = {}
    real = tv.stereo

    def spy(*a, **k):
        seen.update(k)
        return real(*a, **k)

    monkeypatch.setattr(tv, "stereo", spy)
    tex = np.random.default_rng(4).random((30, 50)).astype(np.float32)
    write_image(tmp_path / "l.png", tex[:, 3:43], bit_depth=16)
    write_image(tmp_path / "r.png", tex[:, 6:46], bit_depth=16)
    assert main(["-q", "stereo", str(tmp_path / "l.png"), str(tmp_path / "r.png"),
                 "--disparity-range", "0,6", "--optimizer", "wta", *extra,
                 "-o", str(tmp_path / "o")]) == 0
    assert seen["occlusion"] == want


def test_depth_command_on_a_synthetic_capture(tmp_path, capsys):
    from hyperlf.formats import read_pfm

    cap = tmp_path / "planes"
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "40,48",
                 "--grid", "3,3", "-o", str(cap), "--no-pictures"]) == 0
    out = tmp_path / "d"
    assert main(["depth", str(cap), "--metric", "ncc", "--labels", "16",
                 "--save-intermediate", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "RMSE" in err  # scored against the capture's ground truth
    timing = next(line for line in err.splitlines() if line.startswith("hlf: "))
    assert " s in all (prepare " in timing and "correspondence " in timing  # stage names
    assert "_" not in timing and "total" not in timing, timing  # not the timings' keys
    d = read_pfm(out / "disparity.pfm")
    assert d.shape == (40, 48) and np.isfinite(d).all()
    for name in ("disparity.png", "disparity_error.png", "correspondence_only.pfm"):
        assert (out / name).is_file(), name
    # a result folder given where a capture goes is named for what it is
    assert main(["-q", "depth", str(out), "-o", str(tmp_path / "dd")]) == 2
    assert "holds the results of 'hyperlf depth', not a light field" in capsys.readouterr().err
    assert main(["-q", "depth", str(cap), "--method", "lin2015", "--labels", "16",
                 "-o", str(tmp_path / "lin")]) == 0
    # the post-filter can be switched off; it changes the map, and a negative radius is refused
    assert main(["-q", "depth", str(cap), "--metric", "ncc", "--labels", "16",
                 "--median-radius", "0", "-o", str(tmp_path / "raw")]) == 0
    assert not np.array_equal(read_pfm(tmp_path / "raw" / "disparity.pfm"), d)
    with pytest.raises(SystemExit) as usage:  # a usage error, named by its option
        main(["-q", "depth", str(cap), "--metric", "ncc", "--labels", "16",
              "--median-radius", "-1", "-o", str(tmp_path / "bad")])
    assert usage.value.code == 2 and "--median-radius must be at least 0" in \
        capsys.readouterr().err
    # no calibration, so no metric outputs: --min-confidence says it has nothing to act on
    capsys.readouterr()
    assert main(["depth", str(cap), "--metric", "ncc", "--labels", "16", "--min-confidence",
                 "0.2", "-o", str(tmp_path / "conf")]) == 0
    assert "note: --min-confidence applies to metric depth" in capsys.readouterr().err
    np.testing.assert_array_equal(read_pfm(tmp_path / "conf" / "disparity.pfm"), d)
    conf = read_pfm(tmp_path / "conf" / "confidence.pfm")
    assert conf.shape == d.shape and 0 <= conf.min() and conf.max() <= 1
    assert not (tmp_path / "conf" / "points.ply").exists()


def test_complete_command_writes_a_cube_that_render_reads(tmp_path, capsys):
    from hyperlf.formats import open_cube_h5

    cap = tmp_path / "planes"
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "40,48",
                 "--grid", "3,3", "-o", str(cap), "--no-pictures"]) == 0
    out = tmp_path / "c"
    assert main(["complete", str(cap), "--use-ground-truth", "--stereo", "none",
                 "-o", str(out)]) == 0
    assert "PSNR" in capsys.readouterr().err
    with open_cube_h5(out / "cube.h5") as cf:
        assert cf.cube.shape == (3, 3, 9, 40, 48)
        assert cf.metadata["reference"] == [1, 1]
    for name in ("missing_bands.png", "reference_srgb.png"):
        assert (out / name).is_file(), name
    assert main(["-q", "render", str(out / "cube.h5"), "-o", str(tmp_path / "r")]) == 0
    assert main(["-q", "complete", str(cap), "--disparity", str(tmp_path / "nope.pfm"),
                 "-o", str(tmp_path / "c2")]) == 4
    # a completed cube's spectrum says which bands were registered and which were not
    from hyperlf.completion import read_band_mask
    assert main(["-q", "spectrum", str(out / "cube.h5"), "--at", "2,3", "--view", "0,0", "-o",
                 str(tmp_path / "s.png")]) == 0
    rows = (tmp_path / "s.csv").read_text().splitlines()
    assert rows[0].endswith(",value,source") and len(rows) == 10
    registered = read_band_mask(out / "cube.h5", (0, 0))[:, 3, 2]
    assert [r.endswith(",registered") for r in rows[1:]] == list(registered)


def test_complete_a_capture_without_wavelengths(tmp_path, capsys):
    """A capture whose manifest names no wavelengths (an array's filters not known) is
    completed with the cameras as bands; the colour rendering is replaced by the bands'
    mosaic, the commands that need wavelengths refuse the cube in one line, and spectrum
    plots the cameras' values by band index."""
    from hyperlf.formats import open_cube_h5

    cap = tmp_path / "planes"
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "40,48",
                 "--grid", "3,3", "-o", str(cap), "--no-pictures"]) == 0
    manifest = cap / "capture.toml"
    lines = manifest.read_text().splitlines(keepends=True)
    manifest.write_text("".join(ln for ln in lines if not ln.startswith("wavelength =")))
    out = tmp_path / "c"
    capsys.readouterr()
    assert main(["complete", str(cap), "--use-ground-truth", "--stereo", "none",
                 "-o", str(out)]) == 0
    err = capsys.readouterr().err
    # the ground-truth cube's bands follow wavelengths, so it is not compared band by band
    assert "cameras in raster order" in err and "PSNR" not in err
    assert (out / "reference_bands.png").is_file() and (out / "missing_bands.png").is_file()
    assert not (out / "reference_srgb.png").exists()
    assert main(["render", str(out / "cube.h5"), "-o", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "ingest --wavelengths" in err, err
    assert not (tmp_path / "r").exists()
    # refocus needs weights over the cameras; with them it works
    assert main(["refocus", str(out / "cube.h5"), "--disparity", "0", "-o",
                 str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--profile weights:FILE" in err, err
    (tmp_path / "w.csv").write_text(",".join(["1"] * 9))
    assert main(["-q", "refocus", str(out / "cube.h5"), "--disparity", "0", "--profile",
                 f"weights:{tmp_path / 'w.csv'}", "-o", str(tmp_path / "f")]) == 0
    assert (tmp_path / "f" / "refocus_d+0.00.png").is_file()
    # spectrum gives each camera's value at the pixel, by band index
    assert main(["-q", "spectrum", str(out / "cube.h5"), "--at", "3,4", "--view", "0,2",
                 "-o", str(tmp_path / "s.png")]) == 0
    rows = (tmp_path / "s.csv").read_text().splitlines()
    with open_cube_h5(out / "cube.h5") as cf:
        want = cf.cube[0, 2, :, 4, 3]
    assert rows[0] == "band,value,source" and [r.split(",")[0] for r in rows[1:]] == [
        str(k) for k in range(9)]
    np.testing.assert_allclose([float(r.split(",")[1]) for r in rows[1:]], want, rtol=1e-5)
    assert (tmp_path / "s.png").stat().st_size > 0
    assert main(["-q", "convert", str(out / "cube.h5"), "-o", str(tmp_path / "e.hdr")]) == 0
    assert "wavelength" not in (tmp_path / "e.hdr").read_text()
    # info describes the cube: its shares are those of the masks read back whole
    from hyperlf.completion import read_band_mask

    assert main(["info", str(out / "cube.h5")]) == 0
    info = capsys.readouterr().out
    assert "3 x 3 views x 9 bands of 48 x 40 px" in info and "raster order" in info
    for name in ("band_mask", "inferred_mask"):
        share = f"{100 * read_band_mask(out / 'cube.h5', name=name).mean():.1f} %"
        assert f"{share} of the entries" in info, (name, share, info)


def test_complete_at_1_over_n_scores_against_the_block_means(tmp_path, capsys):
    """``complete --downscale 2``: a cube of half the size, close to the ground-truth cube's
    block means; a full-resolution --disparity is made 1/2 (the same cube as from that map at
    1/2), and a map of a third size is refused before any work."""
    from hyperlf.formats import load_lightfield, open_cube_h5, open_gt_cube, write_pfm
    from hyperlf.imageops import block_reduce
    from hyperlf.metrics import psnr

    cap = tmp_path / "planes"
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "40,48",
                 "--grid", "3,3", "-o", str(cap), "--no-pictures"]) == 0
    gt = load_lightfield(cap, cube=False).gt_disparity[1, 1]
    write_pfm(tmp_path / "full.pfm", gt)
    write_pfm(tmp_path / "half.pfm", block_reduce(gt, 2) / 2)
    cubes, printed = {}, {}
    for name, how in (("truth", ["--use-ground-truth"]),
                      ("full", ["--disparity", str(tmp_path / "full.pfm")]),
                      ("half", ["--disparity", str(tmp_path / "half.pfm")])):
        capsys.readouterr()
        assert main(["complete", str(cap), *how, "--stereo", "none", "--downscale", "2",
                     "-o", str(tmp_path / name)]) == 0
        printed[name] = capsys.readouterr().err
        assert "1/2 resolution: 24 x 20 px" in printed[name]
        with open_cube_h5(tmp_path / name / "cube.h5") as cf:
            cubes[name] = cf.cube[()]
            assert cf.metadata["downscale"] == 2  # the file says so, wherever it is copied
    assert cubes["truth"].shape == (3, 3, 9, 20, 24)
    np.testing.assert_array_equal(cubes["full"], cubes["half"])
    assert main(["-q", "complete", str(cap), "--use-ground-truth", "--stereo", "none",
                 "-o", str(tmp_path / "whole")]) == 0
    with open_cube_h5(tmp_path / "whole" / "cube.h5") as cf, open_gt_cube(cap) as truth:
        whole = psnr(cf.cube[()], truth[()])
        small = block_reduce(truth[()], 2)
    for name in cubes:  # as close to the truth's block means as the full run to the truth,
        assert psnr(cubes[name], small) > whole - 1, name  # and scored against those
        assert f"PSNR {psnr(cubes[name], small):.2f} dB" in printed[name], name
    write_pfm(tmp_path / "third.pfm", gt[:30, :30])
    assert main(["complete", str(cap), "--disparity", str(tmp_path / "third.pfm"),
                 "--downscale", "2", "-o", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "24 x 20 (or 48 x 40 at full resolution)" in err[0]
    assert not (tmp_path / "bad").exists()


def test_stereo_and_depth_commands_pass_the_aggregation(tmp_path, monkeypatch):
    import hyperlf.hlf as hlf
    import hyperlf.twoview as tv
    from hyperlf.costs import AggregationParams
    from hyperlf.formats import write_image

    seen = {}
    real_stereo, real_depth = tv.stereo, hlf.depth

    def spy_stereo(*a, **k):
        seen["stereo"] = k["aggregation"]
        return real_stereo(*a, **k)

    def spy_depth(*a, **k):
        seen["depth"] = k["params"]
        return real_depth(*a, **k)

    monkeypatch.setattr(tv, "stereo", spy_stereo)
    monkeypatch.setattr(hlf, "depth", spy_depth)
    tex = np.random.default_rng(5).random((30, 50)).astype(np.float32)
    write_image(tmp_path / "l.png", tex[:, 3:43], bit_depth=16)
    write_image(tmp_path / "r.png", tex[:, 6:46], bit_depth=16)
    assert main(["-q", "stereo", str(tmp_path / "l.png"), str(tmp_path / "r.png"),
                 "--disparity-range", "0,6", "--optimizer", "wta", "--aggregation", "guided",
                 "--aggregation-radius", "3", "--aggregation-eps", "0.01",
                 "-o", str(tmp_path / "s")]) == 0
    assert seen["stereo"] == AggregationParams("guided", 3, 0.01)
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "24,32",
                 "-o", str(tmp_path / "cap")]) == 0
    assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "4", "--optimizer", "wta",
                 "--aggregation", "guided", "-o", str(tmp_path / "d")]) == 0
    p = seen["depth"]
    assert (p.aggregation, p.aggregation_radius, p.aggregation_eps) == ("guided", 4, 1e-3)
    assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "4", "--optimizer", "wta",
                 "-o", str(tmp_path / "d0")]) == 0
    assert seen["depth"] is None or seen["depth"].aggregation == "none"


def test_quiet_prints_only_the_output_path(tmp_path, capfd):
    """-q silences progress bars and messages on stderr, but the output path still comes on
    stdout, by design: scripts read it (out=$(hyperlf -q depth ...))."""
    out = tmp_path / "s"
    assert main(["-q", "synth", "procedural", "--seed", "1", "--size", "24,28", "--grid", "2,2",
                 "-o", str(out), "--no-pictures"]) == 0
    assert capfd.readouterr() == (f"{out}\n", "")
    for argv in (["--help"], ["synth", "--help"]):  # and the help says so, before and after
        with pytest.raises(SystemExit):
            main(argv)
        text = " ".join(capfd.readouterr().out.split())
        assert "no progress bars or messages on stderr; the output path is still printed" in text


def test_quiet_may_follow_the_command(tmp_path, capsys):
    assert main(["synth", "procedural", "-q", "--size", "24,28", "--grid", "2,2", "-o",
                 str(tmp_path / "s"), "--no-pictures"]) == 0
    assert main(["info", str(tmp_path / "s"), "-q"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("argv, words", [
    (["depth", "CAP", "--method", "wang2015", "--metric", "ncc"], "--metric acts on --method hlf"),
    (["depth", "CAP", "--aggregation-radius", "3"], "--aggregation-radius acts only with"),
    (["complete", "CAP", "--disparity", "d.pfm", "--use-ground-truth"], "give one source"),
    (["refocus", "CAP", "--disparity", "1", "--sweep=-1,1,3"], "--disparity and --sweep"),
    (["stereo", "l.png", "r.png", "--disparity-range", "0,4", "--no-occlusion", "--occlusion",
      "lr-fill"], "--no-occlusion and --occlusion"),
])
def test_options_that_contradict_or_would_be_ignored_are_refused(tmp_path, capsys, argv, words):
    """Refused before the input is even read (CAP need not exist): one line, exit 2."""
    argv = [str(tmp_path / a) if a in ("CAP", "l.png", "r.png", "d.pfm") else a for a in argv]
    assert main(["-q", *argv, "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "out").exists()


def test_a_result_set_records_the_command_line_that_made_it(tmp_path, capsys):
    from hyperlf.formats import describe
    from hyperlf.outputs import read_manifest

    cap = tmp_path / "s"
    assert main(["-q", "synth", "procedural", "--size", "24,28", "--grid", "2,2", "-o", str(cap),
                 "--no-pictures"]) == 0
    argv = ["depth", str(cap), "--labels", "6", "-q", "-o", str(tmp_path / "d")]
    assert main(argv) == 0
    assert read_manifest(tmp_path / "d")["argv"] == ["hyperlf", *argv]
    assert f"made by     : hyperlf depth {cap} --labels 6 -q -o" in describe(tmp_path / "d")


def test_complete_refuses_a_map_that_depth_made_from_another_capture(tmp_path, capsys):
    """Two captures of one size: the depth result's manifest names its input, and
    ``complete --disparity`` refuses the map for the other one (a copy out of the folder is
    taken as it is)."""
    from hyperlf.outputs import read_manifest

    caps = []
    for seed in (3, 4):
        caps.append(tmp_path / f"s{seed}")
        assert main(["-q", "synth", "procedural", "--seed", str(seed), "--size", "32,40",
                     "--grid", "2,2", "-o", str(caps[-1]), "--no-pictures"]) == 0
    d = tmp_path / "d"
    assert main(["-q", "depth", str(caps[0]), "--labels", "6", "-o", str(d)]) == 0
    assert read_manifest(d)["input"]["path"] == str(caps[0])
    capsys.readouterr()
    assert main(["-q", "complete", str(caps[1]), "--disparity", str(d / "disparity.pfm"),
                 "--stereo", "none", "-o", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "was computed from" in err and "another scene" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "c").exists()
    assert main(["-q", "complete", str(caps[0]), "--disparity", str(d / "disparity.pfm"),
                 "--stereo", "none", "-o", str(tmp_path / "c")]) == 0
    (tmp_path / "copy.pfm").write_bytes((d / "disparity.pfm").read_bytes())
    assert main(["-q", "complete", str(caps[1]), "--disparity", str(tmp_path / "copy.pfm"),
                 "--stereo", "none", "-o", str(tmp_path / "c2")]) == 0


def test_depth_notes_a_map_stuck_at_a_limit_of_the_range(tmp_path, capsys):
    """A range that leaves most of the scene out puts those pixels at its limit; depth says
    so (a map without ground truth would show no other sign), and is silent on a fitting
    range."""
    cap = tmp_path / "s"
    assert main(["-q", "synth", "procedural", "--seed", "1", "--size", "48,64", "--grid", "1,3",
                 "-o", str(cap), "--no-pictures"]) == 0
    capsys.readouterr()
    assert main(["depth", str(cap), "--labels", "8", "--disparity-range=0.5,2", "-o",
                 str(tmp_path / "d")]) == 0
    note = [line for line in capsys.readouterr().err.splitlines() if "limit of the" in line]
    assert len(note) == 1 and "at 0.5" in note[0] and "--disparity-range" in note[0]
    share = float(note[0].split("note: ")[1].split(" %")[0])
    from hyperlf.formats import read_pfm
    from hyperlf.metrics import range_limit_shares
    disparity = read_pfm(tmp_path / "d" / "disparity.pfm")
    assert share == pytest.approx(sum(range_limit_shares(disparity, (0.5, 2))), abs=0.05)
    assert share > 50
    assert main(["depth", str(cap), "--labels", "8", "--disparity-range=-2.5,2.5", "-o",
                 str(tmp_path / "d2")]) == 0  # the scene's own range is -1.8..1.4
    assert "limit of the" not in capsys.readouterr().err


def test_depth_of_views_smaller_than_the_post_filter(tmp_path):
    """The default post-filter radius (4) on 3 x 3 px views: a window over the whole view,
    not a refusal of an option the user never gave."""
    cap = tmp_path / "tiny"
    assert main(["-q", "synth", "procedural", "--size", "3,3", "--grid", "3,3", "-o", str(cap),
                 "--no-pictures"]) == 0
    assert main(["-q", "depth", str(cap), "--labels", "8", "-o", str(tmp_path / "d")]) == 0


def test_render_notes_a_cube_with_few_visible_bands(tmp_path, capsys):
    """Two bands (410, 700 nm) make a picture, but the colours are a rough guess: render
    says so; a 3 x 4 array's twelve bands do not get the note."""
    for grid, noted in (("1,2", True), ("3,4", False)):
        cap = tmp_path / f"g{grid[0]}"
        assert main(["-q", "synth", "procedural", "--size", "24,32", "--grid", grid, "-o",
                     str(cap), "--no-pictures"]) == 0
        capsys.readouterr()
        assert main(["render", str(cap), "-o", str(tmp_path / f"r{grid[0]}")]) == 0
        err = capsys.readouterr().err
        assert ("only 2 band(s) between 400 and 700 nm (410, 700)" in err) is noted, err
