"""Helpers shared by the benchmark scripts (imported as a sibling module: the scripts run as
``python benchmarks/<name>.py``, which puts this folder on ``sys.path``)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from hyperlf.datasets import dataset_path
from hyperlf.errors import DataNotFoundError


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


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
