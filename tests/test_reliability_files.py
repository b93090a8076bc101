"""Files as a careful user sees them (issue 10, items 1, 2 and 5).

Output modes follow the umask; ``write_capture(overwrite=True)`` deletes nothing outside its folder
and nothing it must keep; ``read_capture`` reads nothing outside its folder, symlinks included.
"""

from __future__ import annotations

import contextlib
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tomli_w

import hyperlf._atomic as atomic
from hyperlf import LightField, raster_wavelengths
from hyperlf.cli import main
from hyperlf.errors import FormatError
from hyperlf.formats import read_capture, write_capture, write_image
from hyperlf.formats.capture import MANIFEST

try:
    import tomllib
except ImportError:  # pragma: no cover
    import tomli as tomllib

UMASKS = [0o022, 0o077, 0o002, 0o027]


@contextlib.contextmanager
def umask(value: int):
    old = os.umask(value)
    try:
        yield
    finally:
        os.umask(old)


def mode(path: Path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def full_lf(rng, R=2, C=2, H=6, W=7, B=3) -> LightField:
    """A small light field with every kind of file a capture holds (views, PFM, HDF5 cube)."""
    return LightField(
        views=rng.random((R, C, H, W)).astype(np.float32), wavelengths=raster_wavelengths(R, C),
        gt_disparity=rng.normal(size=(H, W)).astype(np.float32),
        gt_cube=rng.random((R, C, B, H, W)).astype(np.float32),
        cube_wavelengths=np.linspace(420, 680, B))


# ----------------------------------------------------------------------------- umask
@pytest.mark.parametrize("mask", UMASKS, ids=oct)
def test_atomic_write_follows_the_umask(tmp_path, mask):
    with umask(mask):
        path = atomic.atomic_write_text(tmp_path / "a.txt", "hello")
        assert atomic.current_umask() == mask
    assert mode(path) == 0o666 & ~mask
    assert path.read_text() == "hello"
    assert os.listdir(tmp_path) == ["a.txt"]  # renamed, no temporary left


@pytest.mark.parametrize("mask", [0o022, 0o077], ids=oct)
@pytest.mark.parametrize("fmt", ["png", "tiff"])
def test_every_capture_file_follows_the_umask(tmp_path, rng, mask, fmt):
    with umask(mask):
        man = write_capture(full_lf(rng), tmp_path / "cap", image_format=fmt)
    files = sorted(man.parent.iterdir())
    view_suffix = ".tif" if fmt == "tiff" else ".png"
    assert {f.suffix for f in files} >= {".toml", ".pfm", ".h5", view_suffix}
    assert {f.name: mode(f) for f in files} == {f.name: 0o666 & ~mask for f in files}
    assert mode(man.parent) == 0o777 & ~mask  # the folder too (plain mkdir)


def test_cube_file_follows_the_umask(tmp_path, rng):
    with umask(0o022):
        man = write_capture(full_lf(rng), tmp_path / "cap")
    assert mode(man.parent / "gt_cube.h5") == 0o644


def test_publish_gives_the_umask_mode(tmp_path):
    import tempfile

    fd, tmp = tempfile.mkstemp(dir=tmp_path)
    os.write(fd, b"data")
    os.close(fd)
    with umask(0o027):
        atomic.publish(tmp, tmp_path / "final.bin")
    assert mode(tmp_path / "final.bin") == 0o640
    assert os.listdir(tmp_path) == ["final.bin"]


def test_umask_read_without_proc_restores_it(monkeypatch):
    def no_proc(*args, **kwargs):
        raise OSError("no /proc here")

    monkeypatch.setattr(atomic, "open", no_proc, raising=False)
    with umask(0o027):
        assert atomic.current_umask() == 0o027
        assert os.umask(0o027) == 0o027  # still set: reading did not change it


def test_replacing_a_0600_file_gives_the_umask_mode(tmp_path):
    path = tmp_path / "old.txt"
    path.write_text("old")
    path.chmod(0o600)
    with umask(0o022):
        atomic.atomic_write_text(path, "new")
    assert mode(path) == 0o644 and path.read_text() == "new"


@pytest.mark.parametrize("mask", [0o022, 0o077], ids=oct)
def test_cli_outputs_follow_the_umask(tmp_path, mask):
    out = tmp_path / "scene"
    src = str(Path(__file__).resolve().parents[1] / "src")
    env = dict(os.environ, PYTHONPATH=src + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run(
        [sys.executable, "-m", "hyperlf.cli", "-q", "synth", "procedural", "--size", "24,32",
         "--grid", "2,2", "-o", str(out)],
        capture_output=True, text=True, timeout=300, env=env,
        preexec_fn=lambda: os.umask(mask))
    assert proc.returncode == 0, proc.stderr
    files = [p for p in out.rglob("*") if p.is_file()]
    assert len(files) >= 5 and any(p.suffix == ".png" for p in files)
    assert {str(p): mode(p) for p in files} == {str(p): 0o666 & ~mask for p in files}


# ----------------------------------------------------------------------------- capture helpers

def manifest(folder: Path) -> dict:
    return tomllib.loads((folder / MANIFEST).read_text())


def save_manifest(folder: Path, doc: dict) -> None:
    (folder / MANIFEST).write_text(tomli_w.dumps(doc))


def plant(path: Path, text: str) -> Path:
    """A user's file with known content."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def old_capture(tmp_path: Path, rng, *names: str) -> Path:
    """A 2 x 2 capture whose manifest also names ``names`` (hostile or stale old entries)."""
    folder = tmp_path / "cap"
    write_capture(LightField(views=rng.random((2, 2, 6, 5))), folder, bit_depth=8)
    doc = manifest(folder)
    doc["view"] += [{"row": 9, "col": i, "file": n} for i, n in enumerate(names)]
    save_manifest(folder, doc)
    return folder


def overwrite(folder: Path, rng) -> None:
    """Write a smaller 1 x 2 capture over ``folder``; it must come out whole and readable."""
    write_capture(LightField(views=rng.random((1, 2, 6, 5))), folder, bit_depth=8, overwrite=True)
    assert read_capture(folder).grid_shape == (1, 2)


# ----------------------------------------------------------------------------- overwrite
def test_overwrite_removes_the_previous_captures_stale_files(tmp_path, rng):
    folder = old_capture(tmp_path, rng, "sub/old.png")
    plant(folder / "sub" / "old.png", "stale view in a real subfolder")
    plant(folder / "notes.txt", "not named by the manifest")
    overwrite(folder, rng)
    assert sorted(os.listdir(folder)) == [MANIFEST, "notes.txt", "sub", "view_r0_c0.png",
                                          "view_r0_c1.png"]
    assert os.listdir(folder / "sub") == []  # the stale file went, the folder stays
    assert (folder / "notes.txt").read_text() == "not named by the manifest"


def test_overwrite_never_follows_a_symlinked_folder(tmp_path, rng):
    victim = plant(tmp_path / "elsewhere" / "precious.png", "user data")
    folder = old_capture(tmp_path, rng, "link/precious.png")
    (folder / "link").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
    overwrite(folder, rng)
    assert victim.read_text() == "user data"
    assert (folder / "link").is_symlink()


@pytest.mark.parametrize("kind", ["parent", "absolute", "nested parent"])
def test_overwrite_never_leaves_the_folder(tmp_path, rng, kind):
    victim = plant(tmp_path / "outside.png", "user data")
    name = {"parent": "../outside.png", "absolute": str(victim),
            "nested parent": "sub/../../outside.png"}[kind]
    folder = old_capture(tmp_path, rng, name)
    (folder / "sub").mkdir()
    overwrite(folder, rng)
    assert victim.read_text() == "user data"


@pytest.mark.parametrize("name", [MANIFEST, f"./{MANIFEST}", "view_r0_c0.png", "./view_r0_c1.png"])
def test_overwrite_keeps_the_new_manifest_and_views(tmp_path, rng, name):
    folder = old_capture(tmp_path, rng, name)
    overwrite(folder, rng)  # reads the new capture back, manifest included
    assert sorted(os.listdir(folder)) == [MANIFEST, "view_r0_c0.png", "view_r0_c1.png"]


def test_overwrite_keeps_old_gt_names_that_the_new_capture_reuses(tmp_path, rng):
    folder = old_capture(tmp_path, rng)
    doc = manifest(folder)
    save_manifest(folder, dict(doc, gt_disparity=MANIFEST, gt_cube="./view_r0_c0.png"))
    overwrite(folder, rng)
    assert sorted(os.listdir(folder)) == [MANIFEST, "view_r0_c0.png", "view_r0_c1.png"]


@pytest.mark.parametrize("where", ["outside", "inside"])
def test_overwrite_leaves_symlinks_and_their_targets(tmp_path, rng, where):
    folder = old_capture(tmp_path, rng, "alias.png")
    target = plant((tmp_path if where == "outside" else folder) / "target.png", "linked data")
    (folder / "alias.png").symlink_to(target)
    overwrite(folder, rng)
    assert (folder / "alias.png").is_symlink()  # not the writer's file: left alone
    assert target.read_text() == "linked data"


def test_overwrite_leaves_folders_named_as_files(tmp_path, rng):
    folder = old_capture(tmp_path, rng, "views", "")
    keep = plant(folder / "views" / "keep.png", "inside a folder named by the old manifest")
    overwrite(folder, rng)
    assert keep.read_text() == "inside a folder named by the old manifest"


def test_cli_overwrite_touches_nothing_outside(tmp_path, rng):
    victims = [plant(tmp_path / "elsewhere" / "a.png", "A"), plant(tmp_path / "b.png", "B")]
    folder = old_capture(tmp_path, rng, "link/a.png", "../b.png", str(victims[0]), MANIFEST)
    (folder / "link").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
    before = sorted(os.listdir(folder))
    code = main(["-q", "synth", "procedural", "--size", "20,24", "--grid", "2,2", "--no-pictures",
                 "-o", str(folder), "--overwrite"])
    assert code == 2  # a folder the CLI did not write (no result manifest) is never replaced
    assert [v.read_text() for v in victims] == ["A", "B"]
    assert sorted(os.listdir(folder)) == before


# ----------------------------------------------------------------------------- reading
@pytest.fixture
def cap(tmp_path, rng):
    """A valid 2 x 2 capture with 8-bit views, ground-truth disparity and cube."""
    folder = tmp_path / "cap"
    write_capture(full_lf(rng, H=6, W=5), folder, bit_depth=8)
    return folder


@pytest.fixture
def no_decoding(monkeypatch):
    """Record every image, PFM or cube file the capture reader decodes."""
    import hyperlf.formats.capture as capture

    opened = []
    def recording(read):
        def wrapper(path, *args, **kwargs):
            opened.append(path)
            return read(path, *args, **kwargs)
        return wrapper

    for name in ("read_image", "read_pfm", "read_cube_h5"):
        monkeypatch.setattr(capture, name, recording(getattr(capture, name)))
    return opened


def point(folder: Path, entry: str, **fields) -> None:
    """Make the manifest name ``entry`` for view (0, 1), or set top-level ``fields``."""
    doc = manifest(folder)
    if entry:
        doc["view"][1]["file"] = entry
    doc.update(fields)
    save_manifest(folder, doc)


def refused(folder: Path, *words: str) -> str:
    with pytest.raises(FormatError) as info:
        read_capture(folder)
    msg = str(info.value)
    assert "\n" not in msg and all(w in msg for w in words), msg
    return msg


def test_view_symlink_out_of_the_folder_is_refused_before_decoding(cap, tmp_path, rng, no_decoding):
    write_image(tmp_path / "outside.png", rng.random((6, 5)), bit_depth=8)
    (cap / "evil.png").symlink_to(tmp_path / "outside.png")
    point(cap, "evil.png")
    refused(cap, "view (0, 1) 'file' 'evil.png'", "resolves outside the capture folder",
            str(tmp_path / "outside.png"))
    assert no_decoding == []


def test_view_in_a_symlinked_folder_out_of_the_folder_is_refused(cap, tmp_path, rng, no_decoding):
    write_image(tmp_path / "elsewhere" / "v.png", rng.random((6, 5)), bit_depth=8)
    (cap / "sub").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
    point(cap, "sub/v.png")
    refused(cap, "'sub/v.png'", "resolves outside the capture folder")
    assert no_decoding == []


def test_dangling_symlink_out_of_the_folder_is_refused(cap, tmp_path):
    (cap / "gone.png").symlink_to(tmp_path / "never-there.png")
    point(cap, "gone.png")
    refused(cap, "'gone.png'", "resolves outside the capture folder")


@pytest.mark.parametrize("field", ["gt_disparity", "gt_cube", "pattern"])
def test_ground_truth_symlink_out_of_the_folder_is_refused_before_decoding(cap, tmp_path, field,
                                                                           no_decoding):
    src = cap / ("gt_cube.h5" if field == "gt_cube" else "gt_disparity.pfm")
    os.replace(src, tmp_path / src.name)
    (cap / src.name).symlink_to(tmp_path / src.name)
    if field == "pattern":
        for r, c in [(0, 0), (0, 1), (1, 0), (1, 1)]:
            os.symlink(tmp_path / src.name, cap / f"gt_r{r}_c{c}.pfm")
        point(cap, "", gt_disparity="gt_r{row}_c{col}.pfm")
    refused(cap, "gt_cube" if field == "gt_cube" else "gt_disparity", "resolves outside")
    assert no_decoding == []


def test_symlinks_that_stay_inside_are_read(cap, rng, no_decoding):
    before = read_capture(cap)
    (cap / "real").mkdir()
    os.replace(cap / "view_r0_c1.png", cap / "real" / "v.png")
    (cap / "alias").symlink_to("real", target_is_directory=True)
    (cap / "view_r0_c1.png").symlink_to(Path("alias") / "v.png")
    point(cap, "alias/v.png")
    np.testing.assert_array_equal(read_capture(cap).views, before.views)
    point(cap, "view_r0_c1.png")
    np.testing.assert_array_equal(read_capture(cap).views, before.views)
    assert cap / "alias" / "v.png" in no_decoding  # the recorder the refusals rely on works


def test_a_capture_folder_reached_through_a_symlink_is_read(cap, tmp_path):
    (tmp_path / "link").symlink_to(cap, target_is_directory=True)
    assert read_capture(tmp_path / "link").grid_shape == (2, 2)


@pytest.mark.parametrize("name", ["../cap/view_r0_c1.png", "sub/../../x.png", "ABS"])
def test_parent_and_absolute_entries_keep_their_message(cap, name, no_decoding):
    name = str(cap / "view_r0_c1.png") if name == "ABS" else name
    point(cap, name)
    refused(cap, f"view (0, 1) 'file' {name!r} must be a path inside the capture folder")
    assert no_decoding == []


def test_cli_refuses_a_view_outside_with_exit_3(cap, tmp_path, rng, capsys):
    write_image(tmp_path / "outside.png", rng.random((6, 5)), bit_depth=8)
    (cap / "evil.png").symlink_to(tmp_path / "outside.png")
    point(cap, "evil.png")
    assert main(["info", str(cap)]) == 3
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "resolves outside the capture folder" in err
