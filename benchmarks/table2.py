#!/usr/bin/env python
"""Table 2 of the paper: H-LF depth on synthetic hyperspectral light fields (SPEC §5, §6, §9).

Protocol
--------
* Scenes: ``antinous`` (HCI 4D LF benchmark, synthesised into a 5 x 6 H-LF, raster filters
  410..700 nm, :func:`hyperlf.synthesis.from_hci_scene` protocol: rows 2..6, columns 2..7,
  reference = ``input_Cam040``) and the procedural scenes of
  :data:`hyperlf.synthesis.SCENES` (``planes``, ``slanted``, ``occlusion``, ``solids``), rendered
  at ``--size H,W`` with exact ground truth.
* ``--downscale K`` (antinous only): the 512 x 512 RGB views are area-averaged by ``K`` **in
  linear RGB** (sRGB decoded, K x K block mean, re-encoded) before the spectral synthesis, which
  equals downscaling the H-LF itself because the RGB -> spectrum map is linear; the ground truth
  is block-averaged and **divided by K** (disparities shrink with the image), the disparity range
  too.  All antinous scores are then reported in **full-resolution pixels** (estimate and ground
  truth multiplied by K before scoring, so BadPix(0.07) uses 0.07 full-resolution px); the
  downscaled-pixel RMSE is in the JSON as ``rmse_working_px``.
* Scores (:func:`hyperlf.metrics.disparity_scores`): RMSE, MSE x 100, BadPix(0.07) (%) on every
  pixel with ground truth minus the HCI **15-pixel border, counted at the working resolution**
  (mask ``all``), on the sub-pixel disparity of each method's reference view.
* Methods: ours (``hlf``: :func:`hyperlf.hlf.depth` with ``--metric``, everything else at its
  default) and the three baselines of :data:`hyperlf.baselines.METHODS` (Tao 2013, Wang 2015,
  Lin 2015) which see the H-LF views as plain intensities, all with ``--labels`` labels over the
  scene's disparity range.  Runtimes are wall-clock seconds after a JIT warm-up on a tiny scene.
* ``--ablations``: ours with one cue toggled from the default each (view selection on, occlusion
  split on, defocus ``tv``, defocus ``paper``, WTA instead of the MRF, SGM instead of graph
  cuts, ``bwncc-paper`` instead of the default cost).  ``--ablations view_selection,wta`` picks
  some.
* Plain-RGB sanity rows (antinous only, unless ``--no-rgb``): the same 5 x 6 sub-grid of the
  original RGB light field (same downscale); the baselines get the RGB views (they reduce them to
  luma), ours gets the Rec. 709 luma views with all wavelengths set to 550 nm (a same-spectrum
  light field; defocus is off by default so the wavelengths are unused).
* Reproducibility: ``procedural_scene(reflectance_source="auto")`` textures the scenes with the
  Munsell library when ``HYPERLF_DATA`` points at the data folder and with the 24 ColorChecker
  spectra otherwise, so the *same* scene name renders different scenes in the two cases; the
  scene description in the table names the library used (this script requires ``HYPERLF_DATA``).
* The paper's RMSE on its two synthetic scenes (SPEC §5) is printed beside ours; the paper's
  scenes are not ours, so the comparison is of magnitude only.

Usage::

    HYPERLF_DATA=../shared/data python benchmarks/table2.py \
        --scenes antinous,planes,slanted,occlusion,solids --size 128,128 --downscale 4 \
        --labels 32 --metric ncc --tag ncc

Writes ``table2[_TAG].md`` (also printed), ``table2[_TAG].json`` (every figure, timing and
setting; rewritten after every cell), ``TAG_SCENE.png`` (reference view, ground truth, every
method's disparity and error map side by side) and ``TAG_SCENE.npz`` (the disparity maps) into
``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shlex
import sys
import textwrap
import time
import traceback
from pathlib import Path

import numpy as np

from _common import data_path, log
from hyperlf.baselines import METHODS as BASELINES
from hyperlf.hlf import DepthParams, depth
from hyperlf.lightfield import LightField
from hyperlf.metrics import disparity_scores
from hyperlf.spectral import linear_to_srgb, srgb_to_linear
from hyperlf.synthesis import SCENES, from_rgb_lightfield, procedural_scene

try:
    from hyperlf._atomic import atomic_write_text
except ImportError:  # pragma: no cover
    def atomic_write_text(path, text):
        Path(path).write_text(text)

HCI_SCENES = ("antinous",)
ALL_SCENES = HCI_SCENES + tuple(SCENES)
ALL_METHODS = ("hlf",) + tuple(BASELINES)
BORDER = 15

# Paper (SPEC §5): RMSE on its two synthetic scenes.
PAPER_RMSE = {
    "tao2013": (0.2052, 0.4393),
    "wang2015": (0.2970, 0.3690),
    "lin2015": (0.4285, 0.2785),
    "hlf": (0.1958, 0.2266),
}
PRETTY = {"hlf": "Ours (hlf)", "tao2013": "Tao 2013", "wang2015": "Wang 2015",
          "lin2015": "Lin 2015"}

# One cue toggled from the library default per row.
ABLATIONS = {
    "view_selection": ({"view_selection": True}, "+ view selection (§5.1)"),
    "occlusion_split": ({"occlusion_split": True}, "+ occlusion split (§5.2)"),
    "defocus_tv": ({"defocus": "tv"}, "+ defocus, TV prior (§5.3)"),
    "defocus_paper": ({"defocus": "paper"}, "+ defocus, paper (§5.3)"),
    "wta": ({"optimizer": "wta"}, "WTA instead of MRF"),
    "sgm": ({"optimizer": "sgm"}, "SGM instead of graph cuts"),
    "bwncc_paper": ({"metric": "bwncc-paper"}, "cost bwncc-paper"),
    "no_median": ({"params": DepthParams(median_radius=0)}, "without the weighted-median post-filter"),
    "visibility": ({"params": DepthParams(visibility_rounds=1)},
                   "visibility-aware re-matching, 1 round (§5.6; the default before "
                   "2026-11-29)"),
    "visibility2": ({"params": DepthParams(visibility_rounds=2)},
                    "visibility-aware re-matching, 2 rounds (§5.6)"),
    "no_visibility": ({"params": DepthParams(visibility_rounds=0)},
                      "without visibility-aware re-matching (§5.6)"),
    "visibility_estimate": ({"params": DepthParams(visibility_test="estimate")},
                            "visibility asked at the estimate's disparity only (before "
                            "2026-11-26)"),
    "visibility_full": ({"params": DepthParams(visibility_scale=1)},
                        "visibility round from a full-resolution first pass (§5.6)"),
    "window5": ({"params": DepthParams(window=5)}, "RSNCC 5 x 5 (the window before 2026-11-25)"),
    "before_dense": ({"params": DepthParams(window=5, visibility_rounds=0)},
                     "before 2026-11-25 (RSNCC 5 x 5, no visibility round)"),
    "mrf_levels1": ({"params": DepthParams(mrf_levels=1)},
                    "graph cuts coarse to fine, 1 halving"),
    "mrf_levels2": ({"params": DepthParams(mrf_levels=2)},
                    "graph cuts coarse to fine, 2 halvings"),
    "no_texture": ({"params": DepthParams(texture_snr=0)},
                   "without the textureless-region weight"),
    "common_views": ({"params": DepthParams(missing_views="common")},
                     "each view only where it sees the pixel at every label"),
    # not a single toggle: the two cues that helped most with the stand-in costs, together
    "selection_split": ({"view_selection": True, "occlusion_split": True},
                        "+ view selection + occlusion split"),
    "selection_tv": ({"view_selection": True, "defocus": "tv"},
                     "+ view selection + defocus TV"),
}


def _json_default(o):
    """JSON for numpy scalars (as floats) and parameter dataclasses (as dicts)."""
    import dataclasses
    if dataclasses.is_dataclass(o):
        return dataclasses.asdict(o)
    try:
        return float(o)
    except (TypeError, ValueError):
        return str(o)


# ----------------------------------------------------------------------------- scenes

def _block_mean(a: np.ndarray, k: int, axes=(-2, -1)) -> np.ndarray:
    """K x K block mean over the two image axes ``axes`` (cropping any remainder)."""
    if k == 1:
        return a
    ay, ax = (ax_ % a.ndim for ax_ in axes)
    H, W = a.shape[ay], a.shape[ax]
    a = np.take(np.take(a, np.arange(H // k * k), axis=ay), np.arange(W // k * k), axis=ax)
    shape = list(a.shape)
    shape[ay:ay + 1] = [H // k, k]
    ax2 = ax + 1
    shape[ax2:ax2 + 1] = [W // k, k]
    return a.reshape(shape).mean(axis=(ay + 1, ax2 + 1))


def load_hci_rgb(name: str, k: int) -> LightField:
    """5 x 6 RGB sub-grid (rows 2..6, cols 2..7) of an HCI scene, area-downscaled by ``k`` in
    linear RGB; ground truth block-averaged and divided by ``k``."""
    from hyperlf.formats import read_hci_scene

    lf = read_hci_scene(data_path(name), rows=range(2, 7), cols=range(2, 8))
    if k == 1:
        return lf
    lin = srgb_to_linear(np.clip(lf.views, 0.0, 1.0))
    views = np.clip(linear_to_srgb(_block_mean(lin, k, axes=(2, 3))), 0.0, 1.0).astype(np.float32)
    gt = lf.reference_gt_disparity
    gt = (_block_mean(gt.astype(np.float64), k) / k).astype(np.float32)
    dmin, dmax = lf.disparity_range
    md = dict(lf.metadata)
    md["downscale"] = k
    return lf.replace(views=views, gt_disparity=gt, disparity_range=(dmin / k, dmax / k),
                      metadata=md)


def rgb_luma_lf(lf_rgb: LightField) -> LightField:
    """Same-spectrum monochrome light field: Rec. 709 luma of the stored values, 550 nm."""
    v = lf_rgb.views
    luma = (0.2126 * v[..., 0] + 0.7152 * v[..., 1] + 0.0722 * v[..., 2]).astype(np.float32)
    R, C = lf_rgb.grid_shape
    return LightField(views=luma, wavelengths=np.full((R, C), 550.0), positions=lf_rgb.positions,
                      reference=lf_rgb.reference, disparity_range=lf_rgb.disparity_range,
                      gt_disparity=lf_rgb.reference_gt_disparity,
                      metadata={"name": "rgb-luma", "note": "plain RGB sanity light field"})


def load_scene(name: str, size, k: int):
    """Returns (hlf, rgb_lf_or_None, unit_factor, description)."""
    if name in HCI_SCENES:
        lf_rgb = load_hci_rgb(name, k)
        hlf = from_rgb_lightfield(lf_rgb, rows=5, cols=6, lambda_min=410.0, lambda_max=700.0,
                                  layout="raster", view_disparity="reference")
        H, W = hlf.image_shape
        desc = (f"HCI {name}, 5x6 H-LF 410-700 nm raster, {W}x{H} px"
                + (f" (512x512 area-downscaled by {k}; scores in full-resolution px)" if k > 1
                   else ""))
        return hlf, lf_rgb, float(k), desc
    if name not in SCENES:
        raise SystemExit(f"unknown scene {name!r}; choose from {', '.join(ALL_SCENES)}")
    H, W = size
    hlf = procedural_scene(**SCENES[name], height=H, width=W)
    n_refl = hlf.metadata.get("reflectance_library_size")
    return hlf, None, 1.0, (f"procedural {name}, 5x6 H-LF 410-700 nm raster, {W}x{H} px, "
                            f"reflectance library: {n_refl} spectra "
                            f"({'Munsell' if n_refl and n_refl > 24 else 'ColorChecker fallback'})")


# ----------------------------------------------------------------------------- methods

_WARM: set = set()


def warm_up(key, fn) -> None:
    """Run ``fn`` on a tiny scene once per ``key`` so that timings exclude numba JIT."""
    if key in _WARM:
        return
    tiny = procedural_scene(**SCENES["planes"], height=24, width=32)
    try:
        fn(tiny)
    except Exception as exc:  # the real call reports it
        log(f"warm-up {key} failed: {exc!r}")
    _WARM.add(key)


def run_ours(lf, labels, metric, extra):
    kw = dict(metric=metric)
    kw.update(extra)
    params = kw.pop("params", None)
    warm_up(("hlf", tuple(sorted(kw.items()))),
            lambda t: depth(t, n_labels=4, params=params, **kw))
    t0 = time.perf_counter()
    res = depth(lf, n_labels=labels, params=params, **kw)
    dt = time.perf_counter() - t0
    info = {"timings": {k: float(v) for k, v in res.timings.items()},
            "config": json.loads(json.dumps(res.config, default=str))}
    return res.disparity, dt, info


def run_baseline(name, lf, labels):
    fn = BASELINES[name]
    warm_up((name,), lambda t: fn(t, n_labels=4))
    t0 = time.perf_counter()
    res = fn(lf, n_labels=labels)
    dt = time.perf_counter() - t0
    info = {"timings": {k: float(v) for k, v in res.timings.items()},
            "params": json.loads(json.dumps(res.params, default=str))}
    return res.disparity, dt, info


def score(est, gt, unit):
    s = disparity_scores(np.asarray(est, np.float64) * unit, np.asarray(gt, np.float64) * unit,
                         border=BORDER)
    s_w = disparity_scores(est, gt, border=BORDER)
    return {"rmse": s.rmse, "mse_x100": s.mse_x100, "badpix_007": s.badpix_007,
            "bad_0_5": s.bad_0_5, "bad_1": s.bad_1, "n_pixels": s.n_pixels, "mask": s.mask,
            "border_working_px": BORDER, "unit_factor": unit, "rmse_working_px": s_w.rmse}


# ----------------------------------------------------------------------------- output

def fmt(x, nd=4):
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.{nd}f}"


def paper_col(method_key):
    p = PAPER_RMSE.get(method_key)
    return "–" if p is None else f"{p[0]:.4f} / {p[1]:.4f}"


def markdown(doc) -> str:
    out = [f"# Table 2 — H-LF depth on synthetic scenes ({doc['tag'] or 'default'})", "",
           f"Command: `{doc['command']}`", "",
           f"Labels: {doc['labels']}; ours: metric `{doc['metric']}`, other settings at the "
           f"library default; HCI border {BORDER} px at the working resolution. "
           f"Machine: {doc['machine']}. Runtime = wall-clock s (after JIT warm-up), shared "
           f"2-core machine under load.", ""]
    for scene, sd in doc["scenes"].items():
        out += [f"## {scene}", "", sd["description"], "",
                "| method | RMSE | MSE x 100 | BadPix(0.07) % | runtime s | paper RMSE (syn. 1 / 2) |",
                "|---|---:|---:|---:|---:|---:|"]
        for row in sd["rows"]:
            if "error" in row:
                out.append(f"| {row['label']} | error: {row['error'][:80]} | | | | |")
                continue
            s = row["scores"]
            out.append(f"| {row['label']} | {fmt(s['rmse'])} | {fmt(s['mse_x100'], 3)} | "
                       f"{fmt(s['badpix_007'], 2)} | {fmt(row['runtime_s'], 1)} | "
                       f"{paper_col(row['paper_key']) if row['paper_key'] else '–'} |")
        out.append("")
    # summary RMSE grid
    scenes = list(doc["scenes"])
    labels = []
    for sd in doc["scenes"].values():
        for row in sd["rows"]:
            if row["label"] not in labels:
                labels.append(row["label"])
    if len(scenes) > 1:
        out += ["## RMSE summary", "", "| method | " + " | ".join(scenes) + " |",
                "|---|" + "---:|" * len(scenes)]
        for lab in labels:
            cells = []
            for sc in scenes:
                r = next((r for r in doc["scenes"][sc]["rows"] if r["label"] == lab), None)
                cells.append("–" if r is None or "error" in r else fmt(r["scores"]["rmse"]))
            out.append(f"| {lab} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def figure(path, title, ref_view, gt, results, unit):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(results) + 1
    fig, axes = plt.subplots(2, n, figsize=(2.6 * n, 5.6), squeeze=False)
    g = np.asarray(gt, np.float64) * unit
    lo, hi = np.nanpercentile(g, 1), np.nanpercentile(g, 99)
    pad = 0.1 * (hi - lo + 1e-6)
    lo, hi = lo - pad, hi + pad
    axes[0, 0].imshow(ref_view, cmap="gray")
    axes[0, 0].set_title("reference view", fontsize=8)
    im0 = axes[1, 0].imshow(g, cmap="turbo", vmin=lo, vmax=hi)
    axes[1, 0].set_title("ground truth", fontsize=8)
    H, W = g.shape
    for j, (label, est, s) in enumerate(results, start=1):
        e = np.asarray(est, np.float64) * unit
        axes[0, j].imshow(e, cmap="turbo", vmin=lo, vmax=hi)
        axes[0, j].set_title(textwrap.fill(label, 34), fontsize=7)
        err = np.abs(e - g)
        im1 = axes[1, j].imshow(err, cmap="magma", vmin=0, vmax=0.5 * unit if unit > 1 else 0.5)
        axes[1, j].add_patch(plt.Rectangle((BORDER - 0.5, BORDER - 0.5), W - 2 * BORDER,
                                           H - 2 * BORDER, fill=False, ec="cyan", lw=0.6))
        axes[1, j].set_title(f"|err| RMSE {s['rmse']:.3f} BP {s['badpix_007']:.1f}%" if s else
                             "|err|", fontsize=7)
    for a in axes.ravel():
        a.set_axis_off()
    fig.suptitle(title, fontsize=9)
    fig.subplots_adjust(left=0.01, right=0.91, bottom=0.02, top=0.88, wspace=0.04, hspace=0.15)
    fig.colorbar(im0, cax=fig.add_axes([0.925, 0.5, 0.01, 0.36]), label="disparity")
    if len(results):
        fig.colorbar(im1, cax=fig.add_axes([0.925, 0.04, 0.01, 0.36]), label="|error|")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    _quantise_png(path)


def _quantise_png(path) -> None:
    """Re-save a PNG with a 256-colour adaptive palette (about 4x smaller; colour maps survive)."""
    try:
        from PIL import Image
    except ImportError:  # pragma: no cover
        return
    with Image.open(path) as im:
        q = im.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT)
    q.save(path, optimize=True)


# ----------------------------------------------------------------------------- main

def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scenes", default=",".join(ALL_SCENES))
    p.add_argument("--size", default="256,256", help="H,W of the procedural scenes")
    p.add_argument("--labels", type=int, default=64)
    p.add_argument("--methods", default=",".join(ALL_METHODS))
    p.add_argument("--ablations", nargs="?", const="all", default=None,
                   help="ours with one cue toggled from the default; 'all' or a comma list of "
                        + ", ".join(ABLATIONS))
    p.add_argument("--metric", default="auto", help="ours' correspondence cost")
    p.add_argument("--downscale", type=int, default=1, help="antinous area-downscale factor K")
    p.add_argument("--no-rgb", action="store_true", help="skip the plain-RGB sanity rows")
    p.add_argument("--out", default="benchmarks/results/table2")
    p.add_argument("--tag", default="", help="suffix of the output files")
    return p.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    scenes = [s for s in args.scenes.split(",") if s]
    methods = [m for m in args.methods.split(",") if m]
    for m in methods:
        if m not in ALL_METHODS:
            raise SystemExit(f"unknown method {m!r}; choose from {', '.join(ALL_METHODS)}")
    size = tuple(int(v) for v in args.size.split(","))
    abl = []
    if args.ablations:
        abl = list(ABLATIONS) if args.ablations == "all" else args.ablations.split(",")
        for a in abl:
            if a not in ABLATIONS:
                raise SystemExit(f"unknown ablation {a!r}; choose from {', '.join(ABLATIONS)}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    suffix = f"_{args.tag}" if args.tag else ""
    cmd = "python benchmarks/table2.py " + " ".join(shlex.quote(a) for a in
                                                  (sys.argv[1:] if argv is None else argv))
    doc = {"tag": args.tag, "command": cmd, "labels": args.labels, "metric": args.metric,
           "size": size, "downscale": args.downscale, "border_working_px": BORDER,
           "machine": f"{platform.machine()} {os.cpu_count()} cores, Python "
                      f"{platform.python_version()}",
           "paper_rmse": PAPER_RMSE, "scenes": {}}
    json_path = out / f"table2{suffix}.json"

    def save():
        atomic_write_text(json_path, json.dumps(doc, indent=1, default=_json_default))

    for scene in scenes:
        k = args.downscale if scene in HCI_SCENES else 1
        t0 = time.perf_counter()
        hlf, lf_rgb, unit, desc = load_scene(scene, size, k)
        log(f"[{scene}] {desc} (loaded in {time.perf_counter() - t0:.1f} s)")
        gt = hlf.reference_gt_disparity
        sd = {"description": desc, "disparity_range": list(hlf.disparity_range),
              "image_shape": list(hlf.image_shape), "rows": []}
        doc["scenes"][scene] = sd
        maps = {}
        jobs = []  # (label, paper_key, method, lf, extra)
        for m in methods:
            if m == "hlf":
                jobs.append((f"Ours (hlf, {args.metric})", "hlf", "hlf", hlf, {}))
            else:
                jobs.append((PRETTY[m], m, m, hlf, {}))
        for a in abl:
            extra, lab = ABLATIONS[a]
            jobs.append((f"Ours {lab}", None, "hlf", hlf, dict(extra)))
        if lf_rgb is not None and not args.no_rgb:
            luma = rgb_luma_lf(lf_rgb)
            for m in methods:
                if m == "hlf":
                    jobs.append((f"RGB sanity: Ours (hlf, {args.metric}, luma)", None, "hlf",
                                 luma, {}))
                else:
                    jobs.append((f"RGB sanity: {PRETTY[m]}", None, m, lf_rgb, {}))
        for label, paper_key, m, lf, extra in jobs:
            row = {"label": label, "method": m, "paper_key": paper_key, "extra": extra}
            log(f"[{scene}] {label} ...")
            try:
                if m == "hlf":
                    est, dt, info = run_ours(lf, args.labels, extra.get("metric", args.metric),
                                             {k_: v for k_, v in extra.items() if k_ != "metric"})
                else:
                    est, dt, info = run_baseline(m, lf, args.labels)
                s = score(est, gt, unit)
                row.update(runtime_s=dt, scores=s, info=info)
                maps[label] = (np.asarray(est, np.float32), s)
                log(f"[{scene}] {label}: RMSE {s['rmse']:.4f} MSEx100 {s['mse_x100']:.3f} "
                    f"BadPix {s['badpix_007']:.2f}% ({dt:.1f} s)")
            except Exception as exc:
                row["error"] = f"{type(exc).__name__}: {exc}"
                row["traceback"] = traceback.format_exc()
                log(f"[{scene}] {label}: FAILED {row['error']}")
            sd["rows"].append(row)
            save()
        # pictures: H-LF rows, then the RGB sanity rows in a second picture
        ref = hlf.reference_view
        main_rows = [(l_, e, s) for l_, (e, s) in maps.items() if not l_.startswith("RGB")]
        rgb_rows = [(l_[len("RGB sanity: "):], e, s) for l_, (e, s) in maps.items()
                    if l_.startswith("RGB")]
        tag = args.tag or "table2"
        try:
            figure(out / f"{tag}_{scene}.png", f"{desc} — {args.labels} labels", ref, gt,
                   main_rows, unit)
            if rgb_rows:
                figure(out / f"{tag}_{scene}_rgb.png",
                       f"plain RGB sanity — {desc} — {args.labels} labels",
                       rgb_luma_lf(lf_rgb).reference_view, gt, rgb_rows, unit)
        except Exception as exc:
            log(f"[{scene}] figure failed: {exc!r}")
        np.savez_compressed(out / f"{tag}_{scene}.npz", gt=np.asarray(gt, np.float32),
                            **{f"m{i}": e for i, (_, (e, _)) in enumerate(maps.items())},
                            labels=np.array(list(maps)))
    md = markdown(doc)
    atomic_write_text(out / f"table2{suffix}.md", md + "\n")
    save()
    print(md)


if __name__ == "__main__":
    main()
