"""Strips of the correspondence stage (SPEC §12, issue 13 item 2): bit for bit the untiled
result, a memory budget that picks them, and the option parsers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf import synthesis
from hyperlf.cli import main
from hyperlf.costs import (ROW_BLOCK, census_view_volume, check_rows, moments_std,
                           normalise_volume, row_moments, view_costs, view_moments)
from hyperlf.errors import InvalidInputError
from hyperlf.hlf import DepthParams, depth
from hyperlf.tiling import (DEFAULT_MAX_MEMORY, check_strips, depth_memory, parse_memory, plan,
                            row_strips)

STRIPS = [(0, 32), (32, 64), (64, 96), (96, 100)]


def _pair(seed=1, H=100, W=70):
    rng = np.random.default_rng(seed)
    a = rng.random((H, W)) + 0.5
    b = np.roll(a, (3, 2), axis=(0, 1)) + 0.05 * rng.random((H, W))
    m = np.ones((H, W), bool)
    m[40:50, 10:30] = False
    return a, b, m


def _whole_scales(a, b, offset, labels, metric, masks):
    mom = [view_moments(a, b, offset, labels, metric, rows=r, **masks) for r in STRIPS]
    if mom[0] is None:
        return None
    return [moments_std(*(np.concatenate([m[k][j] for m in mom]) for j in range(3)))
            for k in range(len(mom[0]))]


@pytest.mark.parametrize("metric", ["ncc", "rsncc", "census", "census-rsncc", "bwncc"])
@pytest.mark.parametrize("masked", [False, True])
def test_strips_of_a_view_volume_are_the_whole_volume_bit_for_bit(metric, masked):
    # a vertical shift of up to 6 px: windows and samples of a strip reach into its neighbours
    a, b, m = _pair()
    masks = dict(ref_valid=m, view_valid=np.roll(m, 5, axis=1)) if masked else {}
    labels = np.linspace(-2.0, 4.0, 9)
    off = (-1.0, -1.5)
    C, valid = view_costs(a, b, off, labels, metric, **masks)
    scales = _whole_scales(a, b, off, labels, metric, masks)
    assert (scales is None) == (metric not in ("census-rsncc",))
    parts = [view_costs(a, b, off, labels, metric, rows=r, scales=scales, **masks)
             for r in STRIPS]
    np.testing.assert_array_equal(np.concatenate([p[0] for p in parts], axis=1), C)
    np.testing.assert_array_equal(np.concatenate([p[1] for p in parts], axis=1), valid)


def test_census_strips_agree_with_the_numpy_reference():
    a, b, _ = _pair(seed=2)
    shifts = [(0.5, -2.25), (-1.0, 3.5)]
    ref = census_view_volume(a, b, shifts, impl="numpy")
    for r in STRIPS:
        np.testing.assert_array_equal(census_view_volume(a, b, shifts, rows=r), ref[:, r[0]:r[1]])
        np.testing.assert_array_equal(census_view_volume(a, b, shifts, rows=r, impl="numpy"),
                                      ref[:, r[0]:r[1]])


def test_row_moments_of_strips_join_to_the_whole_standard_deviation(rng):
    C = rng.normal(3.0, 2.0, (7, 50, 11))
    valid = rng.random(C.shape) > 0.3
    valid[:, 20] = False  # an empty row
    whole = row_moments(C, valid)
    strips = [row_moments(C[:, a:b], valid[:, a:b]) for a, b in ((0, 13), (13, 40), (40, 50))]
    for j in range(3):
        np.testing.assert_array_equal(np.concatenate([s[j] for s in strips]), whole[j])
    np.testing.assert_allclose(moments_std(*whole), C[valid].std(), rtol=1e-12)
    assert moments_std(*row_moments(C, np.zeros(C.shape, bool))) == 0.0
    # the fusion's normaliser with the scale measured elsewhere is the one it measures itself
    sd = moments_std(*whole)
    np.testing.assert_array_equal(normalise_volume(C, 0, valid, sd=sd),
                                  normalise_volume(C, 0, valid))


def test_a_strip_of_a_fused_cost_without_the_whole_scales_is_refused():
    a, b, _ = _pair()
    with pytest.raises(InvalidInputError, match="whole view's scales"):
        view_costs(a, b, (1.0, 0.0), [0.0, 1.0], "census-rsncc", rows=(0, 32))


@pytest.mark.parametrize("rows", [(1, 32), (0, 0), (32, 200), (-32, 10), ("a", 3), (0.5, 9),
                                  (0, 32, 64)])
def test_bad_rows_are_refused(rows):
    with pytest.raises(InvalidInputError, match="rows must be"):
        check_rows(rows, 100)


def _edge_scene():
    """A capture whose strips of 32 rows cut through depth edges."""
    lf = synthesis.procedural_scene(seed=4, rows=3, cols=3, height=100, width=72)
    gt = lf.reference_gt_disparity
    # depth edges run across the first two strip boundaries (jumps along both rows there)
    jumps = [min(np.abs(np.diff(gt[b - 1])).max(), np.abs(np.diff(gt[b])).max())
             for b in (32, 64)]
    assert min(jumps) > 1.0, jumps
    return lf


OPTIONS = {
    "default": {},
    "cues": dict(view_selection=True, occlusion_split=True, defocus="paper"),
    "sgm": dict(optimizer="sgm"),
    "visibility+neutral": dict(params=dict(visibility_rounds=1, missing_views="neutral")),
    "visibility+common": dict(params=dict(visibility_rounds=1, missing_views="common")),
    "single cost": dict(metric="rsncc"),
    "fusion weights": dict(params=dict(fusion_weights=(1, 4))),
}


@pytest.mark.parametrize("name", list(OPTIONS))
def test_tiled_depth_is_the_untiled_depth_bit_for_bit(name):
    lf = _edge_scene()
    kw = dict(OPTIONS[name])
    params = kw.pop("params", {})
    whole = depth(lf, n_labels=20, save_intermediate=True, params=DepthParams(**params), **kw)
    tiled = depth(lf, n_labels=20, save_intermediate=True,
                  params=DepthParams(tile_rows=ROW_BLOCK, **params), **kw)
    assert len(tiled.config["strips"]) == 4 and len(whole.config["strips"]) == 1
    assert "scales_s" in tiled.timings
    assert "scales_s" not in whole.timings
    np.testing.assert_array_equal(tiled.disparity, whole.disparity)
    np.testing.assert_array_equal(tiled.confidence, whole.confidence)
    for key in ("C", "unary", "n_selected"):
        np.testing.assert_array_equal(tiled.intermediate[key], whole.intermediate[key])


def test_a_tiny_budget_picks_strips_and_changes_nothing():
    lf = _edge_scene()
    budget = depth_memory(lf.image_shape, 20, lf.n_views, strip_rows=32) + 1
    strips = [(0, 32), (32, 64), (64, 96), (96, 100)]
    assert plan(lf.image_shape, 20, lf.n_views, budget) == strips
    whole = depth(lf, n_labels=20)
    tiled = depth(lf, n_labels=20, params=DepthParams(max_memory=budget))
    assert tiled.config["strips"] == strips
    np.testing.assert_array_equal(tiled.disparity, whole.disparity)


def test_masked_views_tile_exactly():
    lf = _edge_scene()
    valid = np.ones(lf.views.shape, bool)
    valid[0, 0, 20:45, 10:30] = False
    valid[1, 1, 60:70, :] = False  # the reference
    lfm = lf.replace(valid=valid)
    whole = depth(lfm, n_labels=16)
    tiled = depth(lfm, n_labels=16, params=DepthParams(tile_rows=64))
    np.testing.assert_array_equal(tiled.disparity, whole.disparity)
    np.testing.assert_array_equal(tiled.confidence, whole.confidence)


# ------------------------------------------------------------------------------ the budget
def test_plan_fits_the_budget_and_refuses_what_cannot_fit():
    shape, L, V = (900, 1200), 64, 30
    assert plan(shape, L, V, None) == [(0, 900)]  # the paper's size fits the default budget
    assert depth_memory(shape, L, V) < DEFAULT_MAX_MEMORY
    previous = 1
    for gib in (2.3, 2.2, 2.1):
        strips = plan(shape, L, V, gib * 2**30)
        rows = strips[0][1]
        assert rows % ROW_BLOCK == 0 and strips == row_strips(900, rows)
        assert depth_memory(shape, L, V, strip_rows=rows) <= gib * 2**30
        assert len(strips) >= previous  # less memory, more strips
        previous = len(strips)
    with pytest.raises(InvalidInputError, match=r"needs about .* raise --max-memory"):
        plan(shape, L, V, 2**30)
    assert plan(shape, L, V, 1, tile_rows=448) == [(0, 448), (448, 896), (896, 900)]


def test_the_estimate_grows_with_pixels_labels_and_views():
    base = depth_memory((256, 256), 32, 9)
    assert depth_memory((512, 256), 32, 9) > base
    assert depth_memory((256, 256), 64, 9) > base
    assert depth_memory((256, 256), 32, 81) > base
    assert depth_memory((256, 256), 32, 9, selection=True) > base
    assert depth_memory((256, 256), 32, 9, strip_rows=32) < base


def test_strips_must_cover_the_image_in_order():
    assert check_strips(None, 70) == [(0, 70)]
    assert check_strips([(0, 64), (64, 70)], 70) == [(0, 64), (64, 70)]
    for bad in ([(0, 32)], [(0, 32), (64, 70)], [(32, 70), (0, 32)], []):
        with pytest.raises(InvalidInputError):
            check_strips(bad, 70)
    with pytest.raises(InvalidInputError, match="multiple of"):
        row_strips(100, 48)
    with pytest.raises(InvalidInputError, match="tile_rows"):
        DepthParams(tile_rows=2.5)
    with pytest.raises(InvalidInputError, match="max_memory"):
        DepthParams(max_memory=-1)


_UNIT = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


@given(st.integers(1, 10**6), st.sampled_from(sorted(_UNIT)), st.sampled_from(["", "B", "iB"]),
       st.booleans())
@settings(max_examples=200, deadline=None)
def test_parse_memory_reads_sizes_with_units(n, unit, suffix, lower):
    text = f"{n}{unit}{suffix if unit else ''}"
    if lower:
        text = text.lower()
    assert parse_memory(text) == n * _UNIT[unit]


@given(st.text(max_size=12))
@settings(max_examples=300, deadline=None)
def test_parse_memory_refuses_anything_else_with_a_message(text):
    try:
        v = parse_memory(text)
    except InvalidInputError as e:
        assert "memory size" in str(e)
    else:
        assert isinstance(v, int) and v >= 1


def test_parse_memory_edge_cases():
    assert parse_memory("1.5G") == 3 * 2**29 and parse_memory(" 2 gib ") == 2 * 2**30
    for bad in ("0", "-1G", "G", "1X", "1e400", True, float("nan"), "inf"):
        with pytest.raises(InvalidInputError):
            parse_memory(bad)


# ------------------------------------------------------------------------------ command line
def test_depth_command_honours_max_memory(tmp_path, capsys):
    from hyperlf.formats import read_pfm

    cap = tmp_path / "cap"
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "72,40",
                 "--grid", "3,3", "-o", str(cap), "--no-pictures"]) == 0
    assert main(["-q", "depth", str(cap), "--labels", "12", "-o", str(tmp_path / "a")]) == 0
    need = depth_memory((72, 40), 12, 9, strip_rows=32) + 1
    assert main(["depth", str(cap), "--labels", "12", "--max-memory", str(int(need)),
                 "-o", str(tmp_path / "b")]) == 0
    assert "in 3 strips of 32 rows" in capsys.readouterr().err
    np.testing.assert_array_equal(read_pfm(tmp_path / "b" / "disparity.pfm"),
                                  read_pfm(tmp_path / "a" / "disparity.pfm"))
    # too small a budget: refused before any work, one line, usage exit code, nothing written
    assert main(["depth", str(cap), "--labels", "12", "--max-memory", "1M",
                 "-o", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--max-memory" in err and len(err.splitlines()) == 1 and not (tmp_path / "c").exists()
    with pytest.raises(SystemExit) as e:
        main(["depth", str(cap), "--max-memory", "lots", "-o", str(tmp_path / "d")])
    assert e.value.code == 2
    assert "memory size" in capsys.readouterr().err


def test_depth_command_fits_the_memory_available_when_no_budget_is_given(tmp_path, capsys,
                                                                          monkeypatch):
    from hyperlf import tiling
    from hyperlf.formats import read_pfm

    cap = tmp_path / "cap"
    assert main(["-q", "synth", "procedural", "--scene", "planes", "--size", "72,40",
                 "--grid", "3,3", "-o", str(cap), "--no-pictures"]) == 0
    assert main(["-q", "depth", str(cap), "--labels", "12", "-o", str(tmp_path / "a")]) == 0
    little = int(depth_memory((72, 40), 12, 9, strip_rows=32) + 1)
    monkeypatch.setattr(tiling, "available_memory", lambda: little)
    assert main(["depth", str(cap), "--labels", "12", "-o", str(tmp_path / "b")]) == 0
    assert "in 3 strips of 32 rows" in capsys.readouterr().err
    np.testing.assert_array_equal(read_pfm(tmp_path / "b" / "disparity.pfm"),
                                  read_pfm(tmp_path / "a" / "disparity.pfm"))
