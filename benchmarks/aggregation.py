#!/usr/bin/env python
"""Edge-aware aggregation (issue 12 item 2): the ``aggregation`` option ablated per scene.

    HYPERLF_DATA=../shared/data python benchmarks/aggregation.py [--settings 2:1e-3,4:1e-3,4:1e-2] \\
        [--two-view venus,tsukuba,teddy,art] [--hlf planes,slanted,occlusion,solids] \\
        [--antinous] [--out benchmarks/results/aggregation]

Two-view (Table 1 protocol: red of the left image vs blue of the right one, ``auto`` + graph
cuts with the cost's Venus-tuned parameters, the default occlusion handling): each scene's
volumes are computed once, then aggregated with every setting
(:func:`hyperlf.costs.aggregate_pair`: each volume guided by its own image) and solved again.
H-LF (Table 2 protocol: procedural 5 x 6 scenes at 128 x 128, 32 labels, RMSE with a 15-px
border; ``--antinous``: full-resolution antinous, 64 labels): :func:`hyperlf.hlf.depth` with
``DepthParams(aggregation="guided", ...)``.  Settings are ``RADIUS:EPS``; "none" is always run.

The rule (issue 12 item 4): the option would become a default only if a setting beat "none"
on the tuning scenes (Venus; the procedural scenes and antinous for H-LF); every scene is
reported either way.  Writes ``aggregation.md`` and ``aggregation.json`` into ``--out``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from _common import log, write_report
from table1 import BLUE, RED, load_scene, score
from hyperlf.costs import AggregationParams, aggregate_pair
from hyperlf.hlf import DepthParams, depth
from hyperlf.metrics import disparity_scores
from hyperlf.twoview import compute_volumes, default_window, stereo_from_volumes

BORDER = 15


def settings_of(text: str) -> list[AggregationParams]:
    out = [AggregationParams()]
    for item in filter(None, (s.strip() for s in text.split(","))):
        r, e = item.split(":")
        out.append(AggregationParams("guided", int(r), float(e)))
    return out


def label(p: AggregationParams) -> str:
    return "none" if p.method == "none" else f"guided r{p.radius} eps {p.eps:g}"


def two_view(name: str, settings) -> dict:
    pair, drange, mask, mask_name = load_scene(name)
    L, R = pair.left[:, :, RED], pair.right[:, :, BLUE]
    cl, cr = compute_volumes(L, R, *drange, metric="auto",
                             window=default_window("auto", "graphcut"))
    row = {}
    for p in settings:
        t0 = time.perf_counter()
        al, ar = aggregate_pair(cl, cr, L, R, drange[0], p)
        res = stereo_from_volumes(al, ar, drange[0], "graphcut", guide_left=L, guide_right=R,
                                  metric="auto")
        row[label(p)] = {**score(res.disparity, pair, mask, mask_name),
                         "seconds": time.perf_counter() - t0}
        log(f"{name} {label(p)}: bad5 {row[label(p)]['bad5']:.2f}")
    return row


def light_field(name: str, settings, antinous: bool) -> dict:
    from table2 import load_scene as load_hlf

    lf, _, unit, _ = load_hlf(name, (128, 128), 1)
    labels = 64 if antinous else 32
    row = {}
    for p in settings:
        t0 = time.perf_counter()
        res = depth(lf, n_labels=labels, params=DepthParams(
            aggregation=p.method, aggregation_radius=p.radius, aggregation_eps=p.eps))
        s = disparity_scores(res.disparity * unit, lf.reference_gt_disparity * unit,
                             border=BORDER)
        row[label(p)] = {"rmse": s.rmse, "badpix_007": s.badpix_007,
                         "seconds": time.perf_counter() - t0}
        log(f"{name} {label(p)}: rmse {s.rmse:.4f} badpix {s.badpix_007:.2f}")
    return row


def table(rows: dict, keys: tuple, fmt: str) -> list[str]:
    names = list(next(iter(rows.values())))
    lines = ["| scene | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for scene, row in rows.items():
        lines.append(f"| {scene} | " + " | ".join(
            " / ".join(fmt.format(row[n][k]) for k in keys) for n in names) + " |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--settings", default="2:1e-3,4:1e-3,4:1e-2")
    ap.add_argument("--two-view", default="venus,tsukuba,teddy,art")
    ap.add_argument("--hlf", default="planes,slanted,occlusion,solids")
    ap.add_argument("--antinous", action="store_true", help="also full-resolution antinous")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/aggregation"))
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    settings = settings_of(a.settings)
    report = {"two_view": {}, "hlf": {}}
    for name in filter(None, a.two_view.split(",")):
        report["two_view"][name] = two_view(name, settings)
    hlf_scenes = [s for s in a.hlf.split(",") if s] + (["antinous"] if a.antinous else [])
    for name in hlf_scenes:
        report["hlf"][name] = light_field(name, settings, name == "antinous")
    lines = []
    if report["two_view"]:
        lines += ["Two-view, auto + graph cuts, bad5.0 / bad2.0 (%):", ""]
        lines += table(report["two_view"], ("bad5", "bad2"), "{:.2f}") + [""]
    if report["hlf"]:
        lines += ["H-LF depth, RMSE (px) / BadPix(0.07) (%):", ""]
        lines += table(report["hlf"], ("rmse", "badpix_007"), "{:.4f}")
    write_report(a.out, "aggregation", "\n".join(lines) + "\n", report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
