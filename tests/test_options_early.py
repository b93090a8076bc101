"""Bad input is refused before any long work starts.  The option fuzzers check that junk is
taken or refused in one line, not *when*: ``twoview.stereo_from_volumes`` solved the whole
left map (seconds to minutes on a real pair) before it refused a right volume of the wrong
shape or a guide it could not use.  Here the start of long work is a sentinel (the first step
of any progress bar, or a call of the regularisers' solver), and each argument of the calls
that do long work takes each kind of junk: a value refused without the sentinel must be
refused with it, that is before long work."""

from __future__ import annotations

import contextlib
import functools

import numpy as np
import pytest

from conftest import LongWork, long_work_stopped
import test_options as T
import test_options_modes as M
import test_options_nested as N
from hyperlf._options import shown
from hyperlf.errors import HyperLFError

#: The calls of the fuzzers' tables whose base arguments reach long work.
_TABLE_SITES = (
    "test_options.stereo_from_volumes", "test_options.procedural_scene",
    "test_options_api_io.write_lightfield_pictures", "test_options_compute.emulate_camera",
    "test_options_hlf.correspondence", "test_options_hlf.regularise",
    "test_options_io.write_capture", "test_options_io.save_lightfield",
    "test_options_io.naive_completion", "test_options_io.naive_completion to a file",
    "render.refocus", "render.focal_stack", "render.emulate_camera", "pipeline.depth",
    "pipeline.complete", "pipeline.pairwise_disparities")


def _outcome(fn, kw: dict, *, sentinels: bool) -> str:
    """``"long work"``, ``"refused: <message>"``, ``"ran"`` or the type of another error."""
    with contextlib.ExitStack() as stack:
        stack.enter_context(T._in_temp_folder("ignore"))
        if sentinels:
            stack.enter_context(long_work_stopped())
        try:
            fn(**kw)
        except LongWork:
            return "long work"
        except HyperLFError as exc:
            return f"refused: {exc}"
        except Exception as exc:  # noqa: BLE001 - judged by the other fuzzers
            return type(exc).__name__
    return "ran"


#: Calls with long work that the fuzzers' tables reach only through lambdas.
_OWN_SITES = ("twoview.stereo", "render.focal_sweep", "baselines.tao2013",
              "baselines.wang2015", "baselines.lin2015")


@functools.lru_cache(maxsize=1)
def _sites() -> dict:
    from hyperlf import baselines, render, twoview

    rng = np.random.default_rng(0)
    left = rng.random((20, 28)).astype(np.float32)
    lf = N._tables()["pipeline.depth"][1]["lf"]  # the nested fuzzer's small light field
    own = {"twoview.stereo": (twoview.stereo, dict(left=left, right=np.roll(left, -2, axis=1),
                                                   disparity_range=(0, 4))),
           "render.focal_sweep": (render.focal_sweep, dict(
               views_or_cube=lf.gt_cube, offsets=lf.offsets, disparities=[0.0, 0.5],
               profile="CIE 1931", wavelengths=lf.cube_wavelengths, out_dir="sweep",
               formats=("gif",)))}
    for fn in (baselines.tao2013, baselines.wang2015, baselines.lin2015):
        own[f"baselines.{fn.__name__}"] = (fn, dict(lf=lf, n_labels=4))
    return {**{name: N._tables()[name] for name in _TABLE_SITES}, **own}


@pytest.mark.parametrize("name", [*_TABLE_SITES, *_OWN_SITES])
def test_refused_before_long_work(name):
    fn, base = _sites()[name]
    assert _outcome(fn, base, sentinels=True) == "long work", \
        f"{name}'s base call no longer reaches long work; update _TABLE_SITES"
    late = []
    for key in base:
        for junk in M.JUNK:
            kw = {**base, key: junk}
            if _outcome(fn, kw, sentinels=True) != "long work":
                continue
            plain = _outcome(fn, kw, sentinels=False)
            if plain.startswith("refused"):
                late.append(f"{key}={shown(junk)}: {plain}")
    assert not late, f"{name} refused only after long work started: " + "; ".join(late[:4])
