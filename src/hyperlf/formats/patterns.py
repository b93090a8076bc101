"""File-name patterns that name one file per camera: ``Cam-{index}.png``, ``v_{row}_{col}.tif``.

A pattern may use only the fields it is given (``row``, ``col``, ``index``, ...), each optionally
with a zero-padded width below 100 (``{index:02d}``); attributes, indices, conversions, other
format specs and stray braces are refused, so a pattern read from a file or typed by a user can
never reach into Python objects or ask for a gigantic width.
"""

from __future__ import annotations

import os
import re
import string
from typing import Sequence

from ..errors import InvalidInputError

__all__ = ["pattern_fields", "expand_pattern"]

#: The format spec a field may carry: an optional zero-padded width below 100 (``02d``).
_FIELD_SPEC = re.compile(r"0?\d{0,2}d?")


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
        The field names used, in order.

    Raises
    ------
    InvalidInputError
        A field that is not allowed, an attribute or index (``{row.x}``, ``{row[0]}``), a
        conversion, a width of 100 or more, or stray braces.

    Examples
    --------
    >>> pattern_fields("Cam-{index:02d}.png", ["row", "col", "index"])
    ['index']
    """
    names = [f"{{{a}}}" for a in allowed]
    names = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    bad = InvalidInputError(f"{what} {pattern!r} may only use {names}, optionally with a width "
                            "below 100 such as {" + allowed[0] + ":02d}")
    try:
        fields = [f for f in string.Formatter().parse(pattern) if f[1] is not None]
    except ValueError:
        raise bad from None
    for _, name, spec, conversion in fields:
        if name not in allowed or conversion or not _FIELD_SPEC.fullmatch(spec or ""):
            raise bad
    return [f[1] for f in fields]


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
    """
    pattern_fields(pattern, allowed, what=what)
    name = pattern.format(**values)
    if any(len(os.fsencode(part)) > 255 for part in name.replace("\\", "/").split("/")):
        raise InvalidInputError(f"{what} {pattern!r} gives a name longer than 255 bytes")
    return name
