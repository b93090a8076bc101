"""How H-LF depth grows with pixels, labels and views (issue 13 item 1; SPEC §12).

    python benchmarks/scaling.py WORK [--sizes 256x256,512x512] [--labels 32,64,128]
                                      [--grids 3x3,5x6,9x9] [--out benchmarks/results/scaling]

Synthesises the procedural "solids" scene once per (size, grid) into WORK (kept and reused;
saved without its ground-truth cube),
then runs the default ``hlf.depth`` once per (size, grid, labels), each in its own process so
that its peak memory (``ru_maxrss``) is its own, after a small warm-up call that loads the
compiled kernels.  Writes ``scaling.csv``, ``scaling.md`` (the table BENCHMARKS.md quotes) and
``scaling.png`` (wall time and peak memory against pixels x labels x views) to ``--out``.
Not a test: numbers depend on the machine; record them with the machine's description.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
from pathlib import Path

RESULT_KEYS = ("height", "width", "rows", "cols", "labels", "total_s", "correspondence_s",
               "mrf_s", "peak_gb", "rmse_px")


def _pairs(text: str, sep: str = "x") -> list[tuple[int, int]]:
    return [tuple(int(v) for v in item.split(sep)) for item in text.split(",") if item]


def synthesise(work: Path, size, grid) -> Path:
    """The solids scene at ``size`` (H, W) through a ``grid`` (R, C) array, cached in WORK."""
    from hyperlf import synthesis
    from hyperlf.formats import save_lightfield

    path = work / f"solids_{size[0]}x{size[1]}_{grid[0]}x{grid[1]}"
    if not path.exists():
        spec = dict(synthesis.SCENES["solids"])
        spec.pop("name", None)
        lf = synthesis.procedural_scene(**spec, rows=grid[0], cols=grid[1], height=size[0],
                                        width=size[1])
        # without the ground-truth cube, which loading would otherwise count in the peak
        # memory of depth (81 bands x 81 views x 512 x 512 floats: 6.9 GB)
        save_lightfield(lf.replace(gt_cube=None, cube_wavelengths=None), path)
    return path


def _peak_gb() -> float:
    """This process's peak resident memory: ``VmHWM`` (Linux; reset by exec, unlike
    ``ru_maxrss``, which a child started by fork + exec inherits from its parent), else
    ``ru_maxrss``."""
    import resource

    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 2**20
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


def run_one(capture: str, labels: int) -> dict:
    """One depth run in this process (called in a child process by :func:`main`)."""
    import numpy as np

    from hyperlf import metrics
    from hyperlf.formats import load_lightfield
    from hyperlf.hlf import depth
    from hyperlf.synthesis import procedural_scene

    depth(procedural_scene(seed=0, rows=3, cols=3, height=32, width=40), n_labels=8)  # warm-up
    lf = load_lightfield(capture, cube=False)
    res = depth(lf, n_labels=labels)
    gt = lf.reference_gt_disparity
    sc = None if gt is None else metrics.hci_scores(res.disparity, gt)
    rmse = None if sc is None else sc.rmse
    peak = _peak_gb()
    R, C = lf.grid_shape
    H, W = lf.image_shape
    t = res.timings
    return dict(height=H, width=W, rows=R, cols=C, labels=labels,
                total_s=round(t["total_s"], 2), correspondence_s=round(t["correspondence_s"], 2),
                mrf_s=round(t["mrf_s"], 2), peak_gb=round(peak, 3),
                rmse_px=None if rmse is None else round(rmse, 4),
                _check=bool(np.isfinite(res.disparity).all()))


def write_outputs(rows: list[dict], out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "scaling.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, RESULT_KEYS, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    lines = ["| size | grid | labels | pixels x labels x views (M) | total s | correspondence s "
             "| MRF s | peak GB | RMSE px |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        work = r["height"] * r["width"] * r["labels"] * r["rows"] * r["cols"] / 1e6
        lines.append(f"| {r['height']} x {r['width']} | {r['rows']} x {r['cols']} | "
                     f"{r['labels']} | {work:.3g} | {r['total_s']} | {r['correspondence_s']} | "
                     f"{r['mrf_s']} | {r['peak_gb']} | {r['rmse_px']} |")
    (out / "scaling.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    _plot(rows, out / "scaling.png")


def _plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for grid in sorted({(r["rows"], r["cols"]) for r in rows}):
        sel = sorted((r for r in rows if (r["rows"], r["cols"]) == grid),
                     key=lambda r: r["height"] * r["width"] * r["labels"])
        x = [r["height"] * r["width"] * r["labels"] * r["rows"] * r["cols"] / 1e6 for r in sel]
        for ax, key in zip(axes, ("total_s", "peak_gb")):
            ax.loglog(x, [r[key] for r in sel], "o-", label=f"{grid[0]} x {grid[1]} views")
    for ax, label in zip(axes, ("wall time of depth (s)", "peak memory (GB)")):
        ax.set_xlabel("pixels x labels x views (millions)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("work", type=Path, help="folder for the synthetic captures (reused)")
    ap.add_argument("--sizes", default="256x256,512x512", help="HxW,... (default 256x256,512x512)")
    ap.add_argument("--labels", default="32,64,128")
    ap.add_argument("--grids", default="3x3,5x6,9x9")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/scaling"))
    ap.add_argument("--one", nargs=2, metavar=("CAPTURE", "LABELS"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one:
        print(json.dumps(run_one(a.one[0], int(a.one[1]))))
        return
    a.work.mkdir(parents=True, exist_ok=True)
    rows = []
    for size in _pairs(a.sizes):
        for grid in _pairs(a.grids):
            capture = synthesise(a.work, size, grid)
            for labels in (int(v) for v in a.labels.split(",")):
                proc = subprocess.run([sys.executable, __file__, os.fspath(a.work), "--one",
                                       os.fspath(capture), str(labels)],
                                      capture_output=True, text=True, check=True)
                row = json.loads(proc.stdout.strip().splitlines()[-1])
                print(row, file=sys.stderr, flush=True)
                rows.append(row)
    write_outputs(rows, a.out)


if __name__ == "__main__":
    main()
