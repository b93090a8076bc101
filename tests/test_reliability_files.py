"""Files as a careful user sees them: output modes follow the umask (issue 10, item 5)."""

from __future__ import annotations

import contextlib
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import hyperlf._atomic as atomic
from hyperlf import LightField, raster_wavelengths
from hyperlf.formats import write_capture

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


# hyperlf.formats.hdf5.CubeWriter renames its own mkstemp file (not through _atomic); until it
# calls hyperlf._atomic.publish, cube files stay 0600 and are checked apart, as a strict xfail.
CUBE_0600 = pytest.mark.xfail(
    strict=True, reason="CubeWriter (formats/hdf5.py) still os.replace()s its 0600 temporary; "
                        "make it call hyperlf._atomic.publish and remove this marker")


def not_cube(files):
    return [f for f in files if f.suffix != ".h5"]


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
    assert {f.suffix for f in files} >= {".toml", ".pfm", ".h5", ".tif" if fmt == "tiff" else ".png"}
    files = not_cube(files)
    assert {f.name: mode(f) for f in files} == {f.name: 0o666 & ~mask for f in files}
    assert mode(man.parent) == 0o777 & ~mask  # the folder too (plain mkdir)


@CUBE_0600
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
    files = not_cube(p for p in out.rglob("*") if p.is_file())
    assert len(files) >= 5 and any(p.suffix == ".png" for p in files)
    assert {str(p): mode(p) for p in files} == {str(p): 0o666 & ~mask for p in files}
