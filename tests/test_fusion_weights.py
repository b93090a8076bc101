"""The weights of a fused cost's parts (``DepthParams.fusion_weights``, ``--fusion-weights``):
one weight per part, checked against the cost before any work, and the same volume as a
fusion registered with those weights."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from hyperlf import hlf
from hyperlf.costs import FusedCost, fusion_weights, get_cost, register_cost, unregister_cost
from hyperlf.costs import view_costs
from hyperlf.errors import InvalidInputError
from hyperlf.synthesis import procedural_scene

from conftest import refused_while_parsing_and_handed_on


@pytest.fixture
def weighted_fusion():
    """``census-rsncc`` registered again under another name with census weighted 4:1."""
    base = get_cost("census-rsncc")
    name = "test-census-rsncc-1-4"
    register_cost(FusedCost(name, base.parts, weights=(1, 4), view_window_part=0,
                            params=dict(base.params), part_options=base.part_options))
    yield name
    unregister_cost(name)


def _images():
    rng = np.random.default_rng(3)
    a = rng.random((40, 48)) + 0.5
    return a, np.roll(a, 2, axis=1) * 0.7 + 0.1  # another gain and offset, shifted 2 px


def test_fusion_weights_fit_the_parts_of_the_cost():
    assert fusion_weights("auto", [1, 4]) == (1.0, 4.0)
    assert fusion_weights("fused", (0, 2.5)) == (0.0, 2.5)
    with pytest.raises(InvalidInputError, match="fused cost .*not 'census'"):
        fusion_weights("census", (1, 4))
    for bad in [(1,), (1, 2, 3), (0, 0), (1, -1), (1, np.nan), (np.inf, 1), "14", None, 3]:
        with pytest.raises(InvalidInputError, match="2 weights, one per part .rsncc, census"):
            fusion_weights("census-rsncc", bad)


def test_view_costs_with_weights_are_a_fusion_registered_with_them(weighted_fusion):
    a, b = _images()
    labels = np.arange(0.0, 4.5, 0.5)
    C, valid = view_costs(a, b, (-1.0, 0.0), labels, "census-rsncc", 3, weights=(1, 4))
    ref, ref_valid = view_costs(a, b, (-1.0, 0.0), labels, weighted_fusion, 3)
    np.testing.assert_array_equal(valid, ref_valid)
    np.testing.assert_array_equal(C, ref)
    assert not np.array_equal(C, view_costs(a, b, (-1.0, 0.0), labels, "census-rsncc", 3)[0])
    with pytest.raises(InvalidInputError, match="fused cost"):
        view_costs(a, b, (-1.0, 0.0), labels, "rsncc", weights=(1, 4))


@pytest.mark.parametrize("weights, part", [((0, 1), "census"), ((1, 0), "rsncc")])
def test_a_zero_weight_leaves_the_other_part_scaled(weights, part):
    """The light-field fusion only scales each part (no centring), so with one weight 0 the
    volume is the other part times one constant."""
    a, b = _images()
    labels = np.arange(0.0, 4.5, 0.5)
    C, valid = view_costs(a, b, (-1.0, 0.0), labels, "census-rsncc", 3, weights=weights)
    alone, _ = view_costs(a, b, (-1.0, 0.0), labels, part, 3 if part == "rsncc" else 7)
    keep = valid & (alone > 0.05 * alone[valid].max())
    ratio = C[keep] / alone[keep]
    assert ratio.min() > 0
    np.testing.assert_allclose(ratio, ratio.mean(), rtol=1e-4)


@pytest.fixture(scope="module")
def scene():
    return procedural_scene(3, rows=3, cols=3, height=48, width=56)


def test_depth_with_fusion_weights_is_depth_with_that_fusion(scene, weighted_fusion):
    default = hlf.depth(scene, n_labels=12).disparity
    weighted = hlf.depth(scene, n_labels=12,
                         params=hlf.DepthParams(fusion_weights=(1, 4))).disparity
    np.testing.assert_array_equal(weighted,
                                  hlf.depth(scene, n_labels=12, metric=weighted_fusion).disparity)
    assert not np.array_equal(weighted, default)
    # a weighted mean: only the ratio of the weights counts
    np.testing.assert_array_equal(
        hlf.depth(scene, n_labels=12, params=hlf.DepthParams(fusion_weights=[2, 2])).disparity,
        default)


def test_depth_refuses_weights_that_do_not_fit(scene):
    with pytest.raises(InvalidInputError, match="params.fusion_weights: fusion weights need"):
        hlf.depth(scene, n_labels=4, metric="census", params=hlf.DepthParams(fusion_weights=(1, 4)))
    with pytest.raises(InvalidInputError, match="params.fusion_weights: census-rsncc needs 2"):
        hlf.depth(scene, n_labels=4, params=hlf.DepthParams(fusion_weights=(1, 4, 1)))


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                                    st.integers(-5, 5)), max_size=4),
                 st.text(max_size=6), st.none()))
@example([8.988465674311579e+307, 8.98846567431158e+307])  # finite, but their sum is not
def test_depth_params_keep_only_finite_non_negative_weights(w):
    try:
        p = hlf.DepthParams(fusion_weights=w)
    except InvalidInputError as e:
        assert "params.fusion_weights" in str(e)
        ok = False
    else:
        ok = True
        assert p.fusion_weights is None or isinstance(p.fusion_weights, tuple)
    with np.errstate(over="ignore"):  # the weights are normalised by their sum
        valid = w is None or (isinstance(w, list) and len(w) > 0 and any(w)
                              and all(np.isfinite(x) and x >= 0 for x in w)
                              and np.isfinite(np.sum(np.asarray(w, np.float64))))
    assert ok == valid


@settings(max_examples=80, deadline=None)
@given(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                          st.integers(-5, 9).map(str), st.sampled_from(["", " ", "x", "1e999"])),
                min_size=1, max_size=4).map(",".join))
def test_the_option_parser_takes_finite_non_negative_numbers(text):
    import argparse

    from hyperlf.cli import _fusion_weights_arg

    try:
        numbers = [float(v) for v in text.split(",")]
    except ValueError:
        numbers = None
    valid = numbers is not None and any(numbers) and all(np.isfinite(v) and v >= 0
                                                         for v in numbers)
    if valid:
        assert _fusion_weights_arg(text) == tuple(numbers)
    else:
        with pytest.raises(argparse.ArgumentTypeError, match="like 1,4"):
            _fusion_weights_arg(text)


def test_depth_and_batch_commands_take_fusion_weights(tmp_path, capsys, scene, batch_depth_args):
    from hyperlf.cli import main
    from hyperlf.formats import read_pfm, save_lightfield

    save_lightfield(scene, tmp_path / "cap", bit_depth=32)
    assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "12", "--fusion-weights",
                 "1,4", "-o", str(tmp_path / "d")]) == 0
    expect = hlf.depth(scene, n_labels=12, params=hlf.DepthParams(fusion_weights=(1, 4)))
    np.testing.assert_array_equal(read_pfm(tmp_path / "d" / "disparity.pfm"), expect.disparity)
    capsys.readouterr()
    for argv, what in ((["--metric", "census", "--fusion-weights", "1,4"], "need a fused cost"),
                       (["--fusion-weights", "1,4,1"], "needs 2 weights")):
        out = tmp_path / f"bad{len(argv)}"
        assert main(["-q", "depth", str(tmp_path / "cap"), *argv, "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert what in err and err.count("\n") == 1 and "--fusion-weights" in err
        assert not out.exists()
    refused_while_parsing_and_handed_on(capsys, batch_depth_args, tmp_path / "cap",
                                        tmp_path / "zero", "--fusion-weights", "0,0", "1,4.5")
    calls = len(batch_depth_args.calls)
    assert main(["-q", "batch", str(tmp_path), "--metric", "ncc", "--fusion-weights", "1,4",
                 "-o", str(tmp_path / "o")]) == 2  # refused before the batch is planned
    assert len(batch_depth_args.calls) == calls and "fused cost" in capsys.readouterr().err


def test_stereo_command_takes_fusion_weights(tmp_path, capsys, weighted_fusion):
    from hyperlf.cli import main
    from hyperlf.formats import read_image, read_pfm, write_image
    from hyperlf.twoview import stereo

    rng = np.random.default_rng(5)
    scene = np.clip(rng.random((30, 60)), 0.05, 1)
    # left x matches right x + 4, outside the range 0..8: no label fits, so the weights of
    # the two parts decide every pixel and show in the map
    left, right = scene[:, 6:46], scene[:, 2:42] ** 1.5
    write_image(tmp_path / "l.png", left, bit_depth=16)
    write_image(tmp_path / "r.png", right, bit_depth=16)
    argv = ["-q", "stereo", str(tmp_path / "l.png"), str(tmp_path / "r.png"),
            "--disparity-range", "0,8"]
    assert main([*argv, "--fusion-weights", "1,4", "-o", str(tmp_path / "s")]) == 0
    got = read_pfm(tmp_path / "s" / "disparity.pfm")
    L, R = read_image(tmp_path / "l.png"), read_image(tmp_path / "r.png")
    np.testing.assert_array_equal(got, stereo(L, R, (0, 8), metric=weighted_fusion).disparity)
    assert (got != stereo(L, R, (0, 8)).disparity).sum() > 100  # the weights did something
    assert main([*argv, "--metric", "ncc", "--fusion-weights", "1,4",
                 "-o", str(tmp_path / "bad")]) == 2
    assert "fused cost" in capsys.readouterr().err and not (tmp_path / "bad").exists()
