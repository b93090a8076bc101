"""Helpers shared by the benchmark scripts (imported as a sibling module: the scripts run as
``python benchmarks/<name>.py``, which puts this folder on ``sys.path``)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

from hyperlf.datasets import dataset_path
from hyperlf.errors import DataNotFoundError


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def hyperlf(*argv) -> float:
    """``hyperlf ARGV`` in a subprocess, as a user runs it (an error stops the script); its
    wall time in seconds."""
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "hyperlf", *map(str, argv)], check=True)
    return time.perf_counter() - t


def option_suffix(options=()) -> str:
    """What extra command-line ``options`` add to the names of their outputs
    (``--optimizer=sgm`` -> ``-optimizer=sgm``)."""
    return "".join("-" + o.lstrip("-") for o in options)


def data_path(name: str) -> Path:
    """A dataset under HYPERLF_DATA (:func:`hyperlf.datasets.dataset_path`); exit with its
    one-line message, prefixed by the script's name, when the data is missing."""
    try:
        return dataset_path(name)
    except DataNotFoundError as exc:
        sys.exit(f"{Path(sys.argv[0]).name}: {exc}")


def write_report(folder: Path, stem: str, markdown: str, report: dict) -> None:
    """Print the markdown table and write ``stem.md`` and ``stem.json`` into ``folder``."""
    from hyperlf._atomic import atomic_write_text

    print(markdown)
    atomic_write_text(folder / f"{stem}.md", markdown)
    atomic_write_text(folder / f"{stem}.json", json.dumps(report, indent=2, default=float))


def json_object(text: str) -> dict:
    """An argparse ``type``: a JSON object (``'{"weight": 3}'``), or the script exits with a
    one-line message that says what was wrong."""
    import argparse

    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not JSON ({exc.msg}): {text!r}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"expected a JSON object such as "
                                         f"'{{\"weight\": 3}}', got {text!r}")
    return value


def add_stereo_options(ap) -> None:
    """``--params`` and ``--cost-params`` of the two-view benchmarks: keyword options passed
    to :func:`hyperlf.twoview.stereo` for every cost, so that a candidate default is measured
    on the tuning sets by the scripts that report them, not by a throw-away copy."""
    ap.add_argument("--params", type=json_object, default=None, metavar="JSON",
                    help="optimiser parameters over each cost's defaults, e.g. "
                         "'{\"weight\": 3, \"truncation\": 4}' (twoview.stereo's params)")
    ap.add_argument("--cost-params", type=json_object, default=None, metavar="JSON",
                    help="cost options, e.g. '{\"weights\": [1, 3]}' for a fusion's part "
                         "weights (twoview.stereo's cost_params)")
    ap.add_argument("--hole-params", type=json_object, default=None, metavar="JSON",
                    help="graph cuts' holes step, e.g. '{\"enabled\": true}' (the fields "
                         "of hyperlf.regularisers.HoleParams; twoview.stereo's hole_params)")


def stereo_options(args) -> dict:
    """The keyword options of :func:`hyperlf.twoview.stereo` that :func:`add_stereo_options`
    parsed (empty when none was given); a bad ``--hole-params`` exits with one line."""
    from hyperlf.errors import InvalidInputError
    from hyperlf.regularisers import HoleParams

    out = {k: v for k, v in (("params", args.params), ("cost_params", args.cost_params))
           if v is not None}
    if args.hole_params is not None:
        try:
            out["hole_params"] = HoleParams(**args.hole_params)
        except (InvalidInputError, TypeError) as exc:
            raise SystemExit(f"--hole-params: {exc}") from None
    return out


def check_candidate_out(ap, args, default_out: str, *, departures=()) -> None:
    """A run with ``--params`` / ``--cost-params``, or with any of ``departures`` (the names
    of a script's other options given off their defaults), measures a candidate, not the
    defaults that ``default_out`` records: it must name its own ``--out``."""
    given = [f"--{k.replace('_', '-')}" for k in stereo_options(args)] + list(departures)
    if given and args.out == default_out:
        ap.error(f"{' / '.join(given)} measure a candidate: give it its own --out "
                 f"instead of {default_out}, which records the defaults")


def depth_picture(path: Path, name: str, lf, disp) -> None:
    """The reference view of the light field ``lf``, its ground truth, the estimate ``disp``
    and its error side by side, titled ``name``, as a PNG at ``path``."""
    from hyperlf.visualise import pyplot, save_figure

    plt = pyplot()
    gt = lf.reference_gt_disparity
    lo, hi = float(gt.min()), float(gt.max())
    fig, ax = plt.subplots(1, 4, figsize=(16, 3.6))
    panels = [(lf.views[lf.reference], "reference view", "gray", None, None),
              (gt, "ground truth", "viridis", lo, hi), (disp, "estimate", "viridis", lo, hi),
              (disp - gt, "estimate - truth (px)", "RdBu_r", -1.0, 1.0)]
    for a, (img, title, cmap, vmin, vmax) in zip(ax, panels):
        im = a.imshow(img, cmap=cmap, vmin=vmin, vmax=vmax)
        a.set_title(f"{name}: {title}", fontsize=9)
        a.axis("off")
        fig.colorbar(im, ax=a, fraction=0.046)
    save_figure(fig, path)
