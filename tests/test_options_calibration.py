"""The calibration helpers (``hyperlf.calibration``: board, bundle, full, grid, ingest, io,
metric, parallax, plane, raw, rig, apply, pictures) take what they document, or refuse
anything else with one line of a hyperlf error before any work: never a ``TypeError``,
``ValueError``, ``IndexError``, ``cv2.error`` or NumPy warning from deep inside, nor NaN out
of finite input."""

from __future__ import annotations

import functools
import re
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf.calibration import apply, board as B, bundle, full, grid, ingest, metric
from hyperlf.calibration import parallax, pictures, plane, raw, rig as RI
from hyperlf.calibration.model import CameraCalibration
from hyperlf.errors import InvalidInputError

from test_options import JUNK, _build_or_refuse


@functools.lru_cache(maxsize=None)
def _fixtures() -> dict:
    """A tiny rig (1 x 3 cameras, 5 x 4 board) and exact corners, no rendering."""
    rig = RI.make_rig(1, 3, seed=1, image_size=(200, 150), focal=200.0,
                      board=B.BoardSpec(5, 4, 20.0))
    board = rig.board
    poses = [rig.board_pose(350.0, tilt=t) for t in ((0, 0, 0), (15, -10, 3), (-12, 14, -4),
                                                      (10, 12, 6))]
    corners = {k: {p: rig.project(k, pose.corners_world(board)) for p, pose in enumerate(poses)}
               for k in rig.cameras}
    c0, c1 = corners[(0, 1)][0], corners[(0, 0)][0]
    K, d, _, _ = full.intrinsics(corners[(0, 0)], board, (200, 150))
    Kr, dr, _, _ = full.intrinsics(corners[(0, 1)], board, (200, 150))
    img = np.random.default_rng(0).random((40, 50)).astype(np.float32)
    cam = CameraCalibration(name="a", position=np.zeros(2), reprojection_error=0.1,
                            homography=np.eye(3))
    return dict(rig=rig, board=board, corners=corners, c0=c0, c1=c1, K=K, d=d, Kr=Kr, dr=dr,
                img=img, cam=cam)


def _calls() -> dict:
    """One valid call per function, as keyword arguments (built on first use)."""
    f = _fixtures()
    b, c0, c1 = f["board"], f["c0"], f["c1"]
    stereo = dict(ref_corners=f["corners"][(0, 1)], corners=f["corners"][(0, 0)], board=b,
                  K_ref=f["Kr"], d_ref=f["dr"], K=f["K"], d=f["d"])
    eye = {k: np.eye(3) for k in ((0, 0), (0, 1))}
    ts = {(0, 0): np.array([-40.0, 0, 0]), (0, 1): np.zeros(3)}
    geom = {"mode": "full", "camera_matrix": [[100, 0, 1], [0, 100, 1], [0, 0, 1]],
            "baseline": 40.0}
    part = np.stack([40.0 * np.mgrid[0:4, 0:5][1] - 50, 40.0 * np.mgrid[0:4, 0:5][0] + 50],
                    -1)[:, 2:]
    return {
        B.canonical_order: dict(corners=c1, cols=5, rows=4),
        B.grid_symmetries: dict(cols=5, rows=4),
        B.order_like: dict(corners=c1, anchor=c0, board=b),
        B.orders_like: dict(corners={(0, 0): c1, (0, 1): c0}, reference=(0, 1), board=b),
        B.image_turn: dict(corners=c1, anchor=c0, board=b),
        B.turn_report: dict(corners={(0, 0): c1}, anchors={(0, 0): c0}, board=b, names=None),
        B.camera_label: dict(key=(0, 1), names={(0, 1): "a"}),
        B.place_partial_grid: dict(grid=part, board=B.BoardSpec(5, 4), shape=(300, 300)),
        B.normalise_for_detection: dict(image=f["img"], clahe=True),
        bundle.bundle_adjust: dict(obs=[(0, 0, c1), (1, 0, c0)], obj=b.object_points(),
                                   intr0=np.array([[200, 200, 100, 75, 0, 0, 0, 0]] * 2, float),
                                   rvec0=np.zeros((2, 3)), tvec0=np.array([[40.0, 0, 0], [0, 0, 0]]),
                                   pose_r0=np.zeros((1, 3)), pose_t0=np.array([[-40.0, -30, 350]]),
                                   ref=1),
        full.intrinsics: dict(corners=f["corners"][(0, 0)], board=b, size=(200, 150)),
        full.extrinsics: dict(**stereo, size=(200, 150), label="a"),
        full.turned_orders: dict(**stereo, tolerance=30.0),
        full.rectification: dict(Ks={k: f["K"] for k in eye}, Rs=eye, ts=ts, reference=(0, 1),
                                 size=(200, 150)),
        grid.check_grid: dict(keys=[(0, 0), (0, 1)], reference=None),
        grid.check_images: dict(images={(0, 0): f["img"], (0, 1): f["img"]}, names=None,
                                what="image"),
        ingest.correct_raw: dict(image=f["img"], dark=0.01, flat=np.ones_like(f["img"])),
        metric.depth_from_disparity: dict(disparity=np.full((3, 4), 2.0), geometry=geom),
        metric.point_cloud: dict(depth=np.full((3, 4), 2.0), geometry=geom,
                                 colours=np.zeros((3, 4)), step=1),
        parallax.feature_image: dict(image=f["img"], sigma=1.0),
        parallax.match_flows: dict(ref_feat=f["img"], view_feat=f["img"],
                                   points=np.array([[25.0, 20.0]]),
                                   view_valid=np.ones((40, 50), bool), half=3, radius=6,
                                   min_score=0.6),
        parallax.hub_camera: dict(keys=[(0, 0), (0, 1), (0, 2)], reference=(0, 0)),
        parallax.fitting_entries: dict(flows=np.zeros((2, 3, 2)), d=np.ones(3),
                                       offsets=np.ones((2, 2)), tol=1.0, measured=None),
        plane.board_outline: dict(corners=c0, board=b, margin=1.6),
        plane.resolve_positions: dict(offsets={(0, 0): np.array([1.0, 0]), (0, 1): np.zeros(2)},
                                      pose_centres={(0, 0): np.array([40.0, 1, 0]),
                                                    (0, 1): np.zeros(3)}, reference=(0, 1)),
        plane.board_homographies: dict(corners={(0, 0): c1, (0, 1): c0}, reference=(0, 1),
                                       names=None),
        raw.sensor_bits: dict(largest=4095, file_bits=16),
        raw.camera_files: dict(folder=".", pattern="Cam-{index}.png", grid=(1, 2),
                               must_exist=False, skip=()),
        RI.rotation_matrix: dict(rx=1.0, ry=2.0, rz=3.0),
        RI.make_rig: dict(rows=1, cols=2, seed=0, image_size=(64, 48), baseline=40.0,
                          focal=100.0, board=None, inverted=(1,), imperfect=1.0,
                          scene_depths=(700.0, 1000.0), noise=0.004, distortion=None),
        RI.BoardPose: dict(R=np.eye(3), t=np.array([0, 0, 300.0])),
        RI.Panel: dict(origin=np.zeros(3), u=np.eye(3)[0], v=np.eye(3)[1], width=10.0,
                       height=5.0, kind="texture", seed=0),
        CameraCalibration: dict(name="a", position=np.zeros(2), reprojection_error=0.1,
                                homography=np.eye(3)),
    }


_NAMES = [(fn, key) for fn, kw in _calls().items() for key in kw]


def _finite(out, depth=0) -> bool:
    """Whether every float in ``out`` (arrays, tuples, dicts) is finite."""
    if depth > 4:
        return True
    if isinstance(out, np.ndarray):
        return out.dtype.kind not in "fc" or bool(np.isfinite(out).all())
    if isinstance(out, float):
        return np.isfinite(out)
    if isinstance(out, dict):
        return all(_finite(v, depth + 1) for v in out.values())
    if isinstance(out, (list, tuple)):
        return all(_finite(v, depth + 1) for v in out)
    return True


@pytest.mark.parametrize("fn", list(_calls()), ids=lambda fn: fn.__name__)
def test_the_valid_calls_work(fn, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = fn(**_calls()[fn])
    if fn is not B.place_partial_grid:     # unseen corners are NaN there
        assert _finite(out)


@settings(max_examples=400, deadline=None, derandomize=True)
@given(st.sampled_from(range(len(_NAMES))), JUNK)
def test_every_argument_takes_junk_or_refuses_it_in_one_line(which, value):
    fn, key = _NAMES[which]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        out = _build_or_refuse(fn, **{**_calls()[fn], key: value})
    if out is not None and fn not in (B.place_partial_grid, B.camera_label,
                                      metric.depth_from_disparity, parallax.match_flows):
        # NaN marks unseen corners, unmatched points and depths not finite and positive
        # (disparity <= 0 in full mode); nothing else returns NaN from junk
        assert _finite(out) or (fn in (RI.BoardPose, RI.Panel, CameraCalibration))


@pytest.mark.parametrize("fn, key, value, words", [
    (B.canonical_order, "cols", "x", "cols must be an integer in 1..200"),
    (B.order_like, "anchor", np.zeros(3), "anchor must be the (20, 2) corners"),
    (B.camera_label, "key", [1], "camera must be a (row, col) pair, a name (str) or an int"),
    (bundle.bundle_adjust, "ref", 5, "ref must be an integer in 0..1, got 5"),
    (bundle.bundle_adjust, "obs", [], "obs must be a non-empty list"),
    (full.intrinsics, "size", None, "size must be (W, H) of the images"),
    (full.extrinsics, "size", (2 ** 31, 150), "size must be (W, H) of the images in 1..1048576"),
    (full.rectification, "reference", (5, 5), "reference (5, 5) is not one of the cameras"),
    (full.turned_orders, "K", np.zeros((3, 3)), "K must be a finite 3 x 3 camera matrix"),
    (parallax.hub_camera, "reference", (2, 2), "reference (2, 2) is not one of the cameras"),
    (parallax.match_flows, "half", -1, "half must be an integer in 0..50, got -1"),
    (parallax.feature_image, "sigma", float("inf"), "sigma must be a finite number"),
    (plane.board_outline, "margin", 1e300, "margin must be a finite number in [0, 1000]"),
    (plane.resolve_positions, "offsets", {(0, 1): [np.nan, 0]}, "offsets and pose_centres"),
    (metric.point_cloud, "step", 0, "step must be an integer >= 1, got 0"),
    (metric.depth_from_disparity, "geometry", None, "geometry must be a dict"),
    (ingest.correct_raw, "dark", np.inf, "the dark frame must hold finite values"),
    (raw.sensor_bits, "largest", "x", "largest must be an integer >= 0"),
    (raw.camera_files, "folder", None, "folder must be a path"),
    (raw.camera_files, "pattern", 3, "--pattern must be a file name pattern"),
    (RI.rotation_matrix, "rx", float("nan"), "rx must be a finite number, got nan"),
    (RI.make_rig, "focal", 0, "focal must be a finite number in [1, 1e+07], got 0"),
    (RI.make_rig, "inverted", 3, "inverted must be raster indices of cameras"),
    (RI.BoardPose, "t", [np.inf, 0, 0], "t must be finite"),
    (B.orders_like, "corners", {np.float32(0.0): np.zeros((20, 2))},
     "a camera of corners must be a (row, col) pair, a name (str) or an int, got np.float32"),
])
def test_former_failures_name_the_argument(fn, key, value, words):
    with pytest.raises(InvalidInputError) as exc:
        fn(**{**_calls()[fn], key: value})
    assert str(exc.value).startswith(words) and "\n" not in str(exc.value)


def test_a_camera_or_pose_without_observations_is_refused():
    """The nested fuzzer replaced the first observation's camera by the other one: camera 0
    had nothing to fit, and its residual was the mean of an empty slice (NaN, a warning)."""
    kw = _calls()[bundle.bundle_adjust]
    (_, _, c1), (_, _, c0) = kw["obs"]
    for obs, words in (([(1, 0, c1), (1, 0, c0)], "obs holds no observation of camera 0 (of 2)"),
                       ([(0, 0, c1), (1, 0, c0)], "obs holds no observation of pose 1 (of 2)")):
        extra = {"pose_r0": np.zeros((2, 3)), "pose_t0": np.array([[-40.0, -30, 350]] * 2)} \
            if "pose" in words else {}
        with pytest.raises(InvalidInputError, match=f"^{re.escape(words)}; each"):
            bundle.bundle_adjust(**{**kw, "obs": obs, **extra})


def test_a_saturation_beyond_float32_is_refused_before_any_warp(tmp_path):
    from hyperlf.calibration.model import Calibration

    f = _fixtures()
    cal = Calibration(mode="plane", grid=(1, 2), reference=(0, 0), image_size=(50, 40),
                      output_size=(50, 40), camera_matrix=np.eye(3) * [100, 100, 1],
                      cameras={(0, 0): f["cam"], (0, 1): f["cam"]}, board=f["board"],
                      baseline=1.0, board_plane=np.array([0, 0, 1.0, 300]))
    images = {(0, 0): f["img"], (0, 1): f["img"]}
    with pytest.raises(InvalidInputError, match="^saturation must be within float32's range"):
        apply.apply_calibration(cal, images, saturation=1e300)
    with pytest.raises(InvalidInputError, match="^lines must be an integer in 0..100"):
        pictures.save_registration_picture(tmp_path / "x.png", np.zeros((1, 2, 4, 4)),
                                           np.ones((1, 2, 4, 4), bool), lines=2.5)
    with pytest.raises(InvalidInputError, match="^calibration must be a Calibration"):
        metric.capture_geometry(None)
