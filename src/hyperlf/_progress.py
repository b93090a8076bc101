"""Progress bars for long operations (tqdm on stderr).

Functions that take a while accept ``progress: bool`` (default False, so library calls stay
silent); the command-line tool turns it on unless ``--quiet`` is given.
"""

from __future__ import annotations

from typing import Iterable, Iterator, TypeVar

T = TypeVar("T")

__all__ = ["progress_bar", "grid_views"]


def progress_bar(iterable: Iterable[T], desc: str, total: int | None = None,
                 enabled: bool = False, unit: str = "it") -> Iterator[T]:
    """Wrap ``iterable`` in a tqdm bar when ``enabled``; otherwise return it unchanged."""
    if not enabled:
        return iter(iterable)
    from tqdm.auto import tqdm

    return iter(tqdm(iterable, desc=desc, total=total, unit=unit, leave=False, dynamic_ncols=True))


def grid_views(rows: int, cols: int, desc: str = "views",
               enabled: bool = False) -> Iterator[tuple[int, int]]:
    """``(r, c)`` for every view in raster order, with a progress bar when ``enabled``."""
    views = [(r, c) for r in range(rows) for c in range(cols)]
    return progress_bar(views, desc, total=len(views), enabled=enabled, unit="view")
