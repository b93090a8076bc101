#!/usr/bin/env python
"""Is ``auto`` the lowest-error cost on cross-spectral pairs it was not chosen on?

    HYPERLF_DATA=../shared/data python benchmarks/channels.py [--scenes venus,tsukuba,teddy]
        [--pairs 02,01,12,20,10,21] [--metrics auto,...] [--params JSON] [--cost-params JSON]
        [--out benchmarks/results/channels]

Issue 12 judges ``auto`` on held-out cross-spectral pairs: it must have the lowest bad5.0 of all
costs on every one.  The Table 1 protocol uses one channel pair (red of the left image, blue of
the right one); the other five ordered pairs of distinct RGB channels of the same scenes are
the nearest stand-in for held-out pairs that this data offers (different spectra, same
geometry).  Every registered two-view cost is run with graph cuts and the default occlusion
handling at its Venus-tuned parameters (nothing is tuned here).  Besides bad5.0 / bad2.0 the
script records the share of left-right consistent pixels and the mean confidence
(``StereoResult.confidence``), to see whether either unsupervised figure would pick the best
cost per pair.  Writes ``channels.md`` / ``channels.json``.

Venus is the tuning scene of two-view stereo, so its six pairs are where a candidate default
is measured first: ``--scenes venus --metrics auto --cost-params '{"weights": [1, 3]}'`` runs
``auto`` alone with other part weights (the keyword options of ``twoview.stereo``; they apply
to every cost run).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from _common import add_stereo_options, check_candidate_out, log, stereo_options, write_report
from table1 import load_scene, score
from hyperlf.costs import cost_names, resolve_metric
from hyperlf.twoview import stereo

CHANNELS = "RGB"
PAIRS = ("02", "01", "12", "20", "10", "21")


def run_pair(pair, drange, mask, mask_name, a: int, b: int, metrics, **options) -> dict:
    """``{metric: {bad5, bad2, consistent, seconds}}`` for left channel ``a``, right ``b``;
    ``options`` go to ``twoview.stereo``."""
    row = {}
    for m in metrics:
        t0 = time.perf_counter()
        res = stereo(pair.left[:, :, a], pair.right[:, :, b], drange, metric=m,
                     optimizer="graphcut", **options)
        s = score(res.disparity, pair, mask, mask_name)
        row[m] = {"bad5": s["bad5"], "bad2": s["bad2"], "consistent": float(res.valid.mean()),
                  "confidence": float(res.confidence.mean()),
                  "seconds": time.perf_counter() - t0}
    return row


def lowest(row: dict, metrics) -> str:
    """The metric with the lowest bad5.0 of one pair (ties by bad2.0)."""
    return min(metrics, key=lambda m: (row[m]["bad5"], row[m]["bad2"]))


def _table(scene: str, rows: dict, metrics) -> list[str]:
    head = ("| pair | " + " | ".join(metrics)
            + " | lowest | most consistent | most confident |")
    out = [f"**{scene}** (bad5.0 %, graph cuts, default fill)", "", head,
           "|" + "---|" * (len(metrics) + 4)]
    for key, row in rows.items():
        best = lowest(row, metrics)
        lr = max(metrics, key=lambda m: row[m]["consistent"])
        sure = max(metrics, key=lambda m: row[m]["confidence"])
        cells = [f"**{row[m]['bad5']:.2f}**" if m == best else f"{row[m]['bad5']:.2f}"
                 for m in metrics]
        out.append(f"| {key} | " + " | ".join(cells) + f" | {best} | {lr} | {sure} |")
    return out + [""]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="venus,tsukuba,teddy")
    ap.add_argument("--pairs", default=",".join(PAIRS),
                    help="left/right channel indices, e.g. 02 = red left, blue right")
    ap.add_argument("--metrics", default=None,
                    help="costs to run, comma-separated (default: auto and every registered "
                         "cost)")
    add_stereo_options(ap)
    ap.add_argument("--out", default="benchmarks/results/channels")
    args = ap.parse_args()
    check_candidate_out(ap, args, "benchmarks/results/channels",
                        departures=["--metrics"] if args.metrics else [])
    metrics = (args.metrics.split(",") if args.metrics else
               ["auto"] + [m for m in cost_names() if m != resolve_metric("auto")])
    unknown = [m for m in metrics if m != "auto" and m not in cost_names()]
    if unknown:
        ap.error(f"--metrics: unknown cost {', '.join(unknown)}; choose from "
                 f"auto, {', '.join(cost_names())}")
    report, lines = {}, []
    if stereo_options(args):
        lines += [f"Options of twoview.stereo over the defaults: {stereo_options(args)}", ""]
    for scene in args.scenes.split(","):
        pair, drange, mask, mask_name = load_scene(scene)
        rows = {}
        for p in args.pairs.split(","):
            a, b = int(p[0]), int(p[1])
            key = f"{CHANNELS[a]}-{CHANNELS[b]}"
            log(f"{scene} {key}")
            rows[key] = run_pair(pair, drange, mask, mask_name, a, b, metrics,
                                 **stereo_options(args))
        report[scene] = rows
        lines += _table(scene, rows, metrics)
    wins = [(s, k) for s, rows in report.items() for k, row in rows.items()
            if lowest(row, metrics) == "auto"]
    total = sum(len(r) for r in report.values())
    lines.append(f"`auto` lowest on {len(wins)} of {total} pairs.")
    folder = Path(args.out)
    folder.mkdir(parents=True, exist_ok=True)
    write_report(folder, "channels", "\n".join(lines) + "\n", report)


if __name__ == "__main__":
    main()
