"""The command line under hostile input (issue 10, items 6-8): every failure is one line on
stderr with the documented exit code, comes before any long work and leaves nothing behind."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import write_shifted_pair

SRC = str(Path(__file__).resolve().parents[1] / "src")


def run_cli(*args, cwd=None):
    """``hyperlf ARGS`` in a real subprocess, quiet, this tree's sources first."""
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run([sys.executable, "-m", "hyperlf.cli", "-q", *map(str, args)],
                          capture_output=True, text=True, timeout=300, env=env, cwd=cwd)


def assert_one_line_error(proc, code, *words):
    """Exit ``code``, exactly one line on stderr, no traceback, every word in the message."""
    err = proc.stderr.strip()
    assert proc.returncode == code, (proc.returncode, proc.stderr[-2000:])
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, (w, err)
    return err


def listing(folder):
    """Every path under ``folder`` (relative), to prove a failed run wrote nothing."""
    return sorted(p.relative_to(folder) for p in Path(folder).rglob("*"))


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """A small 3 x 3 capture with ground-truth disparity and cube (also usable as a cube)."""
    from hyperlf import synthesis
    from hyperlf.formats import save_lightfield

    lf = synthesis.procedural_scene(**dict(synthesis.SCENES["planes"], rows=3, cols=3,
                                           height=36, width=40))
    folder = tmp_path_factory.mktemp("cap") / "planes"
    save_lightfield(lf, folder)
    return folder


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A rectified stereo pair (left x matches right x - 3)."""
    return write_shifted_pair(tmp_path_factory.mktemp("pair"))


def _folder_commands(capture, pair):
    """Every command whose ``-o`` is a folder, with cheap options."""
    left, right = pair
    return {
        "depth": ["depth", capture, "--labels", "8", "--metric", "ncc"],
        "stereo": ["stereo", left, right, "--disparity-range", "0,4"],
        "complete": ["complete", capture, "--use-ground-truth", "--stereo", "none"],
        "render": ["render", capture],
        "refocus": ["refocus", capture],
        "sweep": ["refocus", capture, "--sweep=-1,1,3"],
        "demo": ["demo", "--size", "24,28", "--grid", "2,2", "--labels", "4"],
        "synth": ["synth", "procedural", "--size", "20,20", "--grid", "2,2"],
        "convert": ["convert", capture],
    }


FOLDER_COMMANDS = ["depth", "stereo", "complete", "render", "refocus", "sweep", "demo", "synth",
                   "convert"]


# ------------------------------------------------------------------ output location (item 6)
@pytest.mark.parametrize("name", FOLDER_COMMANDS)
def test_output_folder_that_is_an_existing_file(name, capture, pair, tmp_path):
    target = tmp_path / "a-file"
    target.write_text("keep me")
    proc = run_cli(*_folder_commands(capture, pair)[name], "-o", target)
    assert_one_line_error(proc, 2, str(target), "file")
    assert target.read_text() == "keep me" and listing(tmp_path) == [Path("a-file")]


@pytest.mark.parametrize("name", FOLDER_COMMANDS)
def test_output_folder_under_a_file_cannot_be_created(name, capture, pair, tmp_path):
    (tmp_path / "a-file").write_text("keep me")
    proc = run_cli(*_folder_commands(capture, pair)[name], "-o", tmp_path / "a-file" / "out")
    assert_one_line_error(proc, 2, "a-file", "not a folder")
    assert listing(tmp_path) == [Path("a-file")]


@pytest.mark.parametrize("args", [
    ["spectrum", "{cap}", "--at", "10,12"],
    ["convert", "{cap}"],
])
def test_output_file_that_is_an_existing_folder(args, capture, tmp_path):
    target = tmp_path / "out.h5" if args[0] == "convert" else tmp_path / "out.png"
    target.mkdir()
    proc = run_cli(*[a.replace("{cap}", str(capture)) for a in args], "-o", target)
    assert_one_line_error(proc, 2, str(target), "folder")
    assert listing(tmp_path) == [Path(target.name)]


def test_output_file_under_a_file(capture, tmp_path):
    (tmp_path / "a-file").write_text("")
    for args in (["spectrum", capture, "--at", "10,12"], ["convert", capture]):
        proc = run_cli(*args, "-o", tmp_path / "a-file" / "x.h5")
        assert_one_line_error(proc, 2, "not a folder")
    assert listing(tmp_path) == [Path("a-file")]


def test_output_name_too_long(capture, tmp_path):
    proc = run_cli("render", capture, "-o", tmp_path / ("x" * 300))
    assert_one_line_error(proc, 2, "too long")
    assert listing(tmp_path) == []


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0,
                    reason="root may write into a read-only folder")
def test_output_in_a_read_only_folder(capture, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        proc = run_cli("depth", capture, "--labels", "8", "--metric", "ncc", "-o", ro / "out")
        assert_one_line_error(proc, 2, "not writable")
        assert listing(ro) == []
    finally:
        ro.chmod(0o755)


def test_output_in_a_folder_the_user_cannot_write(capture, tmp_path, monkeypatch, capsys):
    """The same case as the root-skipped one above, with the permission answer simulated (so
    it runs as root too): refused before any work, nothing created."""
    from hyperlf.cli import main

    ro = tmp_path / "ro"
    ro.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if os.fspath(p) == str(ro)
                        else real_access(p, mode, **kw))
    assert main(["-q", "depth", str(capture), "--labels", "8", "-o", str(ro / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "not writable" in err and len(err.splitlines()) == 1
    assert listing(ro) == []


# ------------------------------------------------------------------ option values (item 6, 7)
@pytest.mark.parametrize("rng", ["nan,5", "0,inf", "-inf,3", "0,1e400"])
def test_stereo_disparity_range_not_finite(rng, pair, tmp_path):
    proc = run_cli("stereo", *pair, f"--disparity-range={rng}", "-o", tmp_path / "o")
    assert_one_line_error(proc, 2, "finite")
    assert listing(tmp_path) == []


def test_synth_unknown_scene_lists_the_names(tmp_path):
    proc = run_cli("synth", "procedural", "--scene", "nope", "-o", tmp_path / "o")
    assert_one_line_error(proc, 2, "nope", "planes", "solids")
    assert listing(tmp_path) == []


@pytest.mark.parametrize("name", ["x.csv", "x.CSV"])
def test_spectrum_output_must_be_a_picture(name, capture, tmp_path):
    proc = run_cli("spectrum", capture, "--at", "10,12", "-o", tmp_path / name)
    assert_one_line_error(proc, 2, ".png", "CSV")
    assert listing(tmp_path) == []


@pytest.mark.parametrize("at", ["1000,12", "10,-3", "40,12"])
def test_spectrum_at_outside_the_image(at, capture, tmp_path):
    proc = run_cli("spectrum", capture, f"--at={at}", "-o", tmp_path / "s.png")
    assert_one_line_error(proc, 2, "outside", "40 x 36")
    assert listing(tmp_path) == []


def test_spectrum_at_nan(capture, tmp_path):
    proc = run_cli("spectrum", capture, "--at", "nan,12", "-o", tmp_path / "s.png")
    assert_one_line_error(proc, 2, "finite")
    assert listing(tmp_path) == []


@pytest.mark.parametrize("band", ["nan", "inf", "-inf"])
def test_refocus_band_not_finite(band, capture, tmp_path):
    proc = run_cli("refocus", capture, "--profile", f"band:{band}", "-o", tmp_path / "o")
    assert_one_line_error(proc, 2, "band")
    assert listing(tmp_path) == []


def test_refocus_missing_weights_file_is_exit_4(capture, tmp_path):
    proc = run_cli("refocus", capture, "--profile", f"weights:{tmp_path / 'w.csv'}",
                   "-o", tmp_path / "o")
    assert_one_line_error(proc, 4, "w.csv", "does not exist")
    assert listing(tmp_path) == []


def test_refocus_weights_folder_says_folder(capture, tmp_path):
    (tmp_path / "w").mkdir()
    proc = run_cli("refocus", capture, "--profile", f"weights:{tmp_path / 'w'}",
                   "-o", tmp_path / "o")
    assert_one_line_error(proc, 2, "is a folder")
    assert listing(tmp_path) == [Path("w")]


@pytest.mark.parametrize("opts", [["--labels", "0"], ["--labels", "1"], ["--grid", "1,1"],
                                  ["--seed", "-1"]])
def test_demo_validates_before_writing(opts, tmp_path):
    proc = run_cli("demo", *opts, "-o", tmp_path / "demo")
    assert_one_line_error(proc, 2)
    assert listing(tmp_path) == []


def test_api_run_demo_validates_before_writing(tmp_path):
    from hyperlf.errors import InvalidInputError
    from hyperlf.pipeline import run_demo

    with pytest.raises(InvalidInputError, match="2 views"):
        run_demo(tmp_path / "demo", grid=(1, 1))
    assert listing(tmp_path) == []


# ------------------------------------------------------------------ memory (item 6)
@pytest.mark.parametrize("args, option", [
    (["depth", "{cap}", "--labels", "100000000"], "--labels"),
    (["depth", "{cap}", "--method", "tao2013", "--labels", "100000000"], "--labels"),
    (["synth", "procedural", "--size", "100000,100000"], "--size"),
    (["synth", "procedural", "--grid", "1000,1000"], "--grid"),
    (["demo", "--labels", "1000000000"], "--labels"),
    (["demo", "--size", "100000,100000"], "--size"),
    # an int beyond a float (the slow fuzzer's draw): an OverflowError's traceback before
    (["demo", "--labels", "2" * 309], "--labels"),
    (["depth", "{cap}", "--labels", "2" * 309], "--labels"),
    (["synth", "procedural", "--grid", f"{'9' * 200},2"], "--grid"),
])
def test_huge_options_are_refused_with_the_memory_needed(args, option, capture, tmp_path):
    proc = run_cli(*[a.replace("{cap}", str(capture)) for a in args], "-o", tmp_path / "o")
    assert_one_line_error(proc, 2, option, "GiB", "memory")
    assert listing(tmp_path) == []


# ------------------------------------------------------------------ exit codes (item 7)
def test_depth_with_ground_truth_on_small_views_succeeds(tmp_path):
    from hyperlf import synthesis
    from hyperlf.formats import save_lightfield

    lf = synthesis.procedural_scene(**dict(synthesis.SCENES["planes"], rows=3, cols=3,
                                           height=24, width=28))
    cap = tmp_path / "small"
    save_lightfield(lf, cap)
    proc = run_cli("depth", cap, "--labels", "8", "--metric", "ncc", "-o", tmp_path / "d")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "d" / "disparity.pfm").is_file()


# ------------------------------------------------------------------ gt_disparity patterns
def _capture_with_gt_pattern(capture, tmp_path, pattern):
    cap = tmp_path / "cap"
    shutil.copytree(capture, cap)
    man = cap / "capture.toml"
    text = man.read_text()
    old = next(line for line in text.splitlines() if line.startswith("gt_disparity"))
    man.write_text(text.replace(old, f"gt_disparity = {pattern!r}"))
    return cap


@pytest.mark.parametrize("pattern", [
    "{col.foo}", "{col[0]}", "{row}_{col.real}.pfm", "{row}_{col[0]}.pfm", "{col:99999999}",
    "{row:>300}{col}.pfm", "{row!r}{col}.pfm", "{other}_{row}.pfm", "{}.pfm",
    "x" * 300 + "{row}{col}.pfm", "x" * 300 + ".pfm", "{row", "{col}}}{",
])
def test_gt_disparity_pattern_is_one_format_error(pattern, capture, tmp_path):
    cap = _capture_with_gt_pattern(capture, tmp_path, pattern)
    assert_one_line_error(run_cli("info", cap), 3, "gt_disparity")


def test_gt_disparity_pattern_with_a_small_width_still_works(capture, tmp_path):
    cap = _capture_with_gt_pattern(capture, tmp_path, "gt_disparity_r{row:01d}_c{col}.pfm")
    proc = run_cli("info", cap)
    assert proc.returncode == 0, proc.stderr


# ------------------------------------------------------------------ messages (item 8)
def test_overwrite_message_names_the_flag(capture, tmp_path):
    h5 = tmp_path / "lf.h5"
    h5.write_bytes(b"old")
    for args in (["synth", "procedural", "--size", "20,20", "--grid", "2,2", "-o", capture],
                 ["convert", capture, "-o", h5]):
        err = assert_one_line_error(run_cli(*args), 2, "--overwrite")
        assert "overwrite=True" not in err
    assert h5.read_bytes() == b"old"


def test_a_folder_given_as_an_image_says_folder(pair, tmp_path):
    left, right = pair
    proc = run_cli("stereo", left.parent, right, "--disparity-range", "0,4", "-o", tmp_path / "o")
    assert_one_line_error(proc, 2, "is a folder")
    assert listing(tmp_path) == []


def test_a_missing_image_is_exit_4(pair, tmp_path):
    proc = run_cli("stereo", tmp_path / "nope.png", pair[1], "--disparity-range", "0,4",
                   "-o", tmp_path / "o")
    assert_one_line_error(proc, 4, "nope.png")
    assert listing(tmp_path) == []


def test_usage_errors_are_one_line(tmp_path):
    proc = run_cli("synth", "procedural", "--grid", "5,zero", "-o", tmp_path / "o")
    assert_one_line_error(proc, 2, "expected two integers", "--help")


# --- item 3: one --overwrite rule for every output kind -------------------------------------

def _convert_cases(capture):
    pfm = capture / "gt_disparity_r0_c0.pfm"  # the fixture writes per-view ground truth
    return [
        ("pfm-to-png", ["convert", pfm], "d.png", ["d.png", "d.txt", "d_colour.png"]),
        ("pfm-to-pfm", ["convert", pfm], "d.pfm", ["d.pfm"]),
        ("cube-to-envi", ["convert", capture / "gt_cube.h5"], "c.hdr", ["c.hdr", "c.img"]),
    ]


@pytest.mark.parametrize("which", [0, 1, 2])
def test_convert_to_one_file_needs_overwrite_for_it_and_its_sidecars(tmp_path, capture, which):
    name, cmd, out, written = _convert_cases(capture)[which]
    for existing in written:  # any one of the files it would write blocks the run
        folder = tmp_path / f"{name}-{existing}"
        folder.mkdir()
        (folder / existing).write_bytes(b"the user's own file")
        before = listing(folder)
        proc = run_cli(*cmd, "-o", folder / out)
        assert_one_line_error(proc, 2, existing, "--overwrite")
        assert listing(folder) == before
        assert (folder / existing).read_bytes() == b"the user's own file"
        proc = run_cli(*cmd, "-o", folder / out, "--overwrite")
        assert proc.returncode == 0, proc.stderr
        assert (folder / existing).read_bytes() != b"the user's own file"


@pytest.mark.parametrize("existing", ["s.png", "s.csv"])
def test_spectrum_needs_overwrite_for_the_picture_and_the_csv(tmp_path, capture, existing):
    (tmp_path / existing).write_text("keep me")
    proc = run_cli("spectrum", capture, "--at", "10,12", "-o", tmp_path / "s.png")
    assert_one_line_error(proc, 2, existing, "--overwrite")
    assert (tmp_path / existing).read_text() == "keep me"
    assert listing(tmp_path) == [Path(existing)]
    proc = run_cli("spectrum", capture, "--at", "10,12", "-o", tmp_path / "s.png", "--overwrite")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "s.csv").read_text().startswith("wavelength_nm,value")


# ----------------------------------------------------------------------------- twentieth session
def test_synth_pictures_never_replace_a_capture_named_like_the_h5(tmp_path):
    """``synth -o scene.h5 --overwrite`` writes its pictures to ``scene/``; a capture folder
    of that name is the user's, not pictures of an earlier run."""
    assert run_cli("synth", "procedural", "--size", "24,28", "--grid", "2,2",
                   "-o", tmp_path / "scene").returncode == 0
    before = listing(tmp_path / "scene")
    proc = run_cli("synth", "procedural", "--size", "24,28", "--grid", "2,2", "--seed", "2",
                   "-o", tmp_path / "scene.h5", "--overwrite")
    assert_one_line_error(proc, 2, "not the pictures of scene.h5", "--no-pictures")
    assert listing(tmp_path / "scene") == before and not (tmp_path / "scene.h5").exists()
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("x")
    (tmp_path / "lnk").symlink_to(tmp_path / "mine")
    for name, words in (("mine", "a folder hyperlf did not write"), ("lnk", "is a symlink")):
        proc = run_cli("synth", "procedural", "--size", "24,28", "--grid", "2,2",
                       "-o", tmp_path / f"{name}.h5", "--overwrite")
        assert_one_line_error(proc, 2, words, "--no-pictures")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "x"
    # the pictures of an earlier .h5 are replaced, as before
    for _ in range(2):
        assert run_cli("synth", "procedural", "--size", "24,28", "--grid", "2,2", "-o",
                       tmp_path / "p.h5", "--overwrite").returncode == 0
    assert any((tmp_path / "p").glob("*.png"))


def test_a_sidecar_of_the_wrong_kind_is_refused_before_the_work(tmp_path, capture):
    (tmp_path / "foo").write_text("notes")
    proc = run_cli("synth", "procedural", "--size", "24,28", "--grid", "2,2",
                   "-o", tmp_path / "foo.h5", "--overwrite")
    assert_one_line_error(proc, 2, "is a file, where synth would put the pictures")
    assert not (tmp_path / "foo.h5").exists() and (tmp_path / "foo").read_text() == "notes"
    (tmp_path / "s.csv").mkdir()
    proc = run_cli("spectrum", capture, "--at", "3,3", "-o", tmp_path / "s.png", "--overwrite")
    assert_one_line_error(proc, 2, "s.csv is a folder")
    assert not (tmp_path / "s.png").exists()


def test_an_output_that_holds_the_input_is_refused(tmp_path, capture):
    copy = tmp_path / "cap"
    shutil.copytree(capture, copy)
    before = listing(copy)
    for argv in (["convert", copy, "-o", copy, "--overwrite"],
                 ["convert", copy, "-o", tmp_path, "--overwrite"],
                 ["depth", copy, "-o", copy, "--overwrite"]):
        assert_one_line_error(run_cli(*argv), 2, "holds the input", "choose another -o")
    assert listing(copy) == before


def test_an_empty_output_name_is_refused(capture):
    assert_one_line_error(run_cli("depth", capture, "-o", ""), 2, "-o is empty")


def test_an_hci_scene_is_not_read_through_symlinks_out_of_it(tmp_path):
    data = os.environ.get("HYPERLF_DATA")
    if not data:
        pytest.skip("HYPERLF_DATA is not set: the HCI scene lives in ../shared/data")
    scene = tmp_path / "scene"
    scene.mkdir()
    for f in (Path(data).resolve() / "hci4d" / "antinous").iterdir():  # CI: a relative path
        (scene / f.name).symlink_to(f)
    proc = run_cli("synth", "hci", scene, "--grid", "2,2", "-o", tmp_path / "out")
    assert_one_line_error(proc, 2, "leads outside the folder (a symlink)")
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ no room for the results
def _with_file_size_limit(limit):
    """A ``preexec_fn``: files of the subprocess may grow to ``limit`` bytes (``ulimit -f``);
    Python ignores SIGXFSZ, so a write past it fails with EFBIG, as on a full disk."""
    import resource

    return lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))


@pytest.mark.parametrize("name", ["depth", "stereo", "complete", "render", "synth"])
def test_no_room_for_the_results_is_one_line_and_keeps_the_previous_set(name, capture, pair,
                                                                        tmp_path):
    """A write that finds no room (a full disk, a quota, ``ulimit -f``) says so in one line
    with what to do, exit 1, and the previous result set stays as it was. Before, HDF5's own
    text came through (a staging path, a time stamp), and `complete` ended in a traceback:
    closing its scratch file failed too and hid the first error."""
    out = tmp_path / "out"
    args = [*_folder_commands(capture, pair)[name], "-o", out]
    assert run_cli(*args).returncode == 0
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    paths = listing(tmp_path)
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.run([sys.executable, "-m", "hyperlf.cli", "-q", *map(str, args),
                           "--overwrite"], capture_output=True, text=True, timeout=300, env=env,
                          preexec_fn=_with_file_size_limit(512))
    assert_one_line_error(proc, 1, "did not fit", "size limit", "ulimit -f", "-o")
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert listing(tmp_path) == paths  # and no staging folder left beside it


def test_no_room_is_found_behind_the_error_that_hid_it():
    """HDF5 puts the errno in its text, and closing a file on a full disk raises a
    RuntimeError while the OSError is handled; other errors are not taken for it."""
    import errno

    from hyperlf.cli import _no_room_code

    def chained(first, then):
        try:
            try:
                raise first
            except BaseException:
                raise then
        except BaseException as exc:
            return exc

    h5 = OSError("Can't write data (file write failed: errno = 28, error message = 'x')")
    assert _no_room_code(h5) == errno.ENOSPC
    assert _no_room_code(chained(h5, RuntimeError("Can't decrement id ref count"))) == 28
    assert _no_room_code(OSError(errno.EDQUOT, "Disk quota exceeded")) == errno.EDQUOT
    assert _no_room_code(chained(OSError(errno.EFBIG, "File too large"), ValueError())) == 27
    for other in (OSError(errno.EACCES, "Permission denied"), RuntimeError("errno = 13"),
                  ValueError("errno = 28"), None):
        assert _no_room_code(other) is None
