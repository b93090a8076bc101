#!/usr/bin/env python
"""Light fields rendered from Middlebury scenes: held-out stand-ins of other content for H-LF
depth (issue 12).

    HYPERLF_DATA=../shared/data python benchmarks/middlebury_lf.py WORK [--scenes venus,teddy]
                                   [--depth-option=--optimizer=sgm ...] [--out FOLDER]

Antinous is the only HCI scene here, and every earlier H-LF stand-in was antinous changed
(mirrored, darkened, more colourful, ...). This script makes light fields of other content:
each Middlebury scene's left image becomes the centre view of a 9 x 9 folder laid out as the
HCI 4D benchmark's (``input_Cam###.png`` and ``gt_disp_lowres.pfm``), its ground truth mapped
linearly to an HCI-like disparity range (``--span`` px between the nearest and the farthest
surface, centred on 0). Then, as a held-out scene would be, it runs the CLI: ``hyperlf synth
hci`` (the 5 x 6 H-LF) and ``hyperlf depth`` with the defaults, and scores the map as Table 2
scores antinous (RMSE and BadPix(0.07) without the 15 px border).

How a view is rendered (:func:`render_view`): the centre's disparity is forward-warped into
the view (the nearer surface wins, :func:`hyperlf.warp.forward_warp_disparity`); a pixel that
nothing lands on takes the largest disparity of its 3 x 3 neighbours when that one leads back
to a centre pixel of the same disparity (a crack in a stretched surface), and is otherwise
disoccluded (the view sees what the centre does not); every other pixel samples the centre
image at ``x + d dx, y + d dy`` (Lanczos), and the disoccluded ones are inpainted (Telea), so
they hold plausible colour and no true correspondence, as a real occlusion does. Pixels whose
ground truth is unknown (Middlebury's occlusions, Tsukuba's border) first take the farther of
the two nearest known values on their row: the rendered views follow that disparity, so it is
the stand-in's exact ground truth.

Venus is issue 12's tuning scene, so its light field may decide H-LF defaults; the light
fields of Tsukuba, Teddy and Art are stand-ins, reported and not tuned on (BENCHMARKS.md, "How
defaults are chosen"). The scale of their error is their own: a Middlebury scene has larger
depth jumps than most HCI scenes, so the figure to read is how each one moves when the
default does, and whether one fails.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from _common import data_path, depth_picture, hyperlf, log, option_suffix, write_report

SCENES = ("venus", "tsukuba", "teddy", "art")
#: Side of the HCI-style folder's square grid of views.
GRID = 9
#: Default distance (px per baseline) between the nearest and the farthest surface: antinous's
#: ground truth spans 5.8 px (-3.13 .. 2.69).
SPAN = 5.5


def fill_rows_background(d: np.ndarray) -> np.ndarray:
    """Unknown (NaN) values take the smaller (farther) of the nearest known values left and
    right on their row; rows with none known take the nearest known row's values."""
    out = np.array(d, dtype=np.float64)
    H, W = out.shape
    idx = np.arange(W)
    for y in range(H):
        known = np.isfinite(out[y])
        if not known.any() or known.all():
            continue
        xs = idx[known]
        left = np.searchsorted(xs, idx, side="right") - 1
        right = np.searchsorted(xs, idx, side="left")
        lv = np.where(left >= 0, out[y, xs[np.clip(left, 0, None)]], np.inf)
        rv = np.where(right < xs.size, out[y, xs[np.clip(right, None, xs.size - 1)]], np.inf)
        out[y, ~known] = np.minimum(lv, rv)[~known]
    rows = np.isfinite(out).all(axis=1)
    if not rows.any():
        raise ValueError("the ground truth has no known value")
    good = np.flatnonzero(rows)
    for y in np.flatnonzero(~rows):
        out[y] = out[good[np.argmin(np.abs(good - y))]]
    return out


def lf_disparity(gt: np.ndarray, span: float = SPAN) -> np.ndarray:
    """The ground truth mapped linearly to ``[-span / 2, span / 2]`` px per baseline (nearer
    surfaces larger, as in both conventions)."""
    lo, hi = float(np.min(gt)), float(np.max(gt))
    return (gt - 0.5 * (lo + hi)) * (span / max(hi - lo, 1e-9))


def _sample(image: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``image`` at float positions (Lanczos, borders replicated)."""
    import cv2

    return cv2.remap(image, x.astype(np.float32), y.astype(np.float32), cv2.INTER_LANCZOS4,
                     borderMode=cv2.BORDER_REPLICATE)


def render_view(image: np.ndarray, disparity: np.ndarray, offset: tuple[float, float],
                *, tolerance: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The view at ``offset = (dx, dy)`` baselines from the centre: ``(image, disoccluded)``.

    ``image`` is the centre view, uint8 ``(H, W, 3)``; ``disparity`` its complete disparity
    (px per baseline, SPEC §1: a centre pixel ``(x, y)`` appears at ``(x - d dx, y - d dy)``).
    ``tolerance`` (px): how far a pixel's way back to the centre may land from the surface it
    came from before it counts as disoccluded.
    """
    import cv2
    from scipy.ndimage import maximum_filter

    from hyperlf.warp import forward_warp_disparity

    dx, dy = offset
    d0 = disparity.astype(np.float32)
    if dx == 0 and dy == 0:
        return image.copy(), np.zeros(d0.shape, bool)
    dt = forward_warp_disparity(d0, (dx, dy)).astype(np.float64)
    hole = ~np.isfinite(dt)
    cand = maximum_filter(np.where(hole, -np.inf, dt), size=3)
    H, W = d0.shape
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    with np.errstate(invalid="ignore"):
        bx, by = np.rint(xx + cand * dx), np.rint(yy + cand * dy)
        inside = np.isfinite(cand) & (bx >= 0) & (bx < W) & (by >= 0) & (by < H)
    back = d0[np.where(inside, by, 0).astype(np.intp), np.where(inside, bx, 0).astype(np.intp)]
    crack = inside & (np.abs(back - cand) * np.hypot(dx, dy) <= tolerance)
    lost = hole & ~crack
    dt = np.where(hole, np.where(crack, cand, 0.0), dt)
    sx, sy = xx + dt * dx, yy + dt * dy
    view = _sample(image, np.where(lost, xx, sx), np.where(lost, yy, sy))
    if lost.any():
        view = cv2.inpaint(view, lost.astype(np.uint8), 3, cv2.INPAINT_TELEA)
    return view, lost


def write_scene(folder: Path, image: np.ndarray, disparity: np.ndarray,
                *, grid: int = GRID) -> float:
    """An HCI-style folder of ``grid x grid`` rendered views and ``gt_disp_lowres.pfm``;
    returns the share of disoccluded pixels over the views."""
    from hyperlf.formats.images import write_image
    from hyperlf.formats.pfm import write_pfm

    folder.mkdir(parents=True, exist_ok=True)
    c = (grid - 1) // 2
    lost = []
    for r in range(grid):
        for k in range(grid):
            view, gone = render_view(image, disparity, (k - c, r - c))
            write_image(folder / f"input_Cam{grid * r + k:03d}.png", view)
            lost.append(gone.mean())
    write_pfm(folder / "gt_disp_lowres.pfm", disparity.astype(np.float32))
    return float(np.mean(lost))


def centre_image(pair) -> np.ndarray:
    """The left image as uint8 RGB (the centre view's source)."""
    image = np.asarray(pair.left)
    if image.dtype == np.uint8:
        return image
    return np.clip(np.rint(image * 255.0), 0, 255).astype(np.uint8)


def prepare(name: str, work: Path, span: float) -> Path:
    """WORK/<name>-span<S>-lf (the HCI-style folder) and WORK/<name>-span<S>-capture
    (``hyperlf synth hci``), each made only when missing; returns the capture."""
    from hyperlf.formats.middlebury import read_middlebury

    folder, capture = (work / f"{name}-span{span:g}-{kind}" for kind in ("lf", "capture"))
    if not (folder / "gt_disp_lowres.pfm").is_file():
        pair = read_middlebury(data_path(f"middlebury/{name}"))
        gt = lf_disparity(fill_rows_background(pair.gt_disparity), span)
        lost = write_scene(folder, centre_image(pair), gt)
        log(f"{name}: rendered, {100 * lost:.2f} % of the view pixels disoccluded")
    if not (capture / "capture.toml").is_file():
        hyperlf("-q", "synth", "hci", folder, "-o", capture, "--overwrite")
    return capture


def run_scene(name: str, work: Path, out: Path, span: float, options: list[str]) -> dict:
    from hyperlf.formats.capture import read_capture
    from hyperlf.formats.pfm import read_pfm
    from hyperlf.metrics import HCI_BORDER, disparity_scores

    capture = prepare(name, work, span)
    result = work / f"{capture.name[:-len('capture')]}depth{option_suffix(options)}"
    wall = hyperlf("-q", "depth", capture, "-o", result, "--overwrite", *options)
    lf = read_capture(capture, cube=False)
    disp = read_pfm(result / "disparity.pfm")
    s = disparity_scores(disp, lf.reference_gt_disparity, border=HCI_BORDER)
    depth_picture(out / f"{result.name}.png", name, lf, disp)
    log(f"{name}: RMSE {s.rmse:.4f} px, BadPix(0.07) {s.badpix_007:.2f} % ({wall:.0f} s)")
    return {"scene": name, "shape": list(disp.shape), "rmse": s.rmse,
            "badpix_007": s.badpix_007, "depth_s": wall}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("work", type=Path, help="folder for the rendered scenes, their captures "
                                            "and depth maps (made when missing, reused after)")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/middlebury_lf"),
                    help="folder of the report and the pictures (default: %(default)s)")
    ap.add_argument("--scenes", default=",".join(SCENES),
                    help=f"comma-separated, of {', '.join(SCENES)} (default: all)")
    ap.add_argument("--span", type=float, default=SPAN,
                    help=f"nearest minus farthest disparity, px per baseline (default {SPAN})")
    ap.add_argument("--depth-option", action="append", default=[], metavar="ARG",
                    help="an option for hyperlf depth, e.g. --depth-option=--optimizer=sgm "
                         "(repeatable; the report and pictures carry it in their names)")
    args = ap.parse_args(argv)
    scenes = [s for s in args.scenes.split(",") if s]
    unknown = sorted(set(scenes) - set(SCENES))
    if unknown or not scenes:
        ap.error(f"unknown scene(s) {', '.join(unknown) or '(none given)'}; choose from "
                 f"{', '.join(SCENES)}")
    if not 0 < args.span <= 50:
        ap.error(f"--span must be in (0, 50] px per baseline, got {args.span}")
    args.work.mkdir(parents=True, exist_ok=True)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = [run_scene(n, args.work, args.out, args.span, args.depth_option) for n in scenes]
    lines = [f"hyperlf depth {' '.join(args.depth_option) or '(defaults)'}, span {args.span} px",
             "", "| scene | size | RMSE px | BadPix(0.07) % | depth s |", "|---|---|---:|---:|---:|"]
    lines += [f"| {r['scene']} | {r['shape'][1]} x {r['shape'][0]} | {r['rmse']:.4f} | "
              f"{r['badpix_007']:.2f} | {r['depth_s']:.0f} |" for r in rows]
    stem = f"middlebury_lf-span{args.span:g}{option_suffix(args.depth_option)}"
    write_report(args.out, stem, "\n".join(lines) + "\n",
                 {"span": args.span, "depth_options": args.depth_option, "scenes": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
