"""Peak memory and time of H-LF depth in strips of rows (issue 13 item 2; SPEC §12).

    python benchmarks/tiles.py CAPTURE [--labels 64] [--budgets none,2G,1G]
                                       [--tile-rows 256,128,64] [--out benchmarks/results/tiles]

Runs the default ``hlf.depth`` of CAPTURE once per memory budget (``DepthParams.max_memory``;
``none`` = the default budget) and once per forced strip height, each in its own process (its
peak memory ``VmHWM`` is its own; a warm-up call first loads the compiled kernels), and checks
every disparity map bit for bit against the first run's.  Prints and writes ``tiles.md`` (the
table BENCHMARKS.md quotes) with the estimate of :func:`hyperlf.tiling.depth_memory` beside the
measured peak.  A synthetic capture: ``python benchmarks/scaling.py`` makes them (``WORK``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from scaling import _peak_gb  # noqa: E402  (the benchmarks share their peak-memory reader)


def run_one(capture: str, labels: int, budget: str, tile_rows: str, save: str) -> dict:
    """One depth run in this process (called in a child process by :func:`main`)."""
    import numpy as np

    from hyperlf.formats import load_lightfield
    from hyperlf.hlf import DepthParams, depth
    from hyperlf.synthesis import procedural_scene
    from hyperlf.tiling import depth_memory, parse_memory, plan

    depth(procedural_scene(seed=0, rows=3, cols=3, height=32, width=40), n_labels=8)  # warm-up
    lf = load_lightfield(capture, cube=False)
    params = DepthParams(max_memory=None if budget == "none" else parse_memory(budget),
                         tile_rows=None if tile_rows == "none" else int(tile_rows))
    res = depth(lf, n_labels=labels, params=params)
    np.save(save, res.disparity)
    t = res.timings
    strips = plan(lf.image_shape, labels, lf.n_views, params.max_memory,
                  tile_rows=params.tile_rows)
    rows = strips[0][1] if len(strips) > 1 else None
    est = depth_memory(lf.image_shape, labels, lf.n_views, strip_rows=rows)
    H, W = lf.image_shape
    return dict(size=f"{H} x {W}", views=lf.n_views, labels=labels, budget=budget,
                tile_rows=tile_rows, strips=len(strips), total_s=round(t["total_s"], 1),
                correspondence_s=round(t["correspondence_s"], 1),
                scales_s=round(t.get("scales_s", 0.0), 1), peak_gb=round(_peak_gb(), 3),
                estimate_gb=round(est / 2**30, 3))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture")
    ap.add_argument("--labels", type=int, default=64)
    ap.add_argument("--budgets", default="none", help="comma-separated, e.g. none,2G,1G")
    ap.add_argument("--tile-rows", default="", help="comma-separated forced strip heights")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/tiles"))
    ap.add_argument("--one", nargs=3, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one:
        print(json.dumps(run_one(a.capture, a.labels, *a.one)))
        return
    import numpy as np

    runs = [(b, "none") for b in a.budgets.split(",") if b]
    runs += [("none", r) for r in a.tile_rows.split(",") if r]
    rows, first = [], None
    with tempfile.TemporaryDirectory() as tmp:
        for i, (budget, tile_rows) in enumerate(runs):
            save = os.path.join(tmp, f"{i}.npy")
            proc = subprocess.run([sys.executable, __file__, a.capture, "--labels",
                                   str(a.labels), "--one", budget, tile_rows, save],
                                  capture_output=True, text=True, check=True)
            row = json.loads(proc.stdout.strip().splitlines()[-1])
            disp = np.load(save)
            first = disp if first is None else first
            row["identical"] = bool(np.array_equal(disp, first))
            print(row, file=sys.stderr, flush=True)
            rows.append(row)
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(str(r[k]) for k in keys) + " |" for r in rows]
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "tiles.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
