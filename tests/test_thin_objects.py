"""Thin objects that graph cuts lose, and the holes they fill, taken back from SGM (issue
12): :func:`hyperlf.regularisers.thin_foreground` and
:func:`hyperlf.regularisers.enclosed_background` (the rule), :func:`hyperlf.hlf.thin_objects`
(the depth stage), ``DepthParams.thin_*`` and ``--thin-objects``."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from hyperlf import hlf, regularisers, synthesis
from hyperlf.cli import main
from hyperlf.errors import InvalidInputError
from hyperlf.regularisers import enclosed_background, thin_foreground


def _wall_and_square():
    """A wall at 0 with a square at 3 from column 20: graph cuts' answer."""
    d = np.zeros((24, 40))
    d[4:20, 20:36] = 3.0
    return d


def test_a_lost_rod_is_taken_and_a_widened_edge_is_not():
    d = _wall_and_square()
    p = d.copy()
    p[2:22, 5:7] = 3.0         # a rod graph cuts lost: it meets nothing at its depth
    p[4:20, 17:20] = 3.0       # the square widened by 3 px: one whole side is its own depth
    taken = thin_foreground(d, p)
    assert taken[2:22, 5:7].all()
    assert not taken[:, 10:].any()
    assert taken.sum() == 40


def test_a_rod_that_ends_on_the_square_is_still_taken():
    d = _wall_and_square()
    p = d.copy()
    p[10:12, 6:20] = 3.0       # a horizontal rod reaching the square: only its end touches
    assert thin_foreground(d, p)[10:12, 6:20].all()


def test_the_touch_threshold_decides_at_the_share_of_the_outline():
    d = _wall_and_square()
    p = d.copy()
    p[10:12, 6:20] = 3.0
    outline = 4 * 16 - 2 * 14      # the 8-neighbours of a 2 x 14 bar
    share = 4 / outline            # four of them (column 20, rows 9-12) are the square's
    assert thin_foreground(d, p, touch=share + 1e-6)[10:12, 6:20].all()
    assert not thin_foreground(d, p, touch=share).any()


def test_small_components_and_small_jumps_are_left():
    d = np.zeros((20, 20))
    p = d.copy()
    p[5:8, 5:8] = 3.0          # 9 px, under the default 10
    p[12:18, 12:14] = 0.9      # 12 px, nearer by less than the jump
    assert not thin_foreground(d, p).any()
    assert thin_foreground(d, p, min_size=9)[5:8, 5:8].all()
    assert thin_foreground(d, p, jump=0.5)[12:18, 12:14].all()


def test_a_strip_along_the_border_is_left_and_a_rod_across_it_taken():
    d = np.zeros((30, 30))
    p = d.copy()
    p[5:25, 0:2] = 3.0         # along the left border: most of its outline is beyond it
    p[0:12, 14:16] = 3.0       # leaves the image across the top border
    taken = thin_foreground(d, p)
    assert not taken[:, :2].any() and taken[0:12, 14:16].all()


def test_support_decides_where_the_data_do_not_vouch_for_the_proposal():
    d = _wall_and_square()
    p = d.copy()
    p[2:22, 5:7] = 3.0
    support = np.zeros(d.shape)
    assert not thin_foreground(d, p, support=support).any()
    support[2:22, 5:7] = 0.1
    assert thin_foreground(d, p, support=support, min_support=0.05)[2:22, 5:7].all()
    assert not thin_foreground(d, p, support=support, min_support=0.1).any()
    with pytest.raises(InvalidInputError, match="support must have shape"):
        thin_foreground(d, p, support=support[:, :-1])


def test_a_component_mostly_of_untrusted_pixels_is_left():
    d = _wall_and_square()
    p = d.copy()
    p[2:22, 5:7] = 3.0                       # 40 px
    trusted = np.zeros(d.shape, bool)
    trusted[2:22, 5] = True                  # 20 of them: not more than half
    assert not thin_foreground(d, p, trusted=trusted).any()
    trusted[2, 6] = True                     # 21
    assert thin_foreground(d, p, trusted=trusted)[2:22, 5:7].all()
    with pytest.raises(InvalidInputError, match="trusted"):
        thin_foreground(d, p, trusted=trusted[:-1])


@pytest.mark.parametrize("dtype", [np.uint8, np.int16, np.float32])
def test_integer_and_single_precision_maps_give_the_same_mask(dtype):
    d = _wall_and_square()
    p = d.copy()
    p[2:22, 5:7] = 3.0
    p[0, 0] = 0.0
    d[12, 30] = 3.0                # a pixel where the proposal is farther: no wrap-around
    p[12, 30] = 0.0
    expected = thin_foreground(d, p)
    np.testing.assert_array_equal(thin_foreground(d.astype(dtype), p.astype(dtype)), expected)
    assert expected.sum() == 40


def test_farther_proposals_and_the_whole_image_are_left():
    d = np.full((12, 12), 2.0)
    assert not thin_foreground(d, d - 3.0).any()   # farther everywhere
    assert not thin_foreground(d, d + 3.0).any()   # nearer everywhere: no outline at all


@pytest.mark.parametrize("kwargs, match", [
    (dict(disparity=np.zeros((4, 4)), proposal=np.zeros((4, 5))), "proposal must have shape"),
    (dict(disparity=np.zeros(4), proposal=np.zeros(4)), "disparity must be a 2-D"),
    (dict(disparity=np.full((4, 4), np.nan), proposal=np.zeros((4, 4))), "disparity must be fin"),
    (dict(disparity=np.zeros((4, 4)), proposal=np.zeros((4, 4)), jump=0), "jump"),
    (dict(disparity=np.zeros((4, 4)), proposal=np.zeros((4, 4)), touch=1.5), "touch"),
    (dict(disparity=np.zeros((4, 4)), proposal=np.zeros((4, 4)), min_size=0), "min_size"),
])
def test_bad_arguments_are_refused_in_one_line(kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        thin_foreground(**kwargs)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), jump=st.floats(0.1, 3.0),
       touch=st.floats(0.05, 1.0), min_size=st.integers(1, 30))
def test_taken_pixels_are_nearer_by_the_jump_and_whole_components(seed, jump, touch, min_size):
    """And the holes of the mirrored maps are the same pixels, but for components at the
    image's border or at a depth the estimate does not hold: one rule, sides swapped."""
    from scipy import ndimage as ndi

    rng = np.random.default_rng(seed)
    d = rng.integers(0, 4, (24, 30)).astype(float)
    p = d + rng.choice([0.0, 0.0, 2.0, 4.0], d.shape)
    taken = thin_foreground(d, p, jump=jump, touch=touch, min_size=min_size)
    nearer = p - d > jump
    assert not (taken & ~nearer).any()
    components, _ = ndi.label(nearer, structure=np.ones((3, 3), bool))
    for i in np.unique(components[taken]):      # a component is taken whole or not at all
        assert taken[components == i].all()
        assert (components == i).sum() >= min_size
    border = np.ones(d.shape, bool)
    border[1:-1, 1:-1] = False
    at_border = np.isin(components, components[taken & border])
    holes = enclosed_background(-d, -p, jump=jump, touch=touch, min_size=min_size)
    assert not (holes & ~(taken & ~at_border)).any()
    for i in np.unique(components[taken & ~at_border]):
        own = components == i                   # a hole shows a depth the estimate holds
        held = np.count_nonzero(np.abs(d - np.median(p[own])) <= jump)
        assert holes[own].all() == (held >= min_size)


# --------------------------------------------------------------------------------------------
# holes: the same rule, sides swapped
# --------------------------------------------------------------------------------------------

def _ring_with_filled_hole():
    """A wall at 0 behind a ring at 3 (rows 2-21, columns 2-21) whose 8 x 8 hole graph cuts
    filled (``d``) and the proposal kept (``p``)."""
    p = np.zeros((24, 40))
    p[2:22, 2:22] = 3.0
    p[8:16, 8:16] = 0.0
    d = p.copy()
    d[8:16, 8:16] = 3.0
    return d, p


def test_a_filled_hole_is_taken_and_a_widened_edge_is_not():
    d, p = _ring_with_filled_hole()
    d[4:20, 26:29] = 3.0       # graph cuts widened a square (columns 29-36) by 3 px
    p[4:20, 29:37] = d[4:20, 29:37] = 3.0
    taken = enclosed_background(d, p)
    assert taken[8:16, 8:16].all() and taken.sum() == 64
    assert not thin_foreground(d, p).any()          # nothing is nearer in the proposal


def test_a_hole_open_to_the_background_is_left():
    d, p = _ring_with_filled_hole()
    p[8:16, 0:8] = 0.0         # the hole opens to the wall on the left through a gap
    d[8:16, 2:8] = 3.0         # which graph cuts filled too: its outline meets the wall
    share = 10 / (10 * 16 - 8 * 14)    # of the 8 x 14 gap's outline, column 1 is wall
    assert not enclosed_background(d, p, touch=share).any()
    assert enclosed_background(d, p, touch=share + 1e-6)[8:16, 2:16].all()


def test_a_component_at_the_border_is_no_hole():
    """Where the proposal is farther along the image's border (views that do not see the
    border's pixels at their depth), nothing encloses it: left, however little its inner
    outline touches the estimate's surface at its depth."""
    d = np.full((24, 40), 3.0)
    p = d.copy()
    p[0:6, 8:30] = 0.0
    assert not enclosed_background(d, p, touch=1.0).any()
    assert thin_foreground(-d, -p, touch=1.0)[0:6, 8:30].all()   # a rod may cross it


def test_a_hole_shows_a_surface_the_estimate_holds():
    """Through a hole lies a surface that the estimate has elsewhere; a proposal at a depth
    no surface of the estimate holds is its own error."""
    d, p = _ring_with_filled_hole()
    p[8:16, 8:16] = -5.0
    assert not enclosed_background(d, p).any()
    d[22:24, 30:35] = -5.5                     # 10 px of the estimate near -5 ...
    assert enclosed_background(d, p).sum() == 64
    assert not enclosed_background(d, p, min_size=11).any()   # ... and not 11


def test_holes_have_the_guards_of_thin_objects():
    d, p = _ring_with_filled_hole()
    assert not enclosed_background(d, p, min_size=65).any()
    assert not enclosed_background(d, p, jump=3.0).any()
    support = np.where(d != p, 0.2, 0.0)
    assert enclosed_background(d, p, support=support, min_support=0.1).sum() == 64
    assert not enclosed_background(d, p, support=support, min_support=0.2).any()
    trusted = np.ones(d.shape, bool)
    trusted[8:12, 8:16] = False                     # half the hole: not more than half
    assert not enclosed_background(d, p, trusted=trusted).any()
    trusted[8, 8] = True
    assert enclosed_background(d, p, trusted=trusted).sum() == 64


def test_a_proposal_scattered_over_depths_is_no_object():
    # a rod whose proposal takes four depths by turns: no pixel lies within the jump of the
    # median (6.5), so it is refused once coherence is asked for; one depth is taken
    d = np.zeros((20, 30))
    p = d.copy()
    p[2:18, 10:12] = np.array([2.0, 5.0, 8.0, 11.0])[np.arange(16) % 4][:, None]
    assert thin_foreground(d, p).sum() == 32                      # 0: no such test
    assert not thin_foreground(d, p, coherent=0.3).any()
    p[2:18, 10:12] = 5.0
    assert thin_foreground(d, p, coherent=1.0).sum() == 32
    # a hole whose proposal is the wall on 5 of its 8 rows, 2 px farther on the others
    d, p = _ring_with_filled_hole()
    p[13:16, 8:16] = -2.0
    assert enclosed_background(d, p, coherent=0.6).sum() == 64
    assert not enclosed_background(d, p, coherent=0.7).any()


@pytest.mark.parametrize("kwargs, match", [
    (dict(disparity=np.zeros((4, 4)), proposal=np.zeros((4, 4)), coherent=1.5), "coherent"),
    (dict(disparity=np.zeros((4, 4)), proposal=np.zeros((4, 4)), coherent=-0.1), "coherent"),
    (dict(disparity=np.zeros((4, 4)), proposal=np.zeros((4, 5))), "proposal must have shape"),
    (dict(disparity=np.full((4, 4), np.inf), proposal=np.zeros((4, 4))), "disparity must be fin"),
    (dict(disparity=np.zeros((4, 4)), proposal=np.zeros((4, 4)), touch=0), "touch"),
    (dict(disparity=np.zeros((4, 4)), proposal=np.zeros((4, 4)), support=np.zeros((3, 4))),
     "support"),
])
def test_bad_arguments_to_the_hole_rule_are_refused_in_one_line(kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        enclosed_background(**kwargs)


# --------------------------------------------------------------------------------------------
# the depth stage
# --------------------------------------------------------------------------------------------

def _rod_problem(**params):
    """A small problem and a unary whose rod (2 px wide, label 6) prefers its depth five
    times more weakly than the wall (label 1) prefers the wall's."""
    lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    prob = hlf.prepare(lf, n_labels=8, params=hlf.DepthParams(median_radius=0, **params))
    rod = np.zeros((32, 40), bool)
    rod[4:28, 18:20] = True
    steps = np.arange(8.0)[:, None, None]
    U = np.where(rod, 0.2 * np.minimum(abs(steps - 6), 3),
                 np.minimum(abs(steps - 1), 3)).astype(np.float32)
    return prob, U, rod


def _graph_cuts(prob, U):
    f_c = prob.labels[U.argmin(axis=0)]
    labels_map, volume = hlf.regularise(prob, U, f_c)
    d, c = hlf.refine(volume, labels_map, prob.labels, prob.params)
    return f_c, d, c


def test_the_stage_takes_back_the_rod_graph_cuts_lost():
    prob, U, rod = _rod_problem()
    f_c, d, c = _graph_cuts(prob, U)
    assert np.allclose(d, prob.labels[1])                   # graph cuts: all wall
    d2, c2, taken = hlf.thin_objects(prob, U, f_c, d, c)
    assert np.array_equal(taken, rod)
    assert np.allclose(d2[rod], prob.labels[6]) and np.array_equal(d2[~rod], d[~rod])
    assert np.array_equal(c2[~rod], c[~rod]) and (c2[rod] >= 0).all()
    # a coarse prior without its confidence, and no texture weight: the same pixels
    prior = (np.zeros(rod.shape), np.zeros(rod.shape), 1.0)
    assert np.array_equal(hlf.thin_objects(prob, U, f_c, d, c, prior=prior)[2], rod)
    with pytest.raises(InvalidInputError, match="prior"):
        hlf.thin_objects(prob, U, f_c, d, c, prior=(1, 2))
    # a texture weight as a list is read as a map; under 0.5 on the rod, nothing is taken
    weight = np.where(rod, 0.4, 1.0).tolist()
    assert not hlf.thin_objects(prob, U, f_c, d, c, weight=weight)[2].any()
    with pytest.raises(InvalidInputError, match="weight"):
        hlf.thin_objects(prob, U, f_c, d, c, weight=np.full(rod.shape, 2.0))


def _hole_problem(*, weak=0.2, kept=0, **params):
    """A ring (label 6) around a 6 x 6 hole of wall (label 1) whose pixels prefer the wall
    ``1 / weak`` times more weakly than the rest of the wall does, but for its first
    ``kept`` columns, which prefer it as strongly: graph cuts fill the hole (its weak part).
    The reference view is made flat, so that the contrast-sensitive weights do not depend on
    the scene's reflectances (which depend on whether the data is set)."""
    lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    prob = hlf.prepare(lf, n_labels=8, params=hlf.DepthParams(median_radius=0, **params))
    prob.In[prob.reference] = np.full_like(prob.In[prob.reference], 0.5)
    hole = np.zeros((32, 40), bool)
    hole[13:19, 17:23] = True
    ring = np.zeros_like(hole)
    ring[6:26, 10:30] = True
    ring &= ~hole
    steps = np.arange(8.0)[:, None, None]
    wall = np.minimum(abs(steps - 1), 3)
    weak = np.where(hole, weak, 1.0)
    weak[:, 17:17 + kept] = 1.0
    U = np.where(ring, np.minimum(abs(steps - 6), 3), weak * wall)
    return prob, U.astype(np.float32), hole


def test_the_stage_opens_the_hole_graph_cuts_filled():
    prob, U, hole = _hole_problem()
    f_c, d, c = _graph_cuts(prob, U)
    assert np.allclose(d[hole], prob.labels[6])                # graph cuts: the ring's depth
    d2, _, taken = hlf.thin_objects(prob, U, f_c, d, c)
    assert np.array_equal(taken, hole)
    assert np.allclose(d2[hole], prob.labels[1]) and np.array_equal(d2[~hole], d[~hole])
    prob, U, hole = _hole_problem(thin_holes=False)
    f_c, d, c = _graph_cuts(prob, U)
    assert not hlf.thin_objects(prob, U, f_c, d, c)[2].any()


def test_a_hole_filled_in_part_is_decided_at_the_holes_own_outline_share():
    # graph cuts keep the hole's first column open and fill the rest, whose outline meets
    # that column on a quarter of it: taken at the default share, not at 0.25 (the thin
    # objects' share); thin_touch at 0.9 shows that the holes do not read it
    default = hlf.DepthParams().thin_hole_touch
    taken, opened = {}, {}
    for touch in (default, 0.25):
        prob, U, hole = _hole_problem(weak=0.1, kept=1, thin_hole_touch=touch,
                                      thin_touch=0.9)
        f_c, d, c = _graph_cuts(prob, U)
        assert np.allclose(d[:, 17][hole[:, 17]], prob.labels[1])          # kept open
        assert np.allclose(d[:, 18:23][hole[:, 18:23]], prob.labels[6])    # filled
        opened[touch], _, taken[touch] = hlf.thin_objects(prob, U, f_c, d, c)
    assert taken[default].sum() >= 20 and not taken[default][:, :18].any()
    assert (taken[default] <= hole).all()
    assert np.allclose(opened[default][taken[default]], prob.labels[1])
    assert not taken[0.25].any()


@pytest.mark.parametrize("params, optimizer", [({"thin_objects": False}, "graphcut"),
                                               ({"smoothness": 0.0}, "graphcut"),
                                               ({}, "sgm")])
def test_the_stage_is_off_without_graph_cuts_or_when_asked(params, optimizer):
    prob, U, _ = _rod_problem(**params)
    prob.optimizer = optimizer
    f_c, d, c = _graph_cuts(prob, U)
    d2, c2, taken = hlf.thin_objects(prob, U, f_c, d, c)
    assert taken is None and d2 is d and c2 is c


def test_regularise_takes_another_optimiser_and_refuses_an_unknown_one():
    prob, U, rod = _rod_problem()
    f_c = prob.labels[U.argmin(axis=0)]
    labels_map, _ = hlf.regularise(prob, U, f_c, optimizer="sgm")
    assert (labels_map[rod] == 6).mean() > 0.9
    with pytest.raises(InvalidInputError, match="optimizer"):
        hlf.regularise(prob, U, f_c, optimizer="belief")


@pytest.fixture(scope="module")
def rings_and_sticks():
    """Rings and sticks before slanted and fronto-parallel planes, and its default depth."""
    lf = synthesis.procedural_scene(3, rows=3, cols=3, height=96, width=128,
                                    kinds=("ring", "stick", "fronto", "ring", "stick",
                                           "slanted"), n_objects=10, supersample=2)
    return lf, hlf.depth(lf, n_labels=32, save_intermediate=True)


def test_depth_recovers_thin_objects_of_a_procedural_scene(rings_and_sticks):
    """The pixels the stage takes were wrong by more than a pixel under graph cuts, and are
    right after."""
    lf, on = rings_and_sticks
    gt = lf.reference_gt_disparity
    off = hlf.depth(lf, n_labels=32, params=hlf.DepthParams(thin_objects=False))
    taken = on.intermediate["thin_objects"]
    assert on.config["thin_object_share"] == pytest.approx(taken.mean())
    assert taken.sum() > 100
    assert np.median(np.abs(off.disparity - gt)[taken]) > 1.0
    assert np.median(np.abs(on.disparity - gt)[taken]) < 0.25
    assert np.array_equal(on.disparity[~taken], off.disparity[~taken])
    assert "thin_objects_s" in on.timings


def test_noise_in_weak_texture_is_no_thin_object():
    """A noisy camera-like capture (texture weight on) without the coarse prior: SGM spreads
    the noise of weak texture into blobs nearer than graph cuts' right answer, which the
    unary even prefers slightly on their few textured pixels; most of their pixels' data do
    not count, so nothing is taken (before that guard: 4.4 % of the pixels, RMSE 0.26 ->
    0.49 px), and a unary flat on most pixels gives no overflow."""
    import warnings
    from dataclasses import replace

    lf = synthesis.procedural_scene(seed=3, rows=4, cols=4, height=96, width=112,
                                    noise_sigma=0.01, reflectance_source="colorchecker")
    lf = lf.replace(metadata={"calibration": {"mode": "plane"}})
    params = hlf.DepthParams(visibility_min_size=32, visibility_rounds=1, coarse_prior=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = hlf.depth(lf, n_labels=17, params=params, save_intermediate=True)
    assert res.config["weak_data_share"] > 0.5
    assert res.config["thin_object_share"] == 0.0
    w, U = res.intermediate["texture_weight"], res.intermediate["unary"]
    assert (U.max(axis=0) == U.min(axis=0)).mean() > 0.5          # no unary on most pixels
    off = hlf.depth(lf, n_labels=17, params=replace(params, thin_objects=False))
    np.testing.assert_array_equal(res.disparity, off.disparity)
    saving = regularisers.label_saving(U, res.labels, off.disparity, off.disparity + 1,
                                       trusted=w >= hlf.TRUSTED_WEIGHT)
    assert np.isfinite(saving).all()


def test_thin_objects_are_on_by_default_and_their_constants_checked():
    p = hlf.DepthParams()
    assert (p.thin_objects, p.thin_holes, p.thin_jump, p.thin_touch, p.thin_hole_touch,
            p.thin_min_size, p.thin_min_support) == (True, True, 1.0, 0.25, 0.7, 10, 0.05)
    for bad in ({"thin_objects": 1}, {"thin_holes": "yes"}, {"thin_jump": 0}, {"thin_touch": 0},
                {"thin_touch": 1.1}, {"thin_hole_touch": 0}, {"thin_hole_touch": 1.5},
                {"thin_min_size": 0}, {"thin_jump": float("nan")},
                {"thin_min_support": float("inf")}, {"thin_min_support": "0.1"}):
        with pytest.raises(InvalidInputError, match="params.thin_"):
            hlf.DepthParams(**bad)


def test_the_coarse_run_has_no_thin_object_stage():
    lf = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=64, width=64)
    prob = hlf.prepare(lf, n_labels=16)
    _, options = hlf._coarse_problem(prob, 2)
    assert options["params"].thin_objects is False


# --------------------------------------------------------------------------------------------
# the command line
# --------------------------------------------------------------------------------------------

def test_depth_takes_thin_objects(tmp_path, capsys, monkeypatch):
    from hyperlf.formats import save_lightfield

    save_lightfield(synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40),
                    tmp_path / "cap", bit_depth=32)
    seen, real = [], hlf.depth

    def spy(*args, params=None, **kwargs):
        seen.append(hlf.DepthParams() if params is None else params)
        return real(*args, params=params, **kwargs)

    monkeypatch.setattr(hlf, "depth", spy)
    for flags, on in (([], True), (["--thin-objects"], True), (["--no-thin-objects"], False)):
        assert main(["-q", "depth", str(tmp_path / "cap"), "--labels", "16", *flags,
                     "-o", str(tmp_path / "out"), "--overwrite"]) == 0
        assert seen[-1].thin_objects is on
    capsys.readouterr()
    assert main(["-q", "depth", str(tmp_path / "cap"), "--optimizer", "sgm",
                 "--no-thin-objects", "-o", str(tmp_path / "x")]) == 2
    assert "--no-thin-objects acts only with --optimizer graphcut" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_batch_hands_thin_objects_on(batch_depth_args):
    assert "--no-thin-objects" in batch_depth_args("--no-thin-objects")
    assert "--thin-objects" in batch_depth_args("--thin-objects")
    assert not any("thin" in a for a in batch_depth_args())


def test_depth_says_and_shows_what_it_took(tmp_path, capsys, rings_and_sticks):
    from hyperlf.formats import read_pfm, save_lightfield

    lf, ref = rings_and_sticks
    save_lightfield(lf, tmp_path / "cap", bit_depth=32)
    assert main(["depth", str(tmp_path / "cap"), "--labels", "32", "--save-intermediate",
                 "-o", str(tmp_path / "d")]) == 0
    share = 100 * ref.config["thin_object_share"]
    said = capsys.readouterr().err
    assert f"thin objects and holes: {share:.2f} % of the pixels taken from" in said
    mask = read_pfm(tmp_path / "d" / "thin_objects.pfm")
    np.testing.assert_array_equal(mask, ref.intermediate["thin_objects"].astype(np.float32))
    assert (tmp_path / "d" / "thin_objects.png").is_file()


# --------------------------------------------------------------------------------------------
# the data term's saving, and two-view stereo's holes
# --------------------------------------------------------------------------------------------

def test_label_saving_reads_each_map_at_its_nearest_label():
    rng = np.random.default_rng(3)
    volume = rng.random((5, 6, 7)).astype(np.float32)
    labels = np.linspace(-1.0, 1.0, 5)                      # a step of 0.5
    d = rng.uniform(-1.4, 1.4, (6, 7))                       # beyond the range: clipped
    p = rng.uniform(-1.4, 1.4, (6, 7))
    trusted = rng.random((6, 7)) > 0.3
    at = lambda m: np.take_along_axis(                      # noqa: E731
        volume, np.clip(np.rint((m + 1) / 0.5), 0, 4).astype(int)[None], 0)[0]
    spread = volume.max(axis=0) - volume.min(axis=0)
    want = (at(d) - at(p)) / np.median(spread[trusted])
    got = regularisers.label_saving(volume, labels, d, p, trusted=trusted)
    np.testing.assert_allclose(got, want, rtol=1e-6)
    flat = np.ones((3, 2, 2), np.float32)
    assert not regularisers.label_saving(flat, [0, 1, 2], np.zeros((2, 2)),
                                         np.ones((2, 2))).any()


@pytest.mark.parametrize("args, match", [
    ((np.zeros((2, 3, 3)), [0, 1], np.zeros((3, 4)), np.zeros((3, 3))), "disparity"),
    ((np.zeros((2, 3, 3)), [0, 1, 2], np.zeros((3, 3)), np.zeros((3, 3))), "labels"),
    ((np.zeros((2, 3, 3)), [1, 0], np.zeros((3, 3)), np.zeros((3, 3))), "labels must increase"),
    ((np.full((2, 3, 3), np.nan), [0, 1], np.zeros((3, 3)), np.zeros((3, 3))), "volume"),
    ((np.zeros((2, 3, 3)), [0, 1], np.zeros((3, 3)), np.full((3, 3), np.inf)), "proposal"),
])
def test_label_saving_refuses_bad_arguments_in_one_line(args, match):
    with pytest.raises(InvalidInputError, match=match):
        regularisers.label_saving(*args)


@pytest.mark.parametrize("field, value", [("weight_share", 1.0), ("weight_share", 0.0),
                                          ("jump", 0.0), ("touch", 0.0), ("touch", 1.5),
                                          ("min_size", 0), ("coherent", 1.2),
                                          ("min_support", float("nan")), ("enabled", 1),
                                          ("consistent", "yes")])
def test_hole_params_refuse_bad_values_in_one_line(field, value):
    with pytest.raises(InvalidInputError, match=field):
        regularisers.HoleParams(**{field: value})


def _volume(want, L=6):
    """A cost volume whose pixels' costs are each label's distance to ``want``, truncated
    at 2."""
    steps = np.arange(float(L))[:, None, None]
    return np.minimum(abs(steps - want), 2).astype(np.float32)


def _square_with_hole():
    """A cost volume (:func:`_volume`) of a wall (label 0) seen through a 6 x 6 hole in a
    square (label 5), and the hole."""
    square = np.zeros((24, 24), bool)
    square[4:20, 4:20] = True
    hole = np.zeros_like(square)
    hole[9:15, 9:15] = True
    return _volume(np.where(square & ~hole, 5, 0)), hole


ON = regularisers.HoleParams(enabled=True)
OFF = regularisers.HoleParams(enabled=False)


def test_open_holes_opens_what_half_the_smoothness_opens():
    from hyperlf.twoview import open_holes

    data, hole = _square_with_hole()
    gc = regularisers.GraphCutParams(weight=2.0, truncation=2.0, levels=0)
    f = regularisers.optimise(data, gc).labels
    assert (f[hole] == 5).all()                     # the outline costs more than the hole
    f2, none, opened = open_holes(data, f, gc, hole_params=ON)
    assert none is None
    assert np.array_equal(opened, hole) and (f2[hole] == 0).all()
    assert np.array_equal(f2[~hole], f[~hole])
    for on in (None, regularisers.HoleParams()):    # on by default
        assert np.array_equal(open_holes(data, f, gc, hole_params=on)[2], hole)
    f3, _, nothing = open_holes(data, f, gc, hole_params=OFF)
    assert np.array_equal(f3, f) and not nothing.any()
    sgm = regularisers.make_params("sgm", {})
    assert not open_holes(data, f, sgm, hole_params=ON)[2].any()    # graph cuts only
    # at 0.9 of the weight the outline still costs more than the hole saves
    assert not open_holes(data, f, gc, hole_params=regularisers.HoleParams(
        enabled=True, weight_share=0.9))[2].any()


@pytest.mark.parametrize("field, value", [("min_size", 37), ("min_support", 1.0),
                                          ("jump", 5.0)])
def test_open_holes_applies_the_rule_of_its_params(field, value):
    # the 36-px hole, whose data save 1.0 of the volume's median range per pixel, 5 labels
    # farther than the square: refused past each of these
    from hyperlf.twoview import open_holes

    data, hole = _square_with_hole()
    gc = regularisers.GraphCutParams(weight=2.0, truncation=2.0, levels=0)
    f = regularisers.optimise(data, gc).labels
    params = regularisers.HoleParams(enabled=True, **{field: value})
    assert not open_holes(data, f, gc, hole_params=params)[2].any()


def test_open_holes_asks_both_second_answers_to_agree():
    # a square 2 px before the wall, with a 6 x 6 hole, seen by both views: the wall through
    # the left hole (columns 9-14) is seen by the right view through its own (columns 7-12)
    # on columns 9-12, more than half of it; a right view whose square has no hole leaves
    # the left second answer without a partner, and the guard refuses it
    from hyperlf.twoview import open_holes

    square = np.zeros((24, 24), bool)
    square[4:20, 4:20] = True
    hole = np.zeros_like(square)
    hole[9:15, 9:15] = True
    shift = lambda m: np.roll(m, -2, axis=1)          # noqa: E731  (the right view)
    left = _volume(np.where(square & ~hole, 2, 0))
    right = _volume(np.where(shift(square) & ~shift(hole), 2, 0))
    gc = regularisers.GraphCutParams(weight=2.0, truncation=2.0, levels=0)
    fl = regularisers.optimise(left, gc).labels
    fr = regularisers.optimise(right, gc).labels
    assert (fl[hole] == 2).all() and (fr[shift(hole)] == 2).all()     # both filled
    fl2, fr2, opened = open_holes(left, fl, gc, data_right=right, label_map_right=fr,
                                  hole_params=ON)
    assert np.array_equal(opened, hole) and (fr2[shift(hole)] == 0).all()
    closed = _volume(np.where(shift(square), 2, 0))
    fc = regularisers.optimise(closed, gc).labels
    kw = dict(data_right=closed, label_map_right=fc)
    assert not open_holes(left, fl, gc, **kw, hole_params=ON)[2].any()
    loose = regularisers.HoleParams(enabled=True, consistent=False)
    assert np.array_equal(open_holes(left, fl, gc, **kw, hole_params=loose)[2], hole)
    with pytest.raises(InvalidInputError, match="together"):
        open_holes(left, fl, gc, data_right=right, hole_params=ON)


def test_stereo_opens_holes_by_default_and_says_so():
    from hyperlf.twoview import stereo_from_volumes

    data, hole = _square_with_hole()
    params = {"weight": 2.5, "truncation": 2.0, "levels": 0}
    res = stereo_from_volumes(data, None, 0, "graphcut", "none", params=params)
    assert res.extra["holes_opened"] == pytest.approx(hole.mean())
    assert (res.disparity[hole] == 0).all()
    off = stereo_from_volumes(data, None, 0, "graphcut", "none", params=params,
                              hole_params=OFF)
    assert off.extra["holes_opened"] == 0 and (off.disparity[hole] == 5).all()
    with pytest.raises(InvalidInputError, match="hole_params"):
        stereo_from_volumes(data, None, 0, "graphcut", "none", hole_params={"jump": 1})


def test_stereo_command_opens_holes_unless_told_not_to_under_graph_cuts(tmp_path, capsys,
                                                                        monkeypatch):
    import hyperlf.twoview as tv
    from hyperlf.formats import write_image

    seen = []
    real = tv.stereo

    def spy(*a, **k):
        seen.append(k["hole_params"])
        return real(*a, **k)

    monkeypatch.setattr(tv, "stereo", spy)
    tex = np.random.default_rng(5).random((30, 50)).astype(np.float32)
    write_image(tmp_path / "l.png", tex[:, 3:43], bit_depth=16)
    write_image(tmp_path / "r.png", tex[:, 6:46], bit_depth=16)
    for extra, out in (([], "a"), (["--holes"], "b"), (["--no-holes"], "c")):
        assert main(["-q", "stereo", str(tmp_path / "l.png"), str(tmp_path / "r.png"),
                     "--disparity-range", "0,6", *extra, "-o", str(tmp_path / out)]) == 0
    assert seen == [regularisers.HoleParams(), ON, OFF] and seen[0] == ON
    for flag in ("--holes", "--no-holes"):  # graph cuts' step: refused with SGM
        capsys.readouterr()
        assert main(["-q", "stereo", str(tmp_path / "l.png"), str(tmp_path / "r.png"),
                     "--disparity-range", "0,6", flag, "--optimizer", "sgm",
                     "-o", str(tmp_path / "d")]) == 2
        assert f"{flag} acts only with --optimizer graphcut" in capsys.readouterr().err
    assert len(seen) == 3 and not (tmp_path / "d").exists()
    assert main(["-q", "stereo", str(tmp_path / "l.png"), str(tmp_path / "r.png"),
                 "--disparity-range", "0,6", "--optimizer", "sgm",
                 "-o", str(tmp_path / "e")]) == 0      # on by default, and silent under SGM
