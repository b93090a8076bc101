"""``--confidence-floor`` and ``--confidence-edge-px`` of ``stereo``, ``depth`` and ``batch``:
the library's confidence options (``regularisers.ConfidenceParams``, ``DepthParams``) on the
command line, parsed with one-line refusals and passed on unchanged."""

from __future__ import annotations

import argparse
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf.cli import _confidence_edge_px_arg, _confidence_floor_arg, main
from hyperlf.formats import read_pfm

from conftest import write_shifted_pair

_numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                     st.integers(-10**6, 10**6)).map(str)
_texts = st.one_of(_numbers, st.text(max_size=8))


@pytest.mark.parametrize("parse, accepts", [
    (_confidence_floor_arg, lambda v: 0.0 <= v < 1.0),
    (_confidence_edge_px_arg, lambda v: 0.0 <= v <= 1000.0),
])
@settings(max_examples=200, deadline=None)
@given(text=_texts)
def test_a_value_is_a_number_in_its_interval_or_one_line_that_says_so(parse, accepts, text):
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if math.isfinite(v) and accepts(v):
        assert parse(text) == v
    else:
        with pytest.raises(argparse.ArgumentTypeError) as exc:
            parse(text)
        assert str(exc.value) and "\n" not in str(exc.value)  # argparse names the option


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A textured pair whose right image is the left one shifted by 3 px."""
    folder = tmp_path_factory.mktemp("pair")
    write_shifted_pair(folder, seed=5, rows=40, width=50, start=3)
    return folder


def _stereo_confidence(pair, out, *extra):
    assert main(["-q", "stereo", str(pair / "l.png"), str(pair / "r.png"),
                 "--disparity-range", "0,8", *extra, "-o", str(out)]) == 0
    return read_pfm(out / "confidence.pfm")


def test_stereo_writes_the_confidence_of_the_library_call_with_those_options(pair, tmp_path):
    from hyperlf.formats import read_image
    from hyperlf.regularisers import ConfidenceParams
    from hyperlf.twoview import stereo

    got = _stereo_confidence(pair, tmp_path / "s", "--confidence-floor", "0.3",
                             "--confidence-edge-px", "0")
    left, right = (read_image(pair / f, as_float=True) for f in ("l.png", "r.png"))
    want = stereo(left, right, (0, 8), confidence_params=ConfidenceParams(floor=0.3, edge_px=0))
    np.testing.assert_array_equal(got, want.confidence)
    # without the edge factor every consistent pixel keeps at least the floor
    assert got[want.valid].min() >= 0.3 - 1e-6 and (got[~want.valid] == 0).all()
    default = _stereo_confidence(pair, tmp_path / "d")
    np.testing.assert_array_equal(default, stereo(left, right, (0, 8)).confidence)
    assert not np.array_equal(default, got)


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cap") / "cap"
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "32,40",
                 "-o", str(folder)]) == 0
    return folder


def test_depth_passes_both_options_and_the_map_follows(capture, tmp_path, monkeypatch):
    import hyperlf.hlf as hlf

    seen = {}
    real = hlf.depth

    def spy(*a, **k):
        seen["params"] = k["params"]
        return real(*a, **k)

    monkeypatch.setattr(hlf, "depth", spy)
    run = ["-q", "depth", str(capture), "--labels", "8", "--optimizer", "wta"]

    def confidence(name, *options):
        assert main([*run, *options, "-o", str(tmp_path / name)]) == 0
        return read_pfm(tmp_path / name / "confidence.pfm"), seen["params"]

    high, p = confidence("a", "--confidence-floor", "0.4", "--confidence-edge-px", "0")
    assert (p.confidence_floor, p.confidence_edge_px) == (0.4, 0.0)
    # no edge factor: a pixel is 0 (unseen or filled in) or at least the floor
    assert ((high == 0) | (high >= 0.4 - 1e-6)).all() and (high >= 0.4 - 1e-6).mean() > 0.5
    plain, p = confidence("b", "--confidence-edge-px", "0")
    assert p.confidence_floor == hlf.DepthParams().confidence_floor
    assert (high >= plain - 1e-6).all() and high.mean() > plain.mean()  # the floor lifts
    banded, p = confidence("c", "--confidence-edge-px", "6")
    assert p.confidence_edge_px == 6.0
    assert (banded <= plain + 1e-6).all() and banded.mean() < plain.mean()  # the band lowers


@pytest.mark.parametrize("argv, words", [
    (["depth", "CAP", "--confidence-floor", "1"], "--confidence-floor must be in [0, 1)"),
    (["stereo", "L", "R", "--disparity-range", "0,4", "--confidence-floor", "2"],
     "--confidence-floor must be in [0, 1)"),
    (["stereo", "L", "R", "--disparity-range", "0,4", "--confidence-edge-px", "-1"],
     "--confidence-edge-px must be in [0, 1000]"),
    (["depth", "CAP", "--method", "tao2013", "--confidence-floor", "0.2"],
     "--confidence-floor acts on --method hlf only"),
    (["batch", "CAP", "--confidence-floor", "nan"], "--confidence-floor"),
])
def test_bad_values_are_refused_in_one_line_before_any_work(tmp_path, capsys, argv, words):
    argv = [str(tmp_path / a) if a in ("CAP", "L", "R") else a for a in argv]
    try:  # argparse exits on a bad value; the combination check returns the code
        code = main(["-q", *argv, "-o", str(tmp_path / "out")])
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "out").exists()


def test_batch_hands_the_options_to_every_depth_run(capture, tmp_path, monkeypatch):
    import hyperlf.batch as batch
    from hyperlf.errors import InvalidInputError

    seen = {}

    def spy(inputs, output, *, depth_args, **kw):
        seen["depth_args"] = depth_args
        raise InvalidInputError("stopped by the test")

    monkeypatch.setattr(batch, "plan_batch", spy)
    assert main(["-q", "batch", str(capture), "--confidence-floor", "0.25",
                 "--confidence-edge-px", "2", "-o", str(tmp_path / "b")]) == 2
    args = seen["depth_args"]
    assert args[args.index("--confidence-floor") + 1] == "0.25"
    assert args[args.index("--confidence-edge-px") + 1] == "2"
