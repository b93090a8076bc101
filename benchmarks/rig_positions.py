#!/usr/bin/env python
"""Plane registration's camera positions on synthetic rigs with exact ground truth.

    python benchmarks/rig_positions.py [--seeds 0,1,2] [--grids 1x3,3x3,2x2,2x4]
        [--sizes 320x240,160x120] [--turns corner:90,...] [--out benchmarks/results/rig_positions]

One board shot per camera of ``calibration.rig.make_rig`` (imperfect cameras: rotations,
focal lengths, distortion, inverted bands) with the board 450 units in front of the array,
facing it squarely and tilted by (4, -3, 2) degrees; ``register_plane`` with its defaults.
Each row: where the positions came from (the scene's parallax or the board poses), whether
the focal length was determined, and the RMS distance (baselines) of the positions from the
rig's true camera centres, both relative to the reference, against that of the nominal grid
places (what a perfectly regular array would have). A refusal is listed with its message.
No data is needed. Writes ``rig_positions.md`` / ``.json``.

``--turns corner:90,reference:180,...`` mounts one camera turned about its optical axis in
every rig (``corner``: camera (0, 0), or the last one where (0, 0) is the reference;
``reference``: the reference camera) and adds whether exactly the expected cameras were
found turned (the turned one; all the others when it is the reference). A turned reference
turns the whole capture, so the error is then taken after the positions are turned back by
the same quarter turns.
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings
from pathlib import Path

import numpy as np

from _common import log, write_report
from hyperlf.calibration import register_plane
from hyperlf.calibration.board import camera_label
from hyperlf.calibration.grid import check_grid
from hyperlf.calibration.rig import make_rig, rotation_matrix
from hyperlf.errors import HyperLFError

POSES = {"square-on": (0.0, 0.0, 0.0), "tilted": (4.0, -3.0, 2.0)}


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, 1))))


def _turned_camera(rig, which: str):
    """The camera ``which`` (``corner`` or ``reference``) names in ``rig``."""
    ref = check_grid(rig.cameras, None)[1]
    if which == "reference":
        return ref
    keys = sorted(rig.cameras)
    return keys[0] if keys[0] != ref else keys[-1]


def run_rig(seed: int, grid: tuple[int, int], size: tuple[int, int], tilt,
            turn: tuple[str, int] | None = None) -> dict:
    """One registration: its positions' error against the truth, and the nominal grid's;
    with ``turn`` (``(which, degrees)``) one camera mounted turned, and whether the
    cameras found turned are the expected ones."""
    rig = make_rig(*grid, seed=seed, image_size=size)
    turned = None
    if turn is not None:
        turned = _turned_camera(rig, turn[0])
        cam = rig.cameras[turned]
        rig.cameras[turned] = dataclasses.replace(
            cam, R=rotation_matrix(0, 0, turn[1]) @ cam.R)
    shots = rig.render(rig.board_pose(450.0, tilt=tilt), supersample=2)
    try:
        cal = register_plane(shots, rig.board)
    except HyperLFError as exc:
        return {"refused": str(exc)}
    ref, keys = cal.reference, sorted(cal.cameras)
    true = np.array([rig.cameras[k].centre[:2] - rig.cameras[ref].centre[:2] for k in keys])
    true = true / rig.baseline
    est = np.array([cal.cameras[k].position - cal.cameras[ref].position for k in keys])
    nominal = np.array([[k[1] - ref[1], k[0] - ref[0]] for k in keys], np.float64)
    out = {"positions_from": cal.info["positions_from"],
           "focal_determined": bool(cal.info["focal_determined"]),
           "error": _rms(est, true), "nominal_error": _rms(nominal, true)}
    if turned is not None:
        expected = [k for k in keys if k != ref] if turned == ref else [turned]
        out["turns_found"] = (sorted(cal.info["turned_cameras"])
                              == sorted(camera_label(k) for k in expected))
        if turned == ref:   # the whole capture turned: its positions with it
            out["error"] = min(_rms(est @ _quarter(q), true) for q in range(4))
    return out


def _quarter(q: int) -> np.ndarray:
    """The 2 x 2 rotation by ``q`` quarter turns."""
    c, s = [(1, 0), (0, 1), (-1, 0), (0, -1)][q]
    return np.array([[c, -s], [s, c]], np.float64)


def _row(seed, grid, size, pose, r, turn=None) -> str:
    where = f"| {seed} | {grid[0]} x {grid[1]} | {size[0]} x {size[1]} | {pose} |"
    if turn is not None:
        where += f" {turn[0]} {turn[1]} |"
    if "refused" in r:
        return f"{where} refused: {r['refused'][:90]} | | | |" + (" |" if turn else "")
    found = f" {'yes' if r['turns_found'] else '**no**'} |" if turn else ""
    return (f"{where} {r['positions_from']} | {'yes' if r['focal_determined'] else 'no'} | "
            f"{r['error']:.3f} | {r['nominal_error']:.3f} |{found}")


def _turns(text: str) -> list:
    """``--turns``: ``[None]``, or ``(which, degrees)`` per item."""
    if not text:
        return [None]
    try:
        turns = [(w, int(d)) for w, d in (item.split(":") for item in text.split(","))]
    except ValueError:
        turns = []
    if not turns or any(w not in ("corner", "reference") or d % 90 for w, d in turns):
        raise SystemExit(f"rig_positions.py: --turns must be like corner:90,reference:180, "
                         f"got {text!r}")
    return turns


def _pairs(text: str, what: str) -> list[tuple[int, int]]:
    try:
        return [tuple(int(v) for v in item.split("x")) for item in text.split(",")]
    except ValueError:
        raise SystemExit(f"rig_positions.py: {what} must be like 2x4,3x3, got {text!r}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--grids", default="1x3,3x3,2x2,2x4", help="rows x columns of cameras")
    ap.add_argument("--sizes", default="320x240,160x120", help="width x height of the images")
    ap.add_argument("--turns", default="",
                    help="one camera mounted turned, e.g. corner:90,reference:180")
    ap.add_argument("--out", default="benchmarks/results/rig_positions")
    args = ap.parse_args()
    grids, sizes = _pairs(args.grids, "--grids"), _pairs(args.sizes, "--sizes")
    turns = _turns(args.turns)
    warnings.filterwarnings("ignore")
    extra = (" turned |", " found turned |", "---|") if args.turns else ("", "", "")
    lines = [f"| seed | grid | image | board |{extra[0]} positions from | focal fixed | error "
             f"(baselines) | nominal grid's error |{extra[1]}",
             f"|---|---|---|---|{extra[2]}---|---|---:|---:|{extra[2]}"]
    report = []
    for seed in (int(s) for s in args.seeds.split(",")):
        for grid in grids:
            for size in sizes:
                for pose, tilt in POSES.items():
                    for turn in turns:
                        log(f"seed {seed}, {grid}, {size}, {pose}, {turn or 'upright'}")
                        r = run_rig(seed, grid, size, tilt, turn)
                        report.append({"seed": seed, "grid": grid, "size": size, "pose": pose,
                                       "turn": turn, **r})
                        lines.append(_row(seed, grid, size, pose, r, turn))
    folder = Path(args.out)
    folder.mkdir(parents=True, exist_ok=True)
    write_report(folder, "rig_positions", "\n".join(lines) + "\n", {"rows": report})


if __name__ == "__main__":
    main()
