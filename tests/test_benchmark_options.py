"""The two-view benchmarks' candidate options (``benchmarks/_common.py``): ``--params`` and
``--cost-params`` take JSON objects, refuse anything else in one line, and a candidate's run
(those options, or a script's other options off their defaults) must not write over the
results that record the defaults."""

from __future__ import annotations

import argparse
import json
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import benchmark_script as _script
from conftest import require_dataset


_json = st.recursive(st.none() | st.booleans() | st.integers() | st.text(max_size=5)
                     | st.floats(allow_nan=False, allow_infinity=False),
                     lambda inner: st.lists(inner, max_size=3)
                     | st.dictionaries(st.text(max_size=5), inner, max_size=3), max_leaves=8)


@settings(max_examples=60, deadline=None)
@given(st.dictionaries(st.text(max_size=8), _json, max_size=4))
def test_a_json_object_is_read_as_it_was_written(value):
    assert _script("_common").json_object(json.dumps(value)) == value


@settings(max_examples=60, deadline=None)
@given(_json.filter(lambda v: not isinstance(v, dict)))
def test_json_that_is_not_an_object_is_refused(value):
    with pytest.raises(argparse.ArgumentTypeError, match="expected a JSON object"):
        _script("_common").json_object(json.dumps(value))


@settings(max_examples=60, deadline=None)
@given(st.text(max_size=20))
def test_any_text_is_an_object_or_one_message(text):
    common = _script("_common")
    try:
        value = common.json_object(text)
    except argparse.ArgumentTypeError as exc:
        assert "\n" not in str(exc)
    else:
        assert isinstance(value, dict)


def _parser():
    common = _script("_common")
    ap = argparse.ArgumentParser(prog="bench")
    common.add_stereo_options(ap)
    ap.add_argument("--out", default="results/x")
    return common, ap


def test_the_options_become_stereo_keywords():
    common, ap = _parser()
    args = ap.parse_args(["--params", '{"weight": 3}', "--cost-params", '{"weights": [1, 3]}',
                          "--out", "elsewhere"])
    assert common.stereo_options(args) == {"params": {"weight": 3},
                                           "cost_params": {"weights": [1, 3]}}
    common.check_candidate_out(ap, args, "results/x")  # its own --out: accepted
    assert common.stereo_options(ap.parse_args([])) == {}
    from hyperlf.regularisers import HoleParams

    args = ap.parse_args(["--hole-params", '{"enabled": true, "coherent": 0.5}'])
    assert common.stereo_options(args) == {"hole_params": HoleParams(enabled=True,
                                                                     coherent=0.5)}
    for bad in ('{"enabled": 1}', '{"share": 0.5}'):
        with pytest.raises(SystemExit, match="--hole-params: "):
            common.stereo_options(ap.parse_args(["--hole-params", bad]))


def test_a_candidate_may_not_write_over_the_defaults_results(capsys):
    common, ap = _parser()
    args = ap.parse_args(["--params", '{"weight": 3}'])
    with pytest.raises(SystemExit) as exc:
        common.check_candidate_out(ap, args, "results/x")
    assert exc.value.code == 2
    assert "give it its own --out" in capsys.readouterr().err
    common.check_candidate_out(ap, ap.parse_args([]), "results/x")  # the defaults: accepted


def test_a_script_s_other_departures_need_their_own_out_too(capsys):
    common, ap = _parser()
    with pytest.raises(SystemExit):
        common.check_candidate_out(ap, ap.parse_args([]), "results/x",
                                   departures=["--occlusion"])
    assert "--occlusion measure a candidate" in capsys.readouterr().err
    common.check_candidate_out(ap, ap.parse_args(["--out", "elsewhere"]), "results/x",
                               departures=["--occlusion"])


@pytest.mark.parametrize("script, argv", [
    ("channels", ["--params", "[1]"]),
    ("channels", ["--cost-params", '{"weights": [1, 3]}']),
    ("channels", ["--metrics", "auto,nosuchcost", "--out", "elsewhere"]),
    ("procedural_pairs", ["--params", "{weight: 3}"]),
    ("procedural_pairs", ["--cost-params", '{"weights": [1, 3]}']),
    ("procedural_pairs", ["--metric", "rsncc"]),
    ("procedural_pairs", ["--occlusion", "lr-fill"]),
    ("channels", ["--metrics", "auto"]),
    ("faint_thin", ["--params", '{"thin_touch": 0.4}']),
    ("faint_thin", ["--params", '{"thin_touch": 2}', "--out", "elsewhere"]),
    ("faint_thin", ["--params", '{"no_such_field": 1}', "--out", "elsewhere"]),
    ("faint_thin", ["--params", '{"optimizer": "belief"}', "--out", "elsewhere"]),
    ("faint_thin", ["--params", '{"view_selection": 1}', "--out", "elsewhere"]),
    ("faint_thin", ["--seeds", "3-"]),
    ("faint_thin", ["--size", "16,16"]),
    ("faint_thin", ["--tolerance", "0"]),
    ("faint_thin", ["--plain", "--params", '{"thin_touch": 0.4}']),
    ("faint_thin", ["--plain", "--params", '{"thin_touch": 0.4}', "--out",
                    "benchmarks/results/rings_sticks"]),
    ("faint_thin", ["--seeds", "0"]),
    ("faint_thin", ["--plain", "--size", "256,320"]),
    ("faint_thin", ["--out", "benchmarks/results/rings_sticks"]),
    ("faint_thin", ["--plain", "--out", "benchmarks/results/faint_thin"]),
])
def test_the_scripts_refuse_bad_options_before_any_work(script, argv, monkeypatch, capsys):
    mod = _script(script)
    monkeypatch.setattr(sys, "argv", [f"{script}.py", *argv])
    with pytest.raises(SystemExit) as exc:
        mod.main()
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"{script}.py: error:")


def test_faint_thin_plain_runs_its_recorded_size_into_its_own_folder(tmp_path, monkeypatch):
    """benchmarks/faint_thin.py --plain: the six scenes as drawn, at 192 x 256 unless told,
    into results/rings_sticks, whose report says so; the faint scenes keep 256 x 320."""
    require_dataset("munsell")
    ft = _script("faint_thin")
    calls = []

    def fake_run(seed, size, labels, params, tolerance, out, *, faint=True):
        calls.append((seed, size, faint, out))
        return {"seed": seed, "depth_s": 0.0, "rmse": 1.0, "badpix_007": 2.0,
                "thin_rmse": 3.0, "thin_bad1": 4.0, "taken": 0.0}

    assert ft.PLAIN_OUT == ft.Path("benchmarks/results/rings_sticks")
    monkeypatch.setattr(ft, "run", fake_run)
    monkeypatch.setattr(ft, "PLAIN_OUT", tmp_path / "rings_sticks")  # not the repository's
    assert ft.main(["--plain"]) == 0
    assert [c[0] for c in calls] == list(range(6))
    assert {c[1:] for c in calls} == {((192, 256), False, tmp_path / "rings_sticks")}
    report = json.loads((tmp_path / "rings_sticks" / "rings_sticks.json").read_text())
    assert report["plain"] and report["tolerance"] is None and report["size"] == [192, 256]
    calls.clear()
    assert ft.main(["--seeds", "1", "--out", str(tmp_path / "elsewhere")]) == 0
    assert calls == [(1, (256, 320), True, tmp_path / "elsewhere")]
    assert "tolerance 0.03" in (tmp_path / "elsewhere" / "faint_thin.md").read_text()


def test_faint_thin_refuses_a_tolerance_no_chip_meets_before_rendering(tmp_path, capsys):
    """benchmarks/faint_thin.py: a tolerance so tight that no Munsell chip matches a scene's
    background ends in argparse's exit 2 with one message, and no report is written."""
    require_dataset("munsell")
    ft = _script("faint_thin")
    with pytest.raises(SystemExit) as exc:
        ft.main(["--tolerance", "1e-9", "--out", str(tmp_path / "out")])
    assert exc.value.code == 2 and not (tmp_path / "out").exists()
    assert "give a larger --tolerance" in capsys.readouterr().err.strip().splitlines()[-1]


@settings(max_examples=40, deadline=None)
@given(scenes=st.text(max_size=20), span=st.text(max_size=8))
def test_middlebury_lf_refuses_bad_options_before_any_work(tmp_path_factory, scenes, span):
    """benchmarks/middlebury_lf.py: a scene list or span it cannot run ends in argparse's exit
    2 with one message, and the work folder is not made; what it accepts is a known scene
    list and a span in (0, 50]."""
    lf = _script("middlebury_lf")
    work = tmp_path_factory.mktemp("w") / "work"
    names = [s for s in scenes.split(",") if s]
    try:
        value = float(span)
    except ValueError:
        value = None
    runnable = (bool(names) and set(names) <= set(lf.SCENES) and value is not None
                and 0 < value <= 50)
    if runnable:
        return   # a real run: not what this test is for
    with pytest.raises(SystemExit) as exc:
        lf.main([str(work), "--scenes", scenes, "--span", span, "--out", str(work / "out")])
    assert exc.value.code == 2 and not work.exists()
