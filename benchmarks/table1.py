#!/usr/bin/env python
"""Table 1 of the paper: two-view cross-spectral stereo on Middlebury (SPEC §4).

Protocol (SPEC §4)
------------------
* Left input = **red** channel of the left image, right input = **blue** channel of the right
  image (values as stored, in [0, 1]).  Disparities ``0..dmax`` with
  ``dmax = max(info max disparity, ceil(max ground truth))``.
* Ground truth = :func:`hyperlf.formats.middlebury.read_middlebury` (file value / scale).
* Scores bad5.0, bad2.0, bad1.0 (%) on the ``all`` mask where the scene has one (Tsukuba,
  Teddy), else on every pixel with ground truth (Art): ``pair.eval_mask('all')``.  Scored on the
  *filled* map (every pixel has a disparity).  Besides, bad5.0 on the pixels whose match the
  right camera sees (:func:`visible_mask`: Middlebury's ``nonocc``, derived from the ground
  truth for Art), since the paper does not say which pixels its table counts.
* Every cost with the **same optimiser**: graph cuts (alpha-expansion, truncated linear,
  contrast-sensitive) + left-right check + the library's occlusion fill (``--occlusion``:
  ``lr-plane`` by default, ``lr-fill`` = the paper's background fill); and the same with SGM.
  Parameters and windows come from each cost of the registry (``params`` / ``windows`` of
  :class:`hyperlf.costs.Cost`, read by :func:`hyperlf.twoview.default_params` /
  ``default_window``), which are meant to be tuned on **Venus only** (``--tune``) and then
  fixed for every other scene.
* Baselines: OpenCV StereoSGBM on the same red/blue inputs converted to 8 bit (invalid pixels
  background-filled like ours), and a same-spectrum control (red vs red, NCC).
* The paper's bad5.0 figures are printed beside ours.

Usage::

    HYPERLF_DATA=../shared/data python benchmarks/table1.py \
        --scenes tsukuba,teddy --metrics ncc,census --optimizers sgm --out benchmarks/results/table1
    python benchmarks/table1.py --tune            # grid on Venus first, then the table

Writes ``table1.md`` (also printed; it ends with where the default metric's bad5.0 points
lie: :func:`pixel_classes`, :func:`hyperlf.metrics.bad_pixel_breakdown`), ``table1.json`` (every
figure, timing and parameter) and error / disparity pictures for the default metric into
``--out``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from _common import data_path, log
from hyperlf import costs
from hyperlf import regularisers as reg
from hyperlf._atomic import atomic_write_text
from hyperlf.formats.middlebury import read_middlebury
from hyperlf.metrics import bad_pixel_breakdown, disparity_scores
from hyperlf.twoview import (DEFAULT_OCCLUSION, OCCLUSION_MODES, compute_volumes,
                            default_params, default_window, stereo_from_volumes)
from hyperlf.warp import visible_in_view

SCENES = ("tsukuba", "art", "teddy")
TUNING_SCENE = "venus"
ALL_METRICS = ("ssd", "ncc", "rsncc", "census", "bwncc-paper", "bwncc", "fused", "census-rsncc")
OPTIMIZERS = ("graphcut", "sgm")
RED, BLUE = 0, 2

# Paper, Table 1, bad5.0 (%) (SPEC §4): Tsukuba / Art / Teddy.  "Ours" is the paper's BWNCC.
PAPER_BAD5 = {
    "bwncc-paper": {"tsukuba": 3.14, "art": 10.27, "teddy": 7.01},
    "bwncc": {"tsukuba": 3.14, "art": 10.27, "teddy": 7.01},
    "rsncc": {"tsukuba": 5.27, "art": 16.64, "teddy": 11.02},
    "ncc": {"tsukuba": 6.09, "art": 18.31, "teddy": 15.68},
    "ssd": {"tsukuba": 11.18, "art": 28.19, "teddy": 43.53},
}

# Venus tuning grid (kept small: 2 shared cores).
TUNE_WINDOWS = {"ssd": (5, 9), "ncc": (5, 9), "rsncc": (5, 9), "census": (5, 7),
                "bwncc": (None,), "bwncc-paper": (None,), "fused": (None,), "census-rsncc": (None,)}
TUNE_GRID = {
    "graphcut": [{"weight": w, "truncation": t} for w, t in itertools.product((1.0, 2.0, 4.0, 8.0),
                                                                              (2.0, 4.0, 8.0))],
    "sgm": [{"p1": p1, "p2": p2} for p1, p2 in itertools.product((0.5, 1.0, 2.0), (4.0, 8.0, 16.0))],
}


def load_scene(name: str):
    pair = read_middlebury(data_path(name))
    mask_name = "all" if "all" in pair.masks else "gt"
    return pair, pair.search_range, pair.eval_mask("all"), mask_name


def visible_mask(pair) -> np.ndarray:
    """Pixels with ground truth whose match the right camera sees: Middlebury's ``nonocc``
    mask where the scene has one, else the z-test of the ground truth
    (:func:`hyperlf.warp.visible_in_view`, margin 1 px; it agrees with ``nonocc`` on 99.3 %
    (Teddy), 99.7 % (Venus) and 99.98 % (Tsukuba) of the evaluated pixels)."""
    if "nonocc" in pair.masks:
        return pair.eval_mask("nonocc")
    gt = np.where(pair.valid, pair.gt_disparity, np.nan)
    return visible_in_view(gt, (1.0, 0.0), margin=1.0) & pair.valid


def pixel_classes(pair, valid) -> dict:
    """Where a pixel's match is, from the ground truth: seen by the right camera
    (:func:`visible_mask`), outside the right image (``x - d < 0``) or hidden behind a nearer
    surface; each split by the left-right check of the estimate (``valid``: consistent, else
    filled).  A partition of the pixels with ground truth."""
    gt = np.where(pair.valid, pair.gt_disparity, np.nan)
    visible = visible_mask(pair)
    with np.errstate(invalid="ignore"):
        outside = ~visible & (np.arange(gt.shape[1])[None, :] - gt < 0)
    where = {"visible": visible, "hidden": ~visible & ~outside,
             "match outside the image": outside}
    return {f"{k}, {state}": cls & v for k, cls in where.items()
            for state, v in (("consistent", valid), ("filled", ~valid))}


def breakdown(est, valid, pair, mask) -> dict:
    """bad5.0's points by :func:`pixel_classes` (% of the evaluated pixels)."""
    parts = bad_pixel_breakdown(est, pair.gt_disparity, 5.0, pixel_classes(pair, valid),
                                mask=mask)
    return {k: v.as_dict() for k, v in parts.items()}


def score(est, pair, mask, mask_name) -> dict:
    """The protocol's scores on ``mask``, and bad5.0 on its pixels the right camera sees
    (``bad5_visible``, for papers that report the non-occluded pixels)."""
    s = disparity_scores(est, pair.gt_disparity, mask=mask, mask_name=mask_name)
    vis = disparity_scores(est, pair.gt_disparity, mask=mask & visible_mask(pair),
                           mask_name=f"{mask_name}, visible")
    return {"bad5": s.bad_5, "bad2": s.bad_2, "bad1": s.bad_1, "rmse": s.rmse,
            "n_pixels": s.n_pixels, "mask": mask_name, "bad5_visible": vis.bad_5,
            "visible_share": vis.n_pixels / max(s.n_pixels, 1)}


def to8(img) -> np.ndarray:
    return np.clip(np.round(np.asarray(img, np.float64) * 255.0), 0, 255).astype(np.uint8)


def opencv_sgbm(left, right, drange, block: int = 5):
    """OpenCV StereoSGBM (practitioner's defaults) on 8-bit inputs; invalid pixels (no match,
    uniqueness or LR failure) are background-filled like ours."""
    import cv2

    dmin, dmax = drange
    ndisp = 16 * int(math.ceil((dmax - dmin + 1) / 16))
    t0 = time.perf_counter()
    sg = cv2.StereoSGBM_create(minDisparity=dmin, numDisparities=ndisp, blockSize=block,
                               P1=8 * block * block, P2=32 * block * block, disp12MaxDiff=1,
                               uniquenessRatio=10, speckleWindowSize=100, speckleRange=2,
                               mode=cv2.STEREO_SGBM_MODE_SGBM)
    raw = sg.compute(to8(left), to8(right)).astype(np.float32) / 16.0
    valid = raw >= dmin
    disp = reg.fill_occlusions(raw, valid) if valid.any() else np.full(raw.shape, dmin, np.float32)
    disp = np.clip(disp, dmin, dmax)
    return disp, valid, time.perf_counter() - t0


_WARM: set = set()


def warm_up(metric: str) -> None:
    """Compile the numba kernels of ``metric`` on a tiny pair so the runtime column does not
    include JIT compilation."""
    if metric in _WARM:
        return
    rng = np.random.default_rng(0)
    a = 0.2 + rng.random((24, 32)).astype(np.float32)
    compute_volumes(a, a[:, ::-1].copy(), 0, 3, metric=metric)
    reg.sgm(rng.random((4, 24, 32)).astype(np.float32), 0.5, 2.0)
    _WARM.add(metric)


OCCLUSION = {"mode": DEFAULT_OCCLUSION}   # --occlusion


def run_cell(volumes, drange, optimizer, params, guides):
    cl, cr, t_cost = volumes
    res = stereo_from_volumes(cl, cr, drange[0], optimizer=optimizer,
                              occlusion=OCCLUSION["mode"], params=params,
                              guide_left=guides[0], guide_right=guides[1])
    return res, t_cost + res.timings["optimiser"]


def tune(metrics, optimizers, tuned: dict) -> dict:
    """Grid search on Venus (bad5.0, ties by bad2.0); fills ``tuned[(metric, opt)]``."""
    pair, drange, mask, mask_name = load_scene(TUNING_SCENE)
    L, R = pair.left[:, :, RED], pair.right[:, :, BLUE]
    report = {}
    for m in metrics:
        warm_up(m)
        for win in TUNE_WINDOWS.get(m, (None,)):
            t0 = time.perf_counter()
            cl, cr = compute_volumes(L, R, *drange, metric=m, window=win)
            vols = (cl, cr, time.perf_counter() - t0)
            for opt in optimizers:
                for grid_p in TUNE_GRID[opt]:
                    p = {**default_params(m, opt), **grid_p}
                    res, secs = run_cell(vols, drange, opt, p, (L, R))
                    s = score(res.disparity, pair, mask, mask_name)
                    key = (s["bad5"], s["bad2"])
                    log(f"tune venus {m:12s} win={win} {opt:8s} {grid_p} -> bad5 {s['bad5']:.2f} "
                        f"bad2 {s['bad2']:.2f} bad1 {s['bad1']:.2f} ({secs:.1f} s)")
                    best = report.get((m, opt))
                    if best is None or key < best["key"]:
                        report[(m, opt)] = {"key": key, "window": win, "params": p, "scores": s}
            del cl, cr
    for (m, opt), b in report.items():
        tuned[(m, opt)] = {"window": b["window"], "params": b["params"], "venus": b["scores"]}
    return tuned


def speed_report(scene: str = "teddy", metrics=("bwncc", "census-rsncc", "fused"),
                 repeat: int = 3) -> str:
    """End-to-end time of :func:`hyperlf.stereo` (graph cuts + LR + fill, default parameters)
    on ``scene`` (R vs B), best of ``repeat`` after a warm-up, and one run split into descriptor,
    cross terms (cost volume) and optimiser (both views)."""
    from hyperlf import stereo

    pair, drange, mask, mask_name = load_scene(scene)
    L, R = pair.left[:, :, RED], pair.right[:, :, BLUE]
    lines = [f"Speed, {scene} {L.shape[1]} x {L.shape[0]}, d {drange[0]}..{drange[1]} "
             f"({drange[1] - drange[0] + 1} labels), graph cuts + LR + fill, "
             f"{os.cpu_count()} cores:", "",
             "| cost | end to end (s, best of %d) | descriptor (s) | cost volume (s, last run) | "
             "optimiser, both views (s, last run) | bad5.0 |" % repeat, "|---|---|---|---|---|---|"]
    for m in metrics:
        warm_up(m)
        best = float("inf")
        for _ in range(repeat):
            t0 = time.perf_counter()
            res = stereo(L, R, drange, metric=m, optimizer="graphcut")
            best = min(best, time.perf_counter() - t0)
        bad5 = score(res.disparity, pair, mask, mask_name)["bad5"]
        tm: dict = {}
        if m in ("bwncc", "bwncc-paper", "fused"):   # fused = bwncc + census
            costs.bwncc_volume(L, R, *drange, "paper" if m == "bwncc-paper" else "default",
                               timings=tm)
        t_cost = res.timings["cost"]
        desc = f"{tm['descriptor_s']:.1f}" if "descriptor_s" in tm else "–"
        lines.append(f"| {m} | {best:.1f} | {desc} | "
                     f"{t_cost:.1f} | {res.timings['optimiser']:.1f} | {bad5:.2f} |")
        log(lines[-1])
    return "\n".join(lines) + "\n"


def snippet(tuned: dict) -> str:
    """The class attributes to paste into each cost (``hyperlf/costs/builtin.py``)."""
    lines = ["# Paste into the cost objects of hyperlf/costs/builtin.py "
             "(tuned on Venus by benchmarks/table1.py --tune):"]
    for m in sorted({m for m, _ in tuned}):
        opts = sorted(o for mm, o in tuned if mm == m)
        params = {o: tuned[(m, o)]["params"] for o in opts}
        windows = {o: tuned[(m, o)]["window"] for o in opts}
        lines.append(f"# cost {m!r}:")
        lines.append(f"    windows = {windows!r}")
        lines.append(f"    params = {params!r}")
    return "\n".join(lines)


def fmt(x, nd=2):
    return "–" if x is None else f"{x:.{nd}f}"


def markdown(results: dict, scenes, meta: dict) -> str:
    out = ["# Table 1 — two-view cross-spectral stereo (red of left vs blue of right)", "",
           f"Scores: bad5.0 / bad2.0 / bad1.0 (%) on the `all` mask where present, else all "
           f"pixels with ground truth; filled maps; 'bad5 visible' = bad5.0 on those of the "
           f"pixels whose match the right camera sees (`visible_mask`).  "
           f"Runtime = cost + optimiser, seconds "
           f"({meta['cores']} cores).  Occlusion fill: {meta['occlusion']}.  "
           f"Parameters: {meta['param_source']}.  "
           f"Paper: the paper's bad5.0 (SPEC §4; 'Ours' = BWNCC).", ""]
    head = "| optimiser | cost | " + " | ".join(
        f"{s} bad5 | {s} bad2 | {s} bad1 | {s} bad5 visible | {s} paper bad5 | {s} s"
        for s in scenes) + " |"
    out.append(head)
    out.append("|" + "---|" * (2 + 6 * len(scenes)))
    for row in results["rows"]:
        cells = [row["optimizer"], row["label"]]
        for s in scenes:
            c = row["scenes"].get(s)
            if c is None:
                cells += ["–"] * 6
                continue
            cells += [fmt(c["bad5"]), fmt(c["bad2"]), fmt(c["bad1"]), fmt(c.get("bad5_visible")),
                      fmt(PAPER_BAD5.get(row["metric"], {}).get(s)) if row["kind"] == "cost" else "–",
                      fmt(c["seconds"], 1)]
        out.append("| " + " | ".join(cells) + " |")
    out.append("")
    out += breakdown_markdown(results, scenes)
    out.append(f"Rows: `cost` = red-vs-blue with our pipeline (LR check + {meta['occlusion']} fill); "
               "`opencv-sgbm` = cv2.StereoSGBM on 8-bit red/blue, invalid pixels background-filled; "
               "`ncc red-red` = same-spectrum control.")
    return "\n".join(out) + "\n"


def breakdown_markdown(results: dict, scenes) -> list[str]:
    """Where the default cost's bad5.0 points lie (:func:`pixel_classes`), one table per
    optimiser."""
    out = []
    for row in results["rows"]:
        parts = {s: row["scenes"][s]["breakdown"] for s in scenes
                 if "breakdown" in row["scenes"].get(s, {})}
        if not parts:
            continue
        out += [f"Where `{row['label']}` + {row['optimizer']} has its bad5.0 points: share of "
                "the evaluated pixels / points of bad5.0 there (too large / too small, i.e. "
                "the estimate nearer / farther than the truth).", "",
                "| pixels | " + " | ".join(parts) + " |", "|---|" + "---|" * len(parts)]
        for cls in next(iter(parts.values())):
            out.append(f"| {cls} | " + " | ".join(
                f"{p[cls]['share']:.2f} / **{p[cls]['bad']:.2f}** ({p[cls]['too_large']:.2f} / "
                f"{p[cls]['too_small']:.2f})" for p in parts.values()) + " |")
        out.append("")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--metrics", default=",".join(ALL_METRICS),
                    help="comma-separated; 'auto' means the library default (%s)" % costs.AUTO_METRIC)
    ap.add_argument("--optimizers", default=",".join(OPTIMIZERS))
    ap.add_argument("--out", default="benchmarks/results/table1")
    ap.add_argument("--tune", action="store_true", help="grid-search on Venus first (slow)")
    ap.add_argument("--params-json", help="tuned parameters written by an earlier --tune run")
    ap.add_argument("--occlusion", default=DEFAULT_OCCLUSION, choices=OCCLUSION_MODES,
                    help="step 6 of the pipeline for every cost (default: the library's, "
                         f"{DEFAULT_OCCLUSION}; lr-fill is the paper's background fill)")
    ap.add_argument("--no-baselines", action="store_true",
                    help="skip the OpenCV SGBM and red-vs-red rows")
    ap.add_argument("--speed", action="store_true",
                    help="only time hyperlf.stereo end to end on Teddy (bwncc, census-rsncc, "
                         "fused) and exit")
    args = ap.parse_args(argv)
    OCCLUSION["mode"] = args.occlusion
    if args.speed:
        md = speed_report()
        print(md)
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(out / "speed.md", md)
        return 0

    data_path("venus")  # fail early, with a clear message, when the data is missing
    scenes = [s.strip().lower() for s in args.scenes.split(",") if s.strip()]
    metrics = [costs.resolve_metric(m) for m in args.metrics.split(",") if m.strip()]
    optimizers = [o.strip().lower() for o in args.optimizers.split(",") if o.strip()]
    for o in optimizers:
        if o not in OPTIMIZERS:
            sys.exit(f"table1.py: unknown optimiser {o!r} (choose from {', '.join(OPTIMIZERS)})")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    tuned: dict = {}
    param_source = ("the cost registry's defaults, hyperlf.costs.get_cost(m).params / .windows "
                    "(every cost tuned on Venus with --tune, see hyperlf/costs/builtin.py)")
    if args.params_json:
        raw = json.loads(Path(args.params_json).read_text())
        for k, v in raw.items():
            m, o = k.split("|")
            tuned[(m, o)] = v
        param_source = f"tuned on Venus, from {args.params_json}"
    if args.tune:
        t0 = time.perf_counter()
        tune(metrics, optimizers, tuned)
        log(f"tuning took {time.perf_counter() - t0:.0f} s")
        atomic_write_text(out / "tuned_venus.json", json.dumps(
            {f"{m}|{o}": v for (m, o), v in tuned.items()}, indent=2))
        print(snippet(tuned))
        param_source = "tuned on Venus in this run (grid in benchmarks/table1.py)"

    def params_for(m, o):
        t = tuned.get((m, o))
        return (dict(t["params"]), t["window"]) if t else (default_params(m, o), default_window(m, o))

    default_metric = costs.AUTO_METRIC
    pic_metric = default_metric if default_metric in metrics else (metrics[0] if metrics else None)
    rows: dict = {}

    def cell(key, kind, label, metric, opt):
        return rows.setdefault(key, {"kind": kind, "label": label, "metric": metric,
                                     "optimizer": opt, "scenes": {}})

    for sname in scenes:
        pair, drange, mask, mask_name = load_scene(sname)
        L, R = pair.left[:, :, RED], pair.right[:, :, BLUE]
        log(f"{sname}: {L.shape[1]}x{L.shape[0]}, d {drange[0]}..{drange[1]}, mask {mask_name} "
            f"({int(mask.sum())} px)")
        for m in metrics:
            warm_up(m)
            windows = {params_for(m, o)[1] for o in optimizers}
            for win in windows:
                t0 = time.perf_counter()
                cl, cr = compute_volumes(L, R, *drange, metric=m, window=win)
                vols = (cl, cr, time.perf_counter() - t0)
                for opt in optimizers:
                    p, w = params_for(m, opt)
                    if w != win:
                        continue
                    res, secs = run_cell(vols, drange, opt, p, (L, R))
                    s = score(res.disparity, pair, mask, mask_name)
                    s.update(seconds=secs, cost_s=vols[2], optimiser_s=res.timings["optimiser"],
                             lr_invalid_pct=100.0 * float(1 - res.valid.mean()), params=p,
                             window=win, disparity_range=list(drange))
                    cell((opt, m), "cost", m, m, opt)["scenes"][sname] = s
                    log(f"  {opt:8s} {m:12s} bad5 {s['bad5']:6.2f} bad2 {s['bad2']:6.2f} "
                        f"bad1 {s['bad1']:6.2f} visible bad5 {s['bad5_visible']:6.2f}  "
                        f"{secs:6.1f} s (cost {vols[2]:.1f})")
                    if m == pic_metric:
                        s["breakdown"] = breakdown(res.disparity, res.valid, pair, mask)
                        from hyperlf.visualise import save_disparity_png, save_error_png
                        gt = pair.gt_disparity
                        save_error_png(out / f"{sname}_{m}_{opt}_error.png", res.disparity, gt,
                                       title=f"{sname} {m} {opt}: |error| (red vs blue)", vmax=5.0)
                        save_disparity_png(out / f"{sname}_{m}_{opt}_disparity.png", res.disparity,
                                           title=f"{sname} {m} {opt}", vmin=drange[0], vmax=drange[1])
                del cl, cr
        if not args.no_baselines:
            disp, valid, secs = opencv_sgbm(L, R, drange)
            s = score(disp, pair, mask, mask_name)
            s.update(seconds=secs, lr_invalid_pct=100.0 * float(1 - valid.mean()))
            cell(("opencv", "sgbm"), "baseline", "opencv-sgbm (8-bit)", "sgbm", "opencv")["scenes"][sname] = s
            log(f"  opencv   sgbm         bad5 {s['bad5']:6.2f} bad2 {s['bad2']:6.2f} "
                f"bad1 {s['bad1']:6.2f}  {secs:6.1f} s")
            Rr = pair.right[:, :, RED]
            warm_up("ncc")
            for opt in optimizers:
                p, win = params_for("ncc", opt)
                t0 = time.perf_counter()
                cl, cr = compute_volumes(L, Rr, *drange, metric="ncc", window=win)
                res, secs = run_cell((cl, cr, time.perf_counter() - t0), drange, opt, p, (L, Rr))
                s = score(res.disparity, pair, mask, mask_name)
                s.update(seconds=secs, params=p, window=win)
                cell((opt, "ncc-rr"), "control", "ncc red-red (control)", "ncc", opt)["scenes"][sname] = s
                log(f"  {opt:8s} ncc red-red  bad5 {s['bad5']:6.2f} bad2 {s['bad2']:6.2f} "
                    f"bad1 {s['bad1']:6.2f}  {secs:6.1f} s")

    order = {o: i for i, o in enumerate(optimizers + ["opencv"])}
    kinds = {"cost": 0, "control": 1, "baseline": 2}
    mindex = {m: i for i, m in enumerate(metrics)}
    ordered = sorted(rows.values(), key=lambda r: (kinds[r["kind"]], order.get(r["optimizer"], 9),
                                                   mindex.get(r["metric"], 99)))
    meta = {"cores": os.cpu_count(), "param_source": param_source, "occlusion": args.occlusion, "scenes": scenes,
            "metrics": metrics, "optimizers": optimizers, "tuning_scene": TUNING_SCENE,
            "protocol": "left red vs right blue; bad-tau on 'all' mask or all GT pixels; filled maps",
            "python": platform.python_version(), "default_metric": default_metric,
            "date": time.strftime("%Y-%m-%d %H:%M:%S")}
    results = {"meta": meta, "rows": ordered, "paper_bad5": PAPER_BAD5,
               "tuned": {f"{m}|{o}": v for (m, o), v in tuned.items()},
               "default_params": {f"{m}|{o}": p for m in costs.cost_names()
                                  for o, p in costs.get_cost(m).params.items()}}
    md = markdown(results, scenes, meta)
    print(md)
    atomic_write_text(out / "table1.md", md)
    atomic_write_text(out / "table1.json", json.dumps(results, indent=2, default=str))
    log(f"wrote {out / 'table1.md'} and {out / 'table1.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
