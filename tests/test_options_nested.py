"""Junk inside a container argument: one entry of a dict or a sequence replaced by junk, or
junk added as a key or an entry, in every function of the option fuzzers' call tables
(``test_options``, ``test_options_api_io``, ``test_options_calibration``,
``test_options_compute``, ``test_options_costs``, ``test_options_hlf``).  Each call is taken
or refused in one line of a hyperlf error, with no NumPy warning.  The top-level fuzzers
replace a whole argument and never reached inside one: a NumPy scalar among a calibration's
cameras raised ValueError, a huge integer among a fusion's weights OverflowError, text weights
were taken, and a view offset beyond float32 warned of an overflow."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import test_options as T
import test_options_api_io as A
import test_options_calibration as CA
import test_options_compute as CO
import test_options_costs as CS
import test_options_hlf as HL
import test_options_io as IO
from hyperlf.errors import InvalidInputError


def _base(entry):
    """``(function, keyword arguments)`` of a call-table entry.  The tables that wrap their
    base arguments in a lambda keep them as its second default, or (``_with``) in its closure
    beside the function; a lambda that passes other arguments of its own is skipped."""
    fn, call = entry
    if callable(call):
        cells = [c.cell_contents for c in call.__closure__ or ()]
        if call.__defaults__ and len(call.__defaults__) > 1:
            call = call.__defaults__[1]
        elif len(cells) == 2 and any(c is fn for c in cells):
            call = next(c for c in cells if c is not fn)
    return (fn, call) if isinstance(call, dict) else None


@functools.lru_cache(maxsize=1)
def _tables() -> dict:
    tables = {}
    for mod, name in ((T, "_matching_calls"), (T, "_library_calls"), (A, "_calls"),
                      (CO, "_calls"), (HL, "_stage_calls"), (CS, "_bases"),
                      (IO, "_writer_calls")):
        for key, entry in getattr(mod, name)().items():
            if (base := _base(entry)) is not None:
                tables[f"{mod.__name__}.{key}"] = base
    for fn, kw in CA._calls().items():  # keyed by the function itself
        tables[f"{CA.__name__}.{fn.__name__}"] = (fn, kw)
    for key, entry in IO._stage_calls()[0].items():
        tables[f"{IO.__name__}.{key}"] = _base(entry)
    tables.update(_render_bases())
    tables.update(_pipeline_bases())
    return tables


def _pipeline_bases() -> dict:
    """Depth, completion and completion's two stages that the option fuzzers call through
    lambdas with arguments of their own, here with every argument a keyword."""
    from hyperlf import completion, hlf, synthesis

    lf = synthesis.procedural_scene(seed=1, rows=2, cols=2, height=12, width=16,
                                    disparity_range=(-1.0, 1.0))
    ref = lf.gt_disparity[lf.reference]
    sgm = {"p1": 0.5, "p2": 2.0}
    return {f"pipeline.{fn.__name__}": (fn, kw) for fn, kw in (
        (hlf.depth, dict(lf=lf, disparity_range=(-1.0, 1.0), n_labels=4)),
        (completion.complete, dict(lf=lf, disparity=ref, params=sgm,
                                   infer={"radius": 2, "rounds": 1}, max_iter=2)),
        (completion.pairwise_disparities, dict(
            lf=lf, initial=completion.propagate_disparity(lf, ref), params=sgm,
            disparity_range=(-2.0, 2.0))))}


def _render_bases() -> dict:
    """The rendering calls with every argument a keyword (``test_options``' table passes the
    cube by position, which the fuzzer cannot reach into)."""
    from hyperlf import render

    rng = np.random.default_rng(0)
    cube = rng.random((2, 3, 4, 10, 12)).astype(np.float32)
    wl, white = [450.0, 520.0, 590.0, 650.0], [1.0, 1.0, 1.0, 1.0]
    offsets = np.stack(np.meshgrid(np.arange(3) - 1.0, np.arange(2) - 0.5), -1)
    light = dict(offsets=offsets, wavelengths=np.array(wl))
    return {f"render.{fn.__name__}": (fn, kw) for fn, kw in (
        (render.refocus, dict(views_or_cube=cube, disparity=0.5, white=white, **light)),
        (render.focal_stack, dict(views_or_cube=cube, disparities=[0.0, 1.0], **light)),
        (render.emulate_camera, dict(cube=cube[0], wavelengths=wl, white=white)),
        (render.spectrum_at, dict(cube=cube, wavelengths=wl, x=3, y=4, view=[0, 1])),
        (render.camera_matrix, dict(camera="CIE 1931", wavelengths=wl, white=white)),
        (render.fit_ccm, dict(camera="CIE 1931", wavelengths=wl, white=white)))}


def _container(value) -> bool:
    """A dict, or a short sequence of scalars or tuples (not of arrays)."""
    if isinstance(value, dict):
        return bool(value)
    return (isinstance(value, (list, tuple)) and 0 < len(value) < 50
            and not isinstance(value[0], np.ndarray))


_SITES = sorted((name, key) for name, (_, kw) in _tables().items()
                for key, value in kw.items() if _container(value))


def _with_junk(value, junk, as_entry: bool, inner: bool = False):
    """``value`` (a dict or a sequence) with its first entry replaced by ``junk``, or with
    ``junk`` added (as a key of a dict); None where junk cannot be a key.  Where ``inner`` and
    the first entry is itself a container, the junk goes one level down, into that entry."""
    head = next(iter(value.values())) if isinstance(value, dict) else value[0]
    if inner and _container(head):
        changed = _with_junk(head, junk, as_entry)
        return None if changed is None else _with_junk(value, changed, False)
    if isinstance(value, dict):
        out, first = dict(value), next(iter(value))
        if not as_entry:
            out[first] = junk
            return out
        try:
            out[junk] = out[first]
        except TypeError:  # unhashable
            return None
        return out
    out = list(value)
    if as_entry:
        out.append(junk)
    else:
        out[0] = junk
    return tuple(out) if isinstance(value, tuple) else out


def test_the_sites_cover_every_table():
    assert len(_SITES) >= 40 and {n.split(".")[0] for n, _ in _SITES} >= {
        "test_options", "test_options_calibration", "test_options_compute",
        "test_options_costs", "test_options_io", "pipeline", "render"}


@settings(max_examples=800, deadline=None, derandomize=True)
@given(st.sampled_from(_SITES), st.booleans(),
       T.JUNK | st.tuples(st.integers(-2, 3), st.integers(-2, 3)), st.booleans())
def test_junk_inside_a_container_is_taken_or_refused_in_one_line(site, as_entry, junk, inner):
    name, key = site
    fn, kw = _tables()[name]
    value = _with_junk(kw[key], junk, as_entry, inner)
    if value is None:
        return
    with T._in_temp_folder("error", RuntimeWarning):
        T._build_or_refuse(fn, **{**kw, key: value})


@pytest.mark.parametrize("weights, words", [
    ([1, 10 ** 400], "census-rsncc needs 2 weights, one per part (rsncc, census), each "
                     "finite and >= 0, not all 0, with a finite sum; got [1, 1000"),
    ([1e308, 1e308], "census-rsncc needs 2 weights"),
    (["1", "3"], "census-rsncc needs 2 weights"),
    ({"rsncc": 1, "census": 3}, "census-rsncc needs 2 weights"),
])
def test_fusion_weights_are_numbers(weights, words):
    from hyperlf import costs

    with pytest.raises(InvalidInputError) as exc:
        costs.fusion_weights("auto", weights)
    assert str(exc.value).startswith(words) and "\n" not in str(exc.value)
    assert costs.fusion_weights("auto", np.array([1, 3])) == (1.0, 3.0)


def test_a_view_offset_beyond_float32_is_refused():
    from hyperlf import synthesis

    with pytest.raises(InvalidInputError, match="^offset must be at most 1e"):
        synthesis.view_disparity_from_reference(np.zeros((4, 5)), (3.4e38, 0.0))


def test_former_overflows_inside_containers_are_refused_or_ignored():
    """An infinity in a recorded capture signature (a manifest is JSON, which has Infinity)
    means "cannot tell", as other malformed records do; a disparity range with an integer
    beyond a float, a white of 1e308 (an overflow) and HCI sub-grid indices that are infinite
    or not whole are refused."""
    from hyperlf import lightfield
    from hyperlf.formats import read_hci_scene

    sig = {"grid": [3, 3], "image_shape": [60, 80], "reference": [1, 1]}
    assert lightfield.signature_mismatch(dict(sig, grid=[float("inf"), 3]), sig) is None
    with pytest.raises(InvalidInputError, match="^disparity_range must be"):
        lightfield.check_disparity_range([0, 10 ** 400])
    from hyperlf import render

    with pytest.raises(InvalidInputError, match="^white must be at most 1e"):
        render.camera_matrix("CIE 1931", [450.0, 520.0, 590.0, 650.0], white=[1e308, 1, 1, 1])
    for cols in ([float("inf")], [2.7], [0, 0]):
        with pytest.raises(InvalidInputError, match=r"^cols must be distinct indices in 0\.\."):
            read_hci_scene(A._files() / "hci", cols=cols)


def test_a_stranger_key_of_any_type_is_named_in_one_line():
    """Keys of several types beside the names a dict of options takes: sorting them for the
    message raised TypeError (completion's ``infer``; a fusion's part options too).  Six such
    checks, each with its own message, are now one: ``_options.mapping(keys=...)``."""
    from hyperlf import baselines, completion, synthesis
    from hyperlf.costs import FusedCost

    lf = synthesis.procedural_scene(seed=1, rows=2, cols=2, height=12, width=16,
                                    disparity_range=(-1.0, 1.0))
    calls = {
        "infer": lambda: completion.complete(lf, lf.gt_disparity[lf.reference],
                                             infer={"radius": 2, (1, 2): 1, "x": 2}),
        "params": lambda: baselines.tao2013(lf, x=1, y=2),
        "x: part_options": lambda: FusedCost("x", ("rsncc", "census"),
                                             part_options={3: {}, "ncc": {}}),
    }
    for label, call in calls.items():
        with pytest.raises(InvalidInputError) as exc:
            call()
        text = str(exc.value)
        assert text.startswith("unknown key ") and f" in {label}; " in text, text
        assert "\n" not in text
