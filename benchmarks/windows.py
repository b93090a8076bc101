"""H-LF depth error against the correspondence window and the number of views.

The light-field cost averages every other view's cost, so the window that two-view stereo
needs to average noise away is wider than a dense array needs; the wide window only fattens
depth edges.  This script measures where the smaller window starts to pay: each procedural
scene through arrays of several sizes, the default depth with the RSNCC window forced to each
size in ``--windows`` (``DepthParams(window=...)``) and, optionally, each number of visibility
rounds in ``--visibility-rounds``, RMSE with a 15-px border.

Usage::

    python benchmarks/windows.py --grids 2x2,3x3,4x4,5x5,5x6 --windows 5,3 --size 128,128 \\
        --labels 32 --visibility-rounds 0

Prints a markdown table (one row per grid and scene); the figures go to BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

from _common import log
from hyperlf.hlf import DepthParams, depth
from hyperlf.metrics import disparity_scores
from hyperlf.synthesis import SCENES, procedural_scene

BORDER = 15


def _pairs(text: str, what: str) -> list[tuple[int, int]]:
    try:
        out = [tuple(int(x) for x in item.lower().split("x")) for item in text.split(",")]
    except ValueError:
        raise SystemExit(f"windows.py: {what} must look like 3x3,5x6") from None
    if any(len(p) != 2 or min(p) < 1 for p in out):
        raise SystemExit(f"windows.py: {what} must look like 3x3,5x6")
    return out


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grids", default="2x2,3x3,4x4,5x5,5x6", help="array sizes, rows x cols")
    ap.add_argument("--windows", default="5,3", help="RSNCC windows to compare (odd)")
    ap.add_argument("--scenes", default="planes,slanted,occlusion,solids")
    ap.add_argument("--size", default="128,128", help="H,W")
    ap.add_argument("--labels", type=int, default=32)
    ap.add_argument("--visibility-rounds", default=None,
                    help="DepthParams.visibility_rounds to compare, e.g. 0,1 (default: the "
                         "library's rule)")
    return ap.parse_args(argv)


def main(argv=None) -> None:
    a = parse_args(argv)
    grids = _pairs(a.grids, "--grids")
    windows = [int(w) for w in a.windows.split(",")]
    rounds = [None] if a.visibility_rounds is None else \
        [int(r) for r in a.visibility_rounds.split(",")]
    columns = [(w, r) for w in windows for r in rounds]
    H, W = (int(x) for x in a.size.split(","))
    scenes = a.scenes.split(",")
    unknown = [s for s in scenes if s not in SCENES]
    if unknown:
        raise SystemExit(f"windows.py: unknown scene(s) {unknown}; choose from {sorted(SCENES)}")
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; HYPERLF_DATA="
          f"{os.environ.get('HYPERLF_DATA', '(unset: ColorChecker reflectances)')}\n")
    names = [f"RSNCC {w} x {w}" + ("" if r is None else f", {r} visibility round(s)")
             for w, r in columns]
    print("| grid | other views | scene | " + " | ".join(names) + " |")
    print("|---|---:|---|" + "---:|" * len(columns))
    for R, C in grids:
        for name in scenes:
            lf = procedural_scene(**dict(SCENES[name], rows=R, cols=C, height=H, width=W))
            cells = []
            for w, r in columns:
                t0 = time.perf_counter()
                res = depth(lf, n_labels=a.labels,
                            params=DepthParams(window=w, visibility_rounds=r))
                s = disparity_scores(res.disparity, lf.reference_gt_disparity, border=BORDER)
                cells.append(f"{s.rmse:.4f}")
                log(f"{R}x{C} {name} window {w} rounds {r}: RMSE {s.rmse:.4f} "
                    f"({time.perf_counter() - t0:.1f} s)")
            best = min(range(len(cells)), key=lambda i: float(cells[i]))
            cells[best] = f"**{cells[best]}**"
            print(f"| {R} x {C} | {R * C - 1} | {name} | " + " | ".join(cells) + " |",
                  flush=True)


if __name__ == "__main__":
    main()
