"""The real-array benchmark of issue 11 on ``real_arrays/msir_lab`` (or any capture of the kind).

    python benchmarks/real_array.py WORK [--data FOLDER] [--labels 41] [--half-resolution]
                                         [--downscale N] [--depth-option=--OPTION ...]

Runs, with the documented commands only, ``hyperlf calibrate`` on the board shots, ``hyperlf
ingest`` of the scene shot *and* of the board shot, ``hyperlf depth`` of both, then prints the
figures BENCHMARKS.md reports: pixels at a range limit, and the consistency of the two depth maps
on the pixels valid in both and off the board (the array did not move between the shots; off
the board's corner footprint, where the two shots' images agree, and there on the pixels
whose confidence is at least 0.01 / 0.05 / 0.1 in both, i.e. what ``depth --min-confidence``
keeps), and writes WORK/consistency.png (both maps and their difference).
Steps whose output folder already exists in WORK are not run again. Full resolution takes 3-4
minutes per depth map on 2 cores. ``--half-resolution`` also runs ``hlf.depth`` on a 2 x 2
area-downscaled copy of the scene capture (35 labels, half the range), with and without the
textureless-region weight, and prints the range-limit share and the timings of each (~2 min each).
``--downscale N`` also runs ``hyperlf depth --downscale N`` on both shots (``scene-depth-dN``,
``board-depth-dN``) and prints the same consistency figures on their 1/N maps, in their own px
and in full-resolution px (a block is compared where every pixel of it is; ~1 minute per shot
at N = 2).  ``--depth-option=--weak-planes`` (repeatable) passes an option on to both
depth runs, whose folders then carry it in their names (``scene-depth-weak-planes``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from _common import hyperlf, option_suffix


def depth_folder(shot: str, options=()) -> str:
    """The name of the depth folder of ``shot`` run with the extra depth ``options``."""
    return f"{shot}-depth{option_suffix(options)}"


def run_steps(data: Path, work: Path, labels: int, downscale: int = 1, options=()) -> None:
    pattern = "Cam-{index}.png"
    steps = [
        ("cal", ["calibrate", data / "calibration", "--pattern", pattern, "--grid", "3,3",
                 "--board", "11,8"]),
        ("scene", ["ingest", data / "scene", "--calibration", work / "cal", "--pattern",
                   pattern]),
        ("board", ["ingest", data / "calibration", "--calibration", work / "cal", "--pattern",
                   pattern]),
        *((depth_folder(k, options), ["depth", work / k, "--labels", labels, *options])
          for k in ("scene", "board")),
    ]
    if downscale > 1:
        steps += [(f"{k}-depth-d{downscale}", ["depth", work / k, "--labels", labels,
                                                "--downscale", downscale])
                  for k in ("scene", "board")]
    for name, argv in steps:
        if not (work / name).exists():
            hyperlf(*argv, "-o", work / name)


def board_footprint(data: Path, work: Path, shape) -> np.ndarray:
    """The board in the board shot's reference view: its inner-corner hull grown by 1.5
    squares (the outer squares and the frame)."""
    import cv2

    from hyperlf.calibration import BoardSpec, detect_boards, read_calibration
    from hyperlf.calibration.raw import camera_files, read_camera_images

    cal = read_calibration(work / "cal" / "calibration.toml")
    ref = cal.reference
    files = camera_files(data / "calibration", "Cam-{index}.png", cal.grid)
    img = read_camera_images({ref: files[ref]})[ref]
    c = detect_boards({ref: img}, BoardSpec(11, 8, 1.0))[ref].reshape(8, 11, 2)
    square = float(np.median(np.linalg.norm(np.diff(c, axis=1), axis=-1)))
    hull = cv2.convexHull(c.reshape(-1, 2).astype(np.float32)).reshape(-1, 2)
    centre = hull.mean(0)
    r = np.linalg.norm(hull - centre, axis=1, keepdims=True)
    grown = centre + (hull - centre) * (1 + 1.5 * square / r)
    mask = np.zeros(shape, np.uint8)
    cv2.fillConvexPoly(mask, np.round(grown).astype(np.int32), 1)
    return mask.astype(bool)


def unchanged_pixels(lf_scene, lf_board) -> np.ndarray:
    """Reference pixels where the two shots show the same scene: the part "visible both in the
    board shot and in the scene shot" read from the images themselves, so that the board's
    frame and feet, which the corner footprint does not cover, are left out too.

    Relative difference of the two reference images (the board shot scaled by the median
    ratio of the shots, which absorbs the exposure change) averaged over 15 x 15 px, against
    three times its median over the image (the median pixel is unchanged: the board covers
    far less than half of it), the changed pixels grown by 5 px (a matching window and a
    margin).  On the lab capture the median is 0.066 (so the threshold is 0.20; 0.03 more than
    150 px from the board); inside the corner footprint the 10th percentile is 0.42.
    """
    from scipy import ndimage as ndi

    ref = lf_scene.reference
    a = lf_scene.views[ref].astype(np.float64)
    b = lf_board.views[ref].astype(np.float64)
    both = lf_scene.valid[ref] & lf_board.valid[ref]
    gain = np.median(a[both] / np.maximum(b[both], 1e-12))
    level = ndi.uniform_filter((a + gain * b) / 2, 15)
    rel = ndi.uniform_filter(np.abs(a - gain * b), 15) / np.maximum(level, 1e-12)
    changed = rel > 3 * np.median(rel[both])
    return both & ~ndi.binary_dilation(changed, iterations=5)


def textured_pixels(lf) -> np.ndarray:
    """Reference pixels whose data term ``hyperlf depth`` kept whole (texture weight 1)."""
    from hyperlf.hlf import CAMERA_TEXTURE_SNR, DepthParams
    from hyperlf.imageops import normalise_intensity, texture_snr

    valid = lf.valid[lf.reference]
    ref = normalise_intensity(lf.views[lf.reference], valid=valid)
    window = DepthParams().texture_window  # the window depth uses
    return texture_snr(ref, window, valid=valid) >= CAMERA_TEXTURE_SNR


def figures(data: Path, work: Path, options=()):
    """Prints the full-resolution figures; returns both captures and
    :func:`unchanged_pixels` of them, for :func:`downscaled`."""
    from hyperlf.formats import load_lightfield, read_pfm
    from hyperlf.metrics import at_range_limit

    lf = {k: load_lightfield(work / k) for k in ("scene", "board")}
    d = {k: read_pfm(work / depth_folder(k, options) / "disparity.pfm") for k in lf}
    ref = lf["scene"].reference
    lo, hi = lf["scene"].disparity_range
    at_limit = {k: at_range_limit(d[k], (lo, hi)) for k in d}
    for k in d:
        v = lf[k].valid[ref]
        print(f"{k}: {100 * at_limit[k][v].mean():.2f} % of the valid reference pixels at a "
              f"range limit ({lo:g}, {hi:g})")
    both = lf["scene"].valid[ref] & lf["board"].valid[ref]
    foot = board_footprint(data, work, both.shape)
    off = both & ~foot
    textured = {k: textured_pixels(lf[k]) for k in lf}
    for name, m in (("valid in both, off the board", off),
                    ("... and at no range limit", off & ~at_limit["scene"] & ~at_limit["board"]),
                    ("... and textured in both (full data-term weight)",
                     off & textured["scene"] & textured["board"])):
        diff = np.abs(d["scene"] - d["board"])[m]
        print(f"{name}: {100 * m.mean():.1f} % of the pixels; |difference| median "
              f"{np.median(diff):.3f} px, 90th percentile {np.percentile(diff, 90):.3f} px")
    same = unchanged_pixels(lf["scene"], lf["board"])
    diff = np.abs(d["scene"] - d["board"])[same]
    print(f"where the two shots' images agree (unchanged_pixels): {100 * same.mean():.1f} % of "
          f"the pixels; |difference| median {np.median(diff):.3f} px, 90th percentile "
          f"{np.percentile(diff, 90):.3f} px, {100 * (diff > 2).mean():.1f} % off by more than 2 px")
    confident_in_both(work, d, same, options=options)
    consistency_picture(d, off, foot, work / f"consistency{option_suffix(options)}.png")
    return lf, same


def confident_in_both(work: Path, d: dict, same: np.ndarray, levels=(0.01, 0.05, 0.1), *,
                      options=()) -> None:
    """The consistency on the pixels that ``depth --min-confidence C`` keeps in both shots."""
    from hyperlf.formats import read_pfm

    paths = {k: work / depth_folder(k, options) / "confidence.pfm" for k in d}
    if not all(p.is_file() for p in paths.values()):
        print("no confidence.pfm in the depth folders (made before it was written): "
              "delete them to measure the confident pixels")
        return
    conf = {k: read_pfm(p) for k, p in paths.items()}
    for c in levels:
        m = same & (conf["scene"] >= c) & (conf["board"] >= c)
        diff = np.abs(d["scene"] - d["board"])[m]
        print(f"... and confidence >= {c:g} in both: {100 * m.mean():.1f} % of the pixels; "
              f"|difference| median {np.median(diff):.3f} px, 90th percentile "
              f"{np.percentile(diff, 90):.3f} px")


def consistency_picture(d: dict, compared: np.ndarray, foot: np.ndarray, path: Path) -> None:
    """Both disparity maps and their |difference| where compared; prints how many pixels
    disagree by more than 2 px and how many of those lie near the board footprint (its frame
    and feet, which the footprint does not cover, are not visible in the scene shot)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.ndimage import distance_transform_edt

    diff = np.abs(d["scene"] - d["board"])
    bad = compared & (diff > 2)
    near = bad & (distance_transform_edt(~foot) < 40)
    lo = min(float(np.percentile(v, 1)) for v in d.values())
    hi = max(float(np.percentile(v, 99)) for v in d.values())
    fig, ax = plt.subplots(1, 3, figsize=(15, 4))
    for a, (k, v) in zip(ax, d.items()):
        im = a.imshow(v, cmap="turbo", vmin=lo, vmax=hi)
        a.set_title(f"{k} shot: disparity (px)")
        fig.colorbar(im, ax=a, fraction=0.035)
    ax[2].set_facecolor("0.6")
    im = ax[2].imshow(np.where(compared, diff, np.nan), cmap="magma", vmin=0, vmax=5)
    ax[2].set_title(f"|difference| where compared (grey: not), 90th pct "
                    f"{np.percentile(diff[compared], 90):.1f} px", fontsize=9)
    fig.colorbar(im, ax=ax[2], fraction=0.035)
    for a in ax:
        a.set_xticks([]), a.set_yticks([])
    fig.tight_layout()
    fig.savefig(path, dpi=60)
    plt.close(fig)
    print(f"{100 * bad.sum() / max(compared.sum(), 1):.1f} % of the compared pixels disagree by "
          f"more than 2 px, {100 * near.sum() / max(bad.sum(), 1):.0f} % of those within 40 px "
          f"of the board footprint; picture: {path}")


def downscaled(work: Path, n: int, lf: dict, same: np.ndarray) -> None:
    """The consistency of ``hyperlf depth --downscale n``'s maps of the two shots (``lf``, as
    :func:`figures` loaded them), on the blocks whose every pixel ``same``
    (:func:`unchanged_pixels`) keeps."""
    from hyperlf.formats import read_pfm
    from hyperlf.imageops import block_reduce
    from hyperlf.metrics import at_range_limit

    d = {k: read_pfm(work / f"{k}-depth-d{n}" / "disparity.pfm") for k in lf}
    same = block_reduce(same, n, np.all)
    same = same[:d["scene"].shape[0], :d["scene"].shape[1]]
    lo, hi = (v / n for v in lf["scene"].disparity_range)
    ref = lf["scene"].reference
    for k in d:
        v = block_reduce(lf[k].valid[ref], n, np.all)[:d[k].shape[0], :d[k].shape[1]]
        print(f"1/{n} resolution, {k}: {100 * at_range_limit(d[k], (lo, hi))[v].mean():.2f} % of "
              f"the valid reference blocks at a range limit ({lo:g}, {hi:g})")
    diff = np.abs(d["scene"] - d["board"])[same]
    p90 = np.percentile(diff, 90)
    print(f"1/{n} resolution, where the two shots' images agree: {100 * same.mean():.1f} % of "
          f"the blocks; |difference| median {np.median(diff):.3f} px, 90th percentile "
          f"{p90:.3f} px of the 1/{n} maps ({n * p90:.3f} full-resolution px), "
          f"{100 * (diff > 2).mean():.1f} % off by more than 2 px")


def half_resolution(work: Path) -> None:
    """Range-limit pixels and timings of ``hlf.depth`` on the scene capture downscaled 2 x 2,
    with the textureless-region weight off and at its default for cameras."""
    import cv2

    from hyperlf.formats import load_lightfield
    from hyperlf.hlf import CAMERA_TEXTURE_SNR, DepthParams, depth
    from hyperlf.metrics import at_range_limit

    lf = load_lightfield(work / "scene")
    R, C, H, W = lf.views.shape
    size = (W // 2, H // 2)
    views = np.array([[cv2.resize(lf.views[r, c], size, interpolation=cv2.INTER_AREA)
                       for c in range(C)] for r in range(R)])
    valid = np.array([[cv2.resize(lf.valid[r, c].astype(np.float32), size,
                                  interpolation=cv2.INTER_AREA) > 0.999
                       for c in range(C)] for r in range(R)])
    lo, hi = (v / 2 for v in lf.disparity_range)
    half = lf.replace(views=views, valid=valid, disparity_range=(lo, hi))
    for snr in (0.0, CAMERA_TEXTURE_SNR):
        res = depth(half, n_labels=35, params=DepthParams(texture_snr=snr))
        d = res.disparity
        at = at_range_limit(d, (lo, hi))[valid[lf.reference]]
        t = res.timings
        print(f"half resolution, texture_snr={snr:g}: {100 * at.mean():.2f} % at a range limit; "
              f"total {t['total_s']:.1f} s (correspondence {t['correspondence_s']:.1f} s, "
              f"MRF {t['mrf_s']:.1f} s)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("work", type=Path, help="working folder (outputs are kept and reused)")
    ap.add_argument("--data", type=Path, default=None,
                    help="the capture folder (default $HYPERLF_DATA/real_arrays/msir_lab)")
    ap.add_argument("--labels", type=int, default=41)
    ap.add_argument("--half-resolution", action="store_true",
                    help="also measure the textureless-region weight at half resolution")
    ap.add_argument("--downscale", type=int, default=1, metavar="N",
                    help="also run depth --downscale N on both shots and measure them")
    ap.add_argument("--depth-option", action="append", default=[], metavar="--OPTION",
                    help="an option of both depth runs (repeatable; write it as "
                         "--depth-option=--weak-planes)")
    a = ap.parse_args()
    data = a.data or Path(os.environ.get("HYPERLF_DATA", "../shared/data")) / "real_arrays" \
        / "msir_lab"
    a.work.mkdir(parents=True, exist_ok=True)
    run_steps(data, a.work, a.labels, a.downscale, a.depth_option)
    lf, same = figures(data, a.work, a.depth_option)
    if a.downscale > 1:
        downscaled(a.work, a.downscale, lf, same)
    if a.half_resolution:
        half_resolution(a.work)


if __name__ == "__main__":
    main()
