#!/usr/bin/env python
"""Thin objects faint in the reference band: an H-LF tuning family (issue 12).

    HYPERLF_DATA=../shared/data python benchmarks/faint_thin.py [--seeds 0-5] [--size 256,320]
                                   [--params '{"thin_touch": 0.4}' --out FOLDER]
    HYPERLF_DATA=../shared/data python benchmarks/faint_thin.py --plain [--size 192,256]

Every view of a spectral light field sees another band, and the MRF's contrast-sensitive
smoothness and every per-view cost are measured against the reference view. A thin object
(a rod, a wire, a stem) whose reflectance in the reference band is close to what lies behind
it gives that band little to match and little outline, although the other views see it
clearly; graph cuts then give its few pixels to the background. The procedural scenes of
Table 2 have thin objects only in high contrast, so this family makes the case on purpose,
from the principle alone:

- the scene description is the random one of ``procedural_scene(seed, kinds=THIN_KINDS,
  n_objects=10)`` (rings, sticks, fronto-parallel and slanted planes before a background:
  the family of the thirty-sixth session);
- every ring and stick is then given reflectance chips whose reflectance at the reference
  view's wavelength lies within ``--tolerance`` of the background's chips' mean there, and
  that differ from the background's mean spectrum over the filters' range by at least
  :data:`MIN_ELSEWHERE` on average: in the reference band nearly uniform at the
  background's mean level (no texture of its own, no contrast on average), plain in the
  others.
  The chips are drawn from the Munsell library (so ``HYPERLF_DATA`` must be set) with the
  scene's seed.

Each scene is rendered at 256 x 320 px by default, a size at which :func:`hyperlf.hlf.depth`
runs every stage of its default (the visibility rounds start at 192 px on the shorter side),
and runs through it (64 labels; ``--params`` adds :class:`hyperlf.hlf.DepthParams` fields, a
candidate to measure) and is scored as Table 2 scores antinous (RMSE and BadPix(0.07) without
the 15 px border), on every pixel and on the thin objects' pixels alone.

``--plain`` runs the scenes as drawn instead, with no chip made faint: the random rings and
sticks of the thirty-sixth session, the H-LF stand-in for held-out content, at 192 x 256 px
by default and into ``benchmarks/results/rings_sticks``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from _common import data_path, depth_picture, json_object, log, write_report

#: Object kinds of the family (as the thirty-sixth session's rings and sticks).
THIN_KINDS = ("ring", "stick", "fronto", "ring", "stick", "slanted")
#: Mean absolute reflectance difference, over the filters' range, by which a thin object's
#: chip differs from the background's mean spectrum (so that the other bands see it).
MIN_ELSEWHERE = 0.08
#: Keys of ``--params`` that are options of :func:`hyperlf.hlf.depth`, not DepthParams fields.
DEPTH_OPTIONS = ("optimizer", "metric", "view_selection", "occlusion_split", "defocus")
#: The reflectance library the chips come from (``HYPERLF_DATA``'s Munsell chips, so that
#: the figures do not depend on whether the data is set).
LIBRARY = "munsell"
DEFAULT_OUT = Path("benchmarks/results/faint_thin")
#: Where ``--plain`` writes by default.
PLAIN_OUT = Path("benchmarks/results/rings_sticks")
#: The recorded runs' sizes (height, width): the faint scenes, and ``--plain``'s.
SIZE, PLAIN_SIZE = (256, 320), (192, 256)


def _library_at(wavelengths: np.ndarray, source: str = LIBRARY) -> np.ndarray:
    """The reflectance library sampled at ``wavelengths``, ``(chips, bands)``."""
    from hyperlf import spectral

    lib_wl, lib_refl = spectral.reflectance_library(source)
    return np.stack([np.interp(wavelengths, lib_wl, r) for r in np.clip(lib_refl, 0, 1)])


def faint_chips(library: np.ndarray, reference_band: int, background: list[int], count: int,
                rng: np.random.Generator, *, tolerance: float) -> list[int]:
    """``count`` chips of ``library`` (chips x bands) whose reflectance in ``reference_band``
    is within ``tolerance`` of the mean of the ``background`` chips there and whose spectrum
    differs from the background's mean one by at least :data:`MIN_ELSEWHERE` on average."""
    target = library[background].mean(axis=0)
    near = np.abs(library[:, reference_band] - target[reference_band]) <= tolerance
    plain = np.abs(library - target).mean(axis=1) >= MIN_ELSEWHERE
    candidates = np.flatnonzero(near & plain)
    if candidates.size == 0:
        raise ValueError(f"no chip within {tolerance} of the background in the reference band")
    return [int(c) for c in rng.choice(candidates, count, replace=candidates.size < count)]


def faint_description(seed: int, *, rows: int, cols: int, tolerance: float,
                      source: str = LIBRARY) -> tuple[list, float]:
    """The random rings-and-sticks scene of ``seed`` with every ring and stick made faint in
    the reference band (chips of the library ``source``); and that band's wavelength."""
    from hyperlf import synthesis

    probe = synthesis.procedural_scene(seed, rows=rows, cols=cols, height=16, width=16,
                                       kinds=THIN_KINDS, n_objects=10,
                                       reflectance_source=source)
    wavelengths = np.asarray(probe.wavelengths, dtype=np.float64)
    reference_nm = float(wavelengths[probe.reference])
    library = _library_at(wavelengths.ravel(), source)
    band = int(np.argmin(np.abs(wavelengths.ravel() - reference_nm)))
    objects = [dict(o) for o in probe.metadata["objects"]]
    background = objects[0]["texture"]["chips"]
    rng = np.random.default_rng([seed, 58])
    for o in objects[1:]:
        if "shape" in o:
            texture = dict(o["texture"])
            texture["chips"] = faint_chips(library, band, background, len(texture["chips"]),
                                           rng, tolerance=tolerance)
            o["texture"] = texture
    return objects, reference_nm


def faint_scene(seed: int, *, rows: int = 5, cols: int = 6, height: int = 256,
                width: int = 320, tolerance: float = 0.03, source: str = LIBRARY,
                faint: bool = True):
    """The light field of :func:`faint_description` (supersampled 2 x 2) and the mask of the
    reference pixels that see a ring or a stick.  ``faint=False``: the random rings-and-sticks
    scene of ``seed`` as drawn at this size, no chip changed (``tolerance`` is not used)."""
    from hyperlf import synthesis

    if faint:
        objects, _ = faint_description(seed, rows=rows, cols=cols, tolerance=tolerance,
                                       source=source)
        lf = synthesis.procedural_scene(seed, rows=rows, cols=cols, height=height,
                                        width=width, objects=objects, supersample=2,
                                        reflectance_source=source)
    else:
        lf = synthesis.procedural_scene(seed, rows=rows, cols=cols, height=height,
                                        width=width, kinds=THIN_KINDS, n_objects=10,
                                        supersample=2, reflectance_source=source)
        objects = [dict(o) for o in lf.metadata["objects"]]
    thin = [o for o in objects if "shape" in o]
    plain = [o for o in objects if "shape" not in o]
    without = synthesis.procedural_scene(seed, rows=1, cols=1, height=height, width=width,
                                         objects=plain, reflectance_source=source)
    # A reference pixel sees a thin object where the scene without them is farther.
    seen = lf.reference_gt_disparity > without.reference_gt_disparity + 1e-6
    return lf, seen, len(thin)


def score(estimate: np.ndarray, truth: np.ndarray, thin: np.ndarray) -> dict:
    """Table 2's scores (15 px border) on every pixel, and the RMSE and share off by more than
    1 px on the ``thin`` pixels; the thin objects' share of the scored pixels, %."""
    from hyperlf.metrics import HCI_BORDER, bad_pixels, disparity_scores, evaluation_mask, rmse

    s = disparity_scores(estimate, truth, border=HCI_BORDER)
    scored = evaluation_mask(truth, border=HCI_BORDER)
    row = {"rmse": s.rmse, "badpix_007": s.badpix_007,
           "thin_share": float(100 * thin[scored].mean())}
    if not (thin & scored).any():
        return {**row, "thin_rmse": float("nan"), "thin_bad1": float("nan")}
    return {**row, "thin_rmse": rmse(estimate, truth, mask=thin, border=HCI_BORDER),
            "thin_bad1": bad_pixels(estimate, truth, 1.0, mask=thin, border=HCI_BORDER)}


def run(seed: int, size: tuple[int, int], labels: int, params: dict, tolerance: float,
        out: Path, *, faint: bool = True) -> dict:
    """One scene of the family (``faint=False``: as drawn, :func:`faint_scene`) through
    :func:`hyperlf.hlf.depth`: its scores, and its picture ``out/seed<N>.png``."""
    from hyperlf import hlf

    lf, thin, n_thin = faint_scene(seed, height=size[0], width=size[1], tolerance=tolerance,
                                   faint=faint)
    options, fields = _split_params(params)
    t = time.perf_counter()
    res = hlf.depth(lf, n_labels=labels, params=hlf.DepthParams(**fields), **options)
    row = {"seed": seed, "depth_s": time.perf_counter() - t, "thin_objects": n_thin,
           "taken": 100 * float(res.config.get("thin_object_share", 0.0)),
           **score(res.disparity, lf.reference_gt_disparity, thin)}
    depth_picture(out / f"seed{seed}.png", f"seed {seed}", lf, res.disparity)
    log(f"seed {seed}: RMSE {row['rmse']:.4f} BadPix {row['badpix_007']:.2f} % thin RMSE "
        f"{row['thin_rmse']:.4f} bad1 {row['thin_bad1']:.1f} % (taken {row['taken']:.2f} %, "
        f"{row['depth_s']:.0f} s)")
    return row


def _split_params(params: dict) -> tuple[dict, dict]:
    """``--params`` as depth's own options (:data:`DEPTH_OPTIONS`) and DepthParams fields."""
    options = {k: v for k, v in params.items() if k in DEPTH_OPTIONS}
    return options, {k: v for k, v in params.items() if k not in DEPTH_OPTIONS}


def _check_params(ap, params: dict) -> None:
    """Refuse ``--params`` that :func:`run` could not pass on, before any scene is rendered."""
    from hyperlf import hlf

    try:
        hlf.DepthParams(**_split_params(params)[1])
    except (TypeError, ValueError) as exc:
        ap.error(f"--params: {exc}")
    allowed = {"optimizer": hlf.OPTIMIZERS, "metric": ("auto", *hlf.CORR_METRICS),
               "defocus": hlf.DEFOCUS_MODES, "view_selection": (True, False),
               "occlusion_split": (True, False)}
    for key, choices in allowed.items():
        # the type too: JSON's 1 is no switch, though 1 == True
        if key in params and not any(type(params[key]) is type(c) and params[key] == c
                                     for c in choices):
            ap.error(f"--params: {key} must be one of {', '.join(map(str, choices))}, "
                     f"got {params[key]!r}")


def _out(ap, args) -> Path:
    """The run's folder.  The two recorded folders (:data:`DEFAULT_OUT`, :data:`PLAIN_OUT`)
    take only the recorded run of their own mode: ``--params``, or seeds, a size, labels or
    (for the faint scenes) a tolerance off that run's, measure a candidate and need their own
    ``--out``."""
    keys = ("seeds", "labels") if args.plain else ("seeds", "labels", "tolerance")
    recorded = {k: ap.get_default(k) for k in keys}  # the parser's defaults are the run's
    recorded["size"] = PLAIN_SIZE if args.plain else SIZE
    own = PLAIN_OUT if args.plain else DEFAULT_OUT
    out = args.out or own
    given = ["--params"] * bool(args.params) + [f"--{k}" for k, v in recorded.items()
                                                  if getattr(args, k) != v]
    if out in (DEFAULT_OUT, PLAIN_OUT) and (given or out != own):
        what = " / ".join(given) + " measure" if given else "a run of the other scenes measures"
        ap.error(f"{what} a candidate: give it its own --out instead of {out}, which records "
                 f"the defaults")
    return out


def seeds_arg(text: str) -> list[int]:
    """An argparse ``type``: ``0-5`` or ``0,3,4`` (non-negative seeds, at least one)."""
    lo, _, hi = text.partition("-")
    try:
        seeds = (list(range(int(lo), int(hi) + 1)) if hi
                 else [int(s) for s in text.split(",")])
    except ValueError:
        seeds = []
    if not seeds or min(seeds) < 0:
        raise argparse.ArgumentTypeError(f"seeds as 0-5 or 0,3,4, got {text!r}")
    return seeds


def size_arg(text: str) -> tuple[int, int]:
    """An argparse ``type``: ``height,width``, each from 32 to 2048 px."""
    try:
        size = tuple(int(v) for v in text.split(","))
    except ValueError:
        size = ()
    if len(size) != 2 or not all(32 <= v <= 2048 for v in size):
        raise argparse.ArgumentTypeError(f"height,width from 32 to 2048 px, got {text!r}")
    return size


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=seeds_arg, default=list(range(6)), help="default 0-5")
    ap.add_argument("--size", type=size_arg, default=None,
                    help="height,width (default 256,320; with --plain 192,256)")
    ap.add_argument("--labels", type=int, choices=range(2, 257), default=64, metavar="N",
                    help="disparity labels, 2-256 (default %(default)s)")
    ap.add_argument("--tolerance", type=float, default=0.03,
                    help="reflectance in the reference band within this of the background's "
                         "(default %(default)s; not used with --plain)")
    ap.add_argument("--params", type=json_object, default={}, metavar="JSON",
                    help="DepthParams fields over the defaults, a candidate to measure; "
                         "also depth's own options (optimizer, metric, ...)")
    ap.add_argument("--plain", action="store_true",
                    help="the scenes as drawn, no chip made faint (the random rings and "
                         "sticks; default --out: %s)" % PLAIN_OUT)
    ap.add_argument("--out", type=Path, default=None,
                    help="folder of the report and the pictures (default: %s)" % DEFAULT_OUT)
    args = ap.parse_args(argv)
    args.size = args.size or (PLAIN_SIZE if args.plain else SIZE)
    out = _out(ap, args)
    if not 0 < args.tolerance <= 0.5:
        ap.error(f"--tolerance must be in (0, 0.5], got {args.tolerance}")
    _check_params(ap, args.params)
    data_path(LIBRARY)
    for seed in [] if args.plain else args.seeds:  # every scene's chips, before any is rendered
        try:
            faint_description(seed, rows=5, cols=6, tolerance=args.tolerance)
        except ValueError as exc:
            ap.error(f"seed {seed}: {exc}; give a larger --tolerance")
    size = args.size  # (height, width)
    out.mkdir(parents=True, exist_ok=True)
    rows = [run(s, size, args.labels, args.params, args.tolerance, out, faint=not args.plain)
            for s in args.seeds]
    mean = {k: float(np.mean([r[k] for r in rows])) for k in
            ("rmse", "badpix_007", "thin_rmse", "thin_bad1", "taken")}
    scenes = "as drawn (--plain)" if args.plain else f"tolerance {args.tolerance}"
    lines = [f"`hlf.depth`, {args.labels} labels, {size[0]} x {size[1]}, {scenes}, params "
             f"{args.params or '(defaults)'}", "",
             "| seed | RMSE px | BadPix(0.07) % | thin RMSE px | thin off > 1 px % | taken % | s |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    lines += [f"| {r['seed']} | {r['rmse']:.4f} | {r['badpix_007']:.2f} | {r['thin_rmse']:.4f} "
              f"| {r['thin_bad1']:.1f} | {r['taken']:.2f} | {r['depth_s']:.0f} |" for r in rows]
    lines.append(f"| mean | {mean['rmse']:.4f} | {mean['badpix_007']:.2f} | "
                 f"{mean['thin_rmse']:.4f} | {mean['thin_bad1']:.1f} | {mean['taken']:.2f} | |")
    write_report(out, "rings_sticks" if args.plain else "faint_thin", "\n".join(lines) + "\n",
                 {"size": size, "labels": args.labels, "plain": args.plain,
                  "tolerance": None if args.plain else args.tolerance,
                  "params": args.params, "scenes": rows, "mean": mean})
    return 0


if __name__ == "__main__":
    sys.exit(main())
