"""Every other option under every mode: the option fuzzers call each function with one base
set of arguments, so an option that matters only in another mode (``fwhm`` of a Gaussian
filter where the base call samples a Dirac one, ``half`` of the shift average under
``impl="numpy"``) was never reached.  Here each text argument that names a mode (its refusal
lists the modes: "must be one of a, b, c") is set to each of its other modes, and every other
argument of the call then takes junk; each call is taken or refused in one line of a hyperlf
error, with no NumPy warning.  The calls are those of the nested fuzzer's tables
(``test_options_nested``), in a temporary working folder."""

from __future__ import annotations

import functools
import inspect
import re

import numpy as np
import pytest

import test_options as T
import test_options_nested as N
from hyperlf.errors import HyperLFError

#: One of each kind of mistake (the hypothesis fuzzers draw from many more).
JUNK = (None, True, "x", "", -1, 0, 3, 10 ** 400, 1e308, -1e308, float("nan"), float("inf"),
        [], [1, 2], {}, {"a": None}, np.zeros(2), np.zeros((3, 3)), np.float32(1e38),
        np.int64(-5), np.bool_(True), 2.5)

_CHOICES = re.compile(r"^(.+?) must be one of (.+?), got ")
#: Modes a refusal lists by their Python names (``compression`` takes None and False).
_NAMED = {"None": None, "False": False, "True": True}


def _call(fn, kw):
    """``fn(**kw)`` in a temporary working folder, a RuntimeWarning raised: the result, or
    None where it was refused in one line."""
    with T._in_temp_folder("error", RuntimeWarning):
        return T._build_or_refuse(fn, **kw)


def _refusal(fn, kw) -> str | None:
    """Why ``fn(**kw)`` is refused (any other exception: its type), or None where it runs."""
    try:
        with T._in_temp_folder("ignore"):
            fn(**kw)
    except HyperLFError as exc:
        return str(exc)
    except Exception as exc:  # noqa: BLE001 - not a mode of this base call; judged elsewhere
        return type(exc).__name__
    return None


def _text_options(fn, base: dict) -> dict:
    """The call's text arguments: given in ``base``, or text defaults of its signature."""
    out = {k: v for k, v in base.items() if isinstance(v, str)}
    try:
        params = inspect.signature(fn).parameters.items()
    except (TypeError, ValueError):
        return out
    return {**{k: p.default for k, p in params if isinstance(p.default, str)
               and k not in base}, **out}


@functools.lru_cache(maxsize=1)
def _sites() -> list:
    """``(table entry, mode keyword, mode)`` for every other mode the call names.  Whether
    the base arguments suit a mode is not asked: the answer may depend on the data found
    (a Thorlabs filter) and so differ between runs; a mode they do not suit is refused in
    one line, as the junk is."""
    sites = []
    for name, (fn, base) in N._tables().items():
        for key, value in _text_options(fn, base).items():
            words = _refusal(fn, {**base, key: "__no such mode__"})
            m = _CHOICES.match(words or "")
            if m:
                modes = (_NAMED.get(c.strip(), c.strip()) for c in m.group(2).split(","))
                sites += [(name, key, mode) for mode in modes if mode != value]
    return sites


def _base_under(fn, base: dict, key: str, mode) -> dict:
    """The base arguments with ``key=mode``, and where the mode refuses one of them (SGM's
    ``params`` under ``optimizer="graphcut"``), without the first such one: so the other
    arguments are judged under the mode, not all refused for the same reason."""
    under = {**base, key: mode}
    if _refusal(fn, under) is None:
        return under
    for other in base:
        fewer = {k: v for k, v in under.items() if k != other}
        if other != key and _refusal(fn, fewer) is None:
            return fewer
    return under


def test_the_modes_are_found():
    found = {(n, k) for n, k, _ in _sites()}
    assert len(_sites()) >= 60
    assert {("test_options.filter_response", "shape"),
            ("test_options_costs.average_over_shift", "impl"),
            ("pipeline.depth", "optimizer")} <= found


@pytest.mark.parametrize("site", _sites(), ids=lambda s: f"{s[0]}-{s[1]}={s[2]}")
def test_every_other_option_under_every_mode(site):
    name, key, mode = site
    fn, base = N._tables()[name]
    under = _base_under(fn, base, key, mode)
    for other in base:
        if other == key:
            continue
        for junk in JUNK:
            _call(fn, {**under, other: junk})
