"""Calibration of camera arrays (SPEC §11) against a synthetic rig with exact ground truth.

The rig (``hyperlf.calibration.rig``) renders raw images through a deliberately imperfect array
(rotations up to 2 degrees, focal lengths differing by up to 4 %, principal point offsets,
radial distortion, gain, offset, vignetting, bands with inverted board contrast); every
expectation below comes from the rig's own geometry, never from the code under test.
"""

from __future__ import annotations

import dataclasses
import re

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import require_dataset
from hyperlf.calibration import (BoardSpec, apply_calibration, calibrate, calibrate_full,
                                 detect_board, detect_boards, read_calibration, register_plane,
                                 write_calibration)
from hyperlf.calibration.board import camera_label, place_partial_grid
from hyperlf.calibration.parallax import factor_rank1
from hyperlf.calibration.rig import BoardPose, make_rig, rotation_matrix
from hyperlf.errors import FormatError, HyperLFError, InvalidInputError

SEED = 5  # the development runs used other seeds


@pytest.fixture(scope="module")
def rig():
    return make_rig(seed=SEED)


def _turned_rig(key, degrees, *args, **kwargs):
    """A rig whose camera ``key`` is mounted turned about its optical axis by ``degrees``."""
    rig = make_rig(*args, **kwargs)
    cam = rig.cameras[key]
    rig.cameras[key] = dataclasses.replace(cam, R=rotation_matrix(0, 0, degrees) @ cam.R)
    return rig


def _held_turned(pose, board, degrees):
    """``pose`` with the board turned about its own centre by ``degrees`` (90: portrait)."""
    half = 0.5 * np.array([(board.cols - 1) * board.square, (board.rows - 1) * board.square, 0])
    R = pose.R @ rotation_matrix(0, 0, degrees)
    return BoardPose(R, pose.R @ half + pose.t - R @ half)


@pytest.fixture(scope="module")
def plane_pose(rig):
    return rig.board_pose(450.0, tilt=(4.0, -3.0, 2.0), centre_offset=(8.0, -5.0))


@pytest.fixture(scope="module")
def plane_shots(rig, plane_pose):
    return rig.render(plane_pose)


@pytest.fixture(scope="module")
def plane_cal(rig, plane_shots):
    return register_plane(plane_shots, rig.board)


def _angle_deg(a, b):
    cos = np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.degrees(np.arccos(np.clip(cos, -1, 1))))


def _scene_points(rig, pose, n=400, seed=0):
    """World points on the scene's surfaces seen by the reference camera (exact depths)."""
    import cv2

    ref = rig.cameras[rig.reference]
    W, H = rig.image_size
    rng = np.random.default_rng(seed)
    px = np.c_[rng.uniform(20, W - 20, n), rng.uniform(20, H - 20, n)]
    depth = rig.depth(rig.reference, pose)
    z = depth[np.round(px[:, 1]).astype(int), np.round(px[:, 0]).astype(int)]
    und = cv2.undistortPoints(px.reshape(-1, 1, 2), ref.K, ref.dist).reshape(-1, 2)
    return (np.c_[und, np.ones(n)] * z[:, None]) @ ref.R + ref.centre


# ----------------------------------------------------------------------------- the rig
def test_rig_is_deterministic_and_imperfect():
    a, b = make_rig(seed=2), make_rig(seed=2)
    pose = a.board_pose(450.0)
    ia, ib = a.render(pose, supersample=1), b.render(pose, supersample=1)
    assert all(np.array_equal(ia[k], ib[k]) for k in ia)
    rots = [np.degrees(np.arccos((np.trace(c.R) - 1) / 2)) for c in a.cameras.values()]
    assert 0.5 < max(rots) <= 2.0 * np.sqrt(3) + 1e-9
    f = [c.K[0, 0] for c in a.cameras.values()]
    assert (max(f) - min(f)) / np.mean(f) > 0.01
    assert sum(c.inverted for c in a.cameras.values()) == 2


def test_rig_projection_agrees_with_rendering(rig, plane_pose, plane_shots):
    """A dark square's centre renders dark in every normal band and light in inverted ones."""
    sq = rig.board.square
    centre = plane_pose.R @ np.array([-0.5 * sq, -0.5 * sq, 0]) + plane_pose.t  # square (0, 0)
    for key, cam in rig.cameras.items():
        x, y = np.round(rig.project(key, centre[None])[0]).astype(int)
        img = plane_shots[key]
        light = np.percentile(img, 90)
        assert (img[y, x] > 0.5 * light) == cam.inverted, key


# ----------------------------------------------------------------------------- detection
def test_board_found_in_every_band_with_canonical_order(rig, plane_pose, plane_shots):
    truth_world = plane_pose.corners_world(rig.board)
    for key, img in plane_shots.items():
        c = detect_board(img, rig.board)
        assert c is not None, key
        err = np.linalg.norm(c - rig.project(key, truth_world), axis=1)
        assert err.max() < 0.35, (key, err.max())  # right corners, right order


def test_board_found_in_a_raw_16_bit_shot_seen_upside_down(rig, plane_pose, plane_shots):
    key = (0, 1)
    raw = (plane_shots[key] * 4000 + 300).astype(np.uint16)  # dim 16-bit sensor values
    c = detect_board(raw[::-1, ::-1], rig.board)
    W, H = rig.image_size
    truth = (W - 1, H - 1) - rig.project(key, plane_pose.corners_world(rig.board))
    # canonical order starts at the image's top-left: the physical corner order is reversed
    assert np.linalg.norm(c - truth[::-1], axis=1).max() < 0.35


def test_board_partly_out_of_view_names_those_cameras(rig):
    for shift in np.arange(-120.0, -200.0, -5.0):  # a pose that cuts no camera borderline
        pose = rig.board_pose(450.0, centre_offset=(shift, 0.0))
        world = pose.corners_world(rig.board)
        lo = {k: rig.project(k, world)[:, 0].min() for k in rig.cameras}
        cut = [k for k in rig.cameras if lo[k] < 0]
        if 0 < len(cut) < len(rig.cameras) and all(v < -5 or v > 8 for v in lo.values()):
            break
    else:
        pytest.fail("no board pose cuts some cameras cleanly")
    shots = rig.render(pose, supersample=1, scene=False)
    names = {k: f"cam{k[0]}{k[1]}.png" for k in shots}
    with pytest.raises(InvalidInputError) as exc:
        detect_boards(shots, rig.board, names=names)
    msg = str(exc.value)
    assert "\n" not in msg
    for k in rig.cameras:
        assert (names[k] in msg) == (k in cut), k


def _grid(board, origin=(-50.0, 50.0), step=40.0, tilt=0.05):
    """An ideal (slightly sheared) corner grid ``(rows, cols, 2)`` of ``board``."""
    j, i = np.mgrid[0:board.rows, 0:board.cols].astype(float)
    return np.stack([origin[0] + step * i + tilt * step * j,
                     origin[1] + step * j - tilt * step * i], -1)


@pytest.mark.parametrize("cut, origin, expected", [
    ((slice(None), slice(2, None)), (-50.0, 50.0), "placed"),      # left border cuts 2 columns
    ((slice(1, None), slice(2, None)), (-50.0, -10.0), "placed"),  # top-left corner of the image
    ((slice(None), slice(0, 3)), (190.0, 50.0), "placed"),         # right border cuts 2 columns
    ((slice(None), slice(2, None)), (30.0, 50.0), None),  # unseen corners would be in view
    ((slice(None), slice(1, None)), (-35.0, 50.0), "trimmed"),  # column 1 at the very border
    ((slice(0, 2), slice(None)), (30.0, 50.0), None),     # two rows only
])
def test_place_partial_grid_only_where_the_border_explains_the_cut(cut, origin, expected):
    board = BoardSpec(5, 4)
    full = _grid(board, origin)
    placed = place_partial_grid(full[cut], board, (300, 300))
    if expected is None:
        assert placed is None
        return
    seen = np.zeros(full.shape[:2], bool)
    seen[cut] = True
    if expected == "trimmed":  # too near the border for a refinement window: left unseen
        seen[:, 1] = False
    assert np.array_equal(np.isfinite(placed[:, 0]), seen.ravel())
    assert np.allclose(placed[seen.ravel()], full[seen])


def test_place_partial_grid_refuses_a_board_cut_on_both_sides():
    """Columns at -20, 10, ..., 160 px in an image 130 px wide: the three seen columns could
    be the board's 2-4 or 1-3, the unseen ones out of view either way."""
    board = BoardSpec(7, 4)
    full = _grid(board, (-20.0, 40.0), step=30.0, tilt=0.0)
    assert place_partial_grid(full[:, 2:5], board, (200, 130)) is None


def test_place_partial_grid_refuses_a_block_larger_than_the_board():
    board = BoardSpec(5, 4)
    assert place_partial_grid(_grid(BoardSpec(6, 4), (40.0, 50.0)), board, (300, 300)) is None


def _locatable_edge(rig, corners):
    """The largest x at which a detector locates a corner: 0.9 corner spacings in from the
    right border."""
    g = corners.reshape(rig.board.rows, rig.board.cols, 2)
    spacing = np.median(np.linalg.norm(np.diff(g, axis=1), axis=-1))
    return rig.image_size[0] - 1 - 0.9 * spacing


def _cutting_pose(rig):
    """A board pose that takes the last corner columns of some cameras but not of the
    reference out of view (none borderline), its shots and the rig's corners per camera."""
    for shift in np.arange(100.0, 200.0, 2.0):
        pose = rig.board_pose(450.0, centre_offset=(shift, 0.0))
        truth = {k: rig.project(k, pose.corners_world(rig.board)) for k in rig.cameras}
        edge = {k: _locatable_edge(rig, v) for k, v in truth.items()}
        cut = [k for k, v in truth.items() if v[:, 0].max() > edge[k]]
        clear = all(np.abs(v[:, 0] - edge[k]).min() > 3 for k, v in truth.items())
        if cut and rig.reference not in cut and clear:
            return pose, rig.render(pose), truth, edge, cut
    pytest.fail("no board pose cuts some cameras cleanly")


def test_plane_registration_with_the_board_partly_out_of_view(rig):
    pose, shots, truth, edge, cut = _cutting_pose(rig)
    cal = register_plane(shots, rig.board)
    for key, c in cal.corners.items():
        seen = np.all(np.isfinite(c), axis=1)
        assert (key in cut) == (not seen.all()), key
        assert np.all(seen <= (truth[key][:, 0] < rig.image_size[0] - 1)), key  # all in view
        locatable = (truth[key][:, 0] < edge[key]).sum()
        assert seen.sum() >= locatable - rig.board.rows, key  # at most one column lost
        assert np.linalg.norm(c[seen] - truth[key][seen], axis=1).max() < 0.35, key
    truth_pos = rig.true_positions("reference")
    ref = np.array(cal.reference[::-1], float)
    for key, cam in cal.cameras.items():
        assert cam.reprojection_error < 0.3, key
        if key != rig.reference:
            est = cam.position - ref
            assert _angle_deg(est, truth_pos[key]) < 3.0, key
            assert abs(np.linalg.norm(est) / np.linalg.norm(truth_pos[key]) - 1) < 0.06, key


def test_the_same_shot_gives_the_same_corners_on_every_search():
    """OpenCV's sector-based detector draws from a random generator kept per thread, so the
    same shot searched again in the same thread gave another answer: a partial board found
    in one search and none in the next, or 16 corners instead of 24 (and the cameras,
    shared out over threads, were found in one run and refused in the next)."""
    small = make_rig(3, 3, seed=2, image_size=(160, 120))
    shots = small.render(small.board_pose(450.0, tilt=(4.0, -3.0, 2.0)), supersample=2)
    for key in ((2, 1), (2, 2)):
        first = detect_board(shots[key], small.board, partial=True)
        for _ in range(5):
            again = detect_board(shots[key], small.board, partial=True)
            assert (again is None) == (first is None)
            if first is not None:
                np.testing.assert_array_equal(again, first)


def test_board_seen_too_little_for_a_homography_is_named(rig, plane_pose, plane_shots):
    from hyperlf.calibration.plane import MIN_SHARED_CORNERS, board_homographies

    corners = detect_boards(plane_shots, rig.board)
    few = corners[(0, 1)].copy()
    few[MIN_SHARED_CORNERS - 1:] = np.nan
    with pytest.raises(InvalidInputError, match=r"camera left-top sees only 8 of the board"):
        board_homographies({**corners, (0, 1): few}, rig.reference, {(0, 1): "left-top"})


# ----------------------------------------------------------------------------- factorisation
def test_rank1_factorisation_survives_outliers():
    rng = np.random.default_rng(0)
    o = np.array([[1.0, 0.1], [0.0, 1.0], [-1.0, 0.9], [2.0, -0.2]])
    d = rng.uniform(-6, 3, 200)
    F = -d[None, :, None] * o[:, None, :] + rng.normal(0, 0.1, (4, 200, 2))
    bad = rng.random((4, 200)) < 0.35
    F[bad] = rng.uniform(-30, 30, (bad.sum(), 2))
    F[rng.random((4, 200)) < 0.1] = np.nan
    fac = factor_rank1(F)
    scale = fac.offsets[1, 1] / o[1, 1]
    assert np.abs(fac.offsets / scale - o).max() < 0.02


def test_rank1_factorisation_with_one_view_wrong_everywhere():
    """A camera mounted turned gives a view whose every flow is wrong: no point fits in
    every view, and the others' offsets must still come out (the turned view's inliers
    few), so that the turned camera can be found."""
    rng = np.random.default_rng(1)
    o = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.0, -1.0]])
    d = rng.uniform(-8, 8, 150)
    F = -d[None, :, None] * o[:, None, :] + rng.normal(0, 0.1, (5, 150, 2))
    good = [0, 1, 2, 4]
    for share in (0.3, 0.0):   # a few wrong flows in view 3, or none matched at all
        G = F.copy()
        G[3] = np.nan
        some = rng.random(150) < share
        G[3, some] = rng.uniform(-20, 20, (some.sum(), 2))
        fac = factor_rank1(G)
        scale = fac.offsets[0, 0] / o[0, 0]
        assert np.abs(fac.offsets[good] / scale - o[good]).max() < 0.02
        assert fac.inliers[3].sum() < 0.1 * fac.inliers[good].sum(1).min()
    assert np.isnan(fac.offsets[3]).all()   # no point fits it: unknown, not the reference's


def test_fitting_entries_compare_a_loose_model_with_the_right_one():
    """Two views of a row, the second's every flow wrong: the factorisation's own inliers
    follow its residual spread and keep most of the wrong view's entries, so their count
    cannot tell this model from the right one; within a fixed tolerance the wrong view fits
    almost nowhere, and the right flows fit everywhere."""
    from hyperlf.calibration.parallax import fitting_entries

    rng = np.random.default_rng(3)
    o = np.array([[1.0, 0.0], [-1.0, 0.0]])
    d = rng.uniform(-8, 8, 150)
    F = -d[None, :, None] * o[:, None, :] + rng.normal(0, 0.1, (2, 150, 2))
    right = factor_rank1(F)
    G = F.copy()
    G[1] = rng.uniform(-20, 20, (150, 2))
    loose = factor_rank1(G)
    assert loose.inliers[1].sum() > 0.5 * right.inliers[1].sum()
    fits = fitting_entries(F, right.d, right.offsets)[1].sum()
    assert fits >= 145 and fitting_entries(G, loose.d, loose.offsets)[1].sum() < 0.2 * fits


def test_a_view_the_trimming_dropped_is_fitted_again_alone():
    """The trimming only drops entries: a view whose offset came out wrong (another view's
    wrong flows spoilt the start: a camera turned by a quarter beside it) lost every entry
    and stayed unknown, and then all the positions came from the board poses instead (1.09
    baselines off). Fitted alone to the points' d that the other views fix, it comes back;
    a view of wrong flows stays without entries."""
    from hyperlf.calibration.parallax import _readmit_views

    rng = np.random.default_rng(4)
    o = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.0, -1.0]])
    d = rng.uniform(-8, 8, 150)
    F = -d[None, :, None] * o[:, None, :] + rng.normal(0, 0.1, (5, 150, 2))
    F[4] = rng.uniform(-20, 20, (150, 2))                  # every flow wrong
    measured = np.ones((5, 150), bool)
    w = measured.copy()
    w[3:] = False                                          # both dropped by the trimming
    start = o.copy()
    start[3:] = [[5.0, -3.0], [2.0, 2.0]]
    got, kept = _readmit_views(F, measured, w, d, start, 1.0)
    np.testing.assert_allclose(got[3], o[3], atol=0.01)
    assert kept[3].sum() >= 145 and not kept[4].any()
    np.testing.assert_array_equal(got[:3], start[:3])
    np.testing.assert_array_equal(kept[:3], w[:3])


def test_rank1_factorisation_ignores_a_wrong_match_repeated_in_several_views():
    """Wrong matches with large flows, the same in several views (repeated texture, peaks at
    the search border), must not start the model although they are most of the points
    measured in every view and all of the largest flows: they would put cameras on one
    spot (the lab capture with its reference at the array's edge)."""
    rng = np.random.default_rng(2)
    o = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [-1.0, 1.0], [0.0, 2.0]])
    d = rng.uniform(-3, 3, 200)
    F = -d[None, :, None] * o[:, None, :] + rng.normal(0, 0.1, (6, 200, 2))
    lost = rng.random(200) < 0.85                      # most points lost in one view
    F[rng.integers(0, 6, lost.sum()), np.flatnonzero(lost)] = np.nan
    wrong = rng.random(200) < 0.2
    c = rng.uniform(20, 30, (wrong.sum(), 1)) * np.array([1.0, -1.0])   # per point, large
    F[:, wrong] = -d[wrong][None, :, None] * o[:, None, :]
    F[2:, wrong] = c[None] + rng.normal(0, 0.2, (4, wrong.sum(), 2))
    fac = factor_rank1(F)
    scale = fac.offsets[0, 0] / o[0, 0]
    assert np.abs(fac.offsets / scale - o).max() < 0.05


def test_positions_the_board_poses_contradict_are_refused():
    from hyperlf.calibration.plane import POSITION_DISAGREEMENT, _check_positions_agree

    fine = {"positions_from": "parallax", "focal_determined": True, "pose_position_rms": 0.04}
    _check_positions_agree(fine)
    _check_positions_agree({**fine, "pose_position_rms": 11.2, "focal_determined": False})
    _check_positions_agree({**fine, "pose_position_rms": 11.2, "positions_from": "board"})
    with pytest.raises(InvalidInputError, match="disagree by 11.20 baselines.*check --grid"):
        _check_positions_agree({**fine, "pose_position_rms": 11.2})
    assert POSITION_DISAGREEMENT < 1


def test_a_long_lens_before_a_square_on_board_is_told_to_tilt_it():
    """A long lens (900 px against a 320 px image) whose cameras are turned by up to 2
    degrees: the rotations shift each image more than the baseline does, and the poses of a
    board facing the array squarely cannot tell the two apart, not even at the focal length
    given (1.83 baselines from the right positions from parallax). The refusal said only to
    check the files' names; it now says the board's tilt and to tilt it."""
    rig = make_rig(1, 3, seed=2, image_size=(320, 240), focal=900.0,
                   scene_depths=(2100.0, 3000.0))
    shots = rig.render(rig.board_pose(1350.0), supersample=2)
    with pytest.raises(InvalidInputError, match=r"check --grid.*; if it is, the board, tilted "
                                                r"by only \d\.\d degrees, cannot place the "
                                                r"cameras: tilt it by 10 degrees or more"):
        register_plane(shots, rig.board, focal_px=900.0)
    pose = rig.board_pose(1350.0, tilt=(10.0, -8.0, 3.0))
    cal = register_plane(rig.render(pose, supersample=2), rig.board)
    normal = rig.cameras[cal.reference].R @ pose.R[:, 2]    # in the reference camera's axes
    true_tilt = np.degrees(np.arccos(abs(normal[2])))      # 13.98 degrees
    assert abs(cal.info["board_tilt_deg"] - true_tilt) < 0.5 and cal.info["focal_determined"]
    assert cal.info["sign_agreement"] > 0.9 and _position_error(rig, cal) < 0.1


def _position_error(rig, cal) -> float:
    """RMS distance (baselines) of the calibration's camera positions from the rig's true
    ones, both relative to the reference."""
    ref = cal.reference
    keys = sorted(cal.cameras)
    true = np.array([rig.cameras[k].centre[:2] - rig.cameras[ref].centre[:2] for k in keys])
    est = np.array([cal.cameras[k].position - cal.cameras[ref].position for k in keys])
    return float(np.sqrt(np.mean(np.sum((est - true / rig.baseline) ** 2, 1))))


def test_cameras_two_baselines_from_the_hub_get_their_positions_from_parallax():
    """A 2 x 4 array's outer column is two baselines from the reference: its parallax is twice
    its neighbours', beyond the search radius that suits them, and its positions came out
    garbage (16.7 baselines off here; 1-2.4 on other seeds and poses), with no warning. The
    views the common model fits poorly are now matched again with a wider radius cut to the
    image (measured on seeds 0-2, square-on and tilted: 0.04-0.06 baselines off)."""
    rig = make_rig(2, 4, seed=0, image_size=(320, 240))
    cal = register_plane(rig.render(rig.board_pose(450.0), supersample=2), rig.board)
    assert cal.info["positions_from"] == "parallax"
    assert _position_error(rig, cal) < 0.15


def test_a_square_on_board_leaves_the_focal_length_undetermined_and_is_not_refused():
    """OpenCV gives a focal length's standard deviation of 1e-7 px, not 0, for a board that
    faces the cameras squarely: it was taken as precise, the board poses' centres were
    trusted, and a capture whose parallax measured its positions right (0.03 baselines) was
    refused as contradicting them."""
    rig = make_rig(3, 3, seed=2, image_size=(320, 240))
    cal = register_plane(rig.render(rig.board_pose(450.0), supersample=2), rig.board)
    assert cal.info["focal_determined"] is False
    assert cal.info["positions_from"] == "parallax" and _position_error(rig, cal) < 0.1


def test_match_flows_with_a_window_cut_to_the_image():
    """Near the border a full search window leaves the image and the point is not searched;
    cut to the image it is, and its flow is the same; a peak on the cut is refused."""
    from scipy.ndimage import gaussian_filter

    from hyperlf.calibration.parallax import feature_image, match_flows

    texture = gaussian_filter(np.random.default_rng(0).random((64, 64)), 2.0)
    moved = np.roll(texture, (-2, 3), axis=(0, 1))
    points = np.array([[10.0, 32.0], [32.0, 32.0], [32.0, 57.0]])
    args = (feature_image(texture), feature_image(moved), points, np.ones((64, 64), bool))
    plain = match_flows(*args, half=5, radius=12)[0]
    cut = match_flows(*args, half=5, radius=12, clip=True)[0]
    assert np.isnan(plain[[0, 2]]).all()
    # the parabola's sub-pixel peak: within 0.04 px of the true shift (measured), either way
    np.testing.assert_allclose(cut[:2], [[3.0, -2.0], [3.0, -2.0]], atol=0.1)
    np.testing.assert_array_equal(cut[1], plain[1])  # inside, the two agree bit for bit
    # the third point's match lies past the image's bottom edge, so its peak sits on the cut
    assert np.isnan(match_flows(feature_image(texture), feature_image(np.roll(texture, 8, 0)),
                                points[2:], np.ones((64, 64), bool), half=5, radius=12,
                                clip=True)[0]).all()


def test_match_flows_cut_to_the_part_of_a_window_the_view_covers():
    """A camera two baselines out covers only part of the reference's image once registered,
    so a wide search window often reached into the part it does not cover, and the point
    was not searched at all: in a 2 x 4 array turned against its reference, the outer
    column's flows were measured at 7-29 of 600 points and fitted nowhere. Cut to the
    view's valid part, the window is searched there; a peak beside that cut is refused."""
    from scipy.ndimage import gaussian_filter

    from hyperlf.calibration.parallax import feature_image, match_flows

    texture = gaussian_filter(np.random.default_rng(1).random((64, 64)), 2.0)
    moved = np.roll(texture, (0, 6), axis=(0, 1))        # 6 px right
    valid = np.ones((64, 64), bool)
    valid[:, :24] = False                                # the view covers x >= 24 only
    points = np.array([[32.0, 32.0], [20.0, 32.0]])      # the second one's match is at x 26
    args = (feature_image(texture), feature_image(moved), points, valid)
    assert np.isnan(match_flows(*args, half=5, radius=12)[0]).all()
    cut = match_flows(*args, half=5, radius=12, clip=True)[0]
    np.testing.assert_allclose(cut[0], [6.0, 0.0], atol=0.1)
    # the second's patch at its match would reach x 21: into the cut, so refused, not moved
    assert np.isnan(cut[1]).all()
    # where the window lies wholly in the valid part, the flow is the same bit for bit
    inside = match_flows(*args[:3], np.ones((64, 64), bool), half=5, radius=12, clip=True)[0]
    np.testing.assert_array_equal(cut[0], inside[0])


@pytest.mark.parametrize("seed, rows, cols, which, degrees, tilt", [
    (0, 2, 4, (0, 1), 90, 0.0), (1, 2, 4, (0, 1), 270, 4.0)])
def test_plane_registration_of_a_wide_array_whose_reference_is_turned(seed, rows, cols, which,
                                                                     degrees, tilt):
    """A 2 x 4 array whose reference is mounted turned by a quarter: every other camera is
    turned against it, and the outer column, two baselines from the reference, moves along
    the reference's short side beside a board held across it. Its flows fitted no order,
    and the positions came from the board poses (0.4-1.7 baselines off) or from parallax
    (1.5 off). Every camera is now found turned, at the right place."""
    rig = _turned_rig(which, degrees, rows, cols, seed=seed, image_size=(320, 240))
    shots = rig.render(rig.board_pose(450.0, tilt=(tilt, -0.75 * tilt, 0.5 * tilt)),
                       supersample=2)
    cal = register_plane(shots, rig.board)
    assert cal.info["positions_from"] == "parallax"
    assert set(cal.info["camera_turns"].values()) == {360 - degrees}
    assert len(cal.info["camera_turns"]) == rows * cols - 1
    truth = rig.true_positions()
    found = np.stack([cal.positions()[k] - cal.positions()[cal.reference] for k in truth])
    exact = np.stack([truth[k] - truth[cal.reference] for k in truth])
    quarter = np.array([[0.0, -1.0], [1.0, 0.0]])      # the capture turns with its reference
    err = min(np.sqrt(np.mean(np.sum((found @ np.linalg.matrix_power(quarter, q) - exact) ** 2,
                                     1))) for q in range(4))
    assert err < 0.1


def test_the_sign_of_positions_before_a_square_on_board():
    """Before a board facing the array squarely the focal length is undetermined, and the
    board poses solved at OpenCV's estimate of it (801 px here, the truth about 300) put the
    cameras anywhere (3.9 baselines RMS). Their centres still decided the positions' sign,
    and here turned every position from parallax round (2.0 baselines off) without a word.
    The poses are now solved at a focal length short enough for any lens
    (:data:`~hyperlf.calibration.plane.UNDETERMINED_FOCAL`)."""
    rig = _turned_rig((1, 1), 180, 2, 2, seed=1, image_size=(320, 240))
    cal = register_plane(rig.render(rig.board_pose(450.0), supersample=2), rig.board)
    assert cal.info["focal_determined"] is False and cal.info["positions_from"] == "parallax"
    assert cal.info["sign_agreement"] > 0.9
    assert _position_error(rig, cal) < 0.1


def test_parallax_that_no_positions_explain_is_not_taken():
    """A parallax model that fitted two of its eight views at 1-2 of the 96-143 entries it
    kept for each (a 2 x 4 array with its reference turned, during this session's changes;
    14.9 px RMS) gave the positions, 3 baselines off, without a word. A model that fits some
    view loosely (:func:`~hyperlf.calibration.plane._misfit`, the test that makes
    ``turned_cameras`` try other orders) is not taken: the board poses' positions, with a
    note, or, when parallax was asked for, a refusal."""
    from hyperlf.calibration.plane import MISFIT_SHARE, _parallax_offsets

    board_offsets = {(0, 0): np.zeros(2), (0, 1): np.array([40.0, 0.0]),
                     (0, 2): np.array([80.0, 0.0])}
    par = {"n_points": 300, "median_flow": 10.0, "rms": 14.9, "reach": 12.0,
           "offsets": {(0, 0): np.zeros(2), (0, 1): np.array([-3.0, 0.1]),
                       (0, 2): np.array([-6.0, 0.0])},
           "fitting": {(0, 0): 300, (0, 1): 144, (0, 2): 2},
           "consistent": {(0, 0): 300, (0, 1): 126, (0, 2): 110},
           "measured": {(0, 0): 300, (0, 1): 478, (0, 2): 110}}
    names = {(0, 2): "Cam-2.png"}
    info = {}
    assert _parallax_offsets(par, board_offsets, info, "auto", 0.5, names) is board_offsets
    assert "positions_from" not in info
    assert info["parallax_unused"] == ("the common parallax model fits the flows of "
                                       "camera(s) Cam-2.png at few of their points")
    with pytest.raises(InvalidInputError, match="Cam-2.png at few of their points"):
        _parallax_offsets(par, board_offsets, {}, "parallax", 0.5, names)
    # a loose residual alone (a few gross mismatches kept) does not refuse a model that
    # fits every view: a 2 x 4 array's 4.6 px model had its positions within 0.12 baselines
    info = {}
    par["fitting"][(0, 2)] = int(np.ceil(MISFIT_SHARE * 110))
    assert _parallax_offsets(par, board_offsets, info, "auto", 0.5, names) is par["offsets"]
    assert info["positions_from"] == "parallax"


def test_a_board_block_that_is_the_whole_board_is_placed():
    """The partial-board search, handed a block as large as the board, asked OpenCV to move
    no points and failed on its None (an AttributeError out of register_plane, on small
    images of a board facing the cameras squarely)."""
    b = BoardSpec(5, 4)
    j, i = np.mgrid[0:4, 0:5]
    full = np.stack([40.0 * i + 50, 40.0 * j + 50], -1)
    placed = place_partial_grid(full, b, (300, 300))
    np.testing.assert_array_equal(placed, full.reshape(-1, 2))


# ----------------------------------------------------------------------------- plane mode
def test_plane_registration_positions_and_residuals(rig, plane_cal):
    truth = rig.true_positions("reference")
    ref = np.array(plane_cal.reference[::-1], float)
    for key, cam in plane_cal.cameras.items():
        assert cam.reprojection_error < 0.3, key
        est = cam.position - ref
        if key == rig.reference:
            assert np.allclose(est, 0)
            continue
        assert _angle_deg(est, truth[key]) < 3.0, key
        assert abs(np.linalg.norm(est) / np.linalg.norm(truth[key]) - 1) < 0.06, key
    assert plane_cal.info["positions_from"] == "parallax"


def _check_plane_positions(rig, cal, length=0.06):
    truth = rig.true_positions("reference")
    ref = cal.cameras[cal.reference].position
    for key, cam in cal.cameras.items():
        if key != rig.reference:
            est = cam.position - ref
            assert _angle_deg(est, truth[key]) < 3.0, key
            assert abs(np.linalg.norm(est) / np.linalg.norm(truth[key]) - 1) < length, key


@pytest.mark.parametrize("degrees", [90, 270])
def test_plane_registration_with_the_board_held_in_portrait(rig, degrees):
    """Held turned by 90 degrees, the board's rows run down every image, and the image-based
    order of its corners depended on each camera's perspective: positions came out two
    baselines wrong without a word. Every camera's corners now follow the reference's. (The
    lengths' error depends on how much scene the board leaves: 2-7 % over the board held
    0, 90, 180 and 270 degrees at two tilts; 7.3 % here at 90 degrees.)"""
    pose = rig.board_pose(450.0, tilt=(-5.0, 4.0, degrees), centre_offset=(8.0, -5.0))
    cal = register_plane(rig.render(pose), rig.board)
    _check_plane_positions(rig, cal, length=0.1)
    assert cal.info["turned_cameras"] == [] and cal.info["positions_from"] == "parallax"


@pytest.mark.parametrize("degrees, tilt", [(90, (4.0, -3.0, 2.0)), (270, (-5.0, 4.0, -3.0)),
                                           (268, (-5.0, 4.0, -3.0))])
def test_plane_registration_with_a_camera_turned_by_a_quarter(degrees, tilt):
    """A camera mounted turned by a quarter: no order of the board's corners lines it up with
    the reference's, and the one taken may mirror the scene around the board (its position
    came out 577 baselines away for the second case). Its order is now found by the parallax,
    and the turn is reported."""
    rig = _turned_rig((0, 2), degrees, seed=SEED)
    pose = rig.board_pose(450.0, tilt=tilt, centre_offset=(8.0, -5.0))
    cal = register_plane(rig.render(pose), rig.board)
    _check_plane_positions(rig, cal)
    label = camera_label((0, 2))
    assert cal.info["camera_turns"] == {label: round(degrees / 90) * 90 % 360}
    assert cal.info["turned_cameras"] == [label]


def test_plane_disparity_sign_and_lines():
    """Registered scene points follow x_ref - d (p_v - p_ref) with d = f B (1/Z - 1/Z_board):
    positive in front of the board (SPEC §11), on the predicted lines. (A homography cannot
    undo lens distortion, so this rig has none; everything else stays imperfect.)"""
    import cv2

    rig = make_rig(seed=SEED + 2, distortion=0.0)
    plane_pose = rig.board_pose(450.0, tilt=(-3.0, 4.0, -2.0), centre_offset=(-6.0, 4.0))
    plane_cal = register_plane(rig.render(plane_pose), rig.board)
    X = _scene_points(rig, None, seed=1)  # the scene without the board
    ref = rig.reference
    reg = {k: cv2.perspectiveTransform(rig.project(k, X).reshape(-1, 1, 2),
                                       cam.homography).reshape(-1, 2)
           for k, cam in plane_cal.cameras.items()}
    P = plane_cal.positions()
    o = {k: P[k] - P[ref] for k in plane_cal.cameras if k != ref}
    d = sum(((reg[ref] - reg[k]) * o[k]).sum(1) for k in o) / sum((o[k] ** 2).sum() for k in o)
    # truth: depth along the reference axis, board depth along the same ray
    cam = rig.cameras[ref]
    Z = (X - cam.centre) @ cam.R[2]
    rays = (X - cam.centre) @ cam.R.T
    n_b = cam.R @ plane_pose.R[:, 2]
    zb = (n_b @ (cam.R @ (plane_pose.t - cam.centre))) / (rays @ n_b) * Z
    f_b = cam.K[0, 0] * plane_cal.baseline
    d_true = f_b * (1 / Z - 1 / zb)
    assert np.corrcoef(d, d_true)[0, 1] > 0.99
    assert abs(np.median(d / d_true) - 1) < 0.2   # scale from the board pose estimate
    for k in o:
        e = reg[k] - (reg[ref] - d[:, None] * o[k])
        # the reference camera is tilted by up to 2 degrees to the array plane: the parallax
        # then has a small radial part the line model leaves (about 0.2 px at d = 12)
        err = np.linalg.norm(e, axis=1)
        assert np.median(err) < 0.35 and np.percentile(err, 95) < 0.8, k


@pytest.mark.parametrize("description", ["mirrored", "rotated"])
def test_plane_directions_ignore_the_users_array_description(rig, plane_shots, plane_cal,
                                                             description):
    """The user names the cameras through a mirrored / rotated description of the grid; the
    positions still follow the physical cameras."""
    R, C = rig.grid
    if description == "mirrored":
        rename = {(r, c): (r, C - 1 - c) for r in range(R) for c in range(C)}
    else:  # rotated by 90 degrees
        rename = {(r, c): (c, R - 1 - r) for r in range(R) for c in range(C)}
    cal = register_plane({rename[k]: v for k, v in plane_shots.items()}, rig.board)
    truth = rig.true_positions("reference")
    ref_name = rename[rig.reference]
    assert cal.reference == ref_name
    for key in rig.cameras:
        if key == rig.reference:
            continue
        est = cal.cameras[rename[key]].position - cal.cameras[ref_name].position
        assert _angle_deg(est, truth[key]) < 3.0, (description, key)


def test_plane_positions_from_board_poses_alone(rig, plane_shots):
    cal = register_plane(plane_shots, rig.board, positions_from="board")
    truth = rig.true_positions("reference")
    ref = np.array(cal.reference[::-1], float)
    for key, cam in cal.cameras.items():
        if key != rig.reference:  # rotations blur it, but the directions hold
            assert _angle_deg(cam.position - ref, truth[key]) < 15.0, key


def test_plane_names_the_camera_whose_parallax_fits_nowhere():
    """Plenty of parallax, but one camera's flows fit the common model nowhere (its offset
    unknown): the positions come from the board poses, and the note named the 200 points
    and 10 px of flow as too few."""
    from hyperlf.calibration.plane import _parallax_offsets

    par = {"n_points": 200, "rms": 0.3, "median_flow": 10.0, "reach": 5.0,
           "offsets": {(0, 0): np.full(2, np.nan), (0, 1): np.zeros(2)}}
    board = {(0, 0): np.array([-40.0, 0.0]), (0, 1): np.zeros(2)}
    info: dict = {}
    names = {(0, 0): "Cam-0.png"}
    assert _parallax_offsets(par, board, info, "auto", 0.5, names) is board
    assert info["parallax_unused"] == ("the flows of camera(s) Cam-0.png fit the other "
                                       "cameras' parallax nowhere")
    with pytest.raises(InvalidInputError, match=r"\(the flows of camera\(s\) Cam-0.png fit"):
        _parallax_offsets(par, board, {}, "parallax", 0.5, names)


def test_plane_says_why_the_parallax_was_not_used(tmp_path, rig, plane_shots):
    """Too little parallax for the positions: the calibration falls back on the board poses
    and records why (calibrate prints it), also in its file."""
    cal = register_plane(plane_shots, rig.board, min_parallax_px=1e6)
    assert cal.info["positions_from"] == "board"
    why = cal.info["parallax_unused"]
    assert "median flow" in why and "1e+06 px are needed" in why
    assert read_calibration(write_calibration(cal, tmp_path / "c.toml")).info[
        "parallax_unused"] == why
    assert "parallax_unused" not in register_plane(plane_shots, rig.board,
                                                   positions_from="board").info
    # asked for positions from parallax, the same shots are refused, saying why
    with pytest.raises(InvalidInputError, match=r"no usable parallax around the board \(\d+ "
                                                r"points off the board plane with a median "
                                                r"flow of [\d.]+ px; at least 8 points"):
        register_plane(plane_shots, rig.board, positions_from="parallax", min_parallax_px=1e6)


# ----------------------------------------------------------------------------- files
def test_calibration_file_round_trip(tmp_path, plane_cal):
    p = write_calibration(plane_cal, tmp_path / "cal.toml")
    text = p.read_text()
    assert 'mode = "plane"' in text and "[[camera]]" in text
    back = read_calibration(p)
    assert back.mode == plane_cal.mode and back.grid == plane_cal.grid
    assert back.reference == plane_cal.reference
    assert np.allclose(back.positions(), plane_cal.positions())
    for k, cam in plane_cal.cameras.items():
        assert np.allclose(back.cameras[k].homography, cam.homography)
        assert back.cameras[k].reprojection_error == pytest.approx(cam.reprojection_error)


def _with_info_range(text: str, value: str) -> str:
    """The calibration file with ``[info] disparity_range = value`` (replaced or added)."""
    if re.search(r"(?m)^disparity_range = ", text):
        return re.sub(r"(?ms)^disparity_range = \[.*?\]", f"disparity_range = {value}", text,
                      count=1)
    return text.replace("[info]", f"[info]\ndisparity_range = {value}", 1)


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace('mode = "plane"', 'mode = "other"'), "mode"),
    (lambda t: t.replace('format = "hyperlf-calibration"', 'format = "x"'), "format"),
    (lambda t: t.replace("row = 0", "row = 7", 1), "outside"),
    (lambda t: t.split("[[camera]]")[0] + "[[camera]]".join(t.split("[[camera]]")[1:-1]),
     "camera"),
    (lambda t: t.replace("homography = [", "homography = [[1.0], ", 1), "homography"),
    (lambda t: t + "\n[[[broken", "TOML"),
    (lambda t: t.replace("baseline = ", "baseline = -", 1), "baseline"),
    (lambda t: re.sub(r"(homography = \[\s*\[\s*)([-0-9.e]+)", r'\1"\2"', t, count=1),
     "no quotes"),
    (lambda t: re.sub(r"(homography = \[\s*\[\s*)([-0-9.e]+)", r"\1nan", t, count=1),
     "NaN or infinite"),
    (lambda t: _with_info_range(t, "[-3, 0, 3]"), "'disparity_range' in [info] must be two"),
    (lambda t: _with_info_range(t, "[[], 3]"), "'disparity_range' in [info] must be two"),
])
def test_malformed_calibration_files_are_one_line_format_errors(tmp_path, plane_cal, edit,
                                                                  words):
    p = write_calibration(plane_cal, tmp_path / "cal.toml")
    p.write_text(edit(p.read_text()))
    with pytest.raises(FormatError) as exc:
        read_calibration(p)
    assert "\n" not in str(exc.value) and words in str(exc.value)
    assert exc.value.exit_code == 3


def _entries(doc, at=()):
    """Every path to a value in a TOML document (the first three entries of each list)."""
    items = doc.items() if isinstance(doc, dict) else enumerate(doc[:3]) \
        if isinstance(doc, list) else ()
    for key, value in items:
        yield at + (key,)
        yield from _entries(value, at + (key,))


_TOML_JUNK = st.recursive(
    st.integers(-3, 40) | st.integers(-2 ** 63, 2 ** 63 - 1) | st.floats() | st.text(max_size=4)
    | st.booleans(), lambda inner: st.lists(inner, max_size=3)
    | st.dictionaries(st.text(max_size=3), inner, max_size=2), max_leaves=6)


@settings(max_examples=300, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), value=_TOML_JUNK, drop=st.booleans())
def test_any_value_of_a_calibration_file_is_read_or_one_line(plane_cal, data, value, drop):
    """Any entry of a calibration file replaced by TOML junk (nested lists and tables
    included) or dropped: read, or one line of a hyperlf error (a list inside
    ``disparity_range`` raised TypeError)."""
    import copy
    import tempfile

    import tomli_w
    try:
        import tomllib
    except ImportError:  # Python < 3.11
        import tomli as tomllib

    with tempfile.TemporaryDirectory() as folder:
        path = write_calibration(plane_cal, f"{folder}/cal.toml")
        doc = tomllib.loads(path.read_text())
        where = data.draw(st.sampled_from(sorted(_entries(copy.deepcopy(doc)), key=str)))
        table = doc
        for key in where[:-1]:
            table = table[key]
        if drop and isinstance(table, dict):
            del table[where[-1]]
        else:
            table[where[-1]] = value
        path.write_text(tomli_w.dumps(doc))
        try:
            read_calibration(path)
        except HyperLFError as exc:
            assert "\n" not in str(exc) and str(exc)


# ----------------------------------------------------------------------------- applying
def test_registered_views_align_the_board_and_mask_the_outside(rig, plane_shots, plane_cal):
    views, valid = apply_calibration(plane_cal, plane_shots)
    R, C = rig.grid
    W, H = rig.image_size
    assert views.shape == (R, C, H, W) and valid.shape == views.shape
    ref_c = detect_board(views[rig.reference], rig.board)
    for key in rig.cameras:
        c = detect_board(views[key], rig.board)
        assert np.linalg.norm(c - ref_c, axis=1).max() < 0.5, key
        # validity is exactly "the raw pixel sampled lies in the camera's image"
        Hm = plane_cal.cameras[key].homography
        yy, xx = np.mgrid[0:H, 0:W]
        q = np.stack([xx, yy, np.ones_like(xx)], -1) @ np.linalg.inv(Hm).T
        qx, qy = q[..., 0] / q[..., 2], q[..., 1] / q[..., 2]
        e = 1e-3  # float32 maps
        inside = (qx >= -e) & (qx <= W - 1 + e) & (qy >= -e) & (qy <= H - 1 + e)
        assert np.mean(inside != valid[key]) < 1e-3, key
        assert np.all(views[key][~valid[key]] == 0)
    assert not valid.all()  # the views' borders do not all overlap


def test_apply_refuses_images_that_do_not_fit(plane_shots, plane_cal):
    small = {k: v[:-2] for k, v in plane_shots.items()}
    with pytest.raises(InvalidInputError, match="calibration was made for"):
        apply_calibration(plane_cal, small)
    fewer = dict(list(plane_shots.items())[:-1])
    with pytest.raises(InvalidInputError, match="do not fit"):
        apply_calibration(plane_cal, fewer)


def test_saturated_pixels_are_invalid(plane_shots, plane_cal):
    shots = {k: v.copy() for k, v in plane_shots.items()}
    shots[(0, 0)][100:110, 100:110] = 1.0
    _, valid = apply_calibration(plane_cal, shots, saturation=1.0)
    H = plane_cal.cameras[(0, 0)].homography
    q = H @ np.array([105.0, 105.0, 1.0])
    x, y = np.round(q[:2] / q[2]).astype(int)
    assert not valid[0, 0, y, x]


def _hand_made_plane_calibration(homographies, size):
    """A hand-made plane calibration of a 1 x N row, camera ``c`` at ``c`` baselines, the
    first the reference, each camera's homography given."""
    from hyperlf.calibration.model import Calibration, CameraCalibration

    cams = {(0, c): CameraCalibration(f"Cam-{c}.png", np.array([float(c), 0.0]), 0.0,
                                      homography=h) for c, h in enumerate(homographies)}
    return Calibration(mode="plane", grid=(1, len(cams)), reference=(0, 0), image_size=size,
                       output_size=size, camera_matrix=np.diag([100.0, 100.0, 1.0]),
                       cameras=cams, board=BoardSpec(4, 3, 20.0), baseline=40.0,
                       board_plane=np.array([0.0, 0.0, 1.0, 500.0]))


def test_ingest_of_views_without_parallax_gets_a_range():
    """Every camera seeing the scene at the zero-disparity plane (identical registered views):
    the measured range was (0.0, -0.0), and ingest failed inside LightField with a message
    about its own arguments. It is now one px each way."""
    from hyperlf.calibration.ingest import ingest

    texture = cv2.GaussianBlur(np.random.default_rng(1).random((90, 120)), (0, 0), 1.5)
    cal = _hand_made_plane_calibration([np.eye(3)] * 3, (120, 90))
    lf = ingest({(0, c): texture.astype(np.float32) for c in range(3)}, cal)
    assert lf.disparity_range == (-1.0, 1.0)


@pytest.mark.parametrize("mark", ["nan", "saturated"])
def test_an_invalid_raw_pixel_invalidates_only_the_samples_that_weigh_it(mark):
    """A NaN raw pixel (ingest's mark of a saturated pixel, or of a NaN in the dark frame or
    flat field) and a saturated one leave invalid exactly the samples whose bilinear taps weigh
    them: the pixel itself under an identity warp, its two neighbours in the row under a
    half-pixel shift. A NaN warped with the image made the pixels above and to the left of it
    invalid too (a zero-weight tap reads it, 0 * NaN), so ingest lost a 2 x 2 block per
    saturated pixel."""
    half = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    cal = _hand_made_plane_calibration([np.eye(3), half], (8, 6))
    img = np.random.default_rng(0).uniform(0.1, 0.9, (6, 8)).astype(np.float32)
    img[2, 3] = np.nan if mark == "nan" else 1.0
    views, valid = apply_calibration(cal, {(0, 0): img, (0, 1): img},
                                     saturation=None if mark == "nan" else 1.0)
    assert np.argwhere(~valid[0, 0]).tolist() == [[2, 3]]
    # the shifted view's first column samples outside the image; the NaN weighs on two
    assert np.argwhere(~valid[0, 1][:, 1:]).tolist() == [[2, 2], [2, 3]]
    assert np.isfinite(views).all()


def test_inconsistent_inputs_are_clear_errors(rig, plane_shots):
    holes = {k: v for k, v in plane_shots.items() if k != (0, 1)}
    with pytest.raises(InvalidInputError, match=r"no image for \(0, 1\)"):
        register_plane(holes, rig.board)
    sizes = dict(plane_shots)
    sizes[(2, 2)] = sizes[(2, 2)][:, :-4]
    with pytest.raises(InvalidInputError, match="differ in size"):
        register_plane(sizes, rig.board)
    with pytest.raises(InvalidInputError, match="same number of board shots"):
        calibrate_full({k: [v] * (3 if k != (0, 0) else 2) for k, v in plane_shots.items()},
                       rig.board)


# ----------------------------------------------------------------------------- full mode
def _covered(rig, poses, key, q):
    """Points ``q`` inside the convex hull of the board corners camera ``key`` saw whole (the
    part of the image the calibration has data for; distortion beyond it is extrapolated)."""
    import cv2

    W, H = rig.image_size
    pts = [rig.project(key, p.corners_world(rig.board)) for p in poses]
    pts = np.concatenate([c for c in pts if c.min() > 0 and c[:, 0].max() < W - 1
                          and c[:, 1].max() < H - 1])
    hull = cv2.convexHull(pts.astype(np.float32))
    return np.array([cv2.pointPolygonTest(hull, (float(x), float(y)), False) >= 0
                     for x, y in q])


def _rectified_line_errors(rig, cal, X, poses=None):
    """Perpendicular distances of exact correspondences from the predicted lines, and the
    per-point fitted disparity, after rectification with ``cal`` (points every camera sees;
    with ``poses``, only where every camera's calibration had board corners)."""
    import cv2

    W, H = rig.image_size
    seen = np.all([(lambda q: (q[:, 0] > 0) & (q[:, 0] < W - 1) & (q[:, 1] > 0)
                    & (q[:, 1] < H - 1))(rig.project(k, X)) for k in rig.cameras], axis=0)
    if poses is not None:
        seen &= np.all([_covered(rig, poses, k, rig.project(k, X)) for k in rig.cameras], 0)
    X = X[seen]
    rect = {k: cv2.undistortPoints(rig.project(k, X).reshape(-1, 1, 2), c.K, c.dist, None,
                                   c.rectify, cal.camera_matrix).reshape(-1, 2)
            for k, c in cal.cameras.items()}
    ref = cal.reference
    P = cal.positions()
    o = {k: P[k] - P[ref] for k in cal.cameras if k != ref}
    d = sum(((rect[ref] - rect[k]) * o[k]).sum(1) for k in o) / sum((o[k] ** 2).sum() for k in o)
    perp = []
    for k in o:
        u = o[k] / np.linalg.norm(o[k])
        e = rect[k] - (rect[ref] - d[:, None] * o[k])
        perp.append(np.abs(e @ np.array([-u[1], u[0]])))
    return np.max(perp, axis=0), d, X


def _check_full(rig, cal, poses=None):
    truth = rig.true_positions("array")
    ref = np.array(cal.reference[::-1], float)
    for key, cam in cal.cameras.items():
        assert cam.reprojection_error < 0.2, key
        v = cal.residuals[key][1]
        assert np.sqrt(np.mean(np.sum(v ** 2, 1))) == pytest.approx(cam.reprojection_error)
        if key != rig.reference:
            t = truth[key]
            assert np.linalg.norm(cam.position - ref - t) < 0.01 * np.linalg.norm(t), key
    rng = np.random.default_rng(3)
    X = np.c_[rng.uniform(-300, 300, 3000), rng.uniform(-220, 220, 3000),
              rng.uniform(400, 1500, 3000)]
    perp, d, Xs = _rectified_line_errors(rig, cal, X, poses)
    assert len(perp) > 500
    assert perp.max() < 0.3
    # d = f B / Z with Z the depth in the rectified frame (normal to the array plane)
    ref_cam = rig.cameras[rig.reference]
    A = cal.cameras[cal.reference].rectify           # reference camera -> rectified frame
    Z = ((Xs - ref_cam.centre) @ ref_cam.R.T @ A.T)[:, 2]
    d_true = cal.focal_px * cal.baseline / Z
    assert np.abs(d / d_true - 1).max() < 0.01


@pytest.fixture(scope="module")
def row():
    """A 1 x 3 rig, nine board poses (five every camera sees), and its full calibration."""
    rig = make_rig(1, 3, seed=SEED + 1)
    poses = rig.calibration_poses(9, n_shared=5)
    shots = [rig.render(p, salt=i, scene=False) for i, p in enumerate(poses)]
    return rig, poses, shots, calibrate({k: [s[k] for s in shots] for k in rig.cameras},
                                        rig.board)


def test_full_calibration_of_a_row_of_cameras(tmp_path, row):
    rig, poses, shots, cal = row
    assert cal.mode == "full"
    _check_full(rig, cal, poses)  # a row has less data: only where the boards were
    # reproducible bit for bit (OpenCV's threads made the fifth digit of f vary), and OpenCV's
    # thread count is left as it was
    threads = cv2.getNumThreads()
    again = calibrate({k: [s[k] for s in shots] for k in rig.cameras}, rig.board)
    assert cv2.getNumThreads() == threads
    for k, cam in cal.cameras.items():
        for name in ("K", "dist", "R", "t", "rectify"):
            assert np.array_equal(getattr(again.cameras[k], name), getattr(cam, name)), (k, name)
    back = read_calibration(write_calibration(cal, tmp_path / "full.toml"))
    assert back.mode == "full" and np.allclose(back.positions(), cal.positions())
    for k, cam in cal.cameras.items():
        for name in ("K", "dist", "R", "t", "rectify"):
            assert np.allclose(getattr(back.cameras[k], name), getattr(cam, name)), (k, name)
    # rectified views: the maps of a file-read calibration equal the fresh one's
    v1, m1 = apply_calibration(cal, shots[0])
    v2, m2 = apply_calibration(back, shots[0])
    assert np.array_equal(m1, m2) and np.allclose(v1, v2, atol=1e-5)


@pytest.mark.parametrize("turn, found", [((0, 2), [(0, 2)]), ((0, 1), [(0, 0), (0, 2)])])
def test_full_calibration_finds_a_camera_mounted_upside_down(row, turn, found):
    """A camera turned by 180 degrees sees the board's corners in reverse; its own calibration
    fits them as well, but its pose against the reference turned with every board pose, and
    the calibration came out with residuals of 8-21 px and a camera 78 baselines away, without
    a word. It is found by its stereo fit and turned back. Turned relative to the reference:
    when the reference is the turned one, the others are, and the whole capture is upside down
    (every view the upright calibration's turned by 180 degrees)."""
    rig, poses, shots, up = row
    ref = up.reference
    turned_shots = [{k: v[::-1, ::-1] if k == turn else v for k, v in s.items()} for s in shots]
    cal = calibrate({k: [s[k] for s in turned_shots] for k in rig.cameras}, rig.board)
    assert cal.info["turned_cameras"] == [camera_label(k) for k in found]
    assert up.info["turned_cameras"] == []
    sign = -1.0 if turn == ref else 1.0
    for k, cam in cal.cameras.items():
        assert cam.reprojection_error < 0.2, k
        np.testing.assert_allclose(cam.position - cal.cameras[ref].position,
                                   sign * (up.cameras[k].position - up.cameras[ref].position),
                                   atol=0.002)
    v_up, m_up = apply_calibration(up, shots[0])
    v, m = apply_calibration(cal, turned_shots[0])
    if turn == ref:
        v, m = v[..., ::-1, ::-1], m[..., ::-1, ::-1]
    both = m & m_up
    assert both.mean() > 0.8
    err = np.abs(v - v_up)[both] / v_up.max()     # the calibrations differ by their noise
    assert np.median(err) < 1e-3 and np.percentile(err, 99) < 0.02


@pytest.mark.parametrize("rows, cols, seed, turn, tilt", [
    (1, 3, 0, (0, 0), 4.0), (1, 3, 3, (0, 0), 4.0), (3, 3, 1, (0, 0), 4.0),
    (2, 2, 0, (0, 0), 4.0), (1, 3, 1, (0, 1), 0.0)])
def test_plane_registration_finds_a_camera_mounted_upside_down(rows, cols, seed, turn, tilt):
    """One board pose, one camera's shot turned by 180 degrees (in the 2 x 2 array and the
    last row, the reference's: then every other camera is turned against it). Judged by
    how many entries each model kept, a turned view's wrong flows made the common model
    loose enough to keep them all, and the camera was not found: registrations refused as
    contradicting the board poses (1.5 baselines apart), or positions from wrong flows
    without a word. Before a board facing the array squarely, the model fitted 4 of 600
    points in each view, tightly, and nothing was tried. Every case comes out as the
    upright shots do (the positions to float32 rounding: the turned shot registers onto the
    same pixels)."""
    rig = make_rig(rows, cols, seed=seed)
    shots = rig.render(rig.board_pose(450.0, tilt=(tilt, -0.75 * tilt, 0.5 * tilt)))
    up = calibrate({k: [v] for k, v in shots.items()}, rig.board, mode="plane")
    ref = up.reference
    turned = {k: v[::-1, ::-1] if k == turn else v for k, v in shots.items()}
    cal = calibrate({k: [v] for k, v in turned.items()}, rig.board, mode="plane")
    found = [k for k in sorted(shots) if k != ref] if turn == ref else [turn]
    assert cal.info["turned_cameras"] == [camera_label(k) for k in found]
    assert up.info["turned_cameras"] == [] and cal.info["positions_from"] == "parallax"
    sign = -1.0 if turn == ref else 1.0
    np.testing.assert_allclose(cal.positions() - cal.positions()[ref],
                               sign * (up.positions() - up.positions()[ref]), atol=1e-4)


@pytest.mark.parametrize("rows, degrees, tilt", [(3, 90, 4.0), (1, 180, 0.0)])
def test_plane_registration_with_a_corner_camera_turned(rows, degrees, tilt):
    """A corner camera mounted turned. In a 3 x 3 array, by 90 degrees: its wrong flows
    (before it is turned back) left its neighbour (1, 0) without a single inlier, the
    parallax was given up, and the positions came from the board poses, 1.09 baselines
    off, with the note that 234 points and a median flow of 13.4 px were too few. In a row
    before a board facing it squarely, by 180 degrees: the model fitted 4 of 600 points in
    each view, tightly, nothing was tried, and the positions came from the board poses,
    2.8 baselines off."""
    rig = _turned_rig((0, 0), degrees, rows, 3, seed=0 if rows == 3 else 1)
    shots = rig.render(rig.board_pose(450.0, tilt=(tilt, -0.75 * tilt, 0.5 * tilt)),
                       supersample=2)
    cal = calibrate({k: [v] for k, v in shots.items()}, rig.board, mode="plane")
    assert cal.info["positions_from"] == "parallax"
    assert cal.info["camera_turns"] == {camera_label((0, 0)): degrees}
    truth = rig.true_positions()
    found = np.stack([cal.positions()[k] - cal.positions()[cal.reference] for k in truth])
    exact = np.stack([truth[k] - truth[cal.reference] for k in truth])
    assert np.sqrt(np.mean(np.sum((found - exact) ** 2, 1))) < 0.05


def _full_row(rig, turn_poses=()):
    poses = rig.calibration_poses(9, n_shared=5)
    poses = [_held_turned(p, rig.board, 90) if i in turn_poses else p for i, p in enumerate(poses)]
    shots = [rig.render(p, salt=i, scene=False) for i, p in enumerate(poses)]
    return poses, calibrate({k: [s[k] for s in shots] for k in rig.cameras}, rig.board)


def test_full_calibration_with_the_board_held_in_portrait():
    """Two of nine poses with the board held turned by 90 degrees: the cameras numbered its
    corners differently there, and the calibration came out with residuals of 4-5 px and
    positions 8 baselines wrong without a word."""
    rig = make_rig(1, 3, seed=SEED + 1)
    poses, cal = _full_row(rig, turn_poses=(0, 3))
    _check_full(rig, cal, poses)
    assert cal.info["turned_cameras"] == []


@pytest.mark.parametrize("degrees", [90, 270])
def test_full_calibration_finds_a_camera_turned_by_a_quarter(degrees):
    """Turned by 90 degrees, a camera sees the board's rows run down its image, so which
    order its corners take changes from pose to pose: residuals of 7-17 px and positions
    12-17 baselines wrong. Its orders are now found pose by pose (its rotation against the
    reference must be the same in every pose), also with the board held in portrait."""
    rig = _turned_rig((0, 2), degrees, 1, 3, seed=SEED + 1)
    poses, cal = _full_row(rig, turn_poses=(3,))
    _check_full(rig, cal, poses)
    assert cal.info["camera_turns"] == {camera_label((0, 2)): degrees}


@pytest.mark.slow
def test_full_calibration_of_a_3x3_array(tmp_path, rig):
    poses = rig.calibration_poses()
    shots = [rig.render(p, salt=i, scene=False) for i, p in enumerate(poses)]
    cal = calibrate({k: [s[k] for s in shots] for k in rig.cameras}, rig.board)
    assert cal.mode == "full"
    _check_full(rig, cal)
    back = read_calibration(write_calibration(cal, tmp_path / "full.toml"))
    assert np.allclose(back.positions(), cal.positions())
    assert np.allclose(back.cameras[(0, 0)].rectify, cal.cameras[(0, 0)].rectify)


# ----------------------------------------------------------------------------- real data
def test_lab_capture_plane_registration():
    """The lab capture (3 x 3, one board shot): board in all 9 cameras, small residuals,
    positions a 3 x 3 grid up to a symmetry of the square, consistent with the board poses."""
    import cv2

    root = require_dataset("real_arrays/msir_lab") / "calibration"
    shots = {(i // 3, i % 3): cv2.imread(str(root / f"Cam-{i}.png"), cv2.IMREAD_UNCHANGED)
             for i in range(9)}
    cal = register_plane(shots, BoardSpec(11, 8, 1.0),
                         names={(i // 3, i % 3): f"Cam-{i}.png" for i in range(9)})
    assert max(cal.reprojection_errors().values()) < 0.5
    assert cal.info["positions_from"] == "parallax"
    assert cal.info["sign_agreement"] > 0.9
    off = cal.positions() - cal.positions()[cal.reference]
    grid = np.round(off)
    assert np.abs(off - grid).max() < 0.1
    assert sorted(map(tuple, grid.reshape(-1, 2).tolist())) == \
        sorted((x, y) for x in (-1.0, 0.0, 1.0) for y in (-1.0, 0.0, 1.0))
    # neighbours in the user's raster naming are neighbours in the array
    for r in range(3):
        for c in range(2):
            assert np.abs(grid[r, c + 1] - grid[r, c]).sum() == 1


def test_lab_board_pushed_partly_out_of_one_camera():
    """The lab's Cam-0 board shot moved 420 px right (zeros shifted in): the board's last
    corner column leaves the locatable part of the image. That camera's seen corners are the
    unmoved detection moved by the same 420 px, and every position is as before."""
    import cv2

    root = require_dataset("real_arrays/msir_lab") / "calibration"
    shots = {(i // 3, i % 3): cv2.imread(str(root / f"Cam-{i}.png"), cv2.IMREAD_UNCHANGED)
             for i in range(9)}
    board = BoardSpec(11, 8, 1.0)
    before = register_plane(shots, board)
    moved = np.zeros_like(shots[(0, 0)])
    moved[:, 420:] = shots[(0, 0)][:, :-420]
    assert detect_board(moved, board) is None          # the whole board is not in view
    after = register_plane({**shots, (0, 0): moved}, board)
    c = after.corners[(0, 0)]
    seen = np.all(np.isfinite(c), axis=1)
    assert 9 * 8 <= seen.sum() < 11 * 8
    assert np.abs(c[seen] - before.corners[(0, 0)][seen] - (420, 0)).max() < 0.01
    for key, cam in after.cameras.items():
        assert np.abs(cam.position - before.cameras[key].position).max() < 0.01, key
        assert cam.reprojection_error < 0.5, key


# ----------------------------------------------------------------------------- pictures
def test_pictures_are_written(tmp_path, rig, plane_shots, plane_cal):
    from hyperlf.calibration import (save_corner_pictures, save_registration_picture,
                                     save_residual_picture)

    corners = {k: detect_board(v, rig.board) for k, v in plane_shots.items()}
    corners[(0, 0)] = None
    views, valid = apply_calibration(plane_cal, plane_shots)
    paths = [save_corner_pictures(tmp_path / "corners.png", plane_shots, corners),
             save_registration_picture(tmp_path / "registered.png", views, valid),
             save_residual_picture(tmp_path / "residuals.png", plane_cal)]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert set(plane_cal.residuals) == set(plane_cal.cameras)
    assert np.allclose(plane_cal.residuals[plane_cal.reference][1], 0)
    rms = {k: float(np.sqrt(np.mean(np.sum(v ** 2, 1)))) for k, (_, v) in
           plane_cal.residuals.items()}
    assert rms == pytest.approx(plane_cal.reprojection_errors())
    back = read_calibration(write_calibration(plane_cal, tmp_path / "c.toml"))
    with pytest.raises(InvalidInputError, match="no corner residuals"):
        save_residual_picture(tmp_path / "r2.png", back)


def test_pictures_of_large_shots_are_subsampled_in_the_shots_coordinates(monkeypatch, tmp_path):
    """Views are drawn at what the figure shows (a 3 x 3 grid of 1200 x 1600 shots: every
    third pixel), placed on the full image's pixel grid, so corners and guide lines are drawn
    where they were measured."""
    from hyperlf.calibration import pictures
    from hyperlf.visualise import display_step

    drawn = []
    monkeypatch.setattr(pictures, "save_figure", lambda fig, path: drawn.append(fig))
    H, W = 1200, 1600
    shots = {(r, c): np.full((H, W), float(r + c)) for r in range(3) for c in range(3)}
    corners = {k: np.array([[10.0, 20.0], [W - 1.0, H - 1.0]]) for k in shots}
    pictures.save_corner_pictures(tmp_path / "c.png", shots, corners)
    views = np.stack([np.stack([shots[r, c] for c in range(3)]) for r in range(3)])
    pictures.save_registration_picture(tmp_path / "r.png", views, views >= 0)
    assert display_step(3 * H, 3 * W, pictures.MAX_SIDE) == 3
    for fig in drawn:
        for ax in fig.axes:
            (im,) = ax.images
            assert im.get_array().shape[:2] == (-(-H // 3), -(-W // 3))
            assert im.get_extent() == [-0.5, W - 0.5, H - 0.5, -0.5]
    assert [display_step(n, 10, 100) for n in (1, 100, 101, 200, 201)] == [1, 1, 2, 2, 3]


@pytest.mark.parametrize("seed,true_range", [(0, (-3.0, 2.0)), (1, (1.0, 4.0))])
def test_measured_disparity_range_covers_the_scene(seed, true_range):
    """The range ingest measures when the calibration has none (full calibration): it holds
    the scene's disparities, with a margin, not much more."""
    from hyperlf.calibration.parallax import measured_disparity_range
    from hyperlf.synthesis import procedural_scene

    lf = procedural_scene(seed=seed, rows=3, cols=3, height=120, width=160,
                          disparity_range=true_range)
    gt = lf.reference_gt_disparity
    valid = np.ones(lf.views.shape, bool)
    lo, hi = measured_disparity_range(lf.views, valid, lf.positions, lf.reference)
    assert lo <= min(0.0, gt.min()) and hi >= max(0.0, gt.max())
    width = max(0.0, gt.max()) - min(0.0, gt.min())
    assert hi - lo <= 1.25 * width + 2.0
    blank = np.zeros_like(lf.views)
    assert measured_disparity_range(blank, valid, lf.positions, lf.reference) is None


@pytest.mark.parametrize("seed,true_range", [(0, (-9.0, 0.0)), (1, (2.0, 9.5))])
def test_measured_disparity_range_is_the_same_from_every_reference(seed, true_range):
    """From a corner the farthest view moves 2.8 baselines: out of the search radius for the
    largest disparities here (it underestimated the range by 1 px per baseline); the range is
    now measured from the centre camera whatever the reference."""
    from hyperlf.calibration.parallax import measured_disparity_range
    from hyperlf.synthesis import procedural_scene

    lf = procedural_scene(seed=seed, rows=3, cols=3, height=120, width=160,
                          disparity_range=true_range)
    valid = np.ones(lf.views.shape, bool)
    ranges = {ref: measured_disparity_range(lf.views, valid, lf.positions, ref)
              for ref in [(1, 1), (0, 0), (2, 2), (0, 2), (2, 0)]}
    assert len(set(ranges.values())) == 1, ranges
    lo, hi = ranges[(1, 1)]
    gt = lf.reference_gt_disparity
    assert lo <= min(0.0, gt.min()) and hi >= max(0.0, gt.max())
    valid[1, 1] = False  # the centre view missing: the reference's neighbours serve
    assert measured_disparity_range(lf.views, valid, lf.positions, (0, 0)) is not None


@pytest.mark.parametrize("reference", [(0, 0), (2, 2), (0, 2)])
def test_plane_registration_with_a_corner_camera_as_the_reference(rig, plane_shots, reference):
    """The parallax was matched from the reference camera, within a radius that suits the
    centre camera's neighbours: from a corner the farthest view moves twice as far, and
    registration failed after 12 s ('positions ... disagree by 5.40 baselines'), as did six of
    the eight off-centre references. It is now matched from the camera nearest the centre."""
    cal = register_plane(plane_shots, rig.board, reference=reference)
    _check_plane_positions(dataclasses.replace(rig, reference=reference), cal)
    assert cal.reference == reference and cal.info["positions_from"] == "parallax"
