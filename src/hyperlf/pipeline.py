"""Orchestration of whole runs: the synthetic demo and the pictures written beside results.

The command-line tool (:mod:`hyperlf.cli`) only parses arguments, calls these functions and
reports; everything that computes or writes lives here, so that a script or a notebook can run
the same chain as ``hyperlf demo``.

:func:`run_demo` runs capture -> depth -> plenoptic cube -> emulated colour camera -> focal
sweep on a small procedural scene with exact ground truth (:data:`hyperlf.synthesis.SCENES`
``"solids"``) and writes the data, the pictures and one self-contained ``report.html``.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from . import _options as _opt

__all__ = [
    "DemoResult",
    "run_demo",
    "run_calibration",
    "run_ingest",
    "save_metric_outputs",
    "write_lightfield_pictures",
    "save_disparity_outputs",
    "finite_range",
]


def _quiet(msg: str) -> None:
    """Default ``log`` of :func:`run_demo`: say nothing."""


@dataclass
class DemoResult:
    """What :func:`run_demo` wrote and measured.

    Attributes
    ----------
    out_dir : Path
        The output folder.
    report : Path
        The HTML report (every picture embedded).
    written : list of Path
        Every picture and data file written, in order (the capture folder and ``cube.h5``
        included).
    scores : dict
        ``depth_rmse``, ``depth_mse_x100``, ``depth_badpix_007``, ``depth_bad_0_5`` (reference
        view, all pixels), ``cube_psnr`` (dB), ``cube_sam`` (degrees), ``srgb_psnr`` (dB),
        ``completed_pct``.
    timings : dict
        Seconds per stage (``synthesis``, ``depth``, ``completion``, ``rendering``) and
        ``total``.
    """

    out_dir: Path
    report: Path
    written: list[Path] = field(default_factory=list)
    scores: dict[str, float] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)


def finite_range(values: np.ndarray) -> tuple[float, float]:
    """Finite minimum and maximum of an array (a disparity map, say, for a focal sweep).

    Parameters
    ----------
    values : ndarray
        Any array with at least one finite value.

    Returns
    -------
    (float, float)
        ``(min, max)`` over the finite entries.

    Examples
    --------
    >>> finite_range(np.array([np.nan, -1.5, 2.0]))
    (-1.5, 2.0)
    """
    values = _opt.real_array(values, "values")
    f = values[np.isfinite(values)]
    if f.size == 0:
        from .errors import InvalidInputError

        raise InvalidInputError(f"values must hold at least one finite number, got "
                                f"{_opt.shown(values)}")
    return float(f.min()), float(f.max())


def _light_field(lf):
    """``lf`` when it is a :class:`~hyperlf.lightfield.LightField`."""
    from .lightfield import check_light_field

    return check_light_field(lf)


def _text(value, label: str) -> str:
    """``value`` when it is printable text (a title, a unit, a file-name stem)."""
    return _opt.text(value, label, printable=True)


def _stem(value) -> str:
    """A file-name prefix: text without a folder separator, short enough for a file name."""
    from .errors import InvalidInputError

    if _text(value, "stem") and (os.sep in value or "\0" in value or len(value) > 200):
        raise InvalidInputError(f"stem must be a file-name prefix (no folder, at most 200 "
                                f"characters), got {_opt.shown(value)}")
    return value


def _map(value, label: str, shape=None, *, optional: bool = False):
    """A 2-D map of real numbers (NaN allowed, not inf) of ``shape`` where given; None
    passes where ``optional``. One pass for the infinities: these helpers write files."""
    from .errors import InvalidInputError

    if value is None and optional:
        return None
    a = _opt.real_array(value, label)
    if a.ndim != 2 or a.size == 0 or (shape is not None and a.shape != tuple(shape)):
        want = f"shape {tuple(shape)}" if shape is not None else "a non-empty (H, W) map"
        raise InvalidInputError(f"{label} must be {want}, got shape {a.shape}")
    if np.isinf(a).any():
        raise InvalidInputError(f"{label} holds infinite values; use NaN for unknown pixels")
    return a


def write_lightfield_pictures(lf, out: str | os.PathLike, stem: str = "") -> list[Path]:
    """Pictures of a light field: views mosaic, reference ground truth, sRGB cube, spectrum.

    Parameters
    ----------
    lf : LightField
        The light field; ground-truth pictures are written only when it has them.
    out : path-like
        Output folder.
    stem : str
        Prefix of every file name.

    Returns
    -------
    list of Path
        ``views.png``, then (when available) ``gt_disparity.png``, ``reference_srgb.png`` and
        ``spectrum_centre.png``.

    Examples
    --------
    >>> import tempfile
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=0, rows=2, cols=2, height=16, width=20)
    >>> [p.name for p in write_lightfield_pictures(lf, tempfile.mkdtemp())]
    ['views.png', 'gt_disparity.png', 'reference_srgb.png', 'spectrum_centre.png']
    """
    from . import visualise

    _light_field(lf)
    out = Path(_opt.path_like(out, "out", folder=True))
    _stem(stem)
    written = [visualise.save_mosaic_png(out / f"{stem}views.png", lf.views, lf.wavelengths,
                                         title="views (false colour by filter wavelength)")]
    gt = lf.reference_gt_disparity
    if gt is not None:
        written.append(visualise.save_disparity_png(out / f"{stem}gt_disparity.png", gt,
                                                    title="ground-truth disparity (reference)"))
    if lf.gt_cube is not None:
        from . import render
        from .formats import write_image

        cube = lf.gt_cube[lf.reference]  # (B, H, W)
        srgb = render.emulate_camera(cube, lf.cube_wavelengths, "CIE 1931", output="srgb",
                                     exposure="percentile")
        written.append(write_image(out / f"{stem}reference_srgb.png", srgb, bit_depth=8))
        H, W = lf.image_shape
        y, x = H // 2, W // 2
        written.append(visualise.save_spectrum_plot(
            out / f"{stem}spectrum_centre.png", lf.cube_wavelengths, cube[:, y, x],
            title=f"ground-truth spectrum at reference pixel (x={x}, y={y})"))
    return written


def save_disparity_outputs(out: str | os.PathLike, disparity: np.ndarray, title: str,
                           *, truth: np.ndarray | None = None,
                           confidence: np.ndarray | None = None,
                           stem: str = "disparity", unit: str = "px per baseline",
                           error_vmax: float = 1.0,
                           label: str = "disparity (px / baseline)") -> list[Path]:
    """Write a disparity map as PFM (exact), 16-bit PNG and a colour-mapped picture.

    The 16-bit PNG holds ``(disparity - offset) * 256`` rounded; the offset is written to a
    ``.txt`` beside it.

    Parameters
    ----------
    out : path-like
        Output folder.
    disparity : ndarray
        ``(H, W)`` disparity (NaN allowed).
    title : str
        Title of the colour-mapped picture.
    truth : ndarray, optional
        Ground truth; adds ``<stem>_error.png``.
    confidence : ndarray, optional
        Confidence in [0, 1]; adds ``confidence.pfm`` (exact) and ``confidence.png``.
    stem : str
        File-name stem (default ``"disparity"``).
    unit : str
        The disparity's unit, for the ``.txt`` (a pair's disparity is in px).
    error_vmax : float
        The error (in the disparity's unit) at the top of the error picture's colour map:
        1 for a light field's sub-pixel disparities, the bad-pixel threshold for a pair's
        (in (0, 1e6]).
    label : str
        The colour bar's label in the picture (a pair's: ``"disparity (px)"``).

    Returns
    -------
    list of Path
        ``.pfm``, ``_16bit.png``, ``_16bit.txt``, ``.png``, then the error picture and the
        confidence map and picture when written.

    Examples
    --------
    The 16-bit PNG gives the map back to within half its step of 1/256 px, with the offset
    its ``.txt`` states; the PFM gives it back exactly:

    >>> import tempfile, pathlib, cv2
    >>> from hyperlf.formats import read_pfm
    >>> out = pathlib.Path(tempfile.mkdtemp())
    >>> disparity = np.linspace(-1, 1, 16 * 20, dtype=np.float32).reshape(16, 20)
    >>> [p.name for p in save_disparity_outputs(out, disparity, "ramp")]
    ['disparity.pfm', 'disparity_16bit.png', 'disparity_16bit.txt', 'disparity.png']
    >>> png = cv2.imread(str(out / "disparity_16bit.png"), cv2.IMREAD_UNCHANGED)
    >>> (out / "disparity_16bit.txt").read_text().split("#")[0].strip()
    'disparity = value / 256 + (-1)'
    >>> bool(np.abs(png / 256 - 1 - disparity).max() <= 1 / 512)
    True
    >>> bool(np.array_equal(read_pfm(out / "disparity.pfm"), disparity))
    True
    """
    from . import visualise
    from ._atomic import atomic_write_text
    from .formats import write_image, write_pfm

    out = Path(_opt.path_like(out, "out", folder=True))
    shape = _map(disparity, "disparity").shape
    _map(truth, "truth", shape, optional=True)
    _map(confidence, "confidence", shape, optional=True)
    _text(title, "title"), _stem(stem), _text(unit, "unit"), _text(label, "label")
    error_vmax = _opt.number(error_vmax, "error_vmax", positive=True, at_most=1e6)
    written = [write_pfm(out / f"{stem}.pfm", disparity)]
    d = np.nan_to_num(np.asarray(disparity, dtype=np.float64), nan=0.0)
    offset = float(min(0.0, np.floor(d.min())))
    png = np.clip(np.rint((d - offset) * 256.0), 0, 65535).astype(np.uint16)
    written.append(write_image(out / f"{stem}_16bit.png", png))
    written.append(atomic_write_text(
        out / f"{stem}_16bit.txt",
        f"disparity = value / 256 + ({offset:g})   # {unit}; exact values in {stem}.pfm\n"))
    written.append(visualise.save_disparity_png(out / f"{stem}.png", disparity, title=title,
                                                label=label))
    if truth is not None:
        written.append(visualise.save_error_png(out / f"{stem}_error.png", disparity, truth,
                                                vmax=error_vmax))
    if confidence is not None:
        written.append(write_pfm(out / "confidence.pfm", confidence))
        written.append(visualise.save_disparity_png(out / "confidence.png", confidence,
                                                    title="confidence", vmin=0, vmax=1,
                                                    cmap="viridis", label="confidence"))
    return written


# ----------------------------------------------------------------------------- demo stages
def _demo_capture(out: Path, seed: int, grid: tuple[int, int], size: tuple[int, int],
                  progress: bool):
    """Synthesise the ``solids`` scene, write it as a capture, its ground truth and pictures."""
    from . import synthesis
    from .formats import save_lightfield, write_pfm

    scene = {**synthesis.SCENES["solids"], "seed": seed, "rows": grid[0], "cols": grid[1],
             "height": size[0], "width": size[1], "progress": progress}
    lf = synthesis.procedural_scene(**scene)
    capture = save_lightfield(lf, out / "capture", overwrite=True)
    gt_path = write_pfm(out / "gt_disparity.pfm", lf.reference_gt_disparity)
    pics = write_lightfield_pictures(lf, out)
    return lf, [capture, gt_path, *pics], pics


def _demo_depth(lf, out: Path, metric: str, labels: int, progress: bool):
    """H-LF depth of the reference view, its pictures and its scores against the truth."""
    from . import metrics
    from .hlf import depth

    gt = lf.reference_gt_disparity
    dres = depth(lf, n_labels=labels, metric=metric, progress=progress)
    pics = save_disparity_outputs(out / "depth", dres.disparity,
                                  f"estimated disparity ({metric})", truth=gt,
                                  confidence=dres.confidence)
    sc = metrics.disparity_scores(dres.disparity, gt, mask_name="all")
    return dres, sc, pics


def _demo_cube(lf, disparity: np.ndarray, out: Path, progress: bool):
    """Complete the plenoptic cube (plain registration, no pairwise stereo) and score it."""
    from . import metrics
    from .completion import complete
    from .formats import read_cube_h5

    cres = complete(lf, disparity, out_path=out / "cube.h5", optimizer=None, progress=progress)
    cube, wl, _ = read_cube_h5(cres.path)
    valid = np.isfinite(lf.gt_cube)
    cube_psnr = metrics.psnr(cube, lf.gt_cube, mask=valid)
    cube_sam = metrics.sam(cube, lf.gt_cube, band_axis=2)
    return cres, cube, wl, cube_psnr, cube_sam


def _demo_render(lf, cube: np.ndarray, wl: np.ndarray, out: Path) -> dict[str, Any]:
    """Emulated sRGB of the completed and true cubes, a focal sweep and a spectral profile."""
    from . import metrics, render, visualise
    from .formats import write_image

    ref = lf.reference
    srgb = render.emulate_camera(cube[ref], wl, "CIE 1931", output="srgb", white="D65")
    srgb_gt = render.emulate_camera(lf.gt_cube[ref], lf.cube_wavelengths, "CIE 1931",
                                    output="srgb", white="D65")
    srgb_psnr = metrics.psnr(srgb, srgb_gt)

    def big(im):
        return np.repeat(np.repeat(im, 3, axis=0), 3, axis=1)

    p_rgb = write_image(out / "render" / "reference_srgb_completed.png", big(srgb), bit_depth=8)
    p_rgb_gt = write_image(out / "render" / "reference_srgb_truth.png", big(srgb_gt), bit_depth=8)
    sweep = render.focal_sweep(cube, lf.offsets,
                               np.linspace(*finite_range(lf.reference_gt_disparity), 7),
                               "CIE 1931", out_dir=out / "refocus", formats=("gif",),
                               white="D65", wavelengths=wl)
    H, W = lf.image_shape
    y, x = int(0.5 * H), int(0.68 * W)
    p_spec = visualise.save_spectrum_plot(
        out / "render" / "spectrum.png", wl,
        [cube[ref][:, y, x], lf.gt_cube[ref][:, y, x]], labels=["completed", "ground truth"],
        title=f"reference view, pixel x={x}, y={y}")
    return dict(srgb_psnr=srgb_psnr, completed=p_rgb, truth=p_rgb_gt, sweep=sweep["gif"],
                spectrum=p_spec)


def _demo_report(out: Path, lf, metric: str, sc, cres, scores: dict, timings: dict,
                 pics: list[Path], disp_pics: list[Path], rendered: dict) -> Path:
    from .report import Section, write_html_report

    H, W = lf.image_shape
    sections = [
        Section("Synthetic capture",
                f"{lf.grid_shape[0]} x {lf.grid_shape[1]} views of {W} x {H} px, one narrow band "
                f"each ({lf.wavelengths.min():g}-{lf.wavelengths.max():g} nm, raster order); "
                "procedural box and sphere over a textured background, real reflectance spectra, "
                "exact ground truth.", pictures=[(pics[0], "views, tinted by filter wavelength"),
                                                 (pics[1], "ground-truth disparity")]),
        Section("Depth", f"H-LF stereo matching with the {metric} cost and graph cuts.",
                table=[("RMSE (px)", "MSE x 100", "bad 0.07 (%)", "bad 0.5 (%)", "time (s)"),
                       (f"{sc.rmse:.3f}", f"{sc.mse_x100:.2f}", f"{sc.badpix_007:.1f}",
                        f"{sc.bad_0_5:.1f}", f"{timings['depth']:.1f}")],
                pictures=[(disp_pics[3], "estimated disparity"),
                          (disp_pics[4], "absolute error against the ground truth")]),
        Section("Plenoptic cube", "Every view receives every band by disparity-guided "
                "registration with occlusion checks and propagation.",
                table=[("PSNR (dB)", "SAM (deg)", "completed (%)", "time (s)"),
                       (f"{scores['cube_psnr']:.2f}", f"{scores['cube_sam']:.2f}",
                        f"{cres.stats['completed_pct']:.1f}", f"{timings['completion']:.1f}")]),
        Section("Rendering", f"The reference view as a CIE 1931 observer would see it (sRGB, "
                f"D65 white), from the completed cube: {scores['srgb_psnr']:.1f} dB against the "
                "rendering of the true cube. Focal sweep from far to near (disparity rising).",
                pictures=[(rendered["completed"], "emulated sRGB, completed cube"),
                          (rendered["truth"], "emulated sRGB, ground-truth cube"),
                          (rendered["sweep"], "focal sweep"),
                          (rendered["spectrum"], "spectral profile")]),
    ]
    stages = {k: v for k, v in timings.items() if k != "total"}
    return write_html_report(out / "report.html", "hyperlf demo", sections,
                             footer=f"total {timings['total']:.1f} s: " + ", ".join(
                                 f"{k} {v:.1f} s" for k, v in stages.items()))


def _log_or_quiet(log) -> Callable[[str], None]:
    """``log`` when it is callable (or the silent default for None)."""
    from .errors import InvalidInputError

    if log is None:
        return _quiet
    if not callable(log):
        raise InvalidInputError(f"log must be a callable taking one line of text (or None), "
                                f"got {type(log).__name__}")
    return log


def _check_demo_options(out_dir, seed, grid, size, metric, labels, progress) -> None:
    """Refuse impossible demo options before anything is written."""
    from .calibration.grid import MAX_CAMERAS
    from .costs import get_cost
    from .errors import InvalidInputError
    from .tiling import check_label_volume

    _opt.path_like(out_dir, "out_dir", folder=True)
    _opt.integer(seed, "seed", maximum=2 ** 63)
    R, C = _opt.int_pair(grid, "grid", maximum=MAX_CAMERAS, what="(rows, cols)")
    H, W = _opt.int_pair(size, "size", maximum=2 ** 16, what="(height, width) in px")
    if R * C < 2 or R * C > MAX_CAMERAS:
        raise InvalidInputError(f"the demo needs at least 2 views (and at most {MAX_CAMERAS}); "
                                f"got a {R} x {C} grid")
    get_cost(metric, light_field=True)
    check_label_volume(_opt.integer(labels, "labels", 2), (H, W))
    _opt.flag(progress, "progress")


def _check_run_paths(**paths) -> None:
    """The inputs (files or folders), ``out_dir`` (a folder) and ``pattern`` (text) of
    :func:`run_calibration` and :func:`run_ingest`, checked before any image is read."""
    from .errors import InvalidInputError

    for name, value in paths.items():
        if name == "pattern":
            if not isinstance(value, str) or not value:
                raise InvalidInputError(f"pattern must be a file name pattern (text), got "
                                        f"{_opt.shown(value)}")
        else:
            _opt.path_like(value, name, folder=True if name == "out_dir" else None)


def run_demo(out_dir: str | os.PathLike, *, seed: int = 0, grid: tuple[int, int] = (5, 6),
             size: tuple[int, int] = (96, 128), metric: str = "auto", labels: int = 32,
             progress: bool = False, log: Callable[[str], None] | None = None) -> DemoResult:
    """Run the whole chain on a synthetic H-LF and write data, pictures and ``report.html``.

    Stages: the procedural ``"solids"`` scene (:func:`hyperlf.synthesis.procedural_scene`)
    written as a capture folder with its ground truth; H-LF depth of the reference view
    (:func:`hyperlf.hlf.depth`, graph cuts); plenoptic cube completion
    (:func:`hyperlf.completion.complete`, registration only); emulated CIE 1931 sRGB of the
    completed and true cubes, a 7-frame focal sweep (GIF) and a spectral profile
    (:mod:`hyperlf.render`); an HTML report with every picture and score.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created; the capture inside it is overwritten).
    seed : int
        Scene seed (textures and reflectance chips).
    grid : (int, int)
        Rows and columns of views.
    size : (int, int)
        View height and width in pixels.
    metric : str
        Correspondence cost of the depth stage (a name of :data:`hyperlf.costs.METRIC_NAMES`;
        ``"auto"`` = the library default).
    labels : int
        Number of disparity labels.
    progress : bool
        Show progress bars.
    log : callable, optional
        Called with one line of text at the start of every stage and with the summary.

    Returns
    -------
    DemoResult
        The report path, every file written, the scores and the stage timings.

    Examples
    --------
    >>> import tempfile
    >>> res = run_demo(tempfile.mkdtemp(), grid=(3, 3), size=(32, 40), metric="ncc",
    ...                labels=8)  # doctest: +SKIP
    >>> res.report.name  # doctest: +SKIP
    'report.html'
    """
    _check_demo_options(out_dir, seed, grid, size, metric, labels, progress)
    log = _log_or_quiet(log)
    t_start = time.perf_counter()
    out = Path(out_dir)
    timings: dict[str, float] = {}
    log(f"hyperlf demo: building a {grid[0]} x {grid[1]} synthetic H-LF (seed {seed}) ...")
    t0 = time.perf_counter()
    lf, written, pics = _demo_capture(out, seed, grid, size, progress)
    timings["synthesis"] = time.perf_counter() - t0

    log(f"depth: H-LF stereo matching ({metric}, graph cuts, {labels} labels) ...")
    t0 = time.perf_counter()
    dres, sc, disp_pics = _demo_depth(lf, out, metric, labels, progress)
    timings["depth"] = time.perf_counter() - t0
    written += disp_pics

    log("cube completion: every view gets every band ...")
    t0 = time.perf_counter()
    cres, cube, wl, cube_psnr, cube_sam = _demo_cube(lf, dres.disparity, out, progress)
    timings["completion"] = time.perf_counter() - t0
    written.append(cres.path)

    log("rendering: emulated colour camera, focal sweep, spectra ...")
    t0 = time.perf_counter()
    rendered = _demo_render(lf, cube, wl, out)
    timings["rendering"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    written += [rendered["completed"], rendered["truth"], rendered["sweep"], rendered["spectrum"]]

    scores = dict(depth_rmse=sc.rmse, depth_mse_x100=sc.mse_x100,
                  depth_badpix_007=sc.badpix_007, depth_bad_0_5=sc.bad_0_5,
                  cube_psnr=cube_psnr, cube_sam=cube_sam, srgb_psnr=rendered["srgb_psnr"],
                  completed_pct=cres.stats["completed_pct"])
    rep = _demo_report(out, lf, metric, sc, cres, scores, timings, pics, disp_pics, rendered)
    log(f"depth RMSE {sc.rmse:.3f} px; cube PSNR {cube_psnr:.1f} dB, "
        f"SAM {cube_sam:.2f} deg; emulated sRGB {rendered['srgb_psnr']:.1f} dB")
    log(f"done in {timings['total']:.1f} s; the report: {rep.name} in the output folder")
    written.append(rep)
    return DemoResult(out_dir=out, report=rep, written=written, scores=scores, timings=timings)


# ----------------------------------------------------------------------------- real arrays
def run_calibration(shots: str | os.PathLike, out_dir: str | os.PathLike, *, pattern: str,
                    grid: tuple[int, int], board: tuple[int, int], square: float = 1.0,
                    mode: str = "auto", reference: tuple[int, int] | None = None,
                    focal_px: float | None = None, log: Callable[[str], None] | None = None):
    """Calibrate a camera array from board shots; write the calibration file and pictures.

    Reads one set of camera images per pose (:func:`hyperlf.calibration.raw.read_poses`),
    calibrates (:func:`hyperlf.calibration.calibrate`: plane registration with one pose, full
    calibration with three or more) and writes ``calibration.toml``, ``corners.png`` (detected
    corners per camera), ``registered.png`` (the board shots registered, side by side) and
    ``residuals.png`` (corner residual vectors).

    Parameters
    ----------
    shots : path-like
        Folder of board shots (one pose), or of one subfolder per pose.
    out_dir : path-like
        Output folder.
    pattern : str
        Camera file names, with ``{index}`` or ``{row}``/``{col}``.
    grid : (int, int)
        Rows and columns of cameras.
    board : (int, int)
        Inner corners of the checkerboard, ``(cols, rows)``.
    square : float
        Side of a square (any unit; metric outputs come out in it).
    mode : {"auto", "plane", "full"}
    reference : (int, int), optional
        Reference camera (default: the centre).
    focal_px : float, optional
        Known focal length in px (plane mode; default: estimated from the board pose).
    log : callable, optional
        Called with one line per stage.

    Returns
    -------
    (Calibration, list of Path)
        The calibration and every file written.
    """
    from . import calibration as cal_mod
    from .calibration.grid import grid_keys
    from .calibration.raw import pose_folders, read_poses
    from .errors import InvalidInputError

    log = _log_or_quiet(log)
    _check_run_paths(shots=shots, out_dir=out_dir, pattern=pattern)
    out = Path(out_dir)
    grid = _opt.int_pair(grid, "grid", what="(rows, cols)")
    grid_keys(*grid)  # at most MAX_CAMERAS
    spec = cal_mod.BoardSpec(*_opt.int_pair(board, "board", what="(cols, rows) of inner "
                                            "corners"), square)  # options first
    _opt.choice(mode, "mode", ("auto", "plane", "full"))
    if reference is not None:
        reference = _opt.int_pair(reference, "reference", None, what="(row, col)")
        if not (0 <= reference[0] < grid[0] and 0 <= reference[1] < grid[1]):
            raise InvalidInputError(f"--reference {reference[0]},{reference[1]} is outside the "
                                    f"{grid[0]} x {grid[1]} grid (rows and columns count from "
                                    "0)")
    if focal_px is not None:
        _opt.number(focal_px, "focal_px", positive=True)
    per = read_poses(shots, pattern, grid)  # a wrong pattern: refused here
    _say_beyond_grid(pose_folders(shots, pattern, grid)[0], pattern, grid, log)
    n = len(next(iter(per.values())))
    log(f"{len(per)} cameras, {n} pose(s): calibrating ...")
    names = {k: f"{k[0]},{k[1]}" for k in per}
    opts = {"focal_px": focal_px} if focal_px is not None else {}
    cal = cal_mod.calibrate(per, spec, mode=mode, reference=reference, names=names, **opts)
    written = [cal_mod.write_calibration(cal, out / "calibration.toml")]
    first = {k: v[0] for k, v in per.items()}
    written.append(cal_mod.save_corner_pictures(out / "corners.png", first, cal.corners,
                                                names=names))
    views, valid = cal_mod.apply_calibration(cal, first)
    written.append(cal_mod.save_registration_picture(out / "registered.png", views, valid,
                                                     names=names))
    written.append(cal_mod.save_residual_picture(out / "residuals.png", cal))
    return cal, written


def _camera_frames(spec, grid, what: str, bits: int | None, dead=()):
    """A dark frame or flat field: one image for all cameras, or a pattern with ``{index}`` /
    ``{row}``/``{col}`` giving one per camera but the ``dead`` (``None`` stays None), on the
    raw images' scale (``bits``, :class:`hyperlf.calibration.raw.RawScale`)."""
    if spec is None:
        return None
    from .calibration.raw import camera_files, read_camera_images, read_raw_image

    if "{" in str(spec):
        p = Path(spec)
        return read_camera_images(camera_files(p.parent, p.name, grid, skip=dead), where=what,
                                  bits=bits)
    return read_raw_image(spec, bits=bits)


def _say_beyond_grid(folder, pattern: str, grid, log) -> None:
    """Log a file for a camera outside the grid (only the grid's cameras are read)."""
    from .calibration.raw import beyond_grid

    extra = beyond_grid(folder, pattern, grid)
    if extra is not None:
        log(f"note: {extra.name} is there too, outside the {grid[0]} x {grid[1]} grid; only "
            "the grid's cameras are read (check --grid)")


#: Filter wavelengths (nm) ``ingest`` accepts: ultraviolet to thermal infrared.
WAVELENGTH_RANGE_NM = (200.0, 20000.0)


def _wavelength_table(spec, grid) -> np.ndarray | None:
    """Filter wavelengths (nm) in raster order: numbers, a comma list, or a text/CSV file of
    numbers (separated by commas, spaces or lines; one header line is skipped)."""
    if spec is None:
        return None
    from .errors import InvalidInputError

    n = grid[0] * grid[1]
    wl = (_wavelength_text(spec, n) if isinstance(spec, (str, os.PathLike))
          else _opt.real_array(spec, "wavelengths").ravel())
    lo, hi = WAVELENGTH_RANGE_NM
    if wl.size != n:
        raise InvalidInputError(f"--wavelengths: need {n} numbers (one per camera, raster "
                                f"order), got {wl.size}")
    if not (np.isfinite(wl).all() and (wl >= lo).all() and (wl <= hi).all()):
        um = " (micrometres? give nm, e.g. 450)" if np.nanmax(np.abs(wl)) < 20 else ""
        raise InvalidInputError(f"--wavelengths: every value must be a wavelength in nm "
                                f"between {lo:g} and {hi:g}{um}")
    return wl.reshape(grid)


def _wavelength_text(spec, n: int) -> np.ndarray:
    """The numbers of a comma list, or of a text/CSV file of them (``n`` expected)."""
    from .errors import DataNotFoundError, InvalidInputError

    text = str(spec)
    if _is_file(spec):
        text = Path(spec).read_text(encoding="utf-8", errors="replace")
        lines = text.splitlines()
        if lines and _numbers(lines[0]) is None:
            text = "\n".join(lines[1:])
    elif _numbers(text) is None and ("/" in text or Path(text).suffix):
        raise DataNotFoundError(f"--wavelengths: {spec} is not a file; check the path")
    wl = _numbers(text)
    if wl is None:
        raise InvalidInputError(f"--wavelengths {spec!r}: give {n} numbers in nm (raster "
                                "order), separated by commas, or a file of them")
    return wl


def _is_file(spec) -> bool:
    try:
        return Path(spec).is_file()
    except (OSError, ValueError):   # a name too long for the file system, a NUL
        return False


def _numbers(text: str) -> np.ndarray | None:
    """The numbers of ``text`` (separated by commas or white space), or None if any is not."""
    try:
        return np.array([float(v) for v in text.replace(",", " ").split()], dtype=np.float64)
    except ValueError:
        return None


def run_ingest(raw: str | os.PathLike, out_dir: str | os.PathLike, *, calibration,
               pattern: str, wavelengths=None, dark=None, flat=None, dead=(),
               saturation: float | None = 0.98, raw_bits: int | None = None,
               disparity_range=None, log: Callable[[str], None] | None = None):
    """Raw images of a calibrated array -> a capture folder with validity masks and pictures.

    Reads one image per camera (``pattern`` in ``raw``), applies dark frame, flat field and the
    calibration (:func:`hyperlf.calibration.ingest.ingest`) and writes the capture (views,
    ``valid`` masks, positions, the geometry for metric depth) with ``preview/views.png`` and
    ``preview/registered.png`` (registered views with their invalid pixels tinted).

    Parameters
    ----------
    raw : path-like
        Folder of the raw images.
    out_dir : path-like
        The capture folder to write.
    calibration : path-like
        ``calibration.toml`` from ``hyperlf calibrate`` (or its folder).
    pattern : str
        Camera file names, with ``{index}`` or ``{row}``/``{col}``.
    wavelengths : str, optional
        Filter wavelengths in nm, raster order: comma-separated or a file.
    dark, flat : path-like, optional
        One image for all cameras, or a pattern path (``darks/Cam-{index}.png``).
    dead : sequence of (int, int)
        Cameras to leave out (their views are entirely invalid; their files are not read and
        may be missing).
    saturation : float or None
        Raw level in [0, 1] of the sensor's full scale at or above which a pixel is invalid.
    raw_bits : int, optional
        The sensor's bits (full scale ``2**raw_bits - 1``); default: detected from the
        largest raw value (:func:`hyperlf.calibration.raw.sensor_bits`), and said in the log
        when it is below the files' own.
    disparity_range : (float, float), optional
        Default: the calibration's estimate, else measured on the images
        (:func:`hyperlf.calibration.ingest`).
    log : callable, optional

    Returns
    -------
    (LightField, list of Path)
    """
    from .calibration import read_calibration, save_registration_picture
    from .calibration.ingest import check_dead, ingest
    from .calibration.raw import camera_files, read_camera_images
    from .errors import DataNotFoundError
    from .formats import save_lightfield

    log = _log_or_quiet(log)
    _check_run_paths(raw=raw, out_dir=out_dir, calibration=calibration, pattern=pattern)
    for name, frame in (("dark", dark), ("flat", flat)):
        if frame is not None:
            _opt.path_like(frame, name, folder=None)
    if saturation is not None:
        _opt.number(saturation, "saturation", at_most=1)
    if raw_bits is not None:
        _opt.integer(raw_bits, "raw_bits", 1, maximum=32)
    cal_path = Path(calibration)
    cal = read_calibration(cal_path / "calibration.toml" if cal_path.is_dir() else cal_path)
    wl = _wavelength_table(wavelengths, cal.grid)  # the options first: no images read yet
    dead = check_dead(cal, dead)
    for frame, what in ((dark, "--dark"), (flat, "--flat")):
        if frame is not None and "{" not in str(frame) and not Path(frame).is_file():
            raise DataNotFoundError(f"{what} {frame} is not a file; check the path")
    files = camera_files(raw, pattern, cal.grid, skip=dead)  # a wrong pattern: refused here
    _say_beyond_grid(raw, pattern, cal.grid, log)
    images, scale = read_camera_images(files, where=str(raw), bits=raw_bits, return_scale=True)
    if raw_bits is None and scale.bits is not None and scale.bits < scale.file_bits:
        log(f"the raw images' values fit in {scale.bits} of their files' {scale.file_bits} "
            f"bits: {scale.bits}-bit data, full scale {2 ** scale.bits - 1} (--raw-bits to "
            "say otherwise)")
    log(f"{len(images)} raw images -> {cal.mode}-{'registered' if cal.mode == 'plane' else 'rectified'} views ...")
    lf = ingest(images, cal, wavelengths=wl,
                dark=_camera_frames(dark, cal.grid, "dark frames", scale.bits, dead),
                flat=_camera_frames(flat, cal.grid, "flat fields", scale.bits, dead), dead=dead,
                saturation=saturation, disparity_range=disparity_range)
    out = Path(out_dir)
    written = [save_lightfield(lf, out)]
    written += write_lightfield_pictures(lf, out / "preview")
    written.append(save_registration_picture(out / "preview" / "registered.png", lf.views,
                                             lf.valid))
    return lf, written


def save_metric_outputs(out: str | os.PathLike, disparity: np.ndarray, lf, *,
                        confidence: np.ndarray | None = None,
                        min_confidence: float = 0.0) -> list[Path]:
    """Depth in the calibration's unit and a coloured point cloud, for a capture that carries
    its geometry (``lf.metadata["calibration"]``, written by ``hyperlf ingest``).

    Writes ``depth.pfm`` (exact), ``depth.png`` (colour-mapped) and ``points.ply`` (reference
    pixels with a finite depth, coloured by the reference view). Nothing without geometry.

    Parameters
    ----------
    out : path-like
        The result folder.
    disparity : ndarray, shape (H, W)
        The reference view's disparity, px per baseline.
    lf : LightField
        The capture the disparity was estimated from (its geometry, validity and reference).
    confidence : ndarray, shape (H, W), optional
        The estimate's confidence in [0, 1]; stored per vertex as the PLY property
        ``confidence``.
    min_confidence : float
        Pixels whose confidence is below it are left out of the metric outputs (NaN in
        ``depth.pfm``, no vertex in ``points.ply``): e.g. the textureless pixels whose depth
        the regulariser filled in from their surroundings (confidence 0). 0 keeps every pixel.

    Returns
    -------
    list of Path

    Examples
    --------
    A light field without a calibration's geometry (a synthetic one) gets nothing:

    >>> import tempfile
    >>> from hyperlf import synthesis
    >>> lf = synthesis.procedural_scene(seed=0, rows=2, cols=2, height=16, width=20)
    >>> save_metric_outputs(tempfile.mkdtemp(), np.zeros((16, 20)), lf)
    []
    """
    from . import visualise
    from .calibration.metric import depth_from_disparity, point_cloud
    from .errors import InvalidInputError
    from .formats import write_pfm
    from .formats.ply import write_ply

    out = Path(_opt.path_like(out, "out", folder=True))
    shape = _light_field(lf).image_shape
    _map(disparity, "disparity", shape)
    _map(confidence, "confidence", shape, optional=True)
    min_confidence = _opt.share(min_confidence, "min_confidence")
    geo = lf.metadata.get("calibration")
    if not isinstance(geo, dict) or "camera_matrix" not in geo \
            or geo.get("focal_determined") is False:
        return []
    if min_confidence > 0 and confidence is None:
        raise InvalidInputError("min_confidence needs the estimate's confidence map")
    Z = depth_from_disparity(disparity, geo)
    keep = np.ones(Z.shape, bool) if lf.valid is None else lf.valid[lf.reference]
    if min_confidence > 0:
        keep = keep & (confidence >= min_confidence)
    Z = np.where(keep, Z, np.nan).astype(np.float32)
    ref = lf.reference_view
    lo, hi = np.percentile(ref, [1, 99.5])
    colours = np.clip((ref - lo) / max(hi - lo, 1e-9), 0, 1)
    pts, rgb = point_cloud(Z, geo, colours)  # the pixels of finite Z, in row-major order
    scalars = None if confidence is None else {"confidence": confidence[np.isfinite(Z)]}
    unit = geo.get("unit", "board square units")
    return [write_pfm(out / "depth.pfm", Z),
            visualise.save_disparity_png(out / "depth.png", Z, title=f"depth ({unit})",
                                         label=unit, cmap="viridis"),
            write_ply(out / "points.ply", pts, rgb, scalars=scalars,  # a PLY header is ASCII
                      comment=f"unit: {ascii(unit)[1:-1]}; the reference camera's frame: x "
                              "right, y down, z forward (viewers with y up show it upside down)")]
