"""`hyperlf info` on what the commands write: result folders, PFM maps, PLY clouds, cube
files (`hyperlf.formats.describe`)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hyperlf.cli import main
from hyperlf.errors import FormatError
from hyperlf.formats import (describe, describe_pfm, describe_ply, read_pfm, write_cube_h5,
                             write_pfm)
from hyperlf.formats.ply import write_ply
from hyperlf.outputs import MANIFEST, read_manifest, result_folder


@pytest.fixture(scope="module")
def depth_result(tmp_path_factory):
    root = tmp_path_factory.mktemp("info")
    cap, out = root / "cap", root / "depth"
    assert main(["-q", "synth", "procedural", "--size", "32,40", "--grid", "2,3",
                 "--no-pictures", "-o", str(cap)]) == 0
    assert main(["-q", "depth", str(cap), "--labels", "8", "-o", str(out)]) == 0
    return out


def test_a_depth_result_is_described_map_by_map(depth_result, capsys):
    assert main(["info", str(depth_result)]) == 0
    lines = capsys.readouterr().out.splitlines()
    files = read_manifest(depth_result)["files"]
    assert lines[0] == str(depth_result)
    assert lines[1].startswith("result set  : written by `hyperlf depth` (hyperlf ")
    assert lines[1].endswith(f"), {len(files)} files")
    for name in ("disparity.pfm", "confidence.pfm"):
        d = read_pfm(depth_result / name)
        want = f"values {d.min():.6g}..{d.max():.6g}"  # both maps are finite everywhere
        assert f"{name}: PFM map, 40 x 32 px (W x H), {want}" in lines
    pictures = sorted(f for f in files if f.endswith(".png"))
    assert f"pictures    : {', '.join(pictures)}" in lines
    assert "other files : disparity_16bit.txt" in lines


def test_a_result_folder_names_what_it_cannot_read(tmp_path):
    out, outside = tmp_path / "res", tmp_path / "outside.pfm"
    write_pfm(outside, np.ones((2, 2)))
    with result_folder(out, command="depth") as stage:
        write_pfm(stage / "a.pfm", np.ones((2, 3)))
        (stage / "bad.pfm").write_bytes(b"Pf\n3 2\n-1\n" + b"\0" * 5)  # truncated
        write_pfm(stage / "gone.pfm", np.ones((2, 2)))
        write_pfm(stage / "link.pfm", np.ones((2, 2)))
        write_ply(stage / "points.ply", np.zeros((5, 3)), np.zeros((5, 3), np.uint8),
                  scalars={"confidence": np.ones(5)})
        write_cube_h5(stage / "cube.h5", np.ones((1, 2, 3, 4, 5), np.float32),
                      np.array([450.0, 550, 650]))
    (out / "gone.pfm").unlink()
    (out / "link.pfm").unlink()
    (out / "link.pfm").symlink_to(outside)
    text = describe(out)
    assert "a.pfm       : PFM map, 3 x 2 px (W x H), values 1..1" in text
    assert "bad.pfm     : unreadable: " in text and "truncated" in text
    assert "gone.pfm    : missing (removed since it was written)" in text
    assert "link.pfm    : a symlink (not followed)" in text
    assert "points.ply  : PLY point cloud, 5 points (x, y, z, red, green, blue, confidence)" \
        in text
    assert "cube.h5     : cube, 1 x 2 views x 3 bands of 5 x 4 px (W x H)" in text
    assert len(text.splitlines()) == 7


def test_single_files(tmp_path, capsys):
    d = np.array([[1.5, np.nan, -np.inf], [-2.0, 4.0, 0.25]], np.float32)
    write_pfm(tmp_path / "d.pfm", d)
    assert describe_pfm(tmp_path / "d.pfm") == (
        "PFM map, 3 x 2 px (W x H), values -2..4, 2 of 6 values not finite")
    write_pfm(tmp_path / "c.pfm", np.zeros((2, 2, 3)))
    assert describe_pfm(tmp_path / "c.pfm").startswith("PFM colour image, 2 x 2 px")
    write_pfm(tmp_path / "n.pfm", np.full((1, 1), np.nan))
    assert describe_pfm(tmp_path / "n.pfm").endswith("no finite value")
    (tmp_path / "a.ply").write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                                    "property float y\nproperty float z\nend_header\n"
                                    "0 0 0\n1 1 1\n")
    assert describe_ply(tmp_path / "a.ply") == "PLY point cloud, 2 points (x, y, z)"
    (tmp_path / "x.ply").write_text("not a ply")
    with pytest.raises(FormatError, match="not a PLY"):
        describe_ply(tmp_path / "x.ply")
    # through the command: one line, the documented exit status for a malformed file
    assert main(["info", str(tmp_path / "d.pfm")]) == 0
    assert capsys.readouterr().out.splitlines()[1] == describe_pfm(tmp_path / "d.pfm")
    assert main(["info", str(tmp_path / "x.ply")]) == 3
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a PLY" in err


def test_a_folder_without_a_manifest_is_still_read_as_a_light_field(depth_result, tmp_path,
                                                                     capsys):
    plain = tmp_path / "plain"
    plain.mkdir()
    os.link(depth_result / "disparity.png", plain / "disparity.png")
    assert main(["info", str(plain)]) != 0  # loose images: what it said before
    err = capsys.readouterr().err
    assert "no capture.toml" in err and "'hyperlf ingest'" in err  # where raw images go


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=300))
def test_any_bytes_as_a_ply_header_are_described_or_refused_in_one_line(tmp_path, data):
    p = tmp_path / "x.ply"
    p.write_bytes(data)
    try:
        text = describe_ply(p)
    except FormatError as exc:
        assert len(str(exc).splitlines()) == 1
    else:
        assert text.startswith("PLY point cloud, ")


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(doc=st.one_of(st.binary(max_size=200).map(lambda b: b.decode("latin-1")),
                     st.dictionaries(st.sampled_from(["files", "command", "written_by"]),
                                     st.one_of(st.none(), st.integers(), st.text(max_size=8),
                                               st.lists(st.text(max_size=8), max_size=3)))
                     .map(json.dumps)))
def test_any_manifest_is_read_or_ignored(tmp_path, doc):
    folder = tmp_path / "m"
    folder.mkdir(exist_ok=True)
    (folder / MANIFEST).write_text(doc, encoding="utf-8")
    m = read_manifest(folder)
    if m is not None:
        assert isinstance(m["written_by"], str) and isinstance(m["files"], list)
        assert m["command"] is None or isinstance(m["command"], str)
        text = describe(folder)  # files it names that are not there are said to be missing
        assert text.startswith("result set  : written by ")


def test_a_manifest_naming_files_outside_its_folder_does_not_reach_them(tmp_path):
    write_pfm(tmp_path / "secret.pfm", np.ones((2, 2)))
    (tmp_path / "elsewhere").mkdir()
    write_pfm(tmp_path / "elsewhere" / "x.pfm", np.ones((2, 2)))
    out = tmp_path / "res"
    out.mkdir()
    (out / "sub").symlink_to(tmp_path / "elsewhere")
    names = ["../secret.pfm", str(tmp_path / "secret.pfm"), "sub/x.pfm"]
    (out / MANIFEST).write_text(json.dumps({"written_by": "hyperlf", "command": "depth",
                                            "files": names}))
    text = describe(out)
    for name in names:
        assert f"{name:<12}: outside the folder (not read)" in text


@pytest.mark.parametrize("kind", ["capture", "h5"])
def test_a_light_field_is_described_without_reading_its_ground_truth_cube(tmp_path, kind):
    """`info` on a paper-size capture used to load its 3.9 GB cube for one line: the line
    is now made from the cube's shape and wavelengths, and the cube's data is never read
    (a corrupt chunk does not matter)."""
    import h5py

    from hyperlf.formats import gt_cube_file, load_lightfield

    path = tmp_path / ("cap" if kind == "capture" else "lf.h5")
    assert main(["-q", "synth", "procedural", "--size", "24,32", "--grid", "2,3",
                 "--no-pictures", "-o", str(path)]) == 0
    want = load_lightfield(path).describe()  # the cube loaded
    assert "ground truth: cube with" in want
    assert describe(path) == want
    cube_file, name = ((gt_cube_file(path), "cube") if kind == "capture" else (path, "gt_cube"))
    with h5py.File(cube_file, "r+") as f:
        f[name].id.write_direct_chunk((0,) * f[name].ndim, b"not a chunk")
    with pytest.raises(FormatError):
        load_lightfield(path)
    assert describe(path) == want
    with h5py.File(cube_file, "r+") as f:  # wavelengths that are not numbers
        name = "wavelengths" if kind == "capture" else "cube_wavelengths"
        del f[name]
        f[name] = "not numbers"
    if kind == "capture":  # the cube file's reader checks them: a one-line error
        with pytest.raises(FormatError, match="wavelengths"):
            describe(path)
    else:  # a light-field file's cube is described without them
        assert "ground truth: cube with 6 bands per view\n" in describe(path) + "\n"
