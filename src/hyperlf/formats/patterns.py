"""File-name patterns that name one file per camera: ``Cam-{index}.png``, ``v_{row}_{col}.tif``.

A pattern may use only the fields it is given (``row``, ``col``, ``index``, ...), each optionally
plus a number for files numbered from it (``{index+1}`` for Cam-1 ... Cam-9) and with a
zero-padded width below 100 (``{index:02d}``); attributes, indices, conversions, other format
specs and stray braces are refused, so a pattern read from a file or typed by a user can never
reach into Python objects or ask for a gigantic width.
"""

from __future__ import annotations

import os
import re
import string
from typing import Sequence

from .._options import integer, shown, text
from ..errors import InvalidInputError

__all__ = ["pattern_fields", "expand_pattern"]

#: The format spec a field may carry: an optional zero-padded width below 100 (``02d``).
_FIELD_SPEC = re.compile(r"0?\d{0,2}d?")


#: A field: an allowed name, optionally plus a number below 10000 (``index+1``).
_FIELD_NAME = re.compile(r"(\w+?)(?:\+(\d{1,4}))?")


def _parse(pattern: str, allowed: Sequence[str], what: str) -> list[tuple]:
    """``(literal, name, offset, spec)`` per part of ``pattern`` (name None after the last
    field); refuses what :func:`pattern_fields` documents."""
    text(what, "what")
    if not isinstance(allowed, (list, tuple)) or not allowed or not all(
            isinstance(a, str) for a in allowed):
        raise InvalidInputError(f"allowed must be a list of field names (text), got "
                                f"{shown(allowed)}")
    if not isinstance(pattern, str):
        raise InvalidInputError(f"{what} must be a file name pattern (text), got "
                                f"{shown(pattern)}")
    names = [f"{{{a}}}" for a in allowed]
    names = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    bad = InvalidInputError(f"{what} {pattern!r} may only use {names}, optionally plus a number "
                            "(files numbered from 1: {" + allowed[0] + "+1}) and with a width "
                            "below 100 such as {" + allowed[0] + ":02d}")
    try:
        parts = list(string.Formatter().parse(pattern))
    except ValueError:
        raise bad from None
    out = []
    for literal, field, spec, conversion in parts:
        if field is None:
            out.append((literal, None, 0, ""))
            continue
        m = _FIELD_NAME.fullmatch(field)
        if not m or m.group(1) not in allowed or conversion \
                or not _FIELD_SPEC.fullmatch(spec or ""):
            raise bad
        out.append((literal, m.group(1), int(m.group(2) or 0), spec or ""))
    return out


def pattern_fields(pattern: str, allowed: Sequence[str], *, what: str = "pattern") -> list[str]:
    """The fields ``pattern`` uses (empty for a plain name); refuse anything else.

    Parameters
    ----------
    pattern : str
        E.g. ``"Cam-{index}.png"``.
    allowed : sequence of str
        Field names the pattern may use.
    what : str
        How messages name the pattern.

    Returns
    -------
    list of str
        The field names used, in order (``index`` for ``{index+1}``).

    Raises
    ------
    InvalidInputError
        A field that is not allowed, an attribute or index (``{row.x}``, ``{row[0]}``), a
        conversion, a width of 100 or more, or stray braces.

    Examples
    --------
    >>> pattern_fields("Cam-{index:02d}.png", ["row", "col", "index"])
    ['index']
    >>> pattern_fields("r{row+1}c{col+1}.tif", ["row", "col", "index"])
    ['row', 'col']
    """
    return [name for _, name, _, _ in _parse(pattern, allowed, what) if name is not None]


def expand_pattern(pattern: str, allowed: Sequence[str], *, what: str = "pattern",
                   **values: int) -> str:
    """``pattern`` with its fields filled in from ``values`` (checked by :func:`pattern_fields`).

    Raises
    ------
    InvalidInputError
        A bad pattern, or a resulting name part longer than 255 bytes.

    Examples
    --------
    >>> expand_pattern("v_{row}_{col:02d}.png", ["row", "col"], row=1, col=2)
    'v_1_02.png'
    >>> expand_pattern("Cam-{index+1}.png", ["index"], index=0)
    'Cam-1.png'
    """
    parts = _parse(pattern, allowed, what)
    for field in {f for _, f, _, _ in parts if f is not None}:
        if field not in values:
            raise InvalidInputError(f"{what} {pattern!r} uses {{{field}}}, which has no value")
        values[field] = integer(values[field], field, maximum=2 ** 63)
    name = "".join(literal + ("" if field is None else format(values[field] + offset, spec))
                   for literal, field, offset, spec in parts)
    if any(len(os.fsencode(part)) > 255 for part in name.replace("\\", "/").split("/")):
        raise InvalidInputError(f"{what} {pattern!r} gives a name longer than 255 bytes")
    return name
