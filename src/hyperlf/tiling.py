"""Strips of the correspondence stage and the memory budget that sizes them (SPEC §12).

The depth of a capture holds a few volumes of ``L x H x W`` float32 (``L`` labels): the
aggregated correspondence volume that the MRF optimises, its view counts, the unary and the
MRF's own.  The correspondence stage needs more: per pixel and label it adds float32 sums and
counts (twice, for the selection and its fallback, when view selection is on) and the volumes
of the view being matched.  :func:`hyperlf.hlf.correspondence` can aggregate full-width
strips of rows one at a time, so that this part of the memory is held for one strip only; the
result is bit for bit the untiled one (the strips start on the :data:`hyperlf.costs.ROW_BLOCK`
grid, the views stay whole, so every sample and window reads the rows it needs, however far the
largest shift reaches: the halo is implicit; a cost with whole-view scales, the fusions,
measures them in one more pass).

:func:`plan` picks the tallest strips whose estimated peak (:func:`depth_memory`) fits a budget
(``DepthParams.max_memory``, ``hyperlf depth --max-memory``); :func:`parse_memory` reads a
budget such as ``"6G"``.  The estimate's coefficients were measured (BENCHMARKS.md, "Tiles").

Examples
--------
>>> from hyperlf.tiling import parse_memory, plan
>>> parse_memory("1.5G") == 1.5 * 2**30
True
>>> plan((384, 512), 64, 30, max_memory=None)        # fits: one strip
[(0, 384)]
>>> plan((384, 512), 64, 30, max_memory=parse_memory("640M"))
[(0, 160), (160, 320), (320, 384)]
"""

from __future__ import annotations

import math
import os
import re

import numpy as np

from . import _options as _opt
from .errors import InvalidInputError

__all__ = [
    "DEFAULT_MAX_MEMORY",
    "parse_memory",
    "format_memory",
    "available_memory",
    "check_memory",
    "check_label_volume",
    "check_strips",
    "row_strips",
    "depth_memory",
    "plan",
]

#: The budget when none is given: 16 GiB, which leaves 8 GiB to the system and other work on a
#: 24 GB machine.
DEFAULT_MAX_MEMORY = 16 * 2 ** 30

#: Bytes of the interpreter with numpy, numba, OpenCV and SciPy loaded (measured 0.25 GiB).
_PROCESS_BYTES = 0.3 * 2 ** 30
#: Bytes per pixel of every view that depth holds whatever the strips: the view (float32), its
#: normalised copy and gradient magnitude (float64 each); measured 20.
_IMAGE_BYTES = 20.0
#: Bytes per pixel and label of the MRF stage: the correspondence volume, the unary and the
#: graph's own (measured 16.7 with the view counts still held; planned with a margin).
_VOLUME_BYTES = 18.0
#: Bytes per pixel and label of a strip being aggregated: the sums and counts, one view's cost
#: parts (a fusion normalises them in place and sums into the first), its validity, and the
#: finishing temporaries (measured 20; with a margin).
_STRIP_BYTES = 22.0
#: Bytes per pixel and label that view selection adds to a strip: the selected views' sums and
#: counts apart from all views', and their merge (measured 17.4).
_SELECTION_STRIP_BYTES = 18.0
#: Bytes per pixel and label of the whole volume and its view counts that the strips fill.
_GATHER_BYTES = 8.0
#: Bytes per pixel and label of the view-selection means ``Mbar`` and one view's ``M(q_v)``.
_SELECTION_BYTES = 8.0

_UNITS = {"": 1, "B": 1, "K": 2 ** 10, "KB": 2 ** 10, "KIB": 2 ** 10, "M": 2 ** 20,
          "MB": 2 ** 20, "MIB": 2 ** 20, "G": 2 ** 30, "GB": 2 ** 30, "GIB": 2 ** 30,
          "T": 2 ** 40, "TB": 2 ** 40, "TIB": 2 ** 40}
#: The largest byte count the memory helpers take (far beyond any machine, within a float).
_MAX_BYTES = 2.0 ** 1000
_MEMORY = re.compile(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([A-Za-z]*)\s*")


def parse_memory(text) -> int:
    """Bytes of a memory size: a number with an optional binary unit.

    ``"512M"``, ``"6G"``, ``"1.5GiB"``, ``"16GB"`` (K, M, G, T are powers of 1024, with or
    without ``B`` / ``iB``; case does not matter); a plain number is bytes.

    Raises
    ------
    InvalidInputError
        Not such a size, or not positive.

    Examples
    --------
    >>> parse_memory("512M"), parse_memory("2gb"), parse_memory(4096)
    (536870912, 2147483648, 4096)
    """
    if isinstance(text, bool):
        raise InvalidInputError(f"a memory size must be a number with a unit (e.g. 6G), got {text!r}")
    if isinstance(text, (int, float)):
        try:
            value, unit = float(text), ""
        except OverflowError:  # an int beyond a float
            raise InvalidInputError(f"a memory size must be at most {_MAX_BYTES:.3g} bytes, "
                                    f"got {_opt.shown(text)}") from None
    else:
        m = _MEMORY.fullmatch(str(text))
        if m is None or m.group(2).upper() not in _UNITS:
            raise InvalidInputError(
                f"a memory size must be a number with an optional unit K, M, G or T (e.g. 6G), "
                f"got {text!r}")
        value, unit = float(m.group(1)), m.group(2).upper()
    nbytes = value * _UNITS[unit]
    if not math.isfinite(nbytes) or nbytes < 1:
        raise InvalidInputError(f"a memory size must be at least 1 byte, got {_opt.shown(text)}")
    return int(nbytes)


def format_memory(nbytes: float) -> str:
    """``"1.5 GiB"``-style text of a byte count (for messages).

    Examples
    --------
    >>> format_memory(1.5 * 2 ** 30), format_memory(3 * 2 ** 20), format_memory(512)
    ('1.5 GiB', '3 MiB', '512 B')
    """
    nbytes = _opt.number(nbytes, "nbytes")
    for unit, scale in (("GiB", 2 ** 30), ("MiB", 2 ** 20), ("KiB", 2 ** 10)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{int(nbytes)} B"


def available_memory() -> int:
    """Bytes of memory available now (``MemAvailable`` on Linux, else the physical memory).

    Examples
    --------
    >>> available_memory() > 0
    True
    """
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def check_memory(nbytes: float, what: str, remedy: str) -> None:
    """Refuse, before any work, work whose arrays would need more than the available memory.

    Raises
    ------
    InvalidInputError
        ``"{what} would need about ... of memory, more than the ... available; {remedy}"``;
        or ``nbytes`` is not a number >= 0, ``what`` or ``remedy`` not text.

    Examples
    --------
    An exbibyte is refused, before anything is allocated, with the remedy given:

    >>> from hyperlf.errors import InvalidInputError
    >>> try:
    ...     check_memory(2 ** 60, "this volume", "use fewer labels")
    ... except InvalidInputError as exc:
    ...     print(str(exc).split(" would")[0], "/", str(exc).rsplit("; ", 1)[1])
    this volume / use fewer labels
    """
    _check_bytes(nbytes)
    _opt.text(what, "what"), _opt.text(remedy, "remedy")
    avail = available_memory()
    if nbytes > avail:
        # an int beyond a float: at least this (a numpy scalar converts as it is)
        big = float(min(nbytes, 2 ** 1000)) if isinstance(nbytes, int) else float(nbytes)
        gib = big / 2 ** 30
        raise InvalidInputError(f"{what} would need about {gib:.3g} GiB of memory, more than "
                                f"the {avail / 2 ** 30:.3g} GiB available; {remedy}")


def _check_bytes(nbytes) -> None:
    """A byte count: a number >= 0 (an int beyond a float too: it is refused as too large)."""
    ok = isinstance(nbytes, (int, float, np.integer, np.floating)) and not isinstance(
        nbytes, (bool, np.bool_)) and nbytes >= 0  # NaN is not >= 0
    if not ok:
        raise InvalidInputError(f"nbytes must be a number >= 0, got {_opt.shown(nbytes)}")


def _image_size(shape, label: str = "shape") -> tuple[int, int]:
    """``(H, W)`` of ``shape`` ``(..., H, W)``: two ints >= 1."""
    try:
        tail = tuple(shape)[-2:] if not isinstance(shape, (str, bytes, dict)) else None
    except TypeError:  # not iterable
        tail = None
    if tail is None:
        raise InvalidInputError(f"{label} must be an image size (..., H, W), got "
                                f"{_opt.shown(shape)}")
    return _opt.int_pair(tail, label, 1, maximum=2 ** 31, what="an image size (..., H, W)")


def check_label_volume(n_labels: int, shape) -> None:
    """Refuse ``n_labels`` whose float32 volume over images of ``shape`` ``(..., H, W)``
    exceeds the memory available (:func:`check_memory`): one volume, a lower bound of any
    matcher's need.

    Examples
    --------
    64 labels over 512 x 512 px views need 64 MiB of float32 volume, which any machine
    running this has:

    >>> check_label_volume(64, (30, 512, 512)) is None
    True
    """
    n_labels = _opt.integer(n_labels, "n_labels", 1)
    H, W = _image_size(shape)
    check_memory(4.0 * n_labels * H * W, f"{count_text(n_labels)} labels on {W} x {H} px views",
                 "use fewer labels")


def count_text(n: int) -> str:
    """A count as people read it: ``64``, or ``1e+300`` for a count beyond a billion."""
    return str(n) if abs(n) < 10 ** 9 else f"{float(min(abs(n), 10 ** 308)):.3g}"


def row_strips(height: int, rows: int) -> list[tuple[int, int]]:
    """Full-width strips of ``rows`` rows (a multiple of :data:`hyperlf.costs.ROW_BLOCK`; the
    last one shorter) covering ``height`` rows in order.

    Examples
    --------
    >>> row_strips(100, 32)
    [(0, 32), (32, 64), (64, 96), (96, 100)]
    """
    from .costs import ROW_BLOCK

    height = _opt.integer(height, "height", maximum=2 ** 31)
    rows = _opt.integer(rows, "rows", maximum=2 ** 31)
    if rows < ROW_BLOCK or rows % ROW_BLOCK:
        raise InvalidInputError(f"strips must be a positive multiple of {ROW_BLOCK} rows, got {rows}")
    return [(a, min(a + rows, height)) for a in range(0, height, rows)]


def check_strips(strips, height: int) -> list[tuple[int, int]]:
    """``strips`` as a list of ``(a, b)`` covering rows ``0 .. height - 1`` in order, each
    starting on the :data:`hyperlf.costs.ROW_BLOCK` grid; None = one strip of every row.

    Examples
    --------
    >>> check_strips(None, 10), check_strips([(0, 32), (32, 50)], 50)
    ([(0, 10)], [(0, 32), (32, 50)])
    """
    from .costs import check_rows

    height = _opt.integer(height, "height", 1, maximum=2 ** 31)
    if strips is None:
        return [(0, height)]
    try:
        items = list(strips) if not isinstance(strips, (str, bytes, dict)) else None
    except TypeError:  # not iterable
        items = None
    if items is None or any(s is None for s in items):
        raise InvalidInputError(f"strips must be a list of (a, b) row ranges (or None), got "
                                f"{_opt.shown(strips)}")
    out = [check_rows(s, height) for s in items]
    starts = [a for a, _ in out]
    stops = [b for _, b in out]
    if not out or starts[0] != 0 or stops[-1] != height or starts[1:] != stops[:-1]:
        raise InvalidInputError(f"strips must cover rows 0 .. {height - 1} in order without gaps, "
                                f"got {strips!r}")
    return out


def depth_memory(shape, n_labels: int, n_views: int, *, strip_rows: int | None = None,
                 selection: bool = False) -> float:
    """Estimated peak bytes of :func:`hyperlf.hlf.depth` (coefficients measured: module
    docstring).

    Parameters
    ----------
    shape : (H, W)
        Image size.
    n_labels, n_views : int
        Labels, and views in the grid.
    strip_rows : int, optional
        Rows per strip of the correspondence stage; None = one strip.
    selection : bool
        View selection on (its per-label maps).

    Examples
    --------
    Strips of rows lower the peak of the correspondence stage:

    >>> whole = depth_memory((512, 512), 64, 30)
    >>> bool(depth_memory((512, 512), 64, 30, strip_rows=64) < whole)
    True
    """
    H, W, n_labels, n_views = _sizes(shape, n_labels, n_views)
    strip_rows = _opt.integer(strip_rows, "strip_rows", 1, optional=True)
    return _peak(H, W, n_labels, n_views, strip_rows, _opt.flag(selection, "selection"))


def _sizes(shape, n_labels, n_views) -> tuple[int, int, int, int]:
    """The image size ``(H, W)``, the labels and the views of :func:`depth_memory`."""
    H, W = _opt.int_pair(shape, "shape", 1, maximum=2 ** 31, what="(H, W)")
    return (H, W, _opt.integer(n_labels, "n_labels", 1, maximum=2 ** 53),
            _opt.integer(n_views, "n_views", 1, maximum=2 ** 53))


def _peak(H: int, W: int, n_labels: int, n_views: int, strip_rows: int | None,
          selection: bool) -> float:
    """:func:`depth_memory` of checked values."""
    px = float(H * W)
    lw = float(n_labels) * W
    rows = H if strip_rows is None else min(int(strip_rows), H)
    fixed = _PROCESS_BYTES + _IMAGE_BYTES * n_views * px
    per_strip = _STRIP_BYTES
    if selection:
        fixed += _SELECTION_BYTES * n_labels * px
        per_strip += _SELECTION_STRIP_BYTES
    strip = per_strip * lw * rows
    if rows < H:  # the strips are gathered into the whole volume and its counts
        strip += _GATHER_BYTES * n_labels * px
    return fixed + max(_VOLUME_BYTES * n_labels * px, strip)


def plan(shape, n_labels: int, n_views: int, max_memory: float | None, *,
         selection: bool = False, tile_rows: int | None = None) -> list[tuple[int, int]]:
    """The strips of the correspondence stage: one when the estimated peak fits
    ``max_memory`` (None = :data:`DEFAULT_MAX_MEMORY`), else the tallest strips that fit;
    ``tile_rows`` forces their height (a multiple of :data:`hyperlf.costs.ROW_BLOCK`).

    Raises
    ------
    InvalidInputError
        Even strips of :data:`hyperlf.costs.ROW_BLOCK` rows would not fit: the message says
        how much is needed.

    Examples
    --------
    One strip when the estimate fits the budget, else the tallest strips that fit, in
    order and covering every row:

    >>> plan((512, 512), 64, 30, 16 * 2 ** 30)
    [(0, 512)]
    >>> whole = depth_memory((512, 512), 64, 30)
    >>> thinnest = depth_memory((512, 512), 64, 30, strip_rows=32)
    >>> strips = plan((512, 512), 64, 30, (whole + thinnest) / 2)
    >>> len(strips) > 1, strips[0][0], strips[-1][1]
    (True, 0, 512)
    """
    from .costs import ROW_BLOCK

    H, W, n_labels, n_views = _sizes(shape, n_labels, n_views)
    max_memory = _opt.number(max_memory, "max_memory", positive=True, optional=True)
    selection = _opt.flag(selection, "selection")
    if tile_rows is not None:
        return row_strips(H, tile_rows)
    budget = DEFAULT_MAX_MEMORY if max_memory is None else max_memory
    est = lambda rows: _peak(H, W, n_labels, n_views, rows, selection)  # noqa: E731
    if est(None) <= budget:
        return [(0, H)]
    rows = (H // ROW_BLOCK) * ROW_BLOCK
    while rows >= ROW_BLOCK and est(rows) > budget:
        rows -= ROW_BLOCK
    if rows < ROW_BLOCK:
        raise InvalidInputError(
            f"depth of {W} x {H} px with {n_labels} labels needs about "
            f"{format_memory(est(ROW_BLOCK))} even in strips of {ROW_BLOCK} rows, more than the "
            f"{format_memory(budget)} allowed; raise --max-memory or use fewer --labels")
    return row_strips(H, rows)
