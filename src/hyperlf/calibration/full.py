"""Full calibration of a planar camera array from several board poses (SPEC §11, paper §7.1).

Stages:

1. :func:`detect_poses`: the board's corners in every camera and pose (a pose in which a camera
   misses the board is left out for that camera).
2. :func:`intrinsics`: Zhang's method per camera (OpenCV ``calibrateCamera``; radial ``k1``,
   ``k2`` and tangential ``p1``, ``p2``; ``k3`` fixed at 0, which a few poses cannot pin down).
3. :func:`relative_pose`: every camera's pose relative to the reference camera (OpenCV
   ``stereoCalibrate`` with the intrinsics fixed, over the poses both cameras saw,
   :func:`extrinsics`). Every camera's corners come in the reference's order of each pose,
   whichever way the board is held; a camera whose images are turned against the reference's
   (mounted turned by 90, 180 or 270 degrees) is found there and its corners put in the
   orders that fit (:func:`turned_orders`).
4. :func:`rectification`: one image plane parallel to the array plane (its normal from the
   camera centres, facing the scene), ``x`` along the reference camera's ``x`` axis projected
   onto that plane, one focal length (the cameras' mean) and principal point for all views.
   Positions are the camera centres in that frame in units of one baseline (the median
   distance from a camera to its nearest neighbour), so that a point at depth ``Z`` has
   disparity ``d = f B / Z`` and appears in view ``v`` at ``x_ref - d (p_v - p_ref)``.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .. import _options as _opt
from .._parallel import map_threads
from ..warp import MAX_AXIS
from ..errors import InvalidInputError
from .board import (DETECT_THREADS, BoardSpec, camera_label, check_board, check_board_size,
                    check_corners, check_key, check_keys, detect_board, grid_symmetries,
                    orders_like, turn_report)
from .grid import check_grid, check_images
from .model import Calibration, CameraCalibration

__all__ = ["calibrate_full", "detect_poses", "intrinsics", "extrinsics", "relative_pose",
           "turned_orders", "rectification"]

#: A camera whose stereo RMS against the reference is above this (px) is also tried turned.
TURN_TRY_RMS = 1.0


def _image_size(size) -> tuple[int, int]:
    """``(W, H)`` of the images, each at most :data:`hyperlf.warp.MAX_AXIS` px (OpenCV takes
    sizes as 32-bit ints)."""
    return _opt.int_pair(size, "size", 1, maximum=MAX_AXIS, what="(W, H) of the images")


def _shot_lists(shots, names) -> Mapping:
    """``shots``: a non-empty mapping camera -> sequence of board shots."""
    _opt.mapping(shots, "shots", optional=False)
    if not shots:
        raise InvalidInputError("shots must hold the board shots of at least one camera")
    for k, v in shots.items():
        check_key(k)
        if isinstance(v, (str, bytes, Mapping)) or not hasattr(v, "__len__") or \
                (isinstance(v, np.ndarray) and v.ndim != 3):
            raise InvalidInputError(f"the board shots of camera {camera_label(k, names)} must be "
                                    f"a list of images, got {_opt.shown(v)}")
    return shots


def _pose_corners(corners, label: str, board: BoardSpec) -> dict:
    """``corners``: a non-empty mapping pose index -> a camera's whole board's corners."""
    _opt.mapping(corners, label, optional=False)
    if not corners:
        raise InvalidInputError(f"{label} must hold the corners of at least one pose")
    for p, c in corners.items():
        _opt.integer(p, f"a pose index of {label}")
        check_corners(c, f"{label}[{_opt.shown(p)}]", board, unseen=False)
    return corners


def _camera_matrix(K, label: str) -> np.ndarray:
    """``K`` as a finite float64 3 x 3 camera matrix with positive focal lengths."""
    a = _opt.real_array(K, label)
    if a.shape != (3, 3) or not np.isfinite(a).all() or not (a[0, 0] > 0 and a[1, 1] > 0):
        raise InvalidInputError(f"{label} must be a finite 3 x 3 camera matrix with focal "
                                f"lengths > 0, got {_opt.shown(K)}")
    return a


def _distortion(d, label: str) -> np.ndarray:
    """``d`` as finite float64 OpenCV distortion coefficients (4, 5, 8, 12 or 14)."""
    a = _opt.real_array(d, label)
    if a.ndim != 1 or a.size not in (4, 5, 8, 12, 14) or not np.isfinite(a).all():
        raise InvalidInputError(f"{label} must be 4, 5, 8, 12 or 14 finite distortion "
                                f"coefficients (k1, k2, p1, p2, k3, ...), got {_opt.shown(d)}")
    return a


def _stereo_inputs(ref_corners, corners, board, K_ref, d_ref, K, d) -> tuple:
    """The checked inputs of a pose relative to the reference (:func:`extrinsics`)."""
    check_board(board)
    return (_pose_corners(ref_corners, "ref_corners", board),
            _pose_corners(corners, "corners", board), _camera_matrix(K_ref, "K_ref"),
            _distortion(d_ref, "d_ref"), _camera_matrix(K, "K"), _distortion(d, "d"))


def _label(label) -> str:
    return _opt.text(label, "label")


def detect_poses(shots: Mapping, board: BoardSpec, *, names=None, min_poses: int = 3) -> dict:
    """Corners per camera and pose: ``{key: {pose_index: (N, 2)}}``.

    Raises
    ------
    InvalidInputError
        Cameras with fewer than ``min_poses`` detections (all named, with their counts).

    Examples
    --------
    Four poses of the board in front of a two-camera rig; camera ``(0, 1)``'s second shot is
    blank, so that pose is left out for it:

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=1, image_size=(240, 180), focal=225.0)
    >>> renders = [rig.render(p, salt=i, supersample=1, scene=False)
    ...            for i, p in enumerate(rig.calibration_poses(4, n_shared=4))]
    >>> shots = {k: [r[k] for r in renders] for k in rig.cameras}
    >>> shots[(0, 1)][1] = np.full((180, 240), 0.5, np.float32)
    >>> found = detect_poses(shots, rig.board)
    >>> sorted(found[(0, 0)]), sorted(found[(0, 1)]), found[(0, 1)][2].shape
    ([0, 1, 2, 3], [0, 2, 3], (48, 2))
    """
    check_board(board)
    _opt.mapping(names, "names")
    _shot_lists(shots, names)
    min_poses = _opt.integer(min_poses, "min_poses", 1)
    jobs = [(key, i, img) for key, imgs in shots.items() for i, img in enumerate(imgs)]
    corners = map_threads(lambda job: detect_board(job[2], board), jobs, cap=DETECT_THREADS)
    found, short = {key: {} for key in shots}, []
    for (key, i, _), c in zip(jobs, corners):
        if c is not None:
            found[key][i] = c
    for key, imgs in shots.items():
        if len(found[key]) < min_poses:
            short.append(f"{camera_label(key, names)} ({len(found[key])} of {len(imgs)})")
    if short:
        raise InvalidInputError(
            f"checkerboard ({board.cols} x {board.rows} inner corners) found in fewer than "
            f"{min_poses} poses for camera(s) {', '.join(short)}; add board shots those cameras "
            "see whole, or use one pose (plane registration)")
    key = next(iter(found))
    pose = min(found[key])
    check_board_size(shots[key][pose], board, found[key][pose],
                     name=f"pose {pose + 1} of camera {camera_label(key, names)}")
    return found


def intrinsics(corners: Mapping, board: BoardSpec, size) -> tuple:
    """Zhang calibration of one camera from ``{pose: corners}``.

    Returns ``(K, dist(5), rms px, {pose: (rvec, tvec)})`` (board to camera).

    Examples
    --------
    The exact corners of five board poses in one camera of a synthetic rig give back its
    intrinsics (its distortion is radial, which the model holds):

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0)
    >>> cam = rig.cameras[(0, 0)]
    >>> poses = rig.calibration_poses(5, n_shared=5)
    >>> corners = {i: rig.project((0, 0), p.corners_world(rig.board)) for i, p in enumerate(poses)}
    >>> K, dist, rms, board_poses = intrinsics(corners, rig.board, rig.image_size)
    >>> bool(np.abs(K - cam.K).max() < 0.01), bool(np.abs(dist - cam.dist).max() < 1e-4)
    (True, True)
    >>> bool(rms < 0.01), sorted(board_poses)
    (True, [0, 1, 2, 3, 4])
    """
    import cv2

    check_board(board)
    _pose_corners(corners, "corners", board)
    size = _image_size(size)
    obj = board.object_points().astype(np.float32)
    poses = sorted(corners)
    img = [corners[p].astype(np.float32).reshape(-1, 1, 2) for p in poses]
    flags = cv2.CALIB_FIX_K3
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    rms, K, dist, rv, tv = cv2.calibrateCamera([obj] * len(poses), img, tuple(size), None, None,
                                               flags=flags, criteria=crit)
    board_poses = {p: (r.ravel(), t.ravel()) for p, r, t in zip(poses, rv, tv)}
    return K, dist.ravel()[:5].astype(np.float64), float(rms), board_poses


def extrinsics(ref_corners: Mapping, corners: Mapping, board: BoardSpec, K_ref, d_ref, K, d,
               size, *, label: str = "") -> tuple[np.ndarray, np.ndarray, float]:
    """Pose ``(R, t, rms)`` of a camera relative to the reference: ``X = R X_ref + t``.

    Examples
    --------
    The exact corners of five board poses in both cameras of a synthetic rig give back the
    second camera's true pose against the first (the reference):

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0)
    >>> ref, cam = rig.cameras[(0, 0)], rig.cameras[(0, 1)]
    >>> poses = rig.calibration_poses(5, n_shared=5)
    >>> corners = {k: {i: rig.project(k, p.corners_world(rig.board)) for i, p in enumerate(poses)}
    ...            for k in rig.cameras}
    >>> R, t, rms = extrinsics(corners[(0, 0)], corners[(0, 1)], rig.board, ref.K, ref.dist,
    ...                        cam.K, cam.dist, rig.image_size)
    >>> bool(np.abs(R - cam.R @ ref.R.T).max() < 1e-4)
    True
    >>> bool(np.abs(t - cam.R @ (ref.centre - cam.centre)).max() < 0.01), bool(rms < 0.01)
    (True, True)
    """
    import cv2

    ref_corners, corners, K_ref, d_ref, K, d = _stereo_inputs(ref_corners, corners, board,
                                                              K_ref, d_ref, K, d)
    size = _image_size(size)
    _label(label)
    shared = sorted(set(ref_corners) & set(corners))
    if not shared:
        raise InvalidInputError(
            f"camera {label} and the reference never saw the board in the same pose; add a pose "
            "both see")
    obj = board.object_points().astype(np.float32)
    a = [ref_corners[p].astype(np.float32).reshape(-1, 1, 2) for p in shared]
    b = [corners[p].astype(np.float32).reshape(-1, 1, 2) for p in shared]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    out = cv2.stereoCalibrate([obj] * len(shared), a, b, K_ref, d_ref, K, d, tuple(size),
                              flags=cv2.CALIB_FIX_INTRINSIC, criteria=crit)
    return out[5], out[6].ravel(), float(out[0])


def relative_pose(ref_corners: Mapping, corners: Mapping, board: BoardSpec, K_ref, d_ref, K, d,
                  size, *, label: str = "") -> tuple[np.ndarray, np.ndarray, float, dict | None]:
    """:func:`extrinsics`, or those of the camera mounted turned: ``(R, t, rms, corners)``,
    ``corners`` None when kept, else the camera's corners in the orders found.

    The corners come in the reference camera's order (:func:`_aligned`), right for cameras
    mounted the same way. A camera mounted turned by 180 degrees sees the board's corners in
    reverse, one turned by 90 degrees in an order that may change from pose to pose. A
    checkerboard turned looks the same, so its own calibration (:func:`intrinsics`) cannot
    tell; but its pose relative to the reference then differs from pose to pose, and the stereo
    fit is poor. A camera whose RMS is above :data:`TURN_TRY_RMS` is given, pose by pose, the
    orders that make its rotation against the reference the same in every pose
    (:func:`turned_orders`), and taken as turned when that at least halves the RMS (an
    upright camera fits at a tenth of a pixel, tried turned at tens of pixels).

    Examples
    --------
    A camera whose images are upside down (every pose's corners in reverse order) fits badly
    as it is; it is found turned, and its corners come back in the upright order:

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0)
    >>> ref, cam = rig.cameras[(0, 0)], rig.cameras[(0, 1)]
    >>> poses = rig.calibration_poses(5, n_shared=5)
    >>> corners = {k: {i: rig.project(k, p.corners_world(rig.board)) for i, p in enumerate(poses)}
    ...            for k in rig.cameras}
    >>> upside_down = {i: c[::-1] for i, c in corners[(0, 1)].items()}
    >>> R, t, rms, found = relative_pose(corners[(0, 0)], upside_down, rig.board, ref.K, ref.dist,
    ...                                  cam.K, cam.dist, rig.image_size)
    >>> bool(rms < 0.01), all(np.array_equal(found[i], corners[(0, 1)][i]) for i in found)
    (True, True)
    >>> bool(np.abs(R - cam.R @ ref.R.T).max() < 1e-4)
    True
    """
    ref_corners, corners, K_ref, d_ref, K, d = _stereo_inputs(ref_corners, corners, board,
                                                              K_ref, d_ref, K, d)
    R, t, rms = extrinsics(ref_corners, corners, board, K_ref, d_ref, K, d, size, label=label)
    if rms <= TURN_TRY_RMS:
        return R, t, rms, None
    trial = turned_orders(ref_corners, corners, board, K_ref, d_ref, K, d)
    if trial.keys() == corners.keys() and all(np.array_equal(trial[p], corners[p]) for p in trial):
        return R, t, rms, None
    Rr, tr, rmsr = extrinsics(ref_corners, trial, board, K_ref, d_ref, K, d, size, label=label)
    return (Rr, tr, rmsr, trial) if rmsr < 0.5 * rms else (R, t, rms, None)


def _board_rotation(corners: np.ndarray, board: BoardSpec, K, d) -> np.ndarray:
    """Rotation of the board in a camera (board -> camera) from one view's corners."""
    import cv2

    obj = board.object_points().astype(np.float64)
    ok, rvec, _ = cv2.solvePnP(obj, corners.astype(np.float64), K, d, flags=cv2.SOLVEPNP_IPPE)
    return cv2.Rodrigues(rvec)[0] if ok else np.full((3, 3), np.nan)


def _angle(A: np.ndarray, B: np.ndarray) -> float:
    """Angle (degrees) of the rotation between ``A`` and ``B``; 180 when undefined."""
    c = (np.trace(A.T @ B) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1, 1)))) if np.isfinite(c) else 180.0


def turned_orders(ref_corners: Mapping, corners: Mapping, board: BoardSpec, K_ref, d_ref, K,
                  d, *, tolerance: float = 30.0) -> dict:
    """A camera's corners per pose in the grid symmetries' orders (:func:`~hyperlf.calibration.
    board.grid_symmetries`) that make its rotation against the reference camera one rotation.

    Each order of each pose the two cameras share gives a candidate rotation from the
    reference to the camera (the board's rotation in the camera, :func:`_board_rotation`,
    times the inverse of its rotation in the reference). Every candidate is tried as the
    camera's rotation; each pose then takes the order nearest it, and the candidate whose
    nearest orders lie closest (angles capped at ``tolerance`` degrees) wins. Poses the
    reference did not see keep the order every shared pose took, and are left out when the
    shared poses took different ones.

    Examples
    --------
    Corners given in reverse (a camera mounted upside down) are put back in the one order that
    gives the same rotation against the reference in every pose:

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0)
    >>> ref, cam = rig.cameras[(0, 0)], rig.cameras[(0, 1)]
    >>> poses = rig.calibration_poses(5, n_shared=5)
    >>> corners = {k: {i: rig.project(k, p.corners_world(rig.board)) for i, p in enumerate(poses)}
    ...            for k in rig.cameras}
    >>> upside_down = {i: c[::-1] for i, c in corners[(0, 1)].items()}
    >>> out = turned_orders(corners[(0, 0)], upside_down, rig.board, ref.K, ref.dist, cam.K,
    ...                     cam.dist)
    >>> sorted(out), all(np.array_equal(out[i], corners[(0, 1)][i]) for i in out)
    ([0, 1, 2, 3, 4], True)
    """
    ref_corners, corners, K_ref, d_ref, K, d = _stereo_inputs(ref_corners, corners, board,
                                                              K_ref, d_ref, K, d)
    tolerance = _opt.number(tolerance, "tolerance", positive=True, at_most=180)
    orders = grid_symmetries(board.cols, board.rows)
    shared = sorted(set(ref_corners) & set(corners))
    if not shared:
        raise InvalidInputError("the camera and the reference never saw the board in the same "
                                "pose; add a pose both see")
    in_ref = {p: _board_rotation(ref_corners[p], board, K_ref, d_ref) for p in shared}
    rel = {p: [_board_rotation(corners[p][s], board, K, d) @ in_ref[p].T for s in orders]
           for p in shared}

    def nearest(A) -> tuple[float, dict]:
        picks = {p: min(range(len(orders)), key=lambda i: _angle(rel[p][i], A)) for p in shared}
        return sum(min(_angle(rel[p][i], A), tolerance) for p, i in picks.items()), picks

    picks = min((nearest(A) for p in shared for A in rel[p]), key=lambda r: r[0])[1]
    out = {p: corners[p][orders[i]] for p, i in picks.items()}
    if len(set(picks.values())) == 1:
        i = next(iter(picks.values()))
        out.update({p: c[orders[i]] for p, c in corners.items() if p not in picks})
    return dict(sorted(out.items()))


def _aligned(corners: Mapping, reference, board: BoardSpec) -> dict:
    """Every camera's corners of every pose in the reference camera's order of that pose
    (:func:`~hyperlf.calibration.board.orders_like`)."""
    out = {k: {} for k in corners}
    for p in sorted({p for c in corners.values() for p in c}):
        seen = orders_like({k: c[p] for k, c in corners.items() if p in c}, reference, board)
        for k, c in seen.items():
            out[k][p] = c
    return out


def _array_axes(centres: np.ndarray) -> np.ndarray:
    """Rows ``x, y, z`` of the rectified frame in reference-camera coordinates."""
    z_ref = np.array([0.0, 0.0, 1.0])
    x_ref = np.array([1.0, 0.0, 0.0])
    cen = centres - centres.mean(0)
    s = np.linalg.svd(cen, full_matrices=False)
    sv, vt = s[1], s[2]
    if len(sv) >= 2 and sv[1] > 0.1 * sv[0]:  # a 2-D spread of cameras fixes the plane
        n = vt[2] if vt.shape[0] > 2 else np.cross(vt[0], vt[1])
    else:  # (nearly) one row of cameras: the plane through the line nearest the image plane
        line = vt[0]
        n = z_ref - (z_ref @ line) * line
    n = n / np.linalg.norm(n)
    if n @ z_ref < 0:
        n = -n
    x = x_ref - (x_ref @ n) * n
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(n, x), n])


def rectification(Ks: Mapping, Rs: Mapping, ts: Mapping, reference, size) -> dict:
    """Rectifying rotations, shared camera matrix, positions (baselines) and baseline.

    Examples
    --------
    The exact intrinsics and poses (against the reference camera) of a synthetic 2 x 3 rig give
    its true positions in the array's frame, and a baseline near its 40-unit pitch:

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(2, 3, seed=0)
    >>> ref = rig.cameras[rig.reference]
    >>> Ks = {k: c.K for k, c in rig.cameras.items()}
    >>> Rs = {k: c.R @ ref.R.T for k, c in rig.cameras.items()}
    >>> ts = {k: c.R @ (ref.centre - c.centre) for k, c in rig.cameras.items()}
    >>> rect = rectification(Ks, Rs, ts, rig.reference, rig.image_size)
    >>> truth = rig.true_positions("array")
    >>> all(np.allclose(rect["positions"][k], truth[k]) for k in rig.cameras)
    True
    >>> bool(abs(rect["baseline"] - 40.0) < 2.0), bool(rect["planarity"] < 1e-9)
    (True, True)
    """
    keys = list(check_keys(Ks, "Ks"))
    for table, what in ((Rs, "Rs"), (ts, "ts")):
        if set(_opt.mapping(table, what, optional=False)) != set(keys):
            raise InvalidInputError(f"Ks, Rs and ts must have the same cameras, got {what} "
                                    f"for {_opt.shown(list(table))}")
    if len(keys) < 2:
        raise InvalidInputError(f"rectification needs at least two cameras, got {len(keys)}")
    check_key(reference, "reference")
    if reference not in Ks:
        raise InvalidInputError(f"reference {_opt.shown(reference)} is not one of the cameras")
    for k in keys:
        _camera_matrix(Ks[k], f"Ks[{k}]")
        R, t = _opt.real_array(Rs[k], f"Rs[{k}]"), _opt.real_array(ts[k], f"ts[{k}]")
        if R.shape != (3, 3) or t.shape != (3,) or not (np.isfinite(R).all()
                                                        and np.isfinite(t).all()):
            raise InvalidInputError(f"camera {k} needs a finite rotation Rs (3, 3) and "
                                    f"translation ts (3,), got shapes {R.shape}, {t.shape}")
    W, H = _image_size(size)
    centres = {k: -Rs[k].T @ ts[k] for k in keys}        # in the reference camera's frame
    C = np.stack([centres[k] for k in keys])
    A = _array_axes(C)
    f = float(np.mean([0.5 * (Ks[k][0, 0] + Ks[k][1, 1]) for k in keys]))
    axis = A @ np.array([0.0, 0.0, 1.0])                  # reference optical axis, rectified
    K_new = np.array([[f, 0, (W - 1) / 2 - f * axis[0] / axis[2]],
                      [0, f, (H - 1) / 2 - f * axis[1] / axis[2]], [0, 0, 1.0]])
    rel = (C - centres[reference]) @ A.T
    dd = np.linalg.norm(rel[:, None] - rel[None], axis=-1)
    np.fill_diagonal(dd, np.inf)
    base = float(np.median(dd.min(axis=1)))
    if not (np.isfinite(base) and base > 0 and np.isfinite(K_new).all()):
        raise InvalidInputError("the cameras' centres coincide or the reference looks along "
                                "the array plane; no rectification")
    return {"K": K_new, "rectify": {k: A @ Rs[k].T for k in keys}, "baseline": base,
            "positions": {k: rel[i, :2] / base for i, k in enumerate(keys)},
            "planarity": float(np.max(np.abs(rel[:, 2])) / base)}


def _refine(corners, board, Ks, ds, Rs, ts, bposes, ref) -> dict:
    """Bundle-adjust all cameras and board poses together; updates ``Ks, ds, Rs, ts`` in place
    and returns each camera's RMS reprojection error and its corner residuals."""
    import cv2

    from .bundle import bundle_adjust

    keys = list(Ks)
    poses = sorted({p for k in keys for p in corners[k]})
    pidx = {p: i for i, p in enumerate(poses)}
    pr, pt = np.zeros((len(poses), 3)), np.zeros((len(poses), 3))
    for p in poses:       # board -> reference, from the reference or any camera that saw it
        k = ref if p in bposes[ref] else next(k for k in keys if p in bposes[k])
        Rb = cv2.Rodrigues(bposes[k][p][0])[0]
        R0, t0 = Rs[k].T @ Rb, Rs[k].T @ (bposes[k][p][1] - ts[k])
        pr[pidx[p]], pt[pidx[p]] = cv2.Rodrigues(R0)[0].ravel(), t0
    intr = np.array([[Ks[k][0, 0], Ks[k][1, 1], Ks[k][0, 2], Ks[k][1, 2], *ds[k][:4]]
                     for k in keys])
    rv = np.array([cv2.Rodrigues(Rs[k])[0].ravel() for k in keys])
    tv = np.array([ts[k] for k in keys])
    obs = [(i, pidx[p], corners[k][p]) for i, k in enumerate(keys) for p in corners[k]]
    res = bundle_adjust(obs, board.object_points(), intr, rv, tv, pr, pt, keys.index(ref))
    for i, k in enumerate(keys):
        fx, fy, cx, cy, k1, k2, p1, p2 = res.intr[i]
        Ks[k] = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
        ds[k] = np.array([k1, k2, p1, p2, 0.0])
        Rs[k], ts[k] = cv2.Rodrigues(res.rvec[i])[0], res.tvec[i].copy()
    errs = {k: float(res.rms[i]) for i, k in enumerate(keys)}
    resid = {k: (res.uv[res.cam == i], res.residuals[res.cam == i]) for i, k in enumerate(keys)}
    return errs, resid


def _turn_report(corners: Mapping, reference, board: BoardSpec, names=None) -> dict:
    """:func:`~hyperlf.calibration.board.turn_report` on each camera's first pose shared with
    the reference."""
    first = {k: min(set(c) & set(corners[reference])) for k, c in corners.items()
             if k != reference}
    return turn_report({k: corners[k][p] for k, p in first.items()},
                       {k: corners[reference][p] for k, p in first.items()}, board, names)


def calibrate_full(shots: Mapping, board: BoardSpec, *, reference=None, names=None,
                   min_poses: int = 3, refine: bool = True) -> Calibration:
    """Calibrate and rectify a planar array from several board poses.

    Parameters
    ----------
    shots : mapping (row, col) -> sequence of ndarray (H, W)
        Board shots per camera, the same poses in the same order for every camera.
    board : BoardSpec
        Its ``square`` sets the unit of the baseline (e.g. mm).
    reference : (int, int), optional
        Default: the centre camera.
    names : mapping, optional
        Camera names for messages.
    min_poses : int
        Fewest poses in which each camera must see the whole board.
    refine : bool
        Bundle-adjust all cameras and board poses together after the per-camera and pairwise
        calibrations (:mod:`~hyperlf.calibration.bundle`); the reported reprojection errors
        are then those of the joint model.

    Returns
    -------
    Calibration
        ``mode="full"``.

    Raises
    ------
    InvalidInputError
        Different numbers of poses per camera, images of different sizes, a grid with holes, or
        a camera with too few detections (named).

    Examples
    --------
    Four board poses rendered by a small synthetic two-camera rig (no scene behind the board):

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=1, image_size=(240, 180), focal=225.0)
    >>> renders = [rig.render(p, salt=i, supersample=1, scene=False)
    ...            for i, p in enumerate(rig.calibration_poses(4, n_shared=4))]
    >>> cal = calibrate_full({k: [r[k] for r in renders] for k in rig.cameras}, rig.board)
    >>> cal.mode, cal.grid, cal.reference, cal.info["poses"]
    ('full', (1, 2), (0, 0), 4)

    The baseline is the distance between the rig's two camera centres (board units), and each
    camera's focal length its own:

    >>> true_baseline = np.linalg.norm(rig.cameras[(0, 1)].centre - rig.cameras[(0, 0)].centre)
    >>> bool(abs(cal.baseline - true_baseline) < 1.0)
    True
    >>> all(bool(abs(cal.cameras[k].K[0, 0] / c.K[0, 0] - 1) < 0.03)
    ...     for k, c in rig.cameras.items())
    True
    """
    min_poses = _opt.integer(min_poses, "min_poses", 3)
    refine = _opt.flag(refine, "refine")
    check_board(board)
    _opt.mapping(names, "names")
    grid, ref = check_grid(_opt.mapping(shots, "shots", optional=False).keys(), reference)
    counts = {len(v) for v in shots.values()}
    if len(counts) != 1:
        per = ", ".join(f"{camera_label(k, names)}: {len(v)}" for k, v in shots.items())
        raise InvalidInputError(f"every camera needs the same number of board shots ({per})")
    flat = {(k, i): img for k, imgs in shots.items() for i, img in enumerate(imgs)}
    size = check_images(flat, None, what="board shot")
    corners = _aligned(detect_poses(shots, board, names=names, min_poses=min_poses), ref, board)
    Ks, ds, errs, bposes = {}, {}, {}, {}
    for k in shots:
        Ks[k], ds[k], errs[k], bposes[k] = intrinsics(corners[k], board, size)
    Rs, ts, stereo = {ref: np.eye(3)}, {ref: np.zeros(3)}, {}
    for k in (k for k in shots if k != ref):
        Rs[k], ts[k], stereo[k], found = relative_pose(
            corners[ref], corners[k], board, Ks[ref], ds[ref], Ks[k], ds[k], size,
            label=camera_label(k, names))
        if found is not None:       # its board poses follow the corners' new orders
            corners[k] = found
            Ks[k], ds[k], errs[k], bposes[k] = intrinsics(corners[k], board, size)
    resid = {}
    if refine:
        errs, resid = _refine(corners, board, Ks, ds, Rs, ts, bposes, ref)
    rect = rectification(Ks, Rs, ts, ref, size)
    base = np.array([ref[1], ref[0]], np.float64)
    cams = {k: CameraCalibration(name=camera_label(k, names), position=base + rect["positions"][k],
                                 reprojection_error=errs[k], K=Ks[k], dist=ds[k], R=Rs[k], t=ts[k],
                                 rectify=rect["rectify"][k]) for k in shots}
    info = {"stereo_rms": {f"{k[0]},{k[1]}": v for k, v in stereo.items()},
            "planarity": rect["planarity"], "poses": int(counts.pop()),
            **_turn_report(corners, ref, board, names)}
    return Calibration(mode="full", grid=grid, reference=ref, image_size=size, output_size=size,
                       camera_matrix=rect["K"], cameras=cams, board=board,
                       baseline=rect["baseline"], info=info, residuals=resid,
                       corners={k: corners[k].get(0) for k in shots})
