"""The ``hyperlf`` command-line tool.

Exit codes: 0 success; 1 a hyperlf error without a more specific class; 2 bad usage or
impossible input; 3 an unreadable or malformed file; 4 a missing file or dataset; 130 interrupted;
141 output pipe closed early (as git and other peers do).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import inspect
import os
import sys
import textwrap
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from . import __version__, tiling
from .errors import DataNotFoundError, HyperLFError, InvalidInputError, Terminated

__all__ = ["main", "build_parser"]

EXAMPLES = """\
examples:
  hyperlf demo                                 # synthetic H-LF -> pictures in ./hyperlf-demo
  hyperlf synth procedural --seed 3 -o scene3  # procedural 5 x 6 capture with ground truth
  hyperlf synth hci $HYPERLF_DATA/hci4d/antinous -o antinous-hlf
  hyperlf info antinous-hlf                    # grid, bands, sizes, disparity range
  hyperlf convert antinous-hlf -o antinous.h5  # capture folder -> HDF5 light field
  hyperlf convert gt_disp_lowres.pfm -o gt.png # PFM -> 16-bit PNG (+ colour-mapped preview)

Inputs may be a capture folder (capture.toml + one image per view), an HDF5 light field
(.h5) or an HCI 4D light field scene folder. Run 'hyperlf COMMAND --help' for details.

Outputs appear whole at the end of a run (an interrupted or failed run leaves the output as it
was); an existing output is replaced only with --overwrite, and a folder only when it holds
nothing but results hyperlf wrote. Exit status: 0 done, 1 other error, 2 bad usage or input,
3 unreadable file, 4 missing file, 130 interrupted, 143 terminated, 129 hung up.
"""


# --------------------------------------------------------------------------- helpers
def _pair_of_floats(text: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected two numbers separated by a comma, like -1.5,2.5; got {text!r}"
        ) from None
    if not (np.isfinite(a) and np.isfinite(b)):
        raise argparse.ArgumentTypeError(f"expected two finite numbers; got {text!r}")
    return a, b


def _pair_of_ints(text: str) -> tuple[int, int]:
    try:
        a, b = (int(v) for v in text.lower().replace("x", ",").split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected two integers like 5,6 or 5x6; got {text!r}"
        ) from None
    if a < 1 or b < 1:
        raise argparse.ArgumentTypeError(f"both numbers must be at least 1; got {text!r}")
    return a, b


def _sweep_arg(text: str) -> tuple[float, float, int]:
    try:
        lo, hi, n = text.split(",")
        lo, hi, n = float(lo), float(hi), int(n)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected MIN,MAX,N like -2,2,17 (N an integer); got {text!r}") from None
    if n < 2 or not (np.isfinite(lo) and np.isfinite(hi)) or lo >= hi:
        raise argparse.ArgumentTypeError(f"need MIN < MAX and N >= 2; got {text!r}")
    return lo, hi, n


def _channel_arg(text: str):
    try:
        parts = [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a channel like 0 or a pair like 0,2; got {text!r}") from None
    if len(parts) not in (1, 2) or min(parts) < 0:
        raise argparse.ArgumentTypeError(f"expected one or two channel indices >= 0; got {text!r}")
    return parts[0] if len(parts) == 1 else tuple(parts)


def _view_index(text: str) -> tuple[int, int]:
    try:
        a, b = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected row,col like 2,2; got {text!r}") from None
    if a < 0 or b < 0:
        raise argparse.ArgumentTypeError(f"row and column are 0-based and >= 0; got {text!r}")
    return a, b


def _finite_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def _int_at_least(low: int, what: str, high: int | None = None, why: str = ""):
    """An argparse type: an integer >= ``low`` (and <= ``high``, ``why`` saying why), ``what``
    naming it in the message."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if v < low:
            raise argparse.ArgumentTypeError(f"{what} must be at least {low}, got {v}")
        if high is not None and v > high:
            raise argparse.ArgumentTypeError(f"{what} must be at most {high}, got {v}{why}")
        return v
    return parse


_labels_arg = _int_at_least(2, "the number of disparity labels")
_seed_arg = _int_at_least(0, "the seed")


def _memory_arg(text: str) -> int:
    from .tiling import parse_memory

    try:
        return parse_memory(text)
    except InvalidInputError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


#: ``--visibility-rounds``: each round costs one more correspondence pass.
_visibility_rounds_arg = _int_at_least(0, "the number of visibility rounds", 5,
                                       " (each round costs a correspondence pass)")
#: ``--margin-labels``: labels beyond each end of the range (``hlf.MAX_MARGIN_LABELS``).
_margin_labels_arg = _int_at_least(0, "--margin-labels", 64, "")
#: ``--coarse-prior-levels``: each level halves the image again (and must keep 8 texture windows).
_coarse_levels_arg = _int_at_least(1, "--coarse-prior-levels", 8,
                                   " (each level halves the image again)")
#: ``--workers`` of a local cluster: more on one machine only thrash.
_workers_arg = _int_at_least(1, "the number of workers", 256,
                             "; use --scheduler for a larger cluster")


def _median_passes_arg(text: str) -> int | str:
    """``--median-passes``: ``auto`` or a number of passes in [1, 20]."""
    if text.strip().lower() == "auto":
        return "auto"
    return _int_at_least(1, "--median-passes", 20, " (or 'auto')")(text)


#: ``--downscale``: block side of the quick look (whether the image stays large enough is
#: checked against the input, :func:`_downscaled`).
_downscale_arg = _int_at_least(1, "--downscale", 64)

#: ``--raw-bits``: a sensor's sample depth inside 8/16-bit files.
_raw_bits_arg = _int_at_least(1, "--raw-bits", 16, " (raw images are 8 or 16-bit files)")

#: ``--aggregation-radius``: the guided filter's box half-size, px.
_aggregation_radius_arg = _int_at_least(1, "--aggregation-radius", 64)


def _range_arg(text: str) -> tuple[float, float]:
    """``--disparity-range MIN,MAX``: two finite numbers, MIN < MAX."""
    lo, hi = _pair_of_floats(text)
    if not lo < hi:
        raise argparse.ArgumentTypeError(f"MIN must be below MAX, got {text!r}")
    return lo, hi


def _fusion_weights_arg(text: str) -> tuple[float, ...]:
    """``--fusion-weights W1,W2[,...]``: finite numbers >= 0, not all 0, with a finite sum
    (whether their count fits the cost is checked with ``--metric``,
    :func:`hyperlf.costs.fusion_weights`)."""
    from .costs.pair import weights_tuple

    try:
        w = weights_tuple([float(v) for v in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas, like 1,4; got {text!r}") from None
    if w is None:
        raise argparse.ArgumentTypeError(
            f"expected finite numbers >= 0, not all 0, with a finite sum, like 1,4; got "
            f"{text!r}")
    return w


def _check_fusion_weights(args) -> None:
    """Refuse ``--fusion-weights`` that do not fit ``--metric``, before any work."""
    if args.fusion_weights is not None:
        from .costs import fusion_weights

        try:
            fusion_weights(args.metric, args.fusion_weights)
        except InvalidInputError as e:
            raise InvalidInputError(f"--fusion-weights: {e}") from None


def _join_weights(weights) -> str | None:
    """``--fusion-weights`` as a depth command line writes it (None stays None)."""
    return None if weights is None else ",".join(f"{w:g}" for w in weights)


def _add_fusion_weights_option(p: argparse.ArgumentParser, *, brief: bool = False) -> None:
    """``--fusion-weights`` of depth and batch (``DepthParams.fusion_weights``)."""
    p.add_argument("--fusion-weights", type=_fusion_weights_arg, default=None, metavar="W,W",
                   help="as for depth" if brief else
                   "weights of the parts of a fused --metric, in its order (auto = "
                   "census-rsncc: rsncc,census; default 1,1). E.g. 1,4 leans on census, "
                   "which held up better on a strongly coloured scene and worse on the "
                   "procedural test scenes (BENCHMARKS.md)")


def _float_within(low: float, high: float, what: str, *, above_low: bool = False,
                  below_high: bool = False):
    """An argparse type: a finite number in ``[low, high]`` (the bound left out with
    ``above_low`` / ``below_high``)."""
    def parse(text: str) -> float:
        v = _finite_float(text)
        if v < low or v > high or (above_low and v == low) or (below_high and v == high):
            interval = (f"{'(' if above_low else '['}{low:g}, {high:g}"
                        f"{')' if below_high else ']'}")
            raise argparse.ArgumentTypeError(f"{what} must be in {interval}, got {text!r}")
        return v
    return parse


_aggregation_eps_arg = _float_within(0.0, 100.0, "--aggregation-eps", above_low=True)


def _add_aggregation_options(p: argparse.ArgumentParser) -> None:
    """``--aggregation`` and its constants (:mod:`hyperlf.costs.aggregation`)."""
    from .costs import AGGREGATION_METHODS, AggregationParams

    d = AggregationParams()
    p.add_argument("--aggregation", default=d.method, choices=tuple(AGGREGATION_METHODS),
                   help="edge-aware aggregation of the cost volume before the optimiser: none "
                        "(default: the cost's own window) or guided (every disparity slice "
                        "smoothed by a guided filter of the reference image, Hosni et al.; "
                        "measured worse on the benchmark scenes, see BENCHMARKS.md)")
    p.add_argument("--aggregation-radius", type=_aggregation_radius_arg, default=d.radius,
                   metavar="PX", help=f"half-size of the guided filter's box (default {d.radius})")
    p.add_argument("--aggregation-eps", type=_aggregation_eps_arg, default=d.eps, metavar="E",
                   help="the guided filter's regulariser, in squared units of the image scaled "
                        f"to its 99th percentile: larger smooths across weaker edges "
                        f"(default {d.eps:g})")


def _aggregation_of(args):
    from .costs import AggregationParams

    return AggregationParams(args.aggregation, args.aggregation_radius, args.aggregation_eps)


def _texture_snr_arg(text: str) -> float:
    """``--texture-snr``: 0 (off) or a number in (1, 1e6]."""
    v = _float_within(0.0, 1e6, "--texture-snr")(text)
    if 0 < v <= 1:
        raise argparse.ArgumentTypeError(f"--texture-snr must be 0 (off) or > 1, got {text!r}")
    return v


#: ``--min-confidence``: a confidence in [0, 1].
_min_confidence_arg = _float_within(0.0, 1.0, "--min-confidence")
#: ``--confidence-edge-px``: 0 (no edge factor) up to a width no image needs.
_confidence_edge_px_arg = _float_within(0.0, 1000.0, "--confidence-edge-px")
#: ``--confidence-floor``: below 1, which would leave no room for the cost margin.
_confidence_floor_arg = _float_within(0.0, 1.0, "--confidence-floor", below_high=True)


def _add_confidence_options(p: argparse.ArgumentParser, *, floor: float, edge_px: float,
                            brief: bool = False) -> None:
    """``--confidence-floor`` and ``--confidence-edge-px``: what the confidence map gives an
    ambiguous pixel and how far from a depth edge it is discounted (default None: the
    library's; ``floor`` and ``edge_px`` are the command's, for the help)."""
    p.add_argument("--confidence-floor", type=_confidence_floor_arg, default=None,
                   metavar="F",
                   help="as for depth" if brief else
                   "the confidence of a pixel whose own costs left its depth ambiguous, "
                   "the regulariser having chosen; a unique cost minimum rises from F to 1 "
                   f"(in [0, 1), default {floor:g}; 0 gives the cost margin alone, so that "
                   "ambiguous pixels rank with the filled-in ones)")
    p.add_argument("--confidence-edge-px", type=_confidence_edge_px_arg, default=None,
                   metavar="PX",
                   help="as for depth" if brief else
                   f"scale the confidence down within PX px of the map's depth edges, from 0 "
                   f"on the edge to full at PX px, since the depth error gathers there "
                   f"(default {edge_px:g}; 0: no edge factor)")


def _stage_times(timings: dict) -> str:
    """``"prepare 0.2 s, correspondence 4.8 s, mrf round2 1.6 s"``: a result's timings (keys
    such as ``mrf_s_round2``) as a reader would name them, without the overall total."""
    return ", ".join(f"{k.replace('_s_', '_').removesuffix('_s').replace('_', ' ')} {v:.1f} s"
                     for k, v in timings.items() if k not in ("total", "total_s"))


def _say(args, msg: str) -> None:
    if not getattr(args, "quiet", False):
        print(_one_line(msg), file=sys.stderr)


def _one_line(text: str) -> str:
    """``text`` with control characters (a newline in a file name) shown escaped."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _bars(args) -> bool:
    """Progress bars: on a terminal unless --quiet; never into a log file or a pipe, where
    their carriage returns would pile up (the stage messages still say what happens)."""
    return not args.quiet and sys.stderr.isatty()


def _report(args, written, dest) -> None:
    """After the result set is in place: list the files written (stderr, under their final
    names) and print the output location (stdout)."""
    kind, targets = _targets(args)
    roots = [dest] if kind == "folder" else list(dest)
    for w in written or []:
        for root, final in zip(roots, targets):
            with contextlib.suppress(ValueError):
                rel = Path(w).relative_to(root)
                _say(args, f"wrote {final / rel if rel.parts else final}")
                break
    print(args.output)


# --------------------------------------------------------------------------- checks
class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr (exit 2)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {_one_line(message)}; see '{self.prog} --help'\n")


def _check_input_file(path, what: str) -> Path:
    """``path`` as a Path; a folder is refused (exit 2), a missing file too (exit 4)."""
    p = Path(path)
    if p.is_dir():
        raise InvalidInputError(f"{what} {p} is a folder; give a file")
    if not p.exists():
        raise DataNotFoundError(f"{what} {p} does not exist; check the path")
    return p


def _check_output(path, kind: str) -> None:
    """Refuse, before any work, an output ``path`` (a ``"folder"`` or a ``"file"``) that cannot
    be written: a file where a folder is expected or the reverse, a name over 255 bytes, a
    missing folder that cannot be created, a folder that is not writable."""
    p = Path(path)
    long = [part for part in p.parts if len(os.fsencode(part)) > 255]
    if long:
        raise InvalidInputError(f"-o: the name {long[0][:40]}... is too long (at most 255 bytes "
                                "per file or folder name); choose a shorter one")
    if kind == "folder" and p.exists() and not p.is_dir():
        raise InvalidInputError(f"-o {p} is an existing file but this command writes a folder; "
                                "give a folder name")
    if kind == "file" and p.is_dir():
        raise InvalidInputError(f"-o {p} is an existing folder but this command writes a file; "
                                f"give a file name such as {p / 'out'}{p.suffix or '.png'}")
    target = Path(os.path.abspath(p if kind == "folder" else p.parent))
    existing = next(a for a in (target, *target.parents) if a.exists())
    if not existing.is_dir():
        raise InvalidInputError(f"cannot create -o {p}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InvalidInputError(f"cannot write -o {p}: the folder {existing} is not writable; "
                                "choose another output location")


_FIGURE_SUFFIXES = (".png", ".pdf", ".svg")
_FILE_OUTPUTS = {".h5", ".hdf5", ".pfm", ".png", ".tif", ".tiff", ".hdr", ".img"}


def _output_kind(args) -> str | None:
    """What ``-o`` names for this command: ``"folder"``, ``"file"`` or None (no output)."""
    if getattr(args, "output", None) is None:
        return None
    if args.command == "spectrum":
        return "file"
    if args.command == "batch":
        return None  # a folder of result sets, one per capture (hyperlf.batch)
    if args.command in ("synth", "convert"):
        return "file" if Path(args.output).suffix.lower() in _FILE_OUTPUTS else "folder"
    return "folder"


def _writes_lightfield(args) -> bool:
    """Whether the command writes a light field with ``save_lightfield`` (capture or .h5)."""
    if args.command == "synth":
        return True
    if args.command != "convert":
        return False
    single = _FILE_OUTPUTS - {".h5", ".hdf5"}
    return not ({Path(args.input).suffix.lower(), Path(args.output).suffix.lower()} & single)


def _file_outputs(args) -> list[Path]:
    """Every file a single-file command would write (its sidecars included)."""
    out = Path(args.output)
    if args.command == "spectrum":
        return [out, out.with_suffix(".csv")]
    if _writes_lightfield(args):  # a .h5 light field, and synth's pictures folder beside it
        pics = args.command == "synth" and not args.no_pictures
        return [out, out.with_suffix("")] if pics else [out]
    suffix = out.suffix.lower()
    if suffix in (".hdr", ".img"):
        return [out.with_suffix(".hdr"), out.with_suffix(".img")]
    if suffix in (".png", ".tif", ".tiff"):  # convert's image: its value mapping, a preview
        return [out, out.with_suffix(".txt"), out.with_name(out.stem + "_colour.png")]
    return [out]


def _targets(args) -> tuple[str, list[Path]] | tuple[None, list]:
    """The command's result set: ``("folder", [OUT])``, ``("files", [paths])`` or no output."""
    kind = _output_kind(args)
    if kind is None:
        return None, []
    if kind == "folder":
        return "folder", [Path(args.output)]
    return "files", _file_outputs(args)


def _check_overwrite(args) -> None:
    """The same rule for every output kind (:func:`hyperlf.outputs.check_replaceable`): what
    exists is replaced only with --overwrite, a folder only when it holds nothing but a previous
    result set, a symlink never."""
    from .outputs import check_replaceable

    for target in _targets(args)[1]:
        check_replaceable(target, overwrite=args.overwrite)


@contextlib.contextmanager
def _result(args):
    """The staging area of the command's result set (None without output); moved into place
    when the block ends normally, removed when it raises."""
    from .outputs import result_files, result_folder

    kind, targets = _targets(args)
    if kind is None:
        yield None
        return
    opts = dict(overwrite=args.overwrite, command=args.command, argv=getattr(args, "argv", None))
    args.provenance = {}  # filled by the command (_record_input), read when the set is published
    with (result_folder(targets[0], provenance=args.provenance, **opts) if kind == "folder"
          else result_files(targets, **opts)) as dest:
        yield dest


def _record_input(args, lf) -> None:
    """Put what the result is made from in its manifest: the input's path and signature
    (:func:`hyperlf.lightfield.capture_signature`), which ``complete --disparity`` checks."""
    from .lightfield import capture_signature

    if getattr(args, "provenance", None) is not None:
        args.provenance["input"] = {"path": os.path.abspath(args.input),
                                    **capture_signature(lf)}


def _check_disparity_source(args, lf) -> None:
    """Refuse a ``--disparity`` map that a depth result set records as made from another
    capture (a map copied out of its folder is taken as it is)."""
    from .lightfield import capture_signature, signature_mismatch
    from .outputs import read_manifest

    path = Path(args.disparity)
    man = read_manifest(path.parent)
    if man is None or man["input"] is None or path.name not in man["files"]:
        return
    why = signature_mismatch(man["input"], capture_signature(lf))
    if why is not None:
        made_from = man["input"].get("path", "another capture")
        raise InvalidInputError(
            f"--disparity {args.disparity} was computed from {made_from}, not from "
            f"{args.input}: {why}; run 'hyperlf depth {args.input}' first (or copy the map "
            "out of its result folder to use it anyway)")


def _check_views_memory(grid, size) -> None:
    """A synthetic capture: R x C views of H x W px, each with the R*C-band float32 cube."""
    (R, C), (H, W) = grid, size
    tiling.check_memory(4 * (R * C) ** 2 * H * W,   # ints: a count beyond a float is refused
                  f"{R} x {C} views of {W} x {H} px with {R * C} bands",
                  "reduce --size or --grid")


def _check_labels_memory(labels: int, shape) -> None:
    """Depth: a few float32 cost volumes of ``labels`` x H x W (a lower bound)."""
    H, W = shape
    tiling.check_memory(16 * labels * H * W, f"--labels {labels} on {W} x {H} px views",
                  "use fewer --labels")


#: Bytes per pixel and disparity that two-view stereo holds at least: the left and right cost
#: volumes (float32, the data terms made in them) and what the optimiser adds (every cost and
#: optimiser measured 19-233, BENCHMARKS.md "Two-view stereo's memory").
PAIR_BYTES_AT_LEAST = 16.0


def _check_pair_memory(disparity_range, shape) -> None:
    """Stereo: refuse a pair and range whose cost volumes alone exceed the available memory."""
    (lo, hi), (H, W) = disparity_range, shape
    tiling.check_memory(PAIR_BYTES_AT_LEAST * (hi - lo + 1) * H * W,
                  f"--disparity-range {lo},{hi} on {W} x {H} px images",
                  "narrow the range, or match the pair downscaled (half the size and half the "
                  "range need an eighth)")


#: Bytes per pixel and frame a focal sweep holds: every frame is kept until the animations
#: are written. Measured 63 (peak RSS of a 2000-frame sweep of 64 x 80 px views less that of
#: a 10-frame one); the figure leaves a margin.
SWEEP_BYTES_AT_LEAST = 72.0


def _check_sweep_memory(n_frames: int, shape) -> None:
    """Refocus: refuse a sweep whose frames alone exceed the available memory."""
    H, W = shape
    tiling.check_memory(SWEEP_BYTES_AT_LEAST * n_frames * H * W,
                  f"--sweep with {n_frames} frames of {W} x {H} px", "use fewer frames (N)")


def _layout_arg(text: str):
    if text in ("raster", "serpentine", "random"):
        return text
    try:
        return [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            "layout must be raster, serpentine, random or a comma-separated band index list"
        ) from None


def _add_spectral_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("filter array")
    g.add_argument("--grid", type=_pair_of_ints, default=(5, 6), metavar="R,C",
                   help="rows and columns of views (default 5,6 as in the paper)")
    g.add_argument("--bands", type=_pair_of_floats, default=(410.0, 700.0), metavar="MIN,MAX",
                   help="filter centre wavelengths span MIN..MAX nm in equal steps "
                        "(default 410,700)")
    g.add_argument("--layout", type=_layout_arg, default="raster",
                   help="filter layout: raster (paper: view (r,c) gets band r*C+c), "
                        "serpentine, random, or a comma-separated list of band indices")
    g.add_argument("--noise", type=_float_within(0.0, 1.0, "the noise std"), default=0.0,
                   metavar="SIGMA",
                   help="Gaussian noise std on [0,1] intensities (default 0)")
    g.add_argument("--bit-depth", type=int, choices=(8, 16), default=16,
                   help="bit depth of the written view images (default 16)")


# --------------------------------------------------------------------------- commands
def _cmd_info(args, dest) -> None:
    """Print grid, bands, image size, reference view, baselines and disparity range of a light
    field; of a cube file (complete's cube.h5), its grid, bands and how much of it was
    registered or inferred; of a PFM map or PLY point cloud, its size and values; of a folder a
    hyperlf command wrote, the command and a line on each map, point cloud and cube in it.

    examples:
      hyperlf info antinous-hlf
      hyperlf info cube3/cube.h5
      hyperlf info depth3                  # a depth result: its maps and point cloud
      hyperlf info depth3/disparity.pfm
    """
    from .formats import describe

    text = describe(args.input)
    print(f"{args.input}")
    print(text)


def _cmd_synth(args, dest) -> list[Path]:
    """Make a synthetic hyperspectral light field with ground-truth disparity and cube (SPEC
    §6) and write it as a capture folder (or .h5 file).

    examples:
      hyperlf synth procedural --seed 3 -o scene3
      hyperlf synth hci $HYPERLF_DATA/hci4d/antinous -o antinous-hlf
    """
    from . import synthesis
    from .formats import save_lightfield
    from .pipeline import write_lightfield_pictures

    t0 = time.perf_counter()
    R, C = args.grid
    common = dict(rows=R, cols=C, lambda_min=args.bands[0], lambda_max=args.bands[1],
                  layout=args.layout, noise_sigma=args.noise)
    if args.seed is not None:  # a named scene keeps its own seed unless one is given
        common["seed"] = args.seed
    common["progress"] = _bars(args)
    if args.source == "hci":
        lf = synthesis.from_hci_scene(args.scene, **common)
    else:
        H, W = args.size
        kw = dict(common, height=H, width=W)
        if args.scene_name:
            kw = {**synthesis.named_scene(args.scene_name), **kw}
        _check_views_memory(args.grid, args.size)
        lf = synthesis.procedural_scene(**kw)
    out = Path(args.output)
    data = dest if isinstance(dest, Path) else dest[0]  # a capture folder, or a .h5 file
    _say(args, f"writing {out} ...")
    save_lightfield(lf, data, bit_depth=args.bit_depth, progress=_bars(args))
    if not args.no_pictures:
        write_lightfield_pictures(lf, data / "preview" if data is dest else dest[1])
    _say(args, f"made {R} x {C} views of {lf.image_shape[1]} x {lf.image_shape[0]} px "
               f"in {time.perf_counter() - t0:.1f} s")
    return [data]


#: Image files a PFM converts to and back.
_IMAGE_SUFFIXES = {".png", ".tif", ".tiff"}

#: Suffixes of single files a light field cannot be converted to (it becomes a folder or .h5).
_NOT_A_LIGHTFIELD = {".png", ".tif", ".tiff", ".pfm", ".jpg", ".jpeg", ".hdr", ".img", ".txt",
                     ".csv", ".npy", ".gif", ".mp4", ".webm", ".ply", ".toml", ".json"}


def _cmd_convert(args, dest) -> list[Path]:
    """Convert a light field between capture folder, HCI folder (read only) and HDF5 (.h5); a
    PFM to a 16-bit (or --bit-depth 8) PNG/TIFF with a colour-mapped preview and the linear
    mapping back in a .txt beside it, or such an image back to PFM (through the .txt when it
    is there, else as 0..1 of the file's full scale); one view of a cube (.h5) to ENVI
    (.hdr + .img).

    examples:
      hyperlf convert capture -o capture.h5            # capture folder -> one HDF5 file
      hyperlf convert capture.h5 -o capture-copy       # and back
      hyperlf convert $HYPERLF_DATA/hci4d/antinous -o antinous.h5   # an HCI scene (RGB views)
      hyperlf convert out/disparity.pfm -o disparity.png   # + disparity.txt, disparity_colour.png
      hyperlf convert disparity.png -o back.pfm        # the values again, through disparity.txt
      hyperlf convert cube.h5 --view 2,2 -o view.hdr   # ENVI .hdr + .img of one view's bands
    """
    from . import formats

    src = Path(args.input)
    dst = dest if isinstance(dest, Path) else dest[0]  # where this run writes args.output
    if src.suffix.lower() == ".pfm" or (src.suffix.lower() in _IMAGE_SUFFIXES and dst.suffix.lower() == ".pfm"):
        return _convert_map(args, src, dst, dest)
    if dst.suffix.lower() in (".hdr", ".img"):
        return _convert_envi(args, src, dest)
    if dst.suffix.lower() in _NOT_A_LIGHTFIELD:
        raise InvalidInputError(f"-o {args.output}: a light field converts to a capture folder "
                                f"or a .h5 file, not a {dst.suffix} file")
    lf = formats.load_lightfield(src)
    return [formats.save_lightfield(lf, dst, bit_depth=args.bit_depth)]


def _convert_map(args, src: Path, dst: Path, dest) -> list[Path]:
    """A PFM to a 16/8-bit image (+ mapping .txt + colour preview), or an image to PFM."""
    from . import formats, visualise
    from ._atomic import atomic_write_text

    _check_input_file(src, "input")
    if src.suffix.lower() != ".pfm":
        data = formats.read_image(src, as_float=True)
        mapping = _read_value_mapping(src.with_suffix(".txt"))
        if mapping is None:
            _say(args, f"no value mapping ({src.with_suffix('.txt').name}) beside {src.name}: "
                       "values are its 0..1 of full scale")
        else:
            data = formats.read_image(src, as_float=False).astype(np.float64) / mapping[0] \
                + mapping[1]
            _say(args, f"values through {src.with_suffix('.txt').name}")
        return [formats.write_pfm(dst, np.asarray(data, np.float32))]
    data = formats.read_pfm(src)
    if dst.suffix.lower() == ".pfm":
        return [formats.write_pfm(dst, data)]
    if dst.suffix.lower() not in _IMAGE_SUFFIXES:
        raise InvalidInputError(f"cannot convert {src.suffix} to {dst.suffix}; "
                                "use .pfm, .png or .tif")
    finite = data[np.isfinite(data)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    full = 2 ** args.bit_depth - 1
    scaled = (data - lo) / (hi - lo) if hi > lo else np.zeros_like(data)
    written = [formats.write_image(dst, np.nan_to_num(scaled), bit_depth=args.bit_depth)]
    per = full / (hi - lo) if hi > lo else 1.0
    written.append(atomic_write_text(dest[1], f"value = pixel / {per:.17g} + ({lo:.17g})   "
                                     f"# {args.bit_depth}-bit pixels of {dst.name}; exact "
                                     f"values in {src.name}\n"))
    _say(args, f"values {lo:g}..{hi:g} mapped linearly to 0..{full} ({dest[1].name})")
    if data.ndim == 2:
        written.append(visualise.save_disparity_png(dest[2], data, title=src.name,
                                                    label="value"))
    return written


def _read_value_mapping(path: Path) -> tuple[float, float] | None:
    """``(divisor, offset)`` of a ``NAME = pixel / D + (O)`` line hyperlf wrote beside a 16-bit
    image (``convert``'s .txt, depth's ``disparity_16bit.txt``), or None."""
    import re

    try:
        text = path.read_text(encoding="utf-8", errors="replace")[:4096]
    except OSError:
        return None
    m = re.search(r"=\s*(?:pixel|value)\s*/\s*([-+0-9.eE]+)\s*\+\s*\(([-+0-9.eEinfa]+)\)",
                  text)
    try:
        div, off = (float(m.group(1)), float(m.group(2))) if m else (np.nan, np.nan)
    except ValueError:
        return None
    return (div, off) if np.isfinite(div) and div != 0 and np.isfinite(off) else None


def _convert_envi(args, src: Path, dest) -> list[Path]:
    """One view of a cube (.h5) to ENVI .hdr + .img."""
    from . import formats
    from .lightfield import centre_view

    if src.suffix.lower() not in (".h5", ".hdf5"):
        raise InvalidInputError("ENVI export needs a cube file (.h5) as input")
    with formats.open_cube_h5(src) as cf:  # one view is read, not the whole cube
        R, C = cf.cube.shape[:2]
        r, c = args.view if args.view is not None else centre_view(R, C)
        if not (r < R and c < C):
            raise InvalidInputError(f"--view {r},{c} is outside the {R} x {C} grid of {src}")
        view, wl = np.asarray(cf.cube[r, c], np.float32), cf.wavelengths
    formats.write_envi(dest[0], view, wl)
    return list(dest)


def _cmd_demo(args, dest) -> list[Path]:
    """Run the whole chain on a small synthetic hyperspectral light field with ground truth:
    capture -> depth -> plenoptic cube -> emulated colour image -> focal sweep, and write
    report.html with every picture and figure. Needs no data.

    examples:
      hyperlf demo                                  # ./hyperlf-demo/report.html
      hyperlf demo --size 48,64 --grid 3,4 -o small-demo    # smaller and faster
    """
    from .pipeline import run_demo  # the chain itself

    _check_views_memory(args.grid, args.size)
    _check_labels_memory(args.labels, args.size)
    res = run_demo(dest, seed=args.seed, grid=args.grid, size=args.size, metric=args.metric,
                   labels=args.labels, progress=_bars(args), log=lambda msg: _say(args, msg))
    return [res.report]


# --------------------------------------------------------------------------- real arrays
def _turns_message(turns: dict, n_cameras: int) -> str:
    """The calibrate log's line on the cameras found turned (label -> degrees clockwise)."""
    parts = []
    for deg in sorted(set(turns.values())):
        how = "upside down" if deg == 180 else f"turned by {deg} degrees clockwise"
        labels = ", ".join(k for k, v in turns.items() if v == deg)
        parts.append(f"camera(s) {labels}: images {how} against the reference's")
    most = 2 * len(turns) > n_cameras - 1
    return ("; ".join(parts) + " (mounted turned); registered turned back"
            + ("; as most cameras are, the reference may be the one turned (the views are "
               "then turned too): --reference names another" if most else ""))


def _calibrate_notes(info: dict) -> list[str]:
    """What the calibrate log says about a calibration's ``info`` beyond its figures."""
    from .calibration.plane import ADVISED_TILT_DEG, SIGN_AGREEMENT_MIN

    notes = []
    sign_open = (info.get("positions_from") == "parallax"
                 and info.get("sign_agreement", 1.0) < SIGN_AGREEMENT_MIN)
    if sign_open:
        notes.append(f"the board poses barely tell which way the cameras lie (agreement "
                     f"{info['sign_agreement']:.2f} of 1), so near and far may come out "
                     f"swapped in depth; tilt the board by {ADVISED_TILT_DEG:g} degrees or "
                     "more in the shot and calibrate again")
    if info.get("focal_determined") is False:
        if info.get("positions_from") != "parallax":
            positions = ("registration is fine, but the cameras' positions, from the board "
                         "poses alone, may be off by a baseline or more (check them in "
                         "calibration.toml; a shot whose scene has texture beside the board "
                         "at other depths measures them)")
        elif sign_open:
            positions = "registration is fine"
        else:
            positions = "registration and positions are fine"
        notes.append(f"the board faces the cameras too squarely to fix the focal length; "
                     f"{positions}; for metric depth give --focal-px (focal length / pixel "
                     "pitch) or tilt the board")
    if info.get("parallax_unused"):
        notes.append(f"positions from the board poses, not from the scene's parallax "
                     f"({info['parallax_unused']}); 'hyperlf ingest' then measures the "
                     "disparity range on the scene")
    return notes


def _cmd_calibrate(args, dest) -> list[Path]:
    """Calibrate a camera array from checkerboard shots (SPEC §11). One shot per camera
    (files named by --pattern in FOLDER) registers every view onto the reference at the board
    plane, with the views' positions and shift directions measured from the parallax of the
    scene around the board (a board partly out of some views is fine: at least 3 x 3 inner
    corners, cut by the image border); one subfolder of shots per pose (three or more) runs a
    full calibration with rectification (poses a camera does not see whole are left out for
    it). The board may be held any way round, and in either mode a camera mounted turned
    against the reference (by 90, 180 or 270 degrees) is found and turned back. Writes
    calibration.toml and pictures: corners.png (detected corners per camera), registered.png
    (registered views side by side), residuals.png (corner residual vectors).

    examples:
      hyperlf calibrate lab/calibration --pattern 'Cam-{index}.png' --grid 3,3 --board 11,8 -o cal
      hyperlf calibrate poses --pattern 'cam_{row}_{col}.tif' --grid 2,4 --board 9,6 --square 25 -o cal
    """
    from .pipeline import run_calibration

    cal, written = run_calibration(args.shots, dest, pattern=args.pattern, grid=args.grid,
                                   board=args.board, square=args.square, mode=args.mode,
                                   reference=args.reference, focal_px=args.focal_px,
                                   log=lambda m: _say(args, m))
    for note in _calibrate_notes(cal.info):
        _say(args, f"note: {note}")
    turns = cal.info.get("camera_turns") or {}
    if turns:
        _say(args, _turns_message(turns, len(cal.cameras)))
    errs = cal.reprojection_errors()
    worst = max(errs, key=errs.get)
    _say(args, f"{cal.mode} calibration of {len(errs)} cameras: residual up to "
               f"{errs[worst]:.3f} px (camera {worst[0]},{worst[1]}); positions from "
               f"{cal.info.get('positions_from', 'the board poses')}")
    return written


def _cmd_ingest(args, dest) -> list[Path]:
    """Turn raw images of a calibrated array into a capture (SPEC §11): dark frame and flat
    field (optional), the calibration's registration or rectification, per-view validity masks
    (outside the camera's image, saturated, dead cameras), the views' positions from the
    calibration, and the geometry 'hyperlf depth' needs for metric depth and a point cloud.

    examples:
      hyperlf ingest lab/scene --calibration cal --pattern 'Cam-{index}.png' -o lab-capture
      hyperlf depth lab-capture -o lab-depth   # disparity, depth (board units), points.ply
    """
    from .pipeline import run_ingest

    lf, written = run_ingest(args.raw, dest, calibration=args.calibration,
                             pattern=args.pattern, wavelengths=args.wavelengths,
                             dark=args.dark, flat=args.flat, dead=args.dead or (),
                             saturation=None if args.saturation >= 1 else args.saturation,
                             raw_bits=args.raw_bits, disparity_range=args.disparity_range,
                             log=lambda m: _say(args, m))
    R, C = lf.grid_shape
    _say(args, f"{R} x {C} views of {lf.image_shape[1]} x {lf.image_shape[0]} px, "
               f"{100 * lf.valid.mean():.1f} % of pixels valid; disparity range "
               f"{lf.disparity_range}")
    return written[:1]


# --------------------------------------------------------------------------- stereo
def _read_stereo_image(path: str) -> np.ndarray:
    from .formats import read_image

    return read_image(_check_input_file(path, "image"), as_float=True)


def _cmd_stereo(args, dest) -> list[Path]:
    """Disparity of the left image of a rectified pair whose images may see different spectra
    (SPEC §4). Left x matches right x - d. Writes disparity.pfm (exact), disparity_16bit.png
    (value/256 + offset, see the .txt beside it), a colour-mapped disparity.png and the
    confidence (confidence.pfm, exact, and confidence.png; 0: the left-right check failed or on
    a depth edge, 0.1: ambiguous costs, up to 1: unique; scaled down within 8 px of the map's
    depth edges). Matching
    holds about 20-70 bytes per pixel and disparity; a pair and range that cannot fit in the
    memory available are refused before any matching.

    A Middlebury scene folder given alone (imL/imR, or <name>1/<name>5 of 2005, with their
    ground truth, as in $HYPERLF_DATA/middlebury) is matched over its own range unless
    --disparity-range says otherwise, and its map is scored against the ground truth on the
    scene's evaluation mask (bad-pixel shares on stderr, disparity_error.png), as Table 1
    scores it.

    examples:
      hyperlf stereo imL.png imR.png --disparity-range 0,59 -o out
      hyperlf stereo imL.png imR.png --channel 0,2 --metric bwncc --disparity-range 0,15 -o out   # red vs blue
      hyperlf stereo imL.png imR.png --disparity-range 0,59 --occlusion lr-fill -o out   # the paper's fill
      hyperlf stereo $HYPERLF_DATA/middlebury/art --channel 0,2 -o art   # Table 1's Art, scored
    """
    from .pipeline import save_disparity_outputs
    from .twoview import stereo

    _check_fusion_weights(args)
    left, right, pair = _stereo_inputs(args)
    lo, hi = _stereo_range(args, pair)
    _check_pair_memory((lo, hi), left.shape[:2])
    res = stereo(left, right, (lo, hi), metric=args.metric, optimizer=args.optimizer,
                 occlusion="none" if args.no_occlusion else args.occlusion,
                 subpixel=args.subpixel, aggregation=_aggregation_of(args),
                 channel=args.channel, progress=_bars(args),
                 cost_params=None if args.fusion_weights is None
                 else {"weights": args.fusion_weights},
                 confidence_params=_stereo_confidence_params(args),
                 hole_params=_stereo_hole_params(args))
    truth = None if pair is None else pair.gt_disparity
    written = save_disparity_outputs(dest, res.disparity,
                                      f"{res.metric} + {res.optimizer}", confidence=res.confidence,
                                      unit="px", truth=truth, error_vmax=STEREO_ERROR_VMAX,
                                      label="disparity (px)")
    t = res.timings
    _say(args, f"cost {t['cost']:.1f} s, optimiser {t['optimiser']:.1f} s, total {t['total']:.1f} s")
    if res.extra["holes_opened"] > 0:
        _say(args, f"holes opened: {100 * res.extra['holes_opened']:.2f} % of the pixels")
    if pair is not None:
        _say_stereo_scores(args, res.disparity, pair)
    return written


#: The error at the top of a scored pair's error picture (px): Table 1's bad5.0 threshold.
STEREO_ERROR_VMAX = 5.0


def _stereo_inputs(args):
    """``(left, right, scene)``: two images, or a Middlebury scene folder's two views and the
    scene (None for two images)."""
    from .formats import read_middlebury

    if args.right is not None:
        if Path(args.left).is_dir():
            raise InvalidInputError(f"{args.left} is a folder: give a Middlebury scene folder "
                                    "alone, or two images")
        return _read_stereo_image(args.left), _read_stereo_image(args.right), None
    if not Path(args.left).is_dir():
        raise InvalidInputError(f"give the right image after {args.left}, or a Middlebury "
                                "scene folder alone")
    pair = read_middlebury(args.left)
    return pair.left, pair.right, pair


def _stereo_range(args, pair) -> tuple[int, int]:
    """``--disparity-range`` as integers, else a scene folder's own range."""
    if args.disparity_range is None:
        if pair is None:
            raise InvalidInputError("give --disparity-range MIN,MAX (integers, px; left x "
                                    "matches right x - d)")
        return pair.search_range
    lo, hi = args.disparity_range
    if lo != int(lo) or hi != int(hi):
        raise InvalidInputError(f"--disparity-range must be integers, got {lo:g},{hi:g}")
    return int(lo), int(hi)


def _say_stereo_scores(args, disparity: np.ndarray, pair) -> None:
    """Bad-pixel shares against a scene's ground truth on its evaluation mask (``all``
    where the scene has one, else every pixel with ground truth), as Table 1 scores."""
    from .metrics import disparity_scores

    has_all = "all" in pair.masks
    mask = pair.eval_mask("all")
    if not mask.any():
        where = " in its mask 'all'" if has_all else ""
        _say(args, f"the scene has no pixel with ground truth{where}; its map is not scored")
        return
    s = disparity_scores(disparity, pair.gt_disparity, mask=mask)
    name = "all" if has_all else "every pixel with ground truth"
    _say(args, f"against the ground truth ({name}, {s.n_pixels} px): bad5.0 {s.bad_5:.2f} %, "
               f"bad2.0 {s.bad_2:.2f} %, bad1.0 {s.bad_1:.2f} %, RMSE {s.rmse:.3f} px")


def _stereo_confidence_params(args):
    """``stereo``'s confidence: the library's, with ``--confidence-floor`` and
    ``--confidence-edge-px`` where given."""
    from dataclasses import replace

    from .regularisers import ConfidenceParams

    given = {k: v for k, v in (("floor", args.confidence_floor),
                               ("edge_px", args.confidence_edge_px)) if v is not None}
    return replace(ConfidenceParams(), **given)


def _stereo_hole_params(args):
    """``stereo``'s holes step: the library's constants (on), off with ``--no-holes``."""
    from .regularisers import HoleParams

    return HoleParams() if args.holes is None else HoleParams(enabled=bool(args.holes))


#: ``--downscale`` keeps at least this many pixels on the shorter side of the views.
MIN_DOWNSCALED_SIDE = 16


def _downscaled(args, lf, rng):
    """``--downscale`` of depth and complete: the light field at ``1 / N`` (ground truth kept),
    carrying the range ``rng`` (checked in the input's px first; None: the input's) in its own
    px."""
    from .lightfield import downscale, resolve_disparity_range

    n = args.downscale
    H, W = lf.image_shape
    if min(H, W) // n < MIN_DOWNSCALED_SIDE:
        raise InvalidInputError(
            f"--downscale {n} leaves {W // n} x {H // n} px of these {W} x {H} px views; "
            f"use at most {max(1, min(H, W) // MIN_DOWNSCALED_SIDE)}")
    if rng is not None:
        lf = lf.replace(disparity_range=resolve_disparity_range(lf, rng))
    small = downscale(lf, n, truth=True)
    _say(args, f"working at 1/{n} resolution: {small.image_shape[1]} x "
               f"{small.image_shape[0]} px, disparities in those px")
    return small


def _hlf_depth_params(args, budget):
    """The DepthParams of ``hyperlf depth``'s options (None: every default)."""
    from .hlf import DepthParams

    options = {k: v for k, v in (("median_radius", args.median_radius),
                                 ("median_passes", args.median_passes),
                                 ("texture_snr", args.texture_snr),
                                 ("coarse_prior", False if args.no_coarse_prior else None),
                                 ("coarse_prior_levels", args.coarse_prior_levels),
                                 ("missing_views", args.missing_views),
                                 ("unseen_labels", args.unseen_labels),
                                 ("nearest_occluders", args.nearest_occluders),
                                 ("weak_planes", args.weak_planes),
                                 ("thin_objects", args.thin_objects),
                                 ("visibility_rounds", args.visibility_rounds),
                                 ("margin_labels", args.margin_labels),
                                 ("fusion_weights", args.fusion_weights),
                                 ("confidence_floor", args.confidence_floor),
                                 ("confidence_edge_px", args.confidence_edge_px),
                                 ("max_memory", budget))
               if v is not None}
    agg = _aggregation_of(args)
    if agg.method != "none":
        options.update(aggregation=agg.method, aggregation_radius=agg.radius,
                       aggregation_eps=agg.eps)
    return DepthParams(**options) if options else None


def _run_hlf_depth(args, lf, rng):
    """``hyperlf depth --method hlf``: the result, its extra maps, texture weight and coarse
    prior strength (the last three for --save-intermediate)."""
    from .hlf import depth
    from .tiling import DEFAULT_MAX_MEMORY, plan

    budget = args.max_memory  # default: 16 GiB, or less when less is available
    if budget is None and tiling.available_memory() < DEFAULT_MAX_MEMORY:
        budget = tiling.available_memory()
    params = _hlf_depth_params(args, budget)
    if lf.views.ndim != 4:
        raise InvalidInputError("the hlf method needs monochrome spectral views; use "
                                "--method tao2013|wang2015|lin2015 for colour light fields "
                                "or 'hyperlf synth hci' to make an H-LF")
    strips = plan(lf.image_shape, args.labels, lf.n_views, budget,
                  selection=args.view_selection)  # refuses a budget too small, now
    if len(strips) > 1:
        _say(args, f"correspondence in {len(strips)} strips of {strips[0][1]} rows "
                   "(--max-memory)")
    res = depth(lf, disparity_range=rng, n_labels=args.labels, metric=args.metric,
                view_selection=args.view_selection, occlusion_split=args.occlusion_split,
                defocus=args.defocus, optimizer=args.optimizer, params=params,
                save_intermediate=args.save_intermediate, progress=_bars(args))
    inter = res.intermediate or {}
    thin = inter.get("thin_objects")
    extra = {"correspondence_only": res.f_c, "defocus_only": res.f_d,
             "coarse_disparity": inter.get("coarse_disparity"),
             "thin_objects": None if thin is None else thin.astype(np.float32)}
    return res, extra, inter.get("texture_weight"), inter.get("coarse_prior_strength")


def _run_baseline_depth(args, lf, rng):
    """``hyperlf depth --method tao2013|wang2015|lin2015``, returned as :func:`_run_hlf_depth`."""
    from .baselines import METHODS

    res = METHODS[args.method](lf, n_labels=args.labels, disparity_range=rng,
                               progress=_bars(args))
    extra = {k: v for k, v in res.maps.items()
             if isinstance(v, np.ndarray) and v.shape == res.disparity.shape}
    return res, extra, None, None


def _cmd_depth(args, dest) -> list[Path]:
    """Estimate the reference view's disparity of a hyperspectral light field (SPEC §5) or run
    a baseline light-field method on the views as plain intensities. Writes disparity.pfm,
    disparity_16bit.png, a colour-mapped disparity.png, confidence.pfm/png (0: on a depth
    edge, or the depth was filled in from the surroundings; 0.1: the pixel's own costs left
    its depth ambiguous and the regulariser chose; up to 1: unique; scaled down within 4 px of
    the map's depth edges), and an error map when
    the input has ground truth; the scores against it skip a 15 px border, so views of 30 px or
    less are written but not scored. A capture made by 'hyperlf ingest' also gets depth.pfm /
    depth.png (in the unit of the calibration's --square) and points.ply, a point cloud
    coloured by the reference view whose points carry their confidence (--min-confidence
    leaves the unsure ones out). --save-intermediate adds the correspondence-only and
    defocus-only maps and, when the textureless-region weight was used, texture_weight.pfm/png
    (1: the pixel's own costs decided; 0: its depth came from its surroundings).

    examples:
      hyperlf depth scene3 -o depth3
      hyperlf depth antinous-hlf --labels 64 --save-intermediate -o d
      hyperlf depth antinous-hlf --method wang2015 -o d-wang
      hyperlf depth lab-capture --downscale 4 -o first-look   # 1/4 resolution, a quick look
      hyperlf depth lab-capture --min-confidence 0.05 -o lab-depth   # measured points only
    """
    from .formats import load_lightfield
    from .pipeline import save_disparity_outputs, save_metric_outputs

    _check_fusion_weights(args)
    lf = load_lightfield(args.input, cube=False)  # a ground-truth cube is not needed here
    _record_input(args, lf)
    out = dest
    rng = args.disparity_range
    if rng is None and lf.disparity_range is None:
        raise InvalidInputError(f"{args.input} has no disparity range in its metadata; give "
                                "--disparity-range MIN,MAX (px per baseline)")
    if args.downscale > 1:
        lf, rng = _downscaled(args, lf, rng), None  # the range now travels with lf
    _check_labels_memory(args.labels, lf.image_shape)
    t0 = time.perf_counter()
    run = _run_hlf_depth if args.method == "hlf" else _run_baseline_depth
    res, extra, weight, strength = run(args, lf, rng)
    gt = lf.reference_gt_disparity
    small = "" if args.downscale == 1 else f" (1/{args.downscale} resolution)"
    written = save_disparity_outputs(out, res.disparity, f"{args.method} disparity{small}",
                                      truth=gt, confidence=res.confidence,
                                      unit="px per baseline" if not small else
                                      f"px per baseline at 1/{args.downscale} resolution (x "
                                      f"{args.downscale} for full-resolution px)")
    metric = save_metric_outputs(out, res.disparity, lf, confidence=res.confidence,
                                 min_confidence=args.min_confidence)
    if args.min_confidence > 0 and not metric:
        _say(args, "note: --min-confidence applies to metric depth and points.ply, which "
                   "need a capture with a calibrated focal length ('hyperlf ingest'); "
                   "disparity.pfm and confidence.pfm are written whole")
    written += metric
    if args.save_intermediate:
        written += _save_depth_intermediate(out, extra, weight, strength)
    _say(args, f"{args.method}: {time.perf_counter() - t0:.1f} s in all "
               f"({_stage_times(res.timings)})")
    _say_depth_config(args, getattr(res, "config", {}))
    _say_range_limits(args, res.disparity, lf, rng)
    if gt is not None:
        _say_depth_scores(args, res.disparity, gt)
    return written


#: Share (%) of the reference pixels at a limit of the disparity range above which depth warns.
RANGE_LIMIT_NOTE_PCT = 5.0


def _say_range_limits(args, disparity, lf, rng) -> None:
    """A note when many pixels sit at a limit of the range: where the scene reaches beyond
    it (or nothing can be matched) the cost minimum lands there, and a map without ground
    truth shows no other sign of it."""
    from .lightfield import resolve_disparity_range
    from .metrics import range_limit_shares

    lo, hi = resolve_disparity_range(lf, rng)
    shares = range_limit_shares(disparity, (lo, hi),
                                None if lf.valid is None else lf.valid[lf.reference])
    if shares is None or sum(shares) < RANGE_LIMIT_NOTE_PCT:
        return
    _say(args, f"note: {sum(shares):.1f} % of the pixels sit at a limit of the disparity range "
               f"({shares[0]:.1f} % at {lo:g}, {shares[1]:.1f} % at {hi:g}): the scene may "
               "reach beyond it, or there the costs found no match; try a wider "
               "--disparity-range")


def _save_depth_intermediate(out, extra: dict, weight, strength) -> list[Path]:
    """``depth --save-intermediate``: each intermediate map (PFM and picture), the
    textureless-region weight and the coarse prior's pull when they acted."""
    from . import visualise
    from .formats import write_pfm

    written = []
    for name, arr in extra.items():
        if arr is None:
            continue
        written.append(write_pfm(out / f"{name}.pfm", arr))
        written.append(visualise.save_disparity_png(out / f"{name}.png", arr, title=name))
    if weight is not None:
        written.append(write_pfm(out / "texture_weight.pfm", weight))
        written.append(visualise.save_disparity_png(
            out / "texture_weight.png", weight, title="weight of each pixel's own costs",
            vmin=0, vmax=1, cmap="viridis", label="0: depth from the surroundings"))
    if strength is not None:
        written.append(write_pfm(out / "coarse_prior_strength.pfm", strength))
        written.append(visualise.save_disparity_png(
            out / "coarse_prior_strength.png", strength,
            title="pull towards the coarse estimate", vmin=0, vmax=1, cmap="viridis",
            label="1: the data term comes from the coarse level"))
    return written


def _say_depth_config(args, config: dict) -> None:
    """What the H-LF depth run decided for itself: more post-filter passes for soft or noisy
    views, weakly textured pixels taken from the half-resolution estimate, thin objects
    taken from SGM."""
    passes = config.get("median_passes", 1)
    noise_passes = config.get("median_noise_passes", 0)
    why = []
    if passes - noise_passes > 1 and np.isfinite(config.get("edge_blur_px", np.nan)):
        why.append(f"soft image edges (blur {config['edge_blur_px']:.2f} px) pull the depth "
                   "edges off them")
    if noise_passes > 0:
        why.append(f"noise ({100 * config['view_noise']:.1f} % of the signal) leaves blotches")
    if why:
        _say(args, f"{' and '.join(why)}: the weighted median ran {passes} times")
    weak = config.get("weak_data_share", 0.0)
    if weak > 0:
        _say(args, f"weakly textured: {100 * weak:.1f} % of the data term dropped, "
                   f"{100 * config['coarse_prior_share']:.1f} % taken from the "
                   "half-resolution estimate instead (--save-intermediate shows where)")
    thin = config.get("thin_object_share", 0.0)
    if thin > 0:
        _say(args, f"thin objects and holes: {100 * thin:.2f} % of the pixels taken from "
                   "SGM's second opinion (--save-intermediate shows where; --no-thin-objects "
                   "keeps graph cuts' answer)")


def _cmd_batch(args, dest) -> list[Path]:  # noqa: ARG001 - batch writes its own result sets
    """Run 'hyperlf depth' on many captures in parallel with dask.distributed (pip install
    'hyperlf[batch]'): capture folders, .h5 light fields, a folder of them (e.g. the frames of
    an H-LF video) or a glob pattern. Each capture's results appear whole in OUTPUT/NAME (NAME:
    the capture's file or folder name); OUTPUT/summary.csv and summary.html list every capture
    with its time, its scores against the ground truth where there is one, the share of
    pixels at a range limit, and any failure. A re-run computes only the captures that have no
    complete results yet (a worker that died loses only the capture it was running, which is
    run again on another worker); with other depth options it is refused unless --overwrite,
    which recomputes every capture. Exit status 1 when a capture failed (see the summary).
    Warm start from the previous video frame is not implemented: every frame is matched
    alone.

    examples:
      hyperlf batch frames/ -o depths                      # every capture in frames/
      hyperlf batch 'scenes/*.h5' --labels 32 --workers 4 -o depths
      hyperlf batch frames/ --scheduler tcp://scheduler-host:8786 -o depths   # an existing cluster
    """
    from .batch import discard_unused, finish_batch, plan_batch, run_batch, write_summary

    _check_fusion_weights(args)
    depth_args = []
    for flag, value in (("--labels", args.labels), ("--metric", args.metric),
                        ("--optimizer", args.optimizer), ("--median-radius", args.median_radius),
                        ("--median-passes", args.median_passes),
                        ("--texture-snr", args.texture_snr),
                        ("--coarse-prior-levels", args.coarse_prior_levels),
                        ("--margin-labels", args.margin_labels),
                        ("--missing-views", args.missing_views),
                        ("--unseen-labels", args.unseen_labels),
                        ("--nearest-occluders", args.nearest_occluders),
                        ("--fusion-weights", _join_weights(args.fusion_weights)),
                        ("--confidence-floor", args.confidence_floor),
                        ("--confidence-edge-px", args.confidence_edge_px),
                        ("--max-memory", args.max_memory),
                        ("--min-confidence", args.min_confidence)):
        if value is not None:
            depth_args += [flag, f"{value:g}" if isinstance(value, float) else str(value)]
    if args.no_coarse_prior:
        depth_args.append("--no-coarse-prior")
    for name, value in (("weak-planes", args.weak_planes), ("thin-objects", args.thin_objects)):
        if value is not None:
            depth_args.append(f"--{name}" if value else f"--no-{name}")
    new = not os.path.lexists(args.output)
    tasks = plan_batch(args.inputs, args.output, depth_args=depth_args,
                       disparity_range=args.disparity_range, downscale=args.downscale,
                       overwrite=args.overwrite)
    _say(args, f"{len(tasks)} captures -> {args.output}")
    try:
        rows = run_batch(tasks, workers=args.workers, scheduler=args.scheduler,
                         progress=_bars(args))
    except BaseException:
        if new:  # e.g. no scheduler at --scheduler: leave no empty batch folder behind
            discard_unused(args.output)
        raise
    write_summary(args.output, rows)
    finish_batch(args.output, rows)
    counts = {k: sum(r.status == k for r in rows) for k in ("done", "done before", "failed")}
    _say(args, f"{counts['done']} computed, {counts['done before']} done before, "
               f"{counts['failed']} failed; summary in {Path(args.output) / 'summary.html'}")
    for r in rows:
        if r.status == "failed":
            _say(args, f"{r.capture}: {r.message}")
    print(args.output)
    if counts["failed"]:
        raise HyperLFError(f"{counts['failed']} of {len(rows)} captures failed; see "
                           f"{Path(args.output) / 'summary.csv'}")
    return []


def _say_depth_scores(args, disparity: np.ndarray, gt: np.ndarray) -> None:
    """Scores against the ground truth without the HCI 15 px border; views too small to keep
    any pixel inside it are not scored (the result is still valid: exit 0)."""
    from . import metrics

    sc = metrics.hci_scores(disparity, gt)
    if sc is None:
        _say(args, f"views of {gt.shape[1]} x {gt.shape[0]} px are too small to score inside "
                   f"the {metrics.HCI_BORDER} px border; no scores against the ground truth")
        return
    unit = "px" if args.downscale == 1 else f"px at 1/{args.downscale} resolution"
    _say(args, f"against the ground truth ({metrics.HCI_BORDER} px border left out): RMSE "
               f"{sc.rmse:.4f} {unit}, MSE x 100 {sc.mse_x100:.3f}, BadPix(0.07) "
               f"{sc.badpix_007:.2f} %")


def _complete_disparity(args, disparity, full_shape):
    """``complete --disparity`` at the working resolution: under ``--downscale N`` a map of
    the input's size ``full_shape`` becomes its block means / N, and one of 1/N is taken as
    it is."""
    n = args.downscale
    shape = (-(-full_shape[0] // n), -(-full_shape[1] // n))
    if disparity.shape == shape:
        return disparity
    if disparity.shape == full_shape:
        from .lightfield import downscale_disparity

        return downscale_disparity(disparity, n)
    sizes = f"{shape[1]} x {shape[0]}" + (f" (or {full_shape[1]} x {full_shape[0]} at full "
                                          "resolution)" if n > 1 else "")
    raise InvalidInputError(f"--disparity {args.disparity} is {disparity.shape[1]} x "
                            f"{disparity.shape[0]} px but the views are {sizes}")


def _save_reference_bands(path, cf, reference) -> Path:
    """Every band of the reference view's completed cube as one mosaic, band ``k`` in the tile
    of the camera that recorded it (the bands of a cube without wavelengths are the cameras in
    raster order)."""
    from . import visualise

    R, C = cf.cube.shape[:2]
    bands = np.asarray(cf.cube[reference], np.float32)
    return visualise.save_mosaic_png(path, bands.reshape((R, C) + bands.shape[1:]),
                                     title="reference view: every camera's band, registered")


def _cmd_complete(args, dest) -> list[Path]:
    """Register every band into every view (SPEC §7): the reference disparity is warped to
    every view, refined (pairwise cross-spectral stereo + edge-aware WLS), then each band is
    warped in with occlusion checks and propagated. Writes cube.h5 ([R, C, B, H, W] +
    registration and inference masks), a map of missing bands and an sRGB rendering of the
    reference. A capture without wavelengths (ingested without --wavelengths) is completed
    too: its bands are the cameras in raster order, and instead of the colour rendering
    reference_bands.png shows every camera's band registered onto the reference.

    examples:
      hyperlf complete scene3 -o cube3
      hyperlf complete scene3 --disparity depth3/disparity.pfm -o cube3
      hyperlf complete lab-capture --downscale 4 -o first-cube   # 1/4 resolution, a quick look
      hyperlf render cube3/cube.h5 --camera 'Nikon 5100' -o rgb3
    """
    from .completion import complete
    from .formats import load_lightfield, open_cube_h5

    lf = load_lightfield(args.input, cube=False)  # a ground-truth cube is scored from disk
    lf, disparity = _completion_input(args, lf)
    res = complete(lf, disparity, out_path=dest / "cube.h5", metric=args.metric,
                   optimizer=None if args.stereo == "none" else args.stereo,
                   infer=not args.no_infer, progress=_bars(args))
    written = [res.path, _missing_bands_png(dest / "missing_bands.png", res.path,
                                            lf.views.shape[:4], inferred=not args.no_infer)]
    with open_cube_h5(res.path) as cf:
        written.append(_cube_picture(args, dest, cf, lf))
        _score_cube(args, cf, lf)
    _say(args, f"{res.stats['completed_pct']:.1f} % of (view, band, pixel) entries completed "
               f"({res.stats['registered_pct']:.1f} % registered, "
               f"{res.stats['inferred_pct']:.1f} % inferred) in "
               f"{res.stats['timings']['total']:.1f} s")
    return written


def _completion_input(args, lf) -> tuple:
    """The light field to complete (made small by ``--downscale``) and its reference
    disparity: ``--disparity``, the ground truth (``--use-ground-truth``), or None (depth
    first)."""
    from .formats import read_pfm

    disparity = None
    if args.disparity is not None:  # checked before the light field is made small
        _check_disparity_source(args, lf)
        disparity = _complete_disparity(args, read_pfm(_check_input_file(args.disparity,
                                                                         "--disparity")),
                                        lf.image_shape)
    if args.downscale > 1:
        lf = _downscaled(args, lf, None)
    if disparity is None and args.use_ground_truth:
        if lf.gt_disparity is None:
            raise InvalidInputError(f"{args.input} has no ground-truth disparity")
        disparity = lf.gt_disparity
    elif disparity is None:
        _say(args, "no --disparity given: estimating the reference disparity first "
                   "('hyperlf depth' with the default settings)")
    return lf, disparity


def _missing_bands_png(path: Path, cube_path: Path, shape, *, inferred: bool) -> Path:
    """The share of bands holding data (registered, or inferred where ``inferred``) per view
    pixel, read view by view (the masks are the cube's size)."""
    from . import visualise
    from .completion import read_band_mask

    completed = np.empty(shape, np.float32)
    for v in np.ndindex(*shape[:2]):
        mask = read_band_mask(cube_path, view=v)
        if inferred:
            mask |= read_band_mask(cube_path, view=v, name="inferred_mask")
        completed[v] = mask.mean(axis=0)
    return visualise.save_share_mosaic_png(
        path, completed, title="share of bands completed per pixel (registered or inferred)",
        label="1: every band holds data")


def _cube_picture(args, dest: Path, cf, lf) -> Path:
    """The reference view in sRGB, or every camera's band on the reference where the
    wavelengths are unknown."""
    from . import render
    from .formats import write_image

    if lf.wavelengths is None:
        path = _save_reference_bands(dest / "reference_bands.png", cf, lf.reference)
        _say(args, "the views have no wavelengths: the cube's bands are the cameras in "
                   "raster order (reference_bands.png), entries neither observed nor "
                   "inferred are 0, and no colour rendering is made")
        return path
    srgb = render.emulate_camera(cf, camera="CIE 1931", output="srgb", exposure="percentile",
                                 views=lf.reference)
    return write_image(dest / "reference_srgb.png", srgb, bit_depth=8)


def _score_cube(args, cf, lf) -> None:
    """PSNR and SAM against the input's ground-truth cube where it has one (its block means
    under ``--downscale``), read view by view."""
    from . import metrics
    from .formats import ChunkedImages, open_gt_cube
    from .lightfield import BlockMeanCube

    n = args.downscale
    with open_gt_cube(args.input) as gt_cube:  # its bands follow the wavelengths
        if gt_cube is not None and lf.wavelengths is not None:
            gt_cube = ChunkedImages(gt_cube)  # views inflated on every core
            psnr, sam = metrics.cube_scores(ChunkedImages(cf.cube), gt_cube if n == 1
                                            else BlockMeanCube(gt_cube, n))
            _say(args, f"against the ground-truth cube: PSNR {psnr:.2f} dB, SAM "
                       f"{sam:.2f} deg")


# --------------------------------------------------------------------------- cube commands
def _open_cube(path):
    """Open a cube file (``.h5``) or a capture's ground-truth cube, with its geometry.

    Positions and reference come from the cube's metadata (``positions``, ``reference``) or,
    for a capture folder, from its manifest; otherwise the regular grid ``(c, r)``.
    """
    from .formats import gt_cube_file, is_capture, open_cube_h5, read_capture
    from .lightfield import centre_view, grid_positions, view_offsets

    p = Path(path)
    positions = reference = None
    if p.is_dir():
        if not is_capture(p):
            raise InvalidInputError(f"{p} is a folder but not a capture (no capture.toml)")
        cfile = gt_cube_file(p)
        if cfile is None:
            raise InvalidInputError(f"capture {p} has no cube; run 'hyperlf complete {p} -o OUT' "
                                    "first and give OUT/cube.h5")
        lf = read_capture(p, cube=False)  # the geometry; the cube is read lazily below
        positions, reference = lf.positions, lf.reference
        p = cfile
    cf = open_cube_h5(p)
    R, C = cf.cube.shape[:2]
    if positions is None and "positions" in cf.metadata:
        positions = np.asarray(cf.metadata["positions"], dtype=np.float64)
    if reference is None and "reference" in cf.metadata:
        reference = tuple(int(v) for v in cf.metadata["reference"])
    if reference is None:
        reference = centre_view(R, C)
    if positions is None:
        positions = grid_positions(R, C)
    if positions.shape != (R, C, 2):
        raise InvalidInputError(f"{p}: positions in the metadata do not match the {R} x {C} grid")
    offsets = view_offsets(positions, reference)
    return cf, offsets, reference


def _profile_arg(text: str):
    """camera name / CSV path, 'band:550' (nm) or 'weights:FILE' (one weight per band)."""
    if text.startswith("band:"):
        try:
            return float(text[5:])
        except ValueError:
            raise InvalidInputError(f"--profile band:NM needs a wavelength in nm, got {text!r}") from None
    if text.startswith("weights:"):
        path = _check_input_file(text[8:], "weights file")
        try:
            return np.loadtxt(path, delimiter=",", ndmin=1).astype(np.float64).ravel()
        except (OSError, ValueError) as exc:
            raise InvalidInputError(f"cannot read weights from {path}: {exc}") from None
    if text.strip().lower() == "bands":  # the library's every-band profile: not one picture
        raise InvalidInputError("--profile bands would give one image per band, which refocus "
                                "cannot write as a picture; name a camera, band:NM or "
                                "weights:FILE")
    return text


def _cmd_render(args, dest) -> list[Path]:
    """Render what a colour camera would have recorded (SPEC §8): RGB = sum over bands of cube
    x camera sensitivity, white-balanced so a flat spectrum is grey, mapped to sRGB.

    examples:
      hyperlf render cube.h5 --camera 'Nikon 5100' -o out
      hyperlf render scene3 --all-views -o out   # CIE 1931 -> sRGB
    """
    from . import render, visualise
    from .formats import write_image

    cf, offsets, reference = _open_cube(args.cube)
    out = dest
    _say_spectral_coverage(args, cf.wavelengths)
    with cf:
        views = "all" if args.all_views else "reference"
        kw = dict(camera=args.camera, output="srgb", white=args.white, views=views,
                  exposure="percentile" if args.white is None else "white",
                  progress=_bars(args))
        if views == "reference":
            kw["views"] = reference
        rgb = render.emulate_camera(cf, **kw)
    written = []
    if rgb.ndim == 3:
        written.append(write_image(out / "rgb_reference.png", rgb, bit_depth=8))
        written.append(write_image(out / "rgb_reference_16bit.png", rgb, bit_depth=16))
    else:
        for (r, c) in np.ndindex(*rgb.shape[:2]):
            written.append(write_image(out / f"rgb_r{r}_c{c}.png", rgb[r, c], bit_depth=8))
        written.append(visualise.save_mosaic_png(out / "rgb_views.png", rgb,
                                                 title=f"emulated {args.camera}"))
    return written


#: Fewest bands in the visible range (nm) below which ``render`` notes that colours are rough.
VISIBLE_NM, MIN_VISIBLE_BANDS = (400.0, 700.0), 4


def _say_spectral_coverage(args, wavelengths) -> None:
    """A note when a cube samples the visible spectrum with too few bands for faithful
    colour (the rendering integrates camera sensitivities over them)."""
    wl = np.ravel(np.asarray(wavelengths, np.float64))
    seen = wl[np.isfinite(wl) & (wl >= VISIBLE_NM[0]) & (wl <= VISIBLE_NM[1])]
    if np.isfinite(wl).any() and seen.size < MIN_VISIBLE_BANDS:
        bands = ", ".join(f"{v:g}" for v in np.sort(seen)) or "none"
        _say(args, f"note: only {seen.size} band(s) between {VISIBLE_NM[0]:g} and "
                   f"{VISIBLE_NM[1]:g} nm ({bands}); the colours are a rough approximation")


def _cmd_refocus(args, dest) -> list[Path]:
    """Shift-and-add over the views at a disparity for a spectral profile: a camera (RGB), one
    band, or a weight vector. A cube completed without wavelengths is refocused with
    --profile weights:FILE, one weight per camera in raster order.

    examples:
      hyperlf refocus cube.h5 --disparity 1.2 -o out
      hyperlf refocus cube.h5 --profile band:550 --disparity 0 -o out
      hyperlf refocus cube.h5 --sweep=-2,2,17 -o sweep  # GIF + MP4 + WebM
    """
    from . import render
    from .formats import write_image
    from .lightfield import check_disparity_reach
    from .spectral import wavelengths_unknown

    profile = _profile_arg(args.profile)
    cf, offsets, reference = _open_cube(args.cube)
    if wavelengths_unknown(cf.wavelengths) and not isinstance(profile, np.ndarray):
        cf.close()
        raise InvalidInputError(f"{args.cube}: the cube's wavelengths are unknown (its capture "
                                "was ingested without --wavelengths); refocus it with "
                                "--profile weights:FILE, one weight per camera in raster order")
    out = dest
    with cf:
        if isinstance(profile, float):  # say which band a wavelength picked
            band = float(np.ravel(cf.wavelengths)[render.band_index(cf.wavelengths, profile)])
            if band != profile:
                _say(args, f"band {band:g} nm (the nearest to {profile:g} nm)")
        focus = args.sweep[:2] if args.sweep is not None else [args.disparity]
        check_disparity_reach(focus, offsets, cf.cube.shape[-2:])
        if args.sweep is not None:
            lo, hi, n = args.sweep
            _check_sweep_memory(int(n), cf.cube.shape[-2:])
            res = render.focal_sweep(cf, offsets, np.linspace(lo, hi, int(n)), profile,
                                     out_dir=out, fps=args.fps, progress=_bars(args),
                                     reference=reference, white=args.white)
            written = [res[key] for key in ("gif", "mp4", "webm") if res.get(key)]
            _say(args, f"{len(res['frames'])} frames")
        else:
            img = render.refocus(cf, offsets, args.disparity, profile, output="srgb"
                                 if not isinstance(profile, (float, np.ndarray)) else "camera",
                                 exposure="percentile", reference=reference, white=args.white,
                                 progress=_bars(args))
            img = np.clip(img / max(float(np.percentile(img, 99.5)), 1e-6), 0, 1) \
                if img.ndim == 2 else img
            written = [write_image(out / f"refocus_d{args.disparity:+.2f}.png", img,
                                   bit_depth=8)]
    return written


def _cmd_spectrum(args, dest) -> list[Path]:
    """Plot (PNG) and tabulate (CSV) the spectrum of a cube at a pixel of a view. For a cube
    from 'hyperlf complete' the CSV says where each band's value comes from (registered from
    the view that saw the band, inferred from spatial neighbours, or filled across the
    spectrum). A cube completed without wavelengths gives each camera's value instead, by
    band index (the cameras in raster order).

    examples:
      hyperlf spectrum cube3/cube.h5 --at 120,80 -o s.png
      hyperlf spectrum cube3/cube.h5 --at 120,80 --view 0,2 -o s.png
    """
    from . import render
    from ._atomic import atomic_write_text
    from .spectral import wavelengths_unknown

    cf, offsets, reference = _open_cube(args.cube)
    view = args.view if args.view is not None else reference
    x, y = args.at
    H, W = cf.cube.shape[-2:]
    if not (0 <= x <= W - 1 and 0 <= y <= H - 1):
        cf.close()
        raise InvalidInputError(f"--at {x:g},{y:g} is outside the {W} x {H} px image "
                                f"(x from 0 to {W - 1}, y from 0 to {H - 1})")
    with cf:
        spec = render.spectrum_at(cf, None, x, y, view=view)
        wl = np.asarray(cf.wavelengths)
        png = render.save_spectrum_figure(dest[0], cf, None, points=[(x, y)], view=view,
                                          labels=[f"view {view}, x={x:g}, y={y:g}"])
        source = _entry_sources(cf.path, view, int(round(y)), int(round(x)))
    column, keys = (("band", range(wl.size)) if wavelengths_unknown(wl)
                    else ("wavelength_nm", wl))
    head = f"{column},value" + (",source" if source else "")
    rows = [f"{k:g},{v:.6g}" + (f",{source[i]}" if source else "")
            for i, (k, v) in enumerate(zip(keys, np.ravel(spec)))]
    csv = atomic_write_text(dest[1], "\n".join([head, *rows]) + "\n")
    if source and any(s != "registered" for s in source):
        n = sum(s != "registered" for s in source)
        _say(args, f"{n} of {len(source)} bands at that pixel were not registered (the CSV's "
                   "source column: inferred or filled)")
    return [png, csv]


def _entry_sources(path, view, y: int, x: int) -> list[str] | None:
    """Per band of a completed cube at one pixel: registered, inferred or filled (None for a
    cube without completion masks, e.g. a ground-truth cube)."""
    from .completion import read_band_mask

    try:
        reg = read_band_mask(path, view)[:, y, x]
    except (HyperLFError, OSError, KeyError):
        return None
    try:
        inf = read_band_mask(path, view, name="inferred_mask")[:, y, x]
    except (HyperLFError, OSError, KeyError):
        inf = np.zeros_like(reg)
    return ["registered" if r else "inferred" if i else "filled" for r, i in zip(reg, inf)]


# --------------------------------------------------------------------------- parser
_CUBE_HELP = "cube file (.h5 from 'hyperlf complete') or a capture folder with gt_cube.h5"


def _metric_choices(*, light_field: bool = False) -> list[str]:
    """Names ``--metric`` accepts: the cost registry's (those with a light-field evaluator for
    ``light_field``), ``auto`` first."""
    from .costs import cost_names

    return ["auto"] + list(cost_names(light_field=light_field))


def _baseline_choices() -> list[str]:
    """The light-field depth baselines by name."""
    from .baselines import METHODS

    return list(METHODS)


def _defocus_choices() -> list[str]:
    """The modes of the spectral-aware defocus cue."""
    from .hlf import DEFOCUS_MODES

    return list(DEFOCUS_MODES)


def _optimiser_choices() -> list[str]:
    """Names ``--optimizer`` accepts: the optimiser registry's."""
    from .regularisers import OPTIMISERS

    return list(OPTIMISERS)


def _subcommand(sub, name: str, func, *, help: str) -> argparse.ArgumentParser:
    """Add subcommand ``name`` running ``func``. The docstring of ``func`` is its ``--help``
    page: the description, then an optional ``examples:`` block printed as written."""
    description, _, examples = inspect.cleandoc(func.__doc__ or "").partition("\n\nexamples:\n")
    kw = {}
    if examples:
        kw = dict(epilog="examples:\n" + examples,
                  formatter_class=argparse.RawDescriptionHelpFormatter)
    p = sub.add_parser(name, help=help, description=" ".join(description.split()) or None, **kw)
    p.set_defaults(func=func)
    _add_quiet_option(p)
    return p


#: ``-q``: nothing on stderr but errors, yet the output path still comes on stdout, by design:
#: scripts read it (``out=$(hyperlf -q depth ...)``).
_QUIET_HELP = ("no progress bars or messages on stderr; the output path is still printed on "
               "stdout, for scripts")


def _add_quiet_option(p: argparse.ArgumentParser) -> None:
    """-q after the command too ('hyperlf depth -q ...'); SUPPRESS keeps a -q given before."""
    p.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                   help=_QUIET_HELP)


def _add_overwrite_option(p: argparse.ArgumentParser) -> None:
    """``--overwrite``: the one rule of every command that writes (see :mod:`hyperlf.outputs`)."""
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing output: a file, or a folder holding only a result "
                        "set hyperlf wrote (files it did not write are never touched)")


def _add_output_folder(p: argparse.ArgumentParser) -> None:
    """The required ``-o/--output`` folder of the commands that write several files."""
    p.add_argument("-o", "--output", required=True, help="output folder")
    _add_overwrite_option(p)


def _add_metric_option(p: argparse.ArgumentParser, *, help: str, light_field: bool = False,
                       default: str = "auto") -> None:
    """``--metric``: a cost of the registry (one with a light-field evaluator for
    ``light_field``) or ``auto``."""
    p.add_argument("--metric", default=default, choices=_metric_choices(light_field=light_field),
                   help=help)


def _add_optimizer_option(p: argparse.ArgumentParser, *, help: str | None = None) -> None:
    """``--optimizer``: an optimiser of the registry, graph cuts by default."""
    p.add_argument("--optimizer", default="graphcut", choices=_optimiser_choices(),
                   help=help or "regulariser (default graphcut: alpha-expansion; sgm is "
                                "faster)")


def _add_coarse_prior_options(p: argparse.ArgumentParser, *, brief: bool = False) -> None:
    """``--no-coarse-prior`` and ``--coarse-prior-levels``, which contradict each other
    (``brief``: help that points to ``depth``)."""
    prior = p.add_mutually_exclusive_group()
    prior.add_argument("--no-coarse-prior", action="store_true", help="as for depth" if brief else
                       "where --texture-snr discounts a pixel's data term, do not pull it "
                       "towards a half-resolution estimate instead (by default it is, where the "
                       "half-resolution reference is textured: a faint table or wall then keeps "
                       "its own slope rather than one depth from its surroundings)")
    prior.add_argument("--coarse-prior-levels", type=_coarse_levels_arg, default=None,
                       metavar="N", help="as for depth" if brief else
                       "nest that estimate N deep: the half-resolution run is itself pulled "
                       "towards a quarter-resolution one where it finds no texture, and so on, "
                       "as long as a level keeps 8 texture windows on its shorter side (default "
                       "1; deeper levels see fainter texture, but also more of each camera's "
                       "vignetting where it was not flat-fielded)")


#: The help of depth's on/off switches of ``DepthParams`` (``--NAME`` / ``--no-NAME``).
_DEPTH_SWITCHES = {
    "weak-planes": "where a pixel is weakly textured at full and at half resolution, pull it "
                   "towards a slanted plane that the pooled half-resolution costs of such "
                   "pixels choose, tile by tile, instead of towards the half-resolution "
                   "estimate, so that a white table seen at a slant keeps its slope (default: "
                   "on; it acts with the coarse prior, i.e. on captures from cameras)",
    "thin-objects": "graph cuts give rods, wires and stems that are faint in the reference "
                    "band to the background behind them; ask SGM for a second opinion on "
                    "the same costs and take the thin objects it puts nearer that do not lie "
                    "along graph cuts' own surface at their depth, and the background it "
                    "sees through holes that graph cuts filled with the foreground around "
                    "them (default: on; acts with --optimizer graphcut)",
}


def _add_depth_switch(p: argparse.ArgumentParser, name: str, *, brief: bool = False) -> None:
    """``--NAME`` / ``--no-NAME`` of depth and batch: ``DepthParams.<name>`` (``name`` a key
    of :data:`_DEPTH_SWITCHES`; ``brief``: help that points to depth)."""
    p.add_argument(f"--{name}", action=argparse.BooleanOptionalAction, default=None,
                   help="as for depth" if brief else _DEPTH_SWITCHES[name])


def _add_unseen_options(p: argparse.ArgumentParser, *, brief: bool = False) -> None:
    """``--missing-views``, ``--unseen-labels`` and ``--nearest-occluders`` of depth and batch
    (``DepthParams.missing_views``, ``.unseen_labels``, ``.nearest_occluders``)."""
    from .hlf import MISSING_VIEWS, NEAREST_OCCLUDERS, UNSEEN_LABELS

    for flag, choices, text in (
            ("--missing-views", MISSING_VIEWS,
             "near the image border some views cannot see a pixel at every candidate "
             "depth: 'average' (default) averages each depth over the views that see "
             "it there, 'neutral' counts the missing ones as the pixel's median cost, "
             "'common' counts a view at a pixel only where it sees it at every depth, "
             "so that all depths compare the same views (removes the pull of "
             "textureless regions to the range limits without --texture-snr)"),
            ("--unseen-labels", UNSEEN_LABELS,
             "a candidate depth that no view sees at a pixel (along the image edge of "
             "a reference camera at the border of the array, as wide as the disparity): "
             "'share' (default) costs it between the pixel's median and worst cost, "
             "the nearer the worst the more of its depths the views do see; 'worst' "
             "rules it out; 'median' leaves it to the regulariser (surfaces that run "
             "on to the image edge)"),
            ("--nearest-occluders", NEAREST_OCCLUDERS,
             "a candidate depth of a pixel that fewer than two views see under the "
             "previous estimate: 'never' (default) matches it over every view, the "
             "hidden ones too; 'before-last' matches it, in every visibility round but "
             "the last, over the views hidden by the least nearer surface (less than "
             "2 px per baseline nearer, or the least step of sqrt(2) up to 8 px at "
             "which two views count), so that a foreground carried over its "
             "background, or into a hole, gives it back (3-4 %% less error on scenes "
             "of many layers, thin objects before a far background; antinous unchanged, "
             "a smooth Middlebury scene 0.3 %% worse, BENCHMARKS.md); 'always' in the "
             "last round too")):
        p.add_argument(flag, choices=choices, default=None,
                       help="as for depth" if brief else text)


def _add_demo_parser(sub) -> None:
    p = _subcommand(sub, "demo", _cmd_demo,
                    help="build a synthetic H-LF and write pictures and data")
    p.add_argument("-o", "--output", default="hyperlf-demo", help="output folder "
                   "(default ./hyperlf-demo)")
    p.add_argument("--seed", type=_seed_arg, default=0, help="scene seed (default 0)")
    p.add_argument("--grid", type=_pair_of_ints, default=(5, 6), metavar="R,C",
                   help="rows and columns of views (default 5,6 as in the paper)")
    p.add_argument("--size", type=_pair_of_ints, default=(96, 128), metavar="H,W",
                   help="view size in pixels (default 96,128)")
    _add_metric_option(p, light_field=True,
                       help="correspondence cost of the depth step (default auto = census-rsncc; "
                            "ncc is faster still, fused/bwncc far slower)")
    p.add_argument("--labels", type=_labels_arg, default=32,
                   help="disparity labels (default 32)")
    _add_overwrite_option(p)


def _add_synth_parser(sub) -> None:
    p = _subcommand(sub, "synth", _cmd_synth,
                    help="make a synthetic H-LF capture with ground truth")
    ssub = p.add_subparsers(dest="source", metavar="SOURCE", required=True)
    raw = argparse.RawDescriptionHelpFormatter
    ph = ssub.add_parser(
        "hci", help="from an RGB light field (HCI 4D LF scene folder)", formatter_class=raw,
        description=textwrap.fill(
            "Turn an RGB light field of the HCI 4D benchmark into an H-LF capture with ground "
            "truth (SPEC 6): a sub-grid of its views around its centre (--grid, default 5 x "
            "6), every pixel a spectrum fitted to its colour (Mallett 2019), and each view "
            "keeps one band of the filter array; the scene's disparity and the full cube are "
            "the truth. About 30 s and 0.6 GB for a 512 x 512 scene.", 88),
        epilog="examples:\n  hyperlf synth hci $HYPERLF_DATA/hci4d/antinous -o antinous-hlf\n"
               "  hyperlf synth hci SCENE --grid 3,3 --noise 0.005 -o small.h5")
    ph.add_argument("scene", help="HCI scene folder (input_Cam###.png, gt_disp_lowres.pfm)")
    pp = ssub.add_parser(
        "procedural", help="procedural planes and solids with real spectra",
        formatter_class=raw,
        description=textwrap.fill(
            "Render a procedural H-LF capture with exact ground truth (disparity and cube): "
            "textured planes, slanted planes, thin occluders or solids whose surfaces carry "
            "measured reflectance spectra, seen through the filter array.", 88),
        epilog="examples:\n  hyperlf synth procedural --seed 3 -o scene3\n"
               "  hyperlf synth procedural --scene occlusion --size 128,160 --grid 3,4 -o occ")
    pp.add_argument("--scene", dest="scene_name", default=None,
                    help="a named scene: planes, slanted, occlusion, solids, rings (default: "
                         "random from the seed)")
    pp.add_argument("--size", type=_pair_of_ints, default=(256, 256), metavar="H,W",
                    help="view size in pixels (default 256,256)")
    for q in (ph, pp):
        q.add_argument("-o", "--output", required=True,
                       help="output capture folder, or a .h5 file (its pictures then go to "
                            "a folder of the same name beside it, unless --no-pictures)")
        q.add_argument("--seed", type=_seed_arg, default=None,
                       help="random seed (default: 0, or the named scene's own)")
        q.add_argument("--no-pictures", action="store_true", help="write data only")
        _add_quiet_option(q)
        _add_spectral_options(q)
        _add_overwrite_option(q)
        q.set_defaults(func=_cmd_synth)


def _add_info_parser(sub) -> None:
    p = _subcommand(sub, "info", _cmd_info,
                    help="describe a capture, HDF5 light field, HCI scene or cube file")
    p.add_argument("input", help="capture folder, .h5 light field, HCI scene folder or a cube "
                                 "file (complete's cube.h5)")


def _add_convert_parser(sub) -> None:
    p = _subcommand(sub, "convert", _cmd_convert, help="convert between formats")
    p.add_argument("input", help="capture folder, .h5 light field, HCI scene folder, cube .h5, "
                                 ".pfm, or a .png/.tif that convert wrote from a PFM")
    p.add_argument("-o", "--output", required=True,
                   help="target: folder (capture), .h5, .pfm, .png, .tif or .hdr")
    p.add_argument("--bit-depth", type=int, choices=(8, 16), default=16,
                   help="of the images written: a capture's views or a PFM's picture "
                        "(default 16)")
    p.add_argument("--view", type=_view_index, default=None, metavar="R,C",
                   help="view (0-based row,col) whose cube is exported to ENVI "
                        "(default: the centre view)")
    _add_overwrite_option(p)


def _add_pattern_option(p: argparse.ArgumentParser) -> None:
    """``--pattern``: how a real array's files are named (see :mod:`hyperlf.formats.patterns`)."""
    p.add_argument("--pattern", required=True,
                   help="file name of each camera's image, with {index} (raster order) or "
                        "{row} and {col} (0-based; {index+1} for files numbered from 1), e.g. "
                        "'Cam-{index}.png' or 'cam_{row}_{col:02d}.tif'")


def _add_calibrate_parser(sub) -> None:
    p = _subcommand(sub, "calibrate", _cmd_calibrate,
                    help="calibrate a camera array from checkerboard shots")
    p.add_argument("shots", help="folder of board shots (one per camera), or of one subfolder "
                                 "per pose")
    _add_pattern_option(p)
    p.add_argument("--grid", type=_pair_of_ints, required=True, metavar="R,C",
                   help="rows and columns of cameras (names only: positions are measured)")
    p.add_argument("--board", type=_pair_of_ints, required=True, metavar="COLS,ROWS",
                   help="inner corners of the checkerboard (a 12 x 9 squares board has 11,8)")
    p.add_argument("--square", type=_float_within(1e-9, 1e9, "--square"), default=1.0,
                   help="side of a square, in the unit metric depth should use (e.g. mm); "
                        "default 1")
    p.add_argument("--mode", default="auto", choices=["auto", "plane", "full"],
                   help="auto (default): plane registration with one pose, full calibration "
                        "with three or more")
    p.add_argument("--reference", type=_view_index, default=None, metavar="R,C",
                   help="reference camera (default: the centre of the grid)")
    p.add_argument("--focal-px", type=_float_within(1.0, 1e7, "--focal-px"), default=None,
                   help="focal length in px (lens focal length / pixel pitch), when known; "
                        "default: estimated from the board pose (plane mode)")
    _add_output_folder(p)


def _add_ingest_parser(sub) -> None:
    p = _subcommand(sub, "ingest", _cmd_ingest,
                    help="raw images of a calibrated array -> a capture with validity masks")
    p.add_argument("raw", help="folder of the raw images, one per camera")
    p.add_argument("--calibration", required=True,
                   help="calibration.toml from 'hyperlf calibrate' (or its folder)")
    _add_pattern_option(p)
    p.add_argument("--wavelengths", default=None,
                   help="filter centre wavelengths in nm (200-20000), raster order: "
                        "comma-separated, or a text/CSV file of the numbers (one header line "
                        "allowed); default: unknown")
    p.add_argument("--dark", default=None, help="dark frame: one image, or a pattern path "
                                                "such as darks/Cam-{index}.png")
    p.add_argument("--flat", default=None, help="flat field: one image, or a pattern path")
    p.add_argument("--dead", type=_view_index, action="append", metavar="R,C",
                   help="a broken camera to leave out (repeat for several); its file is "
                        "not read and may be missing; not the reference")
    p.add_argument("--saturation", type=_float_within(0.0, 1.0, "--saturation", above_low=True),
                   default=0.98,
                   help="raw level (0..1 of the sensor's full scale) at or above which a "
                        "pixel is invalid; 1 turns the check off (default 0.98)")
    p.add_argument("--raw-bits", type=_raw_bits_arg, default=None, metavar="B",
                   help="bits of the sensor's values, full scale 2^B - 1 (default: the fewest "
                        "of 8, 10, 12, 14, 16 that hold the largest raw value, so that a "
                        "12-bit camera's 16-bit files saturate at 4095, not 65535)")
    p.add_argument("--disparity-range", type=_range_arg, default=None, metavar="MIN,MAX",
                   help="px per baseline (default: the plane registration's estimate, or "
                        "measured on the rectified images after a full calibration)")
    _add_output_folder(p)


def _add_stereo_parser(sub) -> None:
    from .twoview import DEFAULT_OCCLUSION, OCCLUSION_MODES

    p = _subcommand(sub, "stereo", _cmd_stereo, help="cross-spectral two-view stereo")
    p.add_argument("left", help="left image of the rectified pair (disparity is its), or a "
                                "Middlebury scene folder (v2 or 2005 layout) alone: its two "
                                "views, search range and ground truth")
    p.add_argument("right", nargs="?", default=None,
                   help="right image, seeing the same rows (none for a scene folder)")
    p.add_argument("--disparity-range", type=_range_arg, default=None, metavar="MIN,MAX",
                   help="integer disparity search range in px (needed for two images; a "
                        "scene folder's default is 0 to its largest disparity; write "
                        "--disparity-range=-8,8 for a negative MIN)")
    _add_metric_option(p, help="matching cost (default auto: the library's cross-spectral "
                               "default)")
    _add_optimizer_option(p, help="regulariser (default graphcut: alpha-expansion)")
    p.add_argument("--channel", type=_channel_arg, default=None, metavar="C or L,R",
                   help="image channel(s) to match for colour inputs: 0 red, 1 green, 2 blue; "
                        "L,R picks one per image (default: mean of channels)")
    p.add_argument("--subpixel", action="store_true", help="parabola sub-pixel refinement")
    p.add_argument("--occlusion", default=DEFAULT_OCCLUSION, choices=OCCLUSION_MODES,
                   help="pixels that fail the left-right check: lr-plane (default) gives those "
                        "the right view sees the slanted plane of their image region and the "
                        "hidden ones the background of their row, then a median of their "
                        "surroundings removes the fill's streaks; lr-fill gives all the "
                        "background (the paper's protocol); none keeps the raw map")
    p.add_argument("--no-occlusion", action="store_true",
                   help="the same as --occlusion none")
    p.add_argument("--holes", action=argparse.BooleanOptionalAction, default=None,
                   help="open the holes graph cuts filled with the foreground around them "
                        "(rings, gaps between objects) from a second solve of each view at "
                        "half the smoothness, where both views agree (default: on; acts "
                        "with --optimizer graphcut; --no-holes saves the second solves)")
    _add_fusion_weights_option(p, brief=True)
    _add_aggregation_options(p)
    _add_confidence_options(p, **_stereo_confidence_defaults())
    _add_output_folder(p)


def _stereo_confidence_defaults() -> dict:
    from .regularisers import ConfidenceParams

    d = ConfidenceParams()
    return {"floor": d.floor, "edge_px": d.edge_px}


def _depth_confidence_defaults() -> dict:
    from .hlf import DepthParams

    return {"floor": DepthParams.confidence_floor, "edge_px": DepthParams.confidence_edge_px}


def _add_depth_parser(sub) -> None:
    p = _subcommand(sub, "depth", _cmd_depth, help="disparity of the reference view of an H-LF")
    p.add_argument("input", help="capture folder, .h5 light field or HCI scene folder")
    _add_depth_matching_options(p.add_argument_group("matching"))
    _add_depth_regularisation_options(p.add_argument_group("regularisation and post-filter"))
    _add_depth_weak_texture_options(p.add_argument_group("weakly textured regions"))
    _add_depth_visibility_options(p.add_argument_group("views that cannot see a pixel"))
    _add_depth_resource_options(p.add_argument_group("time and memory"))
    _add_depth_output_options(p.add_argument_group("outputs"))


def _add_depth_matching_options(g) -> None:
    """depth's search range, cost and the cues besides correspondence."""
    g.add_argument("--method", default="hlf", choices=["hlf", *_baseline_choices()],
                   help="hlf (ours, default) or a baseline")
    g.add_argument("--disparity-range", type=_range_arg, default=None, metavar="MIN,MAX",
                   help="px per baseline (default: the capture's metadata); leave half a "
                        "pixel or more beyond the nearest and farthest surfaces, which are "
                        "matched worse on an end of the range; write "
                        "--disparity-range=-2,2 when MIN is negative")
    g.add_argument("--labels", type=_labels_arg, default=64,
                   help="number of disparity labels (64)")
    g.add_argument("--margin-labels", type=_margin_labels_arg, default=None, metavar="K",
                   help="hlf: K more labels at the same step beyond each end of the range, "
                        "the map clipped back to it (default 0), for a range that ends at "
                        "the nearest or farthest surface, whose pixels then have candidates "
                        "on both sides (4: a quarter fewer bad pixels on such scenes, "
                        "BENCHMARKS.md)")
    _add_metric_option(g, light_field=True,
                       help="correspondence cost of hlf: auto (default, = census-rsncc), rsncc, "
                            "census, ncc, or the descriptor costs fused, bwncc, bwncc-paper "
                            "(about 50x slower)")
    _add_fusion_weights_option(g)
    g.add_argument("--view-selection", action="store_true",
                   help="enable the paper's local view selection (off by default: it did not "
                        "help on the tuning scenes)")
    g.add_argument("--occlusion-split", action="store_true",
                   help="enable the occlusion-aware half-plane split (off by default)")
    g.add_argument("--defocus", default="off", choices=_defocus_choices(),
                   help="spectral-aware defocus cost (off by default; 'paper' is the literal one)")
    _add_aggregation_options(g)


def _add_depth_regularisation_options(g) -> None:
    """depth's optimiser and the post-filter that snaps depth edges to image edges."""
    _add_optimizer_option(g)
    _add_depth_switch(g, "thin-objects")
    g.add_argument("--median-radius", type=_int_at_least(0, "--median-radius", 64), default=None,
                   metavar="PX",
                   help="radius of the guided weighted-median post-filter that snaps depth "
                        "edges to image edges (default 4; 0 turns it off)")
    g.add_argument("--median-passes", type=_median_passes_arg, default=None, metavar="N",
                   help="how often the post-filter runs (default auto: once, once more "
                        "per 0.4 px of the reference view's edge blur above 0.8 px, since "
                        "soft views carry the foreground further over the background, and "
                        "once more per 1 %% of white noise against the signal, since noise "
                        "leaves blotches)")


def _add_depth_weak_texture_options(g) -> None:
    """depth's handling of pixels whose window holds too little texture to match."""
    g.add_argument("--texture-snr", type=_texture_snr_arg,
                   default=None, metavar="T",
                   help="pixels whose matching window holds less texture than T times the "
                        "sensor noise (estimated from the reference view) count less, so that "
                        "textureless regions (a white table, a wall) take their depth from "
                        "their surroundings instead of a chance cost minimum (> 1, or 0 for "
                        "off; default: 2 for captures made by 'hyperlf ingest' from camera "
                        "images, off for rendered and synthetic light fields, whose "
                        "pixel-scale texture one image cannot tell from noise)")
    _add_coarse_prior_options(g)
    _add_depth_switch(g, "weak-planes")


def _add_depth_visibility_options(g) -> None:
    """depth's visibility rounds and what it does where views cannot see a candidate depth."""
    g.add_argument("--visibility-rounds", type=_visibility_rounds_arg, default=None,
                   metavar="N",
                   help="re-match N times, each candidate depth of a pixel over only the "
                        "views that see it there under the previous estimate (sharper depth "
                        "edges; the first round starts from a quick half-resolution run, and "
                        "a further one averages the previous pass's per-view costs again "
                        "when they fit in memory, else computes them again, and moves the "
                        "previous labels with one cycle of graph cuts; default: 3 on images "
                        "at least 192 px on their shorter side whose costs fit in 3 GB "
                        "(512 x 512, 64 labels, 30 views), 1 on larger ones, else 0; 1 saves "
                        "about a sixth of the time where a scene has few depth edges)")
    _add_unseen_options(g)


def _add_depth_resource_options(g) -> None:
    """depth's memory budget and its quick look at 1/N resolution."""
    g.add_argument("--max-memory", type=_memory_arg, default=None, metavar="SIZE",
                   help="memory budget of the hlf method, e.g. 6G or 512M (default 16G, which "
                        "leaves room on a 24 GB machine, or the memory available now when that "
                        "is less): above it the correspondence stage "
                        "runs in strips of rows, with results identical to one pass; the "
                        "default cost (auto: census-rsncc, a fusion) then needs one more "
                        "matching pass for its "
                        "normalisers (up to twice the matching time); a budget that even the "
                        "thinnest strips exceed is refused before any work")
    g.add_argument("--downscale", type=_downscale_arg, default=1, metavar="N",
                   help="match at 1/N of the resolution (means of N x N pixel blocks), "
                        "about N^2 times faster, for a first look at a large capture: the maps "
                        "are N times smaller and their disparities in their own px (1/N of "
                        "the full-resolution values; --disparity-range stays in the input's "
                        "px); metric depth and the point cloud keep their unit (default 1)")


def _add_depth_output_options(g) -> None:
    """depth's output folder and what its confidence leaves out of the metric outputs."""
    g.add_argument("--min-confidence", type=_min_confidence_arg, default=0.0, metavar="C",
                   help="leave pixels whose confidence (confidence.pfm/png) is below C out of "
                        "the metric outputs: NaN in depth.pfm, no point in points.ply, whose "
                        "points carry their confidence as a property either way. With the "
                        "default confidence options, 0.05 "
                        "drops the textureless pixels whose depth was filled in from their "
                        "surroundings (confidence 0) and those within 2 px of a depth edge, "
                        "0.15 also those whose own costs were ambiguous (0.1); disparity.pfm "
                        "stays whole (default 0: keep every pixel)")
    _add_confidence_options(g, **_depth_confidence_defaults())
    g.add_argument("--save-intermediate", action="store_true",
                   help="also write correspondence-only and defocus-only maps, and the "
                        "textureless-region weight and the thin objects and holes taken from "
                        "SGM when they were used")
    _add_output_folder(g)


def _add_batch_parser(sub) -> None:
    p = _subcommand(sub, "batch", _cmd_batch,
                    help="depth of many captures in parallel (dask.distributed)")
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="capture folder, .h5 light field, a folder of them, or a glob pattern "
                        "(quote it)")
    _add_batch_cluster_options(p.add_argument_group("cluster"))
    _add_batch_depth_options(p.add_argument_group("depth of each capture (see 'hyperlf depth "
                                                  "--help')"))
    g = p.add_argument_group("outputs")
    g.add_argument("-o", "--output", required=True,
                   help="output folder: one result set per capture and the summary")
    g.add_argument("--overwrite", action="store_true",
                   help="recompute every capture, also those with results (needed to change "
                        "the depth options of an existing batch folder)")


def _add_batch_cluster_options(g) -> None:
    """batch's local cluster or the scheduler it uses instead."""
    g.add_argument("--workers", type=_workers_arg, default=2,
                   help="worker processes of the local cluster (default 2; each runs one "
                        "capture at a time, using every core numba is given)")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="use an existing dask scheduler instead of a local cluster, e.g. "
                        "tcp://scheduler-host:8786 (its workers need hyperlf installed and must see "
                        "the input and output paths)")


def _add_batch_depth_options(g) -> None:
    """The depth options batch hands on to every capture's run."""
    g.add_argument("--disparity-range", type=_range_arg, default=None, metavar="MIN,MAX",
                   help="as for depth (default: each capture's metadata)")
    g.add_argument("--labels", type=_labels_arg, default=None,
                   help="number of disparity labels (depth's default, 64)")
    g.add_argument("--margin-labels", type=_margin_labels_arg, default=None, metavar="K",
                   help="as for depth")
    _add_metric_option(g, light_field=True, help="correspondence cost (depth's default, auto)")
    _add_optimizer_option(g)
    g.add_argument("--median-radius", type=int, default=None, metavar="PX",
                   help="as for depth")
    g.add_argument("--median-passes", type=_median_passes_arg, default=None, metavar="N",
                   help="as for depth")
    g.add_argument("--texture-snr", type=_texture_snr_arg, default=None, metavar="T",
                   help="as for depth")
    _add_coarse_prior_options(g, brief=True)
    _add_depth_switch(g, "weak-planes", brief=True)
    _add_depth_switch(g, "thin-objects", brief=True)
    _add_unseen_options(g, brief=True)
    _add_fusion_weights_option(g, brief=True)
    g.add_argument("--min-confidence", type=_min_confidence_arg, default=None, metavar="C",
                   help="as for depth (captures with metric outputs)")
    _add_confidence_options(g, **_depth_confidence_defaults(), brief=True)
    g.add_argument("--downscale", type=_downscale_arg, default=1, metavar="N",
                   help="as for depth: every capture matched at 1/N resolution, and its "
                        "scores taken at that resolution (default 1)")
    g.add_argument("--max-memory", type=_memory_arg, default=None, metavar="SIZE",
                   help="as for depth, for each capture: with N workers on one machine give "
                        "each at most 1/N of its memory")


def _add_complete_parser(sub) -> None:
    p = _subcommand(sub, "complete", _cmd_complete,
                    help="complete the plenoptic cube: every view gets every band")
    p.add_argument("input", help="capture folder or .h5 light field (monochrome spectral views)")
    p.add_argument("--disparity", default=None, metavar="PFM",
                   help="reference disparity (e.g. from 'hyperlf depth'); default: estimate it")
    p.add_argument("--use-ground-truth", action="store_true",
                   help="use the capture's ground-truth disparity (synthetic data)")
    _add_metric_option(p, default="rsncc", help="pairwise stereo cost (default rsncc)")
    p.add_argument("--stereo", default="sgm", choices=[*_optimiser_choices(), "none"],
                   help="pairwise stereo optimiser, or none (WLS refinement only)")
    p.add_argument("--no-infer", action="store_true",
                   help="do not infer entries no view observed (points hidden in the view that "
                        "records the band) from the same band nearby; leave them to the "
                        "spectral fill and mark them missing")
    p.add_argument("--downscale", type=_downscale_arg, default=1, metavar="N",
                   help="complete the means of N x N pixel blocks: a cube at 1/N resolution "
                        "in about 1/N^2 of the time; --disparity may then be the full-"
                        "resolution map (made 1/N) or one made at 1/N (default 1)")
    _add_output_folder(p)


def _add_render_parser(sub) -> None:
    p = _subcommand(sub, "render", _cmd_render, help="emulate a colour camera from a cube")
    p.add_argument("cube", help=_CUBE_HELP)
    p.add_argument("--camera", default="CIE 1931",
                   help="camera name (colour-science or camspec), CSV of sensitivities "
                        "(wavelength,r,g,b), or 'CIE 1931' (default)")
    p.add_argument("--white", default=None,
                   help="illuminant whose spectrum should come out neutral (e.g. D65); "
                        "default: a flat spectrum is neutral, exposure by percentile")
    p.add_argument("--all-views", action="store_true", help="render every view, not only the "
                   "reference")
    _add_output_folder(p)


def _add_refocus_parser(sub) -> None:
    p = _subcommand(sub, "refocus", _cmd_refocus,
                    help="spectral refocusing at a disparity, or a focal sweep")
    p.add_argument("cube", help=_CUBE_HELP)
    p.add_argument("--disparity", type=_finite_float, default=0.0,
                   help="focus disparity (px/baseline)")
    p.add_argument("--sweep", type=_sweep_arg, default=None, metavar="MIN,MAX,N",
                   help="write a focal sweep of N frames instead (write --sweep=-2,2,17 when "
                        "MIN is negative)")
    p.add_argument("--profile", default="CIE 1931",
                   help="camera name or CSV, band:NM for one band, weights:FILE (one weight "
                        "per band, comma-separated); default CIE 1931 -> sRGB")
    p.add_argument("--white", default=None, help="illuminant to render neutral (e.g. D65)")
    p.add_argument("--fps", type=_float_within(0.01, 1000.0, "--fps"),
                   default=8.0, help="frames per second of the sweep (default 8)")
    _add_output_folder(p)


def _add_spectrum_parser(sub) -> None:
    p = _subcommand(sub, "spectrum", _cmd_spectrum, help="plot the spectral profile of a pixel")
    p.add_argument("cube", help=_CUBE_HELP)
    p.add_argument("--at", type=_pair_of_floats, required=True, metavar="X,Y",
                   help="pixel position (x = column, y = row)")
    p.add_argument("--view", type=_view_index, default=None, metavar="R,C",
                   help="view (0-based; default the reference)")
    p.add_argument("-o", "--output", default="spectrum.png",
                   help="output picture, e.g. s.png (s.csv is written beside it)")
    _add_overwrite_option(p)


def build_parser() -> argparse.ArgumentParser:
    """The ``hyperlf`` argument parser: one small function per subcommand.

    Examples
    --------
    >>> args = build_parser().parse_args(["depth", "capture", "-o", "out"])
    >>> args.labels, args.metric, args.optimizer
    (64, 'auto', 'graphcut')
    """
    parser = _Parser(
        prog="hyperlf",
        description="Hyperspectral light fields: depth from a camera array whose views each "
                    "see a different narrow band, plenoptic cube completion and rendering.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"hyperlf {__version__}")
    parser.add_argument("-q", "--quiet", action="store_true", help=_QUIET_HELP)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    parser.commands = sub.choices  # each command's parser, for its own usage errors
    _add_demo_parser(sub)
    _add_synth_parser(sub)
    _add_calibrate_parser(sub)
    _add_ingest_parser(sub)
    _add_info_parser(sub)
    _add_convert_parser(sub)
    _add_stereo_parser(sub)
    _add_depth_parser(sub)
    _add_complete_parser(sub)
    _add_render_parser(sub)
    _add_refocus_parser(sub)
    _add_spectrum_parser(sub)
    _add_batch_parser(sub)
    return parser


def _check_arguments(args) -> None:
    """Checks every command shares, before any work: the output location and --overwrite."""
    if getattr(args, "output", None) == "":
        raise InvalidInputError("-o is empty; give a name (use -o . for the current folder)")
    kind = _output_kind(args)
    if kind is not None:
        _check_output(args.output, kind)
    elif args.command == "batch":  # a folder of result sets that hyperlf.batch manages
        _check_output(args.output, "folder")
    out = Path(getattr(args, "output", None) or ".")
    if args.command == "spectrum" and out.suffix.lower() not in _FIGURE_SUFFIXES:
        raise InvalidInputError(f"-o {out}: give the picture's name, e.g. "
                                f"{out.with_suffix('.png')} (.png, .pdf or .svg); the CSV is "
                                "written beside it")
    _check_sidecars(args)
    _check_output_spares_inputs(args)
    if hasattr(args, "overwrite"):
        _check_overwrite(args)


def _pictures_folder(args) -> Path | None:
    """``synth``'s pictures folder beside a ``.h5`` light field (None when it writes none)."""
    kind, targets = _targets(args)
    if args.command == "synth" and kind == "files" and len(targets) > 1:
        return targets[1]
    return None


def _check_sidecars(args) -> None:
    """What a command writes beside ``-o`` must be of the kind it writes there (synth's
    pictures: a folder; the rest: files), and synth's pictures folder replaces only pictures:
    a capture folder named like the ``.h5`` is the user's, also under --overwrite."""
    from .outputs import read_manifest

    kind, targets = _targets(args)
    if kind != "files":
        return
    pictures = _pictures_folder(args)
    for t in targets[1:]:
        if t == pictures:
            if os.path.lexists(t) and (t.is_symlink() or not t.is_dir()):
                raise InvalidInputError(
                    f"{t} is a {'symlink' if t.is_symlink() else 'file'}, where synth would "
                    f"put the pictures of {targets[0].name} (a folder); move it, choose "
                    "another -o, or give --no-pictures")
            man = read_manifest(t) if t.is_dir() else None
            if t.is_dir() and man is None and any(t.iterdir()):
                raise InvalidInputError(
                    f"{t} is a folder hyperlf did not write, where synth would put the "
                    f"pictures of {targets[0].name}; choose another -o or give --no-pictures")
            if man is not None and not all(f.lower().endswith(".png") for f in man["files"]):
                raise InvalidInputError(
                    f"{t} holds a result of 'hyperlf {man['command'] or '...'}', not the "
                    f"pictures of {targets[0].name}; choose another -o or give --no-pictures")
        elif t.is_dir():
            raise InvalidInputError(f"{t} is a folder, where this command writes a file beside "
                                    f"-o {targets[0]}; move it or choose another -o")


#: The arguments that may name an input file or folder.
_INPUT_ARGS = ("input", "inputs", "scene", "shots", "raw", "left", "right", "cube",
               "calibration", "wavelengths", "dark", "flat", "disparity")


def _check_output_spares_inputs(args) -> None:
    """Refuse an output that is, or holds, one of the command's inputs: writing there (with
    --overwrite) would replace the input with the result."""
    outs = [Path(os.path.abspath(t)) for t in _targets(args)[1]]
    if args.command == "batch":
        outs.append(Path(os.path.abspath(args.output)))
    for name in _INPUT_ARGS:
        values = getattr(args, name, None)
        for v in values if isinstance(values, list) else [values]:
            if not isinstance(v, (str, os.PathLike)) or not os.path.lexists(v):
                continue
            p = Path(os.path.abspath(v))
            for o in outs:
                if p == o or o in p.parents:
                    raise InvalidInputError(
                        f"-o {o} holds the input {v}: writing there would replace it with the "
                        "result; choose another -o")


def _run(args) -> int:
    """Check, run the command into its staging area, put the result set in place, report."""
    _check_arguments(args)
    with _result(args) as dest:
        written = args.func(args, dest)
    if dest is not None:
        _report(args, written, dest)
    return 0


#: Options that contradict each other: (command, option, option, what to do).
_EXCLUSIVE = (
    ("stereo", "--no-occlusion", "--occlusion", "--no-occlusion is --occlusion none; give one"),
    ("complete", "--disparity", "--use-ground-truth", "give one source of disparity"),
    ("refocus", "--disparity", "--sweep", "a sweep focuses at its own disparities; give one"),
    ("depth", "--weak-planes", "--no-coarse-prior", "the planes replace the coarse prior's "
     "target; give one"),
    ("batch", "--weak-planes", "--no-coarse-prior", "the planes replace the coarse prior's "
     "target; give one"),
)
#: Options that act only with another option's value: (option, other, value).
_ONLY_WITH = (("--aggregation-radius", "--aggregation", "guided"),
              ("--aggregation-eps", "--aggregation", "guided"),
              ("--thin-objects", "--optimizer", "graphcut"),
              ("--no-thin-objects", "--optimizer", "graphcut"),
              ("--holes", "--optimizer", "graphcut"),
              ("--no-holes", "--optimizer", "graphcut"))
#: Options of ``depth`` that act on ``--method hlf`` only (the baselines take the range and
#: the labels).
_HLF_ONLY = ("--metric", "--optimizer", "--view-selection", "--occlusion-split", "--defocus",
             "--median-radius", "--median-passes", "--texture-snr", "--max-memory",
             "--no-coarse-prior", "--missing-views", "--unseen-labels",
             "--nearest-occluders", "--weak-planes",
             "--no-weak-planes", "--thin-objects", "--no-thin-objects",
             "--visibility-rounds", "--margin-labels", "--confidence-floor",
             "--confidence-edge-px", "--aggregation", "--aggregation-radius",
             "--aggregation-eps")


def _check_combinations(args, argv) -> None:
    """Refuse options given together that contradict each other or would be ignored."""
    given = {a.split("=", 1)[0] for a in argv if a.startswith("--")}
    for command, a, b, fix in _EXCLUSIVE:
        if args.command == command and {a, b} <= given:
            raise InvalidInputError(f"{a} and {b} together: {fix}")
    for a, b, value in _ONLY_WITH:
        if a in given and getattr(args, b[2:].replace("-", "_"), value) != value:
            raise InvalidInputError(f"{a} acts only with {b} {value}")
    if args.command == "depth" and args.method != "hlf":
        ignored = [a for a in _HLF_ONLY if a in given]
        if ignored:
            raise InvalidInputError(f"{ignored[0]} acts on --method hlf only; --method "
                                    f"{args.method} takes --labels and --disparity-range")


def main(argv: Sequence[str] | None = None) -> int:
    """The ``hyperlf`` command: parse ``argv``, run the subcommand, return the exit status.

    Exit statuses: 0 success, 1 other error, 2 bad usage or impossible input, 3 unreadable or
    malformed file, 4 missing file, 130 interrupted (SIGINT), 143 terminated (SIGTERM), 129
    hung up (SIGHUP). An interrupted or failed command leaves its output as it was before.

    Examples
    --------
    The exit status comes back; the output path is printed even with ``-q``, and a refusal
    is one line on stderr (here: the output would replace the input):

    >>> import os, tempfile
    >>> scene = os.path.join(tempfile.mkdtemp(), "scene")
    >>> main(["-q", "synth", "procedural", "--size", "16,20", "--grid", "2,2", "-o", scene])
    /.../scene
    0
    >>> main(["-q", "depth", scene, "-o", scene])
    2
    """
    from .outputs import signals_as_exceptions

    argv = sys.argv[1:] if argv is None else [os.fspath(a) for a in argv]
    args = _parse(argv)
    if isinstance(args, int):
        return args
    args.argv = ["hyperlf", *argv]  # what made the result set, for its manifest
    with signals_as_exceptions():
        return _run_reporting(args, argv)


def _parse(argv: list[str]):
    """The parsed arguments, or the exit status of a refusal (its message printed)."""
    parser = build_parser()
    if any("\0" in a for a in argv):
        print("hyperlf: error: an argument contains a NUL character, which no file name or "
              "option value may hold; remove it",
              file=sys.stderr)
        return 2
    odd = [a for a in argv if a.startswith("-") and a.endswith("=--")]
    if odd:  # argparse (3.11) silently drops such a value
        print(f"hyperlf: error: {_one_line(odd[0])}: '--' is not a value; see 'hyperlf --help'",
              file=sys.stderr)
        return 2
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:  # named by the command they were given to, with its --help
            command = parser.commands.get(getattr(args, "command", None), parser)
            command.error(f"unrecognized arguments: {' '.join(extra)}")
    except ValueError as exc:  # argparse's own failures on odd values (e.g. '--opt=--')
        print(f"hyperlf: error: {_one_line(str(exc))}; see 'hyperlf --help'", file=sys.stderr)
        return 2
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    return args


def _run_reporting(args, argv: list[str]) -> int:
    """Run the subcommand; every failure becomes one line on stderr and its exit status."""
    from .outputs import received_interrupt

    try:
        _check_combinations(args, argv)
        return _run(args)
    except HyperLFError as exc:
        print(f"hyperlf {args.command}: error: {_one_line(str(exc))}", file=sys.stderr)
        return exc.exit_code
    except MemoryError:
        print(f"hyperlf {args.command}: error: out of memory; reduce the size of the work "
              "(--size, --grid, --labels) or free memory", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`, which closed early
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as exc:  # the output checks come first; this is the last resort
        where = f": {exc.filename}" if exc.filename else ""
        message = _no_room_message(args, exc) or (f"{_one_line(str(exc.strerror or exc))}"
                                                  f"{_one_line(where)}")
        print(f"hyperlf {args.command}: error: {message}", file=sys.stderr)
        if isinstance(exc, FileNotFoundError):
            return 4
        return 2 if exc.errno in (errno.ENAMETOOLONG, errno.ELOOP) else 1
    except KeyboardInterrupt as exc:  # Ctrl-C, or Terminated (SIGTERM, SIGHUP)
        return _interrupted(args, exc)
    except Exception as exc:
        # a signal that came while Python ran code that wraps what it raises (Python 3.11
        # turns an exception in a class's __set_name__, e.g. while colour-science is being
        # imported, into "RuntimeError: Error calling __set_name__"; C code that called
        # back into Python turns it into its own error): the run was stopped, not broken
        cause = _interrupt_cause(exc) or received_interrupt()
        if cause is None:
            no_room = _no_room_message(args, exc)
            if no_room is None:
                raise
            print(f"hyperlf {args.command}: error: {no_room}", file=sys.stderr)
            return 1
        return _interrupted(args, cause)


#: errno values of a write that found no room: the disk full, a file over the size limit
#: (``ulimit -f``), the disk quota spent.
_NO_ROOM = {getattr(errno, n): text for n, text in (
    ("ENOSPC", "no space left on the device; free space there"),
    ("EFBIG", "a file grew past the size limit; raise it (ulimit -f)"),
    ("EDQUOT", "the disk quota is spent; free space within it")) if hasattr(errno, n)}


def _no_room_code(exc: BaseException | None) -> int | None:
    """The errno of :data:`_NO_ROOM` behind ``exc`` or an exception it was raised from or
    while handling, else None. HDF5 reports it in its own text (staging paths, a time stamp,
    ``errno = 27``), from closing a file also as a RuntimeError."""
    import re

    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        code = getattr(exc, "errno", None)
        if code not in _NO_ROOM and isinstance(exc, (OSError, RuntimeError)):
            found = re.search(r"errno = (\d+)", str(exc))
            code = int(found.group(1)) if found else None
        if code in _NO_ROOM:
            return code
        exc = exc.__cause__ or exc.__context__
    return None


def _no_room_message(args, exc: BaseException) -> str | None:
    """The one line for a write that found no room, or None for any other error."""
    code = _no_room_code(exc)
    if code is None:
        return None
    output = getattr(args, "output", None)
    where = f" while writing {_one_line(repr(str(output)))}" if output else ""
    problem, fix = _NO_ROOM[code].split("; ")
    return (f"the results did not fit: {problem}{where}; {fix} or write them elsewhere with "
            "-o (the output was left as it was)")


def _interrupt_cause(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C or :class:`Terminated` behind ``exc`` (its chain of causes), if any."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _interrupted(args, exc: KeyboardInterrupt) -> int:
    what = "terminated" if isinstance(exc, Terminated) else "interrupted"
    print(f"hyperlf {args.command}: {what}; the output holds its previous results "
          "(or the new ones, if they were complete)", file=sys.stderr)
    return getattr(exc, "exit_code", 130)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
