"""Tests of the one optimiser entry: typed parameters, the registry and regularisers.optimise."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from hyperlf import hlf, regularisers as R, twoview
from hyperlf.errors import InvalidInputError


@pytest.fixture
def volume(rng):
    return rng.random((10, 20, 22)).astype(np.float32)


# ----------------------------------------------------------------------------------------------
# parameters and registry
# ----------------------------------------------------------------------------------------------

def test_registry_names_every_optimiser_and_callers_choose_from_it():
    assert R.OPTIMISERS == {"graphcut": R.GraphCutParams, "sgm": R.SGMParams,
                            "wta": R.WTAParams}
    assert twoview.OPTIMIZERS == hlf.OPTIMIZERS == ("graphcut", "sgm", "wta")


def test_make_params_fills_defaults_and_keeps_given_values():
    p = R.make_params("sgm", {"p1": 2})
    assert p == R.SGMParams(p1=2, p2=2.0, paths=8, smoothness="p1p2")
    g = R.make_params("graphcut", {"weight": 4.0, "levels": 2, "max_cycles": 3.0})
    assert (g.weight, g.levels, g.max_cycles, g.truncation) == (4.0, 2, 3, 2.0)
    assert isinstance(g.max_cycles, int)              # integral floats become ints
    assert R.make_params("wta") == R.WTAParams()
    assert R.params_dict(g)["levels"] == 2
    with pytest.raises(AttributeError):
        g.weight = 1.0                                  # frozen


def test_make_params_names_the_allowed_keys():
    with pytest.raises(InvalidInputError,
                       match=r"^unknown key 'weight' in params; optimizer 'sgm' takes p1, "
                             r"p2, paths, smoothness"):
        R.make_params("sgm", {"weight": 2.0})
    with pytest.raises(InvalidInputError, match="optimizer 'wta' takes no keys$"):
        R.make_params("wta", {"p1": 1.0})
    for key in (3, ("p1",), np.float64(1.0)):  # keys of other types, with a name beside them
        with pytest.raises(InvalidInputError, match=r"^unknown key [^;]* in params; "
                                                    r"optimizer 'sgm' takes p1"):
            R.make_params("sgm", {"p1": 1.0, key: 2.0, "zz": 1})
    with pytest.raises(InvalidInputError, match="optimizer must be one of graphcut, sgm, wta"):
        R.make_params("icm", {})
    with pytest.raises(InvalidInputError, match="params must be a dict"):
        R.make_params("sgm", [("p1", 1.0)])


@pytest.mark.parametrize("cls, kw, msg", [
    (R.SGMParams, {"p1": -1.0}, "sgm p1 must be a finite number >= 0"),
    (R.SGMParams, {"p2": float("nan")}, "sgm p2 must be a finite number"),
    (R.SGMParams, {"paths": 6}, "sgm paths must be one of 2, 4, 8"),
    (R.SGMParams, {"paths": 8.5}, "sgm paths must be an integer"),
    (R.SGMParams, {"smoothness": "potts"}, "sgm smoothness must be one of"),
    (R.SGMParams, {"adaptive_p2": 1}, "sgm adaptive_p2 must be True or False"),
    (R.SGMParams, {"guide_scale": 0.0}, "sgm guide_scale must be a finite number > 0"),
    (R.SGMParams, {"impl": "cuda"}, "sgm impl must be one of"),
    (R.GraphCutParams, {"weight": -0.5}, "graphcut weight must be a finite number >= 0"),
    (R.GraphCutParams, {"weight": True}, "graphcut weight must be a finite number"),
    (R.GraphCutParams, {"smoothness": "quadratic"}, "graphcut smoothness must be one of"),
    (R.GraphCutParams, {"truncation": -1.0}, "graphcut truncation must be"),
    (R.GraphCutParams, {"edge_sigma": 0.0}, "graphcut edge_sigma must be a finite number > 0"),
    (R.GraphCutParams, {"max_cycles": -1}, "graphcut max_cycles must be an integer >= 0"),
    (R.GraphCutParams, {"levels": 1.5}, "graphcut levels must be an integer >= 0"),
    (R.GraphCutParams, {"min_size": 0}, "graphcut min_size must be an integer >= 1"),
])
def test_invalid_parameters_raise_one_line_messages(cls, kw, msg):
    with pytest.raises(InvalidInputError, match=msg) as exc:
        cls(**kw)
    assert "\n" not in str(exc.value)


def test_optional_parameters_accept_none():
    assert R.GraphCutParams(truncation=None, edge_sigma=None).truncation is None
    assert R.SGMParams(guide_scale=None).guide_scale is None


# ----------------------------------------------------------------------------------------------
# optimise: the same numbers as the optimisers it dispatches to
# ----------------------------------------------------------------------------------------------

def test_optimise_wta(volume):
    res = R.optimise(volume, R.WTAParams(), guide=volume[0])     # WTA ignores the guide
    np.testing.assert_array_equal(res.labels, R.wta(volume))
    assert res.labels.dtype == np.int32 and res.volume is volume


@pytest.mark.parametrize("adaptive", [False, True])
def test_optimise_sgm_returns_the_aggregated_volume(volume, rng, adaptive):
    guide = rng.random(volume.shape[1:])
    p = R.SGMParams(p1=0.2, p2=1.5, paths=4, smoothness="truncated_linear", adaptive_p2=adaptive)
    res = R.optimise(volume, p, guide=guide)
    agg = R.sgm(volume, 0.2, 1.5, paths=4, guide=guide if adaptive else None,
                smoothness="truncated_linear")
    np.testing.assert_array_equal(res.volume, agg)
    np.testing.assert_array_equal(res.labels, np.argmin(agg, axis=0))
    if adaptive:   # the guide changes the result only when asked for
        plain = R.sgm(volume, 0.2, 1.5, paths=4, smoothness="truncated_linear")
        assert not np.array_equal(res.volume, plain)


def test_optimise_plain_graphcut_with_edge_weights(volume, rng):
    guide = rng.random(volume.shape[1:])
    H, W = volume.shape[1:]
    ew = (rng.random((H, W - 1)), rng.random((H - 1, W)))
    labels = np.linspace(-1.0, 1.0, volume.shape[0])
    p = R.GraphCutParams(weight=0.3, truncation=0.5, max_cycles=2, levels=0)
    res = R.optimise(volume, p, guide=guide, labels=labels, edge_weights=ew)
    expected = R.graphcut(volume, "truncated_linear", 0.3, 0.5, guide=guide, max_cycles=2,
                          labels=labels, edge_weights=ew)
    np.testing.assert_array_equal(res.labels, expected)
    assert res.volume is volume


def test_optimise_coarse_to_fine_graphcut(rng):
    c = rng.random((12, 40, 44)).astype(np.float32)
    guide = rng.random((40, 44))
    p = R.GraphCutParams(weight=0.4, truncation=3.0, max_cycles=2, levels=1, min_size=8)
    res = R.optimise(c, p, guide=guide)
    expected = R.graphcut_multiscale(c, weight=0.4, truncation=3.0, guide=guide, max_cycles=2,
                                     levels=1, min_size=8)
    np.testing.assert_array_equal(res.labels, expected)
    # with levels=1 the result differs from plain alpha-expansion on this random volume
    plain = R.graphcut(c, weight=0.4, truncation=3.0, guide=guide, max_cycles=2)
    assert not np.array_equal(res.labels, plain)


def test_optimise_starts_graph_cuts_from_init(rng):
    """``init`` is graph cuts' starting labelling: with no cycles it comes back unchanged, and
    with some it gives exactly :func:`graphcut`'s answer from the same start."""
    c = rng.random((6, 20, 24)).astype(np.float32)
    init = rng.integers(0, 6, (20, 24)).astype(np.int32)
    none = R.optimise(c, R.GraphCutParams(weight=0.3, max_cycles=0), init=init)
    np.testing.assert_array_equal(none.labels, init)
    res = R.optimise(c, R.GraphCutParams(weight=0.3, max_cycles=1), init=init)
    np.testing.assert_array_equal(res.labels, R.graphcut(c, weight=0.3, max_cycles=1, init=init))
    tie = np.zeros((2, 5, 7), np.float32)  # a tie: no move lowers the energy, the start stays
    ones = np.ones((5, 7), np.int32)
    assert (R.optimise(tie, R.GraphCutParams(), init=ones).labels == 1).all()
    assert (R.optimise(tie, R.GraphCutParams()).labels == 0).all()


def test_optimise_rejects_what_it_cannot_use(volume):
    H, W = volume.shape[1:]
    ew = (np.ones((H, W - 1)), np.ones((H - 1, W)))
    init = np.zeros((H, W), np.int32)
    for kw in (dict(edge_weights=ew), dict(init=init)):
        name = next(iter(kw))
        for p in (R.SGMParams(), R.WTAParams()):
            with pytest.raises(InvalidInputError, match=f"{name} is a graph-cut option"):
                R.optimise(volume, p, **kw)
        with pytest.raises(InvalidInputError, match=f"{name} is an option of .*levels=0"):
            R.optimise(volume, R.GraphCutParams(levels=1), **kw)
    with pytest.raises(InvalidInputError, match="params must be one of"):
        R.optimise(volume, {"p1": 1.0})
    with pytest.raises(InvalidInputError, match="NaN"):
        R.optimise(np.full((2, 3, 3), np.nan), R.WTAParams())


def test_twoview_params_record_the_merged_dict_and_reject_bad_values():
    rng = np.random.default_rng(3)
    L = rng.random((24, 40)).astype(np.float32) + 0.1
    R_ = np.roll(L, -2, axis=1)
    res = twoview.stereo(L, R_, (0, 4), metric="ssd", optimizer="graphcut",
                         params={"levels": 0, "weight": 2.0})
    assert isinstance(res.params, dict)
    assert res.params["levels"] == 0 and res.params["weight"] == 2.0
    with pytest.raises(InvalidInputError, match="graphcut weight must be"):
        twoview.stereo(L, R_, (0, 4), metric="ssd", params={"weight": -1.0})


def test_import_does_not_load_numba():
    code = ("import sys, hyperlf.regularisers as R; R.optimise; "
            "print('numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"
