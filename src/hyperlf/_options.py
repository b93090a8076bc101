"""Checking the value of one option: the one home of these rules.

The parameter classes (:class:`hyperlf.hlf.DepthParams`, the optimisers' parameters in
:mod:`hyperlf.regularisers.params`, the plane fill's, ...) and the library functions' keyword
options (:func:`hyperlf.completion.complete`, the regularisers, the baselines) are checked
here, so that a wrong value gets the same one-line :class:`InvalidInputError` everywhere,
never a ``TypeError`` or ``ValueError`` from deep inside. Each checker takes the
value and the label the message names it by (``"params.eps"``, ``"graphcut weight"``), and
returns the value in its canonical type.

Examples
--------
>>> number(0.5, "eps", positive=True)
0.5
>>> integer(4.0, "radius")
4
>>> integer(2.5, "radius")
Traceback (most recent call last):
...
hyperlf.errors.InvalidInputError: radius must be an integer >= 0, got 2.5
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping

import numpy as np

from .errors import InvalidInputError

__all__ = ["number", "real", "integer", "share", "flag", "choice", "real_array", "array",
           "all_finite", "real_pair", "int_pair", "index", "float_dtype", "bool_mask", "path_like",
           "path_list", "text", "instance",
           "shown", "rule", "word_or", "check_fields", "check_values", "params_of", "window",
           "mapping"]

_REAL = (int, float, np.integer, np.floating)


def _is_real(value) -> bool:
    """A finite real number, bools excluded (``True`` is an int to Python, not to a user)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, _REAL):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an int too large for a float
        return False


def number(value, label: str, *, positive: bool = False, optional: bool = False,
           below: float | None = None, at_most: float | None = None,
           at_least: float | None = None) -> float | None:
    """``value`` as a float, finite and ``>= 0`` (``> 0`` if ``positive``, ``>= at_least``
    where given), below ``below`` / at most ``at_most`` where given; None passes when
    ``optional``.

    Examples
    --------
    >>> number(2, "sigma", at_least=1e-6, at_most=1e6)
    2.0
    """
    if value is None and optional:
        return None
    ok = _is_real(value) and (value > 0 if positive else value >= 0)
    ok = ok and (at_least is None or value >= at_least)
    start = f"[{at_least:g}" if at_least is not None else "(0" if positive else "[0"
    if below is not None:
        low = f"in {start}, {below:g})"
        ok = ok and value < below
    elif at_most is not None:
        low = f"in {start}, {at_most:g}]"
        ok = ok and value <= at_most
    else:
        low = f">= {at_least:g}" if at_least is not None else "> 0" if positive else ">= 0"
    if not ok:
        none = " or None" if optional else ""
        raise InvalidInputError(f"{label} must be a finite number {low}{none}, got {shown(value)}")
    return float(value)


def real(value, label: str, *, nan: bool = False) -> float:
    """``value`` as a float of any sign, finite (or NaN where ``nan`` allows it: a fill value
    that marks what has none).

    Examples
    --------
    >>> real(-2, "fill"), real(float("nan"), "fill", nan=True)
    (-2.0, nan)
    """
    if nan and isinstance(value, (float, np.floating)) and math.isnan(value):
        return float(value)
    if not _is_real(value):
        what = "a finite number or NaN" if nan else "a finite number"
        raise InvalidInputError(f"{label} must be {what}, got {shown(value)}")
    return float(value)


def integer(value, label: str, minimum: int | None = 0, *, maximum: int | None = None,
            odd: bool = False, optional: bool = False) -> int | None:
    """``value`` as an int ``>= minimum`` (of any sign when ``minimum`` is None; and
    ``<= maximum``, odd where asked); an integral float such as ``4.0`` is taken, a bool or
    ``4.5`` is not; None passes when ``optional``.

    Examples
    --------
    >>> integer(4.0, "n"), integer(-3, "dmin", minimum=None)
    (4, -3)
    """
    if value is None and optional:
        return None
    ok = _is_real(value) and float(value).is_integer()
    ok = ok and (minimum is None or minimum <= value) and (maximum is None or value <= maximum)
    ok = ok and (not odd or int(value) % 2 == 1)
    if not ok:
        kind = f"an {'odd ' if odd else ''}integer"
        bound = (f" in {minimum}..{maximum}" if maximum is not None and minimum is not None
                 else f" <= {maximum}" if maximum is not None
                 else f" >= {minimum}" if minimum is not None else "")
        none = "None or " if optional else ""
        raise InvalidInputError(f"{label} must be {none}{kind}{bound}, got {shown(value)}")
    return int(value)


def share(value, label: str) -> float:
    """``value`` as a float in ``[0, 1]``."""
    if _is_real(value) and value > 1:
        raise InvalidInputError(f"{label} must be a share in [0, 1], got {shown(value)}")
    return number(value, label)


def flag(value, label: str) -> bool:
    """``value`` as a bool; only ``True`` and ``False`` (numpy's too) are flags."""
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidInputError(f"{label} must be True or False, got {shown(value)}")
    return bool(value)


def choice(value, label: str, choices):
    """``value`` itself, when it is one of ``choices``."""
    try:
        ok = value in choices
    except (TypeError, ValueError):  # unhashable, or an array with no single truth value
        ok = False
    if not ok:
        raise InvalidInputError(f"{label} must be one of {', '.join(map(str, choices))}, "
                                f"got {shown(value)}")
    return value


def real_pair(value, label: str, what: str = "two finite numbers") -> tuple[float, float]:
    """``value`` as two finite floats: an offset ``(dx, dy)``, a range ``(low, high)``, a
    chromaticity ``(x, y)``; a refusal says ``what`` it takes.

    Examples
    --------
    >>> real_pair([1, 0.5], "offset")
    (1.0, 0.5)
    """
    pair = real_array(value, label)
    if pair.shape != (2,) or not np.isfinite(pair).all():
        raise InvalidInputError(f"{label} must be {what}, got {shown(value)}")
    return float(pair[0]), float(pair[1])


def int_pair(value, label: str, minimum: int | None = 1, *, maximum: int | None = None,
             what: str = "two integers") -> tuple[int, int]:
    """``value`` as two ints ``>= minimum`` (``<= maximum`` where given): a grid, a size, a
    board's corners; a refusal says ``what`` it takes.

    Examples
    --------
    >>> int_pair([5, 6.0], "grid")
    (5, 6)
    """
    try:
        a, b = value
        return integer(a, label, minimum, maximum=maximum), integer(b, label, minimum,
                                                                     maximum=maximum)
    except (TypeError, ValueError, InvalidInputError):
        bound = (f" in {minimum}..{maximum}" if maximum is not None and minimum is not None
                 else f" >= {minimum}" if minimum is not None else "")
        raise InvalidInputError(f"{label} must be {what}{bound}, got {shown(value)}") from None


def float_dtype(value, label: str = "dtype") -> np.dtype:
    """``value`` as numpy's float32 or float64 dtype (the precisions of the sampling and
    normalising helpers)."""
    try:
        dtype = np.dtype(value)
        ok = dtype in (np.float32, np.float64)
    except (TypeError, ValueError, SyntaxError):  # numpy parses text: '0:', '01'
        ok = False
    if not ok:
        raise InvalidInputError(f"{label} must be numpy.float32 or numpy.float64, got "
                                f"{shown(value)}")
    return dtype


def bool_mask(value, label: str, shape: tuple[int, ...], *, broadcast: bool = False,
              of: str = "the data") -> np.ndarray:
    """``value`` (bools or numbers, not text) as a bool mask of ``shape``, or broadcast to it
    where ``broadcast``; a bool array is used as it is (no copy of a cube-sized mask).

    Examples
    --------
    >>> bool_mask([1, 0], "valid", (2,)).tolist()
    [True, False]
    """
    mask = value if isinstance(value, np.ndarray) and value.dtype == np.bool_ else \
        real_array(value, label).astype(bool)
    if mask.shape == shape:
        return mask
    if broadcast:
        try:
            return np.broadcast_to(mask, shape)
        except ValueError:
            pass
    fits = "broadcast to" if broadcast else "match"
    raise InvalidInputError(f"{label} has shape {mask.shape}, which does not {fits} {of}'s "
                            f"{shape}")


def index(value, label: str, shape: tuple[int, ...]) -> tuple[int, ...]:
    """``value`` as a tuple of ``len(shape)`` integers, each within its axis of ``shape``: a
    view of a camera grid, say.

    Examples
    --------
    >>> index((1, 2.0), "view", (3, 3))
    (1, 2)
    >>> index((3, 0), "view", (3, 3))
    Traceback (most recent call last):
    ...
    hyperlf.errors.InvalidInputError: view must be 2 integers within (3, 3) (from 0), got (3, 0)
    """
    shape = tuple(int(n) for n in shape)
    try:
        items = tuple(value) if not isinstance(value, (str, bytes, dict)) else None
    except TypeError:  # not iterable
        items = None
    ok = items is not None and len(items) == len(shape) and all(
        _is_real(v) and float(v).is_integer() and 0 <= v < n for v, n in zip(items, shape))
    if not ok:
        raise InvalidInputError(f"{label} must be {len(shape)} integers within {shape} (from "
                                f"0), got {shown(value)}")
    return tuple(int(v) for v in items)


def shown(value, limit: int = 60) -> str:
    """``repr(value)`` on one line, cut at ``limit`` characters (for one-line messages)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def real_array(value, label: str, dtype=np.float64) -> np.ndarray:
    """``value`` as an array of ``dtype`` (its own where ``dtype`` is None); text (numerals
    included: ``"2"`` is not a number to this library), None (numpy would read it as NaN),
    mappings and ragged lists are refused (values too large for ``dtype`` become inf, for the
    caller's own finiteness rule).

    Examples
    --------
    >>> real_array([1, 2.5], "offsets")
    array([1. , 2.5])
    >>> real_array(["1", "2"], "offsets")
    Traceback (most recent call last):
    ...
    hyperlf.errors.InvalidInputError: offsets must be an array of real numbers, got ['1', '2']
    """
    try:
        raw = np.asarray(value)
        if _holds_text(raw):
            raise TypeError
        with np.errstate(over="ignore"):
            return raw.astype(dtype, copy=False) if dtype is not None else raw
    except (TypeError, ValueError, OverflowError):
        raise InvalidInputError(f"{label} must be an array of real numbers, got "
                                f"{shown(value)}") from None


def _holds_text(a: np.ndarray) -> bool:
    """Whether ``a`` is text, or an object array with text, None or a mapping among its
    entries."""
    if a.dtype.kind in "USV":
        return True
    return a.dtype.kind == "O" and any(v is None or isinstance(v, (str, bytes, Mapping))
                                       for v in a.flat)


_KINDS = {"biuf": "real numbers", "iuf": "real numbers", "iu": "integers", "f": "floats"}


def all_finite(a: np.ndarray) -> bool:
    """Whether every entry of the numeric ``a`` is finite: two reductions, no array the size
    of ``a`` (NaN propagates through min and max)."""
    if a.dtype.kind not in "fc" or a.size == 0:
        return True
    return bool(np.isfinite(a.min()) and np.isfinite(a.max()))


def array(value, label: str, shape=None, *, ndim: int | tuple[int, ...] | None = None,
          kinds: str = "biuf", empty: bool = True, finite: bool = False,
          bound: float | None = None, of: str = "") -> np.ndarray:
    """``value`` as an array (an ndarray as it is, no copy) of the numpy dtype ``kinds``, of
    ``shape`` (or ``ndim`` axes, an int or a tuple of those allowed) where given, non-empty
    unless ``empty``, finite where asked, and of magnitude at most ``bound`` where given
    (finite then too); ``of`` names where the shape comes from (``" (the problem's H x W)"``).
    Without ``finite`` or ``bound`` an ndarray is checked in O(1): nothing is scanned.

    Examples
    --------
    >>> array([[1, 2]], "offsets", ndim=2).shape
    (1, 2)
    >>> array([1.0, np.nan], "labels", finite=True)
    Traceback (most recent call last):
    ...
    hyperlf.errors.InvalidInputError: labels must be finite (no NaN or inf)
    """
    a = value if isinstance(value, np.ndarray) else real_array(value, label, dtype=None)
    if a.dtype.kind not in kinds:
        raise InvalidInputError(f"{label} must be an array of {_KINDS[kinds]}, got "
                                f"{shown(value)}")
    got = shown(value) if a.ndim == 0 else f"shape {a.shape}"
    if shape is not None and a.shape != tuple(shape):
        raise InvalidInputError(f"{label} must have shape {tuple(shape)}{of}, got {got}")
    ndims = (ndim,) if isinstance(ndim, int) else ndim
    if (ndims is not None and a.ndim not in ndims) or (a.size == 0 and not empty):
        want = "" if ndims is None else " " + " or ".join(f"{n}-D" for n in ndims)
        some = "" if empty else " non-empty"
        raise InvalidInputError(f"{label} must be a{some}{want} array{of}, got {got}")
    if (finite or bound is not None) and not all_finite(a):
        raise InvalidInputError(f"{label} must be finite (no NaN or inf)")
    if bound is not None and a.size and float(np.abs(a).max()) > bound:
        raise InvalidInputError(f"{label} must be at most {bound:g} in magnitude")
    return a


def text(value, label: str, *, optional: bool = False, printable: bool = False) -> str | None:
    """``value`` when it is a str (printable where asked: a title, a unit, a file-name stem),
    or None where ``optional``.

    Examples
    --------
    >>> text("Depth", "title")
    'Depth'
    """
    if value is None and optional:
        return None
    if not isinstance(value, str) or (printable and not value.isprintable()):
        what = "printable text (a str)" if printable else "text (a str)"
        raise InvalidInputError(f"{label} must be {what}{' or None' if optional else ''}, got "
                                f"{shown(value)}")
    return value


def instance(value, label: str, cls, what: str, *, optional: bool = False):
    """``value`` when it is a ``cls`` (``what`` names it: ``"a hyperlf.LightField"``), or None
    where ``optional``.

    Examples
    --------
    >>> instance(2, "count", int, "an int")
    2
    """
    if not isinstance(value, cls) and not (optional and value is None):
        none = " or None" if optional else ""
        raise InvalidInputError(f"{label} must be {what}{none}, got {type(value).__name__}")
    return value


def rule(check, **options):
    """``check`` with ``options`` fixed, called as ``rule(value, label)``.

    Examples
    --------
    >>> rule(integer, minimum=1, odd=True)(5.0, "window")
    5
    """
    return lambda value, label: check(value, label, **options)


def word_or(check, words, what: str):
    """A rule that keeps any of ``words`` (None among them, or strings such as ``"auto"``) as
    it is and checks anything else by the rule ``check``; a refusal says ``what`` it takes.

    Examples
    --------
    >>> passes = word_or(rule(integer, minimum=1), ("auto",), "'auto' or an integer >= 1")
    >>> passes("auto", "passes"), passes(2.0, "passes")
    ('auto', 2)
    """
    def checked(value, label):
        if any(value is w or (isinstance(value, str) and value == w) for w in words):
            return value
        try:
            return check(value, label)
        except InvalidInputError:
            raise InvalidInputError(f"{label} must be {what}, got {shown(value)}") from None
    return checked


def check_fields(obj, rules: dict, prefix: str = "") -> None:
    """Check every field ``name`` of the dataclass ``obj`` (frozen or not) by ``rules[name]``,
    naming it ``prefix + name``, and keep the value the rule returns."""
    for name, check in rules.items():
        object.__setattr__(obj, name, check(getattr(obj, name), prefix + name))


def check_values(values: dict, rules: dict, prefix: str = "") -> dict:
    """``values`` with each ``name`` in ``rules`` checked by its rule (named ``prefix + name``)
    and kept as the rule returns it: a function's keyword options."""
    return {**values, **{name: check(values[name], prefix + name)
                         for name, check in rules.items() if name in values}}


def params_of(value, label: str, cls):
    """``value`` as parameters of the class ``cls`` (None: its defaults)."""
    if value is None:
        return cls()
    if not isinstance(value, cls):
        raise InvalidInputError(f"{label} must be a {cls.__name__} (or None for its "
                                f"defaults), got {type(value).__name__}")
    return value


def window(value, label: str, *, side: int | None = None, of: str = "the image") -> int:
    """An odd window width ``>= 1`` that does not reach past ``of`` (``side`` px on its
    longer side) on both sides, i.e. at most ``2 side + 1``: wider asks for memory to no use.
    """
    n = integer(value, label, 1, odd=True)
    if side is not None and n > 2 * side + 1:
        raise InvalidInputError(f"{label} {n} px reaches past {of} on both sides ({side} px "
                                f"on its longer side); use at most {2 * side + 1}")
    return n


def mapping(value, label: str, *, optional: bool = True, keys=None,
            taker: str | None = None) -> Mapping | None:
    """``value`` when it is a mapping (a dict of options, images by camera), or None where
    ``optional``.  Where ``keys`` (names) is given, a key not among them is refused, naming
    what ``taker`` (default ``label``) takes; a key of any type is shown by its repr.

    Examples
    --------
    >>> mapping({"p1": 2}, "params", keys=("p1", "p2"), taker="sgm")
    {'p1': 2}
    """
    if not isinstance(value, Mapping) and not (value is None and optional):
        none = " (or None)" if optional else ""
        raise InvalidInputError(f"{label} must be a dict{none}, got {type(value).__name__}")
    strangers = [k for k in value or () if k not in keys] if keys is not None else []
    if strangers:
        raise InvalidInputError(f"unknown key {shown(strangers[0])} in {label}; "
                                f"{taker or label} takes {', '.join(keys) or 'no keys'}")
    return value


def path_like(value, label: str = "path", *, folder: bool | None = False):
    """``value`` when it names a file (a folder where ``folder``; either where None) to write:
    a non-empty ``str`` or ``os.PathLike`` without NUL characters, not an existing folder (not
    an existing file where ``folder``).

    Examples
    --------
    >>> path_like("out.pfm")
    'out.pfm'
    """
    text = os.fspath(value) if isinstance(value, (str, os.PathLike)) else None
    if not isinstance(text, str) or not text or "\0" in text:
        raise InvalidInputError(f"{label} must be a path (a non-empty str or os.PathLike), got "
                                f"{shown(value)}")
    if folder is True and os.path.exists(text) and not os.path.isdir(text):
        raise InvalidInputError(f"{label} {text} exists and is not a folder")
    if folder is False and os.path.isdir(text):
        raise InvalidInputError(f"{label} {text} is a folder; it must name a file")
    return value


def path_list(value, label: str, *, single: bool = False) -> list:
    """``value`` as a list of at least one path (each by :func:`path_like`, file or folder); a
    lone path too where ``single``.

    Examples
    --------
    >>> path_list(["a.png", "b.png"], "paths")
    ['a.png', 'b.png']
    """
    if single and isinstance(value, (str, os.PathLike)):
        return [path_like(value, label, folder=None)]
    try:
        items = list(value) if not isinstance(value, (str, bytes, dict, os.PathLike)) else None
    except TypeError:  # not iterable
        items = None
    if not items:
        what = "a path or a list of at least one path" if single else \
            "a list of at least one path"
        raise InvalidInputError(f"{label} must be {what}, got {shown(value)}")
    return [path_like(p, label, folder=None) for p in items]
