"""Plane registration of a camera array from one board pose (SPEC §11).

Stages (each a function):

1. :func:`~hyperlf.calibration.board.detect_boards`: the board's corners in every camera (a
   board partly out of some views is accepted: the corners they miss are left out below), put
   in the reference camera's order (:func:`~hyperlf.calibration.board.orders_like`).
2. :func:`board_homographies`: each camera's homography onto the reference view at the board
   plane, and its RMS corner residual.
3. :func:`board_geometry`: one pinhole model fitted to all shots (shared focal length, principal
   point at the image centre) gives every camera's pose relative to the board; the camera
   centres, expressed in the reference camera's axes, are a first, rough estimate of the
   positions (rotations and an assumed principal point blur it) and fix the physical sign.
   A board facing the cameras squarely leaves the focal length undetermined; the poses are
   then solved at a short one (:data:`UNDETERMINED_FOCAL`), which keeps the centres' error
   within the shift the cameras' own small rotations make.
4. :func:`parallax_offsets`: the parallax of off-board scene content in the registered views,
   factored into ``-d(x) (p_v - p_ref)`` (:mod:`~hyperlf.calibration.parallax`): the offsets'
   directions and relative lengths, free of the rotations that confound the board's raw shift.
   Before the homographies, :func:`turned_cameras` finds cameras mounted turned by 90, 180 or
   270 degrees (their corners come in another of the grid's symmetric orders, which the board
   alone cannot tell) by the same matching.
5. :func:`resolve_positions`: scale (median nearest-neighbour distance = one baseline) and sign
   (the one that agrees with the board-pose centres, so that ``d_rel = f B (1/Z - 1/Z_board)``
   is positive for points nearer than the board). Parallax whose common model fits some
   view loosely (:data:`MISFIT_SHARE`) is not taken; agreement with the centres below
   :data:`SIGN_AGREEMENT_MIN` is reported (``hyperlf calibrate`` says it).

The user's description of the array (which name is where) is never used for geometry: a
mirrored or rotated naming gives the same physical positions under the other names.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .. import _options as _opt
from ..errors import InvalidInputError
from .board import (BoardSpec, camera_label, check_board, check_corner_sets, check_corners,
                    check_key, check_keys, detect_boards, grid_symmetries, image_turn, orders_like,
                    turn_report)
from .grid import check_grid, check_images
from .model import Calibration, CameraCalibration
from .parallax import (SEARCH_DEFAULTS, SEARCH_RULES, factor_rank1, feature_image,
                       fitting_entries, hub_camera, match_flows, select_points)

__all__ = ["register_plane", "board_homographies", "board_geometry", "parallax_offsets",
           "turned_cameras", "resolve_positions", "board_outline"]


#: Fewest board corners a camera must share with the reference view (a board partly out of
#: view in either): a homography has 8 degrees of freedom, and the residual should mean
#: something.
MIN_SHARED_CORNERS = 9


def _seen(points: np.ndarray) -> np.ndarray:
    """Which board corners a camera saw (unseen ones are NaN)."""
    return np.all(np.isfinite(points), axis=1)


def _in(key, table: Mapping, label: str = "reference"):
    """``key`` when ``table`` has it (a camera of the array)."""
    check_key(key, label)
    if key not in table:
        raise InvalidInputError(f"{label} {_opt.shown(key)} is not one of the cameras")
    return key


def _corner_table(corners) -> Mapping:
    """``corners``: a non-empty mapping camera -> ``(N, 2)`` corners, one ``N`` for all (NaN:
    unseen)."""
    check_keys(corners, "corners")
    shapes = set()
    for k, c in corners.items():
        a = _opt.real_array(c, f"corners[{_opt.shown(k)}]")
        if a.ndim != 2 or a.shape[1] != 2 or np.isinf(a).any():
            raise InvalidInputError(f"corners[{_opt.shown(k)}] must be (N, 2) pixels, finite or "
                                    f"NaN (unseen), got shape {a.shape}")
        shapes.add(a.shape)
    if len(shapes) != 1:
        raise InvalidInputError(f"every camera's corners must be of one board, got shapes "
                                f"{sorted(shapes)}")
    return corners


def board_homographies(corners: Mapping, reference, names: Mapping | None = None
                       ) -> tuple[dict, dict, dict]:
    """Homography (raw -> reference), RMS corner residual (px) and the residual vectors
    (reference corners, mapped minus reference) of every camera, on the corners both saw.

    Examples
    --------
    The exact corners of one board pose in a two-camera rig without lens distortion (a
    homography cannot undo distortion): each homography maps its camera's corners onto the
    reference's.

    >>> import cv2
    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0, distortion=0.0)
    >>> pose = rig.board_pose(450.0, tilt=(15.0, -10.0, 3.0))
    >>> corners = {k: rig.project(k, pose.corners_world(rig.board)) for k in rig.cameras}
    >>> Hs, errors, residuals = board_homographies(corners, (0, 0))
    >>> Hs[(0, 0)].tolist()
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    >>> mapped = cv2.perspectiveTransform(corners[(0, 1)].reshape(-1, 1, 2), Hs[(0, 1)])
    >>> bool(np.abs(mapped.reshape(-1, 2) - corners[(0, 0)]).max() < 1e-3)
    True
    >>> bool(errors[(0, 1)] < 1e-3), residuals[(0, 1)][1].shape
    (True, (48, 2))
    """
    import cv2

    _corner_table(corners)
    _opt.mapping(names, "names")
    dst = corners[_in(reference, corners)]
    Hs, errs, resid = {}, {}, {}
    for key, pts in corners.items():
        both = _seen(pts) & _seen(dst)
        if both.sum() < MIN_SHARED_CORNERS:
            raise InvalidInputError(
                f"camera {camera_label(key, names)} sees only {int(both.sum())} of the board's "
                f"inner corners that the reference view sees (at least {MIN_SHARED_CORNERS} "
                "needed); place the board where every camera sees most of it")
        H = np.eye(3) if key == reference else cv2.findHomography(pts[both], dst[both], 0)[0]
        if H is None:
            raise InvalidInputError(
                f"no homography from camera {camera_label(key, names)} onto the reference: the "
                "board's corners are degenerate there")
        H = H / H[2, 2]
        proj = cv2.perspectiveTransform(pts[both].reshape(-1, 1, 2), H).reshape(-1, 2)
        Hs[key] = H
        errs[key] = float(np.sqrt(np.mean(np.sum((proj - dst[both]) ** 2, axis=1))))
        resid[key] = (dst[both].copy(), proj - dst[both])
    return Hs, errs, resid


#: Relative standard deviation above which a board pose does not determine the focal length.
FOCAL_TOLERANCE = 0.05

#: Standard deviation (px) of the focal length below which OpenCV's figure means a singular
#: problem, not a precise one: corners found to a tenth of a pixel never fix a focal length to
#: a thousandth. A board facing the cameras squarely gives 1e-7 px (or exactly 0).
SINGULAR_FOCAL_STD = 1e-3

#: Focal length (as a fraction of the larger image side) at which the board poses are solved
#: when the board leaves the focal length undetermined. A focal length guessed ``k`` times too
#: long moves a camera's centre by ``(k^2 - 1)`` times the shift its own small rotation makes;
#: one shorter than the true one moves it by less than that shift, whatever the lens. The
#: poses then still give the physical direction (the positions' sign) and the board-only
#: positions; metric figures are left out for such a board anyway.
UNDETERMINED_FOCAL = 0.5


def board_geometry(corners: Mapping, board: BoardSpec, image_size, reference, *,
                   focal_px: float | None = None) -> dict:
    """Board poses from one shared pinhole model (principal point at the image centre).

    Returns a dict with ``focal`` (px), ``centres`` (camera centres in the reference camera's
    axes, board units, keyed like ``corners``), ``plane`` (the board plane ``(n, dist)`` in
    the reference frame) and ``rms`` (px).

    Examples
    --------
    An ideal two-camera rig (``imperfect=0``: focal length 300 px, principal point at the image
    centre, no distortion, cameras 40 units apart) and the exact corners of a tilted board:

    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 2, seed=0, imperfect=0.0)
    >>> pose = rig.board_pose(450.0, tilt=(15.0, -10.0, 3.0))
    >>> corners = {k: rig.project(k, pose.corners_world(rig.board)) for k in rig.cameras}
    >>> geo = board_geometry(corners, rig.board, rig.image_size, (0, 0))
    >>> bool(abs(geo["focal"] - 300.0) < 0.01)
    True
    >>> bool(np.allclose(geo["centres"][(0, 1)], [40.0, 0.0, 0.0], atol=1e-3))
    True

    The board plane ``n . X = dist`` in the reference camera's frame (here the world's):

    >>> n = pose.R[:, 2]
    >>> bool(np.allclose(geo["plane"], [*n, n @ pose.t], atol=1e-4))
    True
    """
    import cv2

    check_board(board)
    check_corner_sets(corners, "corners", board)
    _in(reference, corners)
    W, H = _opt.int_pair(image_size, "image_size", 1, what="(W, H) of the images")
    focal_px = _PLANE_RULES["focal_px"](focal_px, "focal_px")
    keys = list(corners)
    f0 = float(focal_px) if focal_px else float(max(W, H))
    K0 = np.array([[f0, 0, (W - 1) / 2], [0, f0, (H - 1) / 2], [0, 0, 1.0]])
    flags = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_PRINCIPAL_POINT
             | cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K1
             | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3)
    if focal_px:
        flags |= cv2.CALIB_FIX_FOCAL_LENGTH
    obj = board.object_points().astype(np.float32)
    seen = {k: _seen(corners[k]) for k in keys}
    rms, K, _, rvecs, tvecs, std, _, _ = cv2.calibrateCameraExtended(
        [obj[seen[k]] for k in keys],
        [corners[k][seen[k]].astype(np.float32).reshape(-1, 1, 2) for k in keys],
        (W, H), K0, np.zeros(5), flags=flags)
    rot = {k: cv2.Rodrigues(rv)[0] for k, rv in zip(keys, rvecs)}
    trans = {k: tv.ravel() for k, tv in zip(keys, tvecs)}
    world = {k: -rot[k].T @ trans[k] for k in keys}          # centres in board coordinates
    Rref = rot[reference]
    centres = {k: Rref @ (world[k] - world[reference]) for k in keys}
    n = Rref[:, 2]                                            # board normal in the ref frame
    dist = float(n @ trans[reference])
    if dist < 0:
        n, dist = -n, -dist
    # with a fixed aspect ratio OpenCV reports the focal length's deviation at fy
    focal_std = 0.0 if focal_px else float(np.max(np.ravel(std)[:2]))
    return {"focal": float(K[0, 0]), "centres": centres, "plane": np.append(n, dist),
            "rms": float(rms), "focal_std": focal_std}


def board_outline(corners: np.ndarray, board: BoardSpec, *, margin: float = 1.6) -> np.ndarray:
    """Image polygon ``(4, 2)`` of the board including ``margin`` squares around its corners.

    Examples
    --------
    A 3 x 3 board whose corners lie 10 px apart in the image, outlined one square beyond them:

    >>> j, i = np.mgrid[0:3, 0:3]
    >>> corners = np.stack([10.0 * i + 50, 10.0 * j + 50], -1).reshape(-1, 2)
    >>> np.round(board_outline(corners, BoardSpec(3, 3), margin=1.0), 3).tolist()
    [[40.0, 40.0], [80.0, 40.0], [80.0, 80.0], [40.0, 80.0]]
    """
    import cv2

    check_board(board)
    corners = check_corners(corners, "corners", board)
    margin = _opt.number(margin, "margin", at_most=1e3)  # squares
    seen = _seen(corners)
    if seen.sum() < 4:
        raise InvalidInputError(f"corners must hold at least 4 seen corners, got {seen.sum()}")
    obj = board.object_points()[:, :2] / board.square
    Hb, _ = cv2.findHomography(obj[seen], corners[seen], 0)
    quad = np.array([[-margin, -margin], [board.cols - 1 + margin, -margin],
                     [board.cols - 1 + margin, board.rows - 1 + margin],
                     [-margin, board.rows - 1 + margin]], np.float64)
    return cv2.perspectiveTransform(quad.reshape(-1, 1, 2), Hb).reshape(-1, 2)


def _registered(images: Mapping, Hs: Mapping, scale: float, size,
                cache: dict | None = None) -> tuple[dict, dict]:
    """Feature images and validity of every view registered onto the reference, at ``scale``
    (taken from ``cache`` where it holds the view under the same warp; it keeps one warp per
    view, the latest, so that trials of many orders do not pile up images)."""
    import cv2

    W, H = size
    S = np.diag([scale, scale, 1.0])
    out_size = (max(1, int(round(W * scale))), max(1, int(round(H * scale))))
    feats, valid = {}, {}
    cache = {} if cache is None else cache
    for key, img in images.items():
        M = S @ Hs[key]
        known = cache.get(("registered", key))
        if known is not None and known[0] == M.tobytes():
            feats[key], valid[key] = known[1:]
            continue
        src = np.asarray(img, np.float32)
        warped = cv2.warpPerspective(src, M, out_size, flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_REPLICATE)
        inside = cv2.warpPerspective(np.ones(src.shape, np.uint8), M, out_size,
                                     flags=cv2.INTER_NEAREST, borderValue=0)
        feats[key] = feature_image(warped)
        valid[key] = cv2.erode(inside, np.ones((5, 5), np.uint8)) > 0
        cache[("registered", key)] = M.tobytes(), feats[key], valid[key]
    return feats, valid


def parallax_offsets(images: Mapping, Hs: Mapping, corners_ref: np.ndarray, board: BoardSpec,
                     reference, *, work_size: int = SEARCH_DEFAULTS["work_size"],
                     max_parallax: float = SEARCH_DEFAULTS["max_parallax"]) -> dict:
    """Offsets ``p_v - p_ref`` (px per unit ``d``, common scale and sign free) from parallax.

    The flows are matched from the camera nearest the grid's centre (:func:`~hyperlf.calibration.parallax.hub_camera`; the
    reference unless it lies off-centre) to every other, all registered onto the reference,
    and the offsets then shifted so that the reference's is zero. A view the common parallax
    model fits at few points (a camera two or more baselines from the hub, whose parallax
    lies beyond ``max_parallax``) is matched again with a wider radius
    (:data:`FAR_VIEW_GROWTH`).

    Parameters
    ----------
    images : mapping key -> (H, W) raw shots (the board shot itself works: the scene around
        the board is off the plane).
    Hs : mapping key -> homography raw -> reference.
    corners_ref : the board's corners in the reference view (to leave the board out).
    board : BoardSpec
    reference : key of the reference camera.
    work_size : int
        Images are matched at a scale whose larger side is at most this many px.
    max_parallax : float
        Search radius as a fraction of the larger image side (a view it does not reach is
        searched again up to three times as far).

    Returns
    -------
    dict with ``offsets`` (key -> (2,) in full-resolution px per unit d, NaN if unknown),
    ``n_points``, ``rms`` (px), ``median_flow`` (px), ``d`` (per point), ``consistent``
    (key -> at how many points that view's flow fits the common parallax model, by the
    model's own residual spread), ``fitting`` (the same within a fixed tolerance,
    :func:`~hyperlf.calibration.parallax.fitting_entries`: counts that compare between
    models) and ``measured`` (at how many points the view's flow was measured at all).

    Examples
    --------
    One board shot per camera of a small synthetic 1 x 3 rig; the scene around the board gives
    the outer cameras' offsets, which point along the rig's true positions (up to the free
    scale and sign):

    >>> from hyperlf.calibration.board import detect_boards, orders_like
    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(1, 3, seed=1, imperfect=0.3, image_size=(160, 120), focal=150.0)
    >>> pose = rig.board_pose(450.0, tilt=(10.0, -8.0, 3.0))
    >>> shots = rig.render(pose, supersample=2)
    >>> corners = orders_like(detect_boards(shots, rig.board), (0, 1), rig.board)
    >>> Hs = board_homographies(corners, (0, 1))[0]
    >>> par = parallax_offsets(shots, Hs, corners[(0, 1)], rig.board, (0, 1))
    >>> par["offsets"][(0, 1)].tolist(), bool(par["n_points"] >= 8)
    ([0.0, 0.0], True)
    >>> truth = rig.true_positions()
    >>> found = np.stack([par["offsets"][k] for k in truth])
    >>> exact = np.stack(list(truth.values()))
    >>> cosine = np.sum(found * exact) / (np.linalg.norm(found) * np.linalg.norm(exact))
    >>> bool(abs(cosine) > 0.99)
    True
    """
    W, H = check_images(images, what="image")
    _in(reference, images)
    check_board(board)
    corners_ref = check_corners(corners_ref, "corners_ref", board)
    _opt.mapping(Hs, "Hs", optional=False)
    for k in images:
        h = _opt.real_array(Hs.get(k), f"the homography of camera {camera_label(k)}")
        if h.shape != (3, 3) or not np.isfinite(h).all():
            raise InvalidInputError(f"Hs must hold a finite 3 x 3 homography for every camera "
                                    f"of images; camera {camera_label(k)}'s is {_opt.shown(h)}")
    o = _opt.check_values(dict(work_size=work_size, max_parallax=max_parallax), SEARCH_RULES)
    return _parallax(images, Hs, corners_ref, board, reference, (W, H), o["work_size"],
                     o["max_parallax"])


def _parallax(images: Mapping, Hs: Mapping, corners_ref: np.ndarray, board: BoardSpec,
              reference, size, work_size: int, max_parallax: float,
              cache: dict | None = None) -> dict:
    """:func:`parallax_offsets` on checked arguments; ``cache`` (a dict kept between calls
    on the same shots) holds each view's latest registration and its flows by its
    homography and the hub's, so that trying one camera's corner order again recomputes
    only that camera's."""
    import cv2

    W, H = size
    cache = {} if cache is None else cache
    scale = min(1.0, work_size / max(W, H))
    feats, valid = _registered(images, Hs, scale, (W, H), cache)
    hub = hub_camera(images, reference)  # matched from: the reference unless it is off-centre
    h, w = feats[hub].shape
    allowed = np.ones((h, w), np.uint8)
    cv2.fillConvexPoly(allowed, np.round(board_outline(corners_ref, board) * scale)
                       .astype(np.int32), 0)
    allowed &= valid[hub].astype(np.uint8)
    half = max(5, int(round(max(h, w) / 60)))
    radius = max(6, int(round(max_parallax * max(h, w))))
    pts = select_points(feats[hub], allowed > 0, spacing=half)
    others = [k for k in images if k != hub]

    warps = {k: (k, Hs[k].tobytes(), Hs[hub].tobytes()) for k in others}   # cache keys

    def match(k, grow=1):  # a wider search is cut to the image, not refused at its border
        key = ("flows", grow, *warps[k])
        if key not in cache:
            cache[key] = match_flows(feats[hub], feats[k], pts, valid[k], half=half,
                                     radius=grow * radius, clip=grow > 1)[0]
        return cache[key]

    # a view matched wider once keeps that while its registration and the hub's stay: so
    # that another camera's trial order is not judged by this view's search radius
    grown = [cache.get(("grown", *warps[k]), 1) for k in others]
    flows = (np.stack([match(k, g) for k, g in zip(others, grown)]) if len(pts)
             else np.zeros((len(others), 0, 2)))
    flows, fac = _reach_far_views(flows, factor_rank1(flows), lambda i, g: match(others[i], g),
                                  grown)
    for k, g in zip(others, grown):
        cache[("grown", *warps[k])] = g
    consistent, fitting = {hub: len(pts)}, {hub: len(pts)}
    consistent.update({k: int(n) for k, n in zip(others, fac.inliers.sum(1))})
    measured = {hub: len(pts), **{k: int(n) for k, n in
                                  zip(others, np.isfinite(flows).all(-1).sum(1))}}
    fitting.update({k: int(n) for k, n in
                    zip(others, fitting_entries(flows, fac.d, fac.offsets).sum(1))})
    found = dict(zip(others, fac.offsets))   # p_k - p_hub, in the reference's axes
    found[hub] = np.zeros(2)
    offsets = {reference: np.zeros(2)}
    for k in images:
        if k != reference:
            offsets[k] = (found[k] - found[reference]) / scale
    used = fac.inliers.any(0)
    med = float(np.median(np.abs(flows[fac.inliers]))) / scale if fac.inliers.any() else 0.0
    spacing = nearest_spacing(np.stack(list(offsets.values())))
    reach = float(np.percentile(np.abs(fac.d[used]), 99)) * spacing if used.any() else np.nan
    return {"offsets": offsets, "n_points": int(used.sum()), "rms": fac.rms / scale
            if np.isfinite(fac.rms) else np.nan, "median_flow": med, "d": fac.d,
            "reach": reach, "consistent": consistent, "fitting": fitting,
            "measured": measured}


#: How many times the search radius a view that the first radius may not reach is matched
#: again with, in turn (:func:`_reach_far_views`).
FAR_VIEW_GROWTH = (2, 3)


def _reach_far_views(flows: np.ndarray, fac, match, grown: list, *, share: float = 0.5):
    """A camera two or more baselines from the hub sees the scene move two or more times as
    far as its neighbours do, beyond a search radius that suits them: its flows are then
    mismatches or missing, and the common model fits few of its points. Each view consistent
    at fewer than ``share`` of the median view's points is matched again with the radius
    times :data:`FAR_VIEW_GROWTH` in turn (``match(i, growth)``; a view already matched at a
    growth, ``grown[i]``, only with larger ones), and the flows are kept when the model then
    fits more entries in all. Returns ``(flows, factorisation)``; ``grown`` is updated."""
    for grow in FAR_VIEW_GROWTH:
        counts = fac.inliers.sum(1)
        weak = [i for i in (np.flatnonzero(counts < share * np.median(counts)) if counts.size
                            else []) if grown[i] < grow]
        if not weak:
            continue
        wider = flows.copy()
        for i in weak:
            wider[i] = match(int(i), grow)
        refit = factor_rank1(wider)
        if refit.inliers.sum() > fac.inliers.sum():
            flows, fac = wider, refit
            for i in weak:
                grown[i] = grow
    return flows, fac


#: Share of the entries the common parallax model keeps for a view that it must fit within
#: the fixed tolerance (:func:`_misfit`): below it the model is loose there, spread by wrong
#: flows; :func:`turned_cameras` then tries other corner orders, and the positions are not
#: taken from such a model.
MISFIT_SHARE = 0.5


def turned_cameras(shots: Mapping, corners: Mapping, board: BoardSpec, reference, *,
                   names=None, share: float = MISFIT_SHARE, suspect_rms: float = 2.0,
                   **search) -> tuple[list, dict, dict]:
    """Cameras whose images are turned against the reference's (by 90, 180 or 270 degrees).

    Every camera's corners come in the reference camera's order (:func:`~hyperlf.calibration.
    board.orders_like`), which is right for cameras mounted the same way. A camera mounted
    turned gets another of the grid's symmetric orders (:func:`~hyperlf.calibration.board.
    grid_symmetries`), and as a checkerboard looks the same turned, its homography fits the
    board as well as the right one would, but turns or mirrors the scene around the board.
    Such a view's parallax fits the other views' common model (:func:`parallax_offsets`) at
    few points within a fixed tolerance (its ``fitting`` count), or spoils the model's fit.

    A camera is a suspect when it fits at fewer than ``share`` of the other views' median
    count, when it fits fewer than ``share`` of the points the model keeps for it (a loose
    model, spread by wrong flows), when it fits fewer than :data:`TURN_MIN_POINTS` of the
    many points its flows were measured at, or when no order lines its board up with the
    reference's (a quarter turn of a board that is not square). Suspects are tried, alone,
    in each of the other orders, the least fitting first; then, while the model's RMS
    residual is above ``suspect_rms`` px or a view is loose or fits that few, the other
    cameras too. A camera
    takes its best order when that order fits at least twice its points and 8 or more,
    without fewer fitting points in all. When most cameras are suspects, every camera but
    the reference is first tried in each order at once (the reference itself turned), else
    last if the model is still poor; that is taken when it at least doubles the points that
    fit in all, and leaves neither a residual above ``suspect_rms`` nor a loose view. (An
    upright camera tried turned keeps almost no fitting point.)

    Parameters
    ----------
    shots, corners : mapping key -> board shot, corners (the reference's order)
    board : BoardSpec
    reference : key of the reference camera
    names : mapping, optional
    share : float
        Share of the entries the model keeps for a view that it must fit (default
        :data:`MISFIT_SHARE`), and of the median view's fitting count.
    suspect_rms : float
        RMS residual (px) above which the common model is poor.
    **search
        ``work_size``, ``max_parallax`` of :func:`parallax_offsets`.

    Returns
    -------
    turned : list of keys
        The cameras put in another order.
    parallax : dict
        :func:`parallax_offsets` of the views with those cameras turned back (what the
        positions are measured from; not computed again).
    corners : dict
        ``corners`` with the turned cameras' in their found order.

    Examples
    --------
    A small synthetic 2 x 2 rig whose camera ``(1, 1)`` is mounted upside down: its corners,
    put in the reference's order, run the wrong way round, and are turned back:

    >>> import dataclasses
    >>> from hyperlf.calibration.board import detect_boards, orders_like
    >>> from hyperlf.calibration.rig import make_rig, rotation_matrix
    >>> rig = make_rig(2, 2, seed=0, imperfect=0.3, image_size=(160, 120), focal=150.0)
    >>> cam = rig.cameras[(1, 1)]
    >>> rig.cameras[(1, 1)] = dataclasses.replace(cam, R=rotation_matrix(0, 0, 180) @ cam.R)
    >>> shots = rig.render(rig.board_pose(450.0, tilt=(10.0, -8.0, 3.0)), supersample=2)
    >>> corners = orders_like(detect_boards(shots, rig.board), (0, 0), rig.board)
    >>> turned, parallax, fixed = turned_cameras(shots, corners, rig.board, (0, 0))
    >>> turned, bool(np.array_equal(fixed[(1, 1)], corners[(1, 1)][::-1]))
    ([(1, 1)], True)
    """
    check_board(board)
    size = check_images(shots, names, what="board shot")
    check_corner_sets(corners, "corners", board)
    _in(reference, corners)
    if set(shots) != set(corners):
        raise InvalidInputError("shots and corners must have the same cameras")
    _opt.mapping(names, "names")
    share = _opt.share(share, "share")
    suspect_rms = _opt.number(suspect_rms, "suspect_rms", positive=True)
    unknown = set(search) - set(SEARCH_RULES)
    if unknown:
        raise InvalidInputError(f"turned_cameras takes the search options "
                                f"{', '.join(SEARCH_RULES)}, got {', '.join(map(str, unknown))}")
    search = {**SEARCH_DEFAULTS, **_opt.check_values(search, SEARCH_RULES)}
    cache: dict = {}        # each view's registration and flows, by its homography

    def parallax(c) -> dict:
        Hs = board_homographies(c, reference, names)[0]
        return _parallax(shots, Hs, c[reference], board, reference, size,
                         search["work_size"], search["max_parallax"], cache)

    others = [k for k in corners if k != reference]
    orders = grid_symmetries(board.cols, board.rows)[1:]
    now, best = dict(corners), parallax(corners)
    suspects = _turn_suspects(best, corners, others, reference, board, share)
    whole = 2 * len(suspects) > len(others) > 1     # most look turned: the reference may be
    if whole:
        now, best = _reference_turned(now, best, others, board, parallax, suspect_rms, share)
        suspects = _turn_suspects(best, now, others, reference, board, share)
    for k in suspects + [k for k in others if k not in suspects]:
        if k not in suspects and not _model_poor(best, others, suspect_rms, share):
            break
        trials = [{**now, k: now[k][s]} for s in orders]    # one camera at a time
        pars = [parallax(t) for t in trials]
        i = int(np.argmax([p["fitting"][k] for p in pars]))
        if _better_order(pars[i], best, k, others):
            now, best = trials[i], pars[i]
    if not whole and len(others) > 1 and _model_poor(best, others, suspect_rms, share):
        now, best = _reference_turned(now, best, others, board, parallax, suspect_rms, share)
    turned = [k for k in others if not np.array_equal(now[k], corners[k])]
    return turned, best, now


#: The fewest points a camera's new order must fit (:func:`turned_cameras`), as many as a
#: parallax measurement needs to be used at all.
TURN_MIN_POINTS = 8


def _fitting_total(par: dict, keys) -> int:
    return int(sum(par["fitting"][k] for k in keys))


def _turn_suspects(par: dict, corners: Mapping, others: list, reference, board: BoardSpec,
                   share: float) -> list:
    """The cameras :func:`turned_cameras` tries first, the least fitting first."""
    fit = par["fitting"]
    floor = share * float(np.median([fit[k] for k in others])) if others else 0.0
    sus = [k for k in others if fit[k] < floor or _misfit(par, k, share)
           or image_turn(corners[k], corners[reference], board)]
    return sorted(sus, key=fit.get)


def _misfit(par: dict, k, share: float) -> bool:
    """Whether the model fits view ``k`` badly: fewer than ``share`` of the points it keeps
    for it (a loose model), or fewer than :data:`TURN_MIN_POINTS` of flows measured at
    that many times as many points (texture matched, but not as parallax)."""
    fit = par["fitting"][k]
    return bool(fit < share * par["consistent"][k]
                or fit < TURN_MIN_POINTS <= par["measured"][k] / TURN_MIN_POINTS)


def _model_poor(par: dict, others: list, suspect_rms: float, share: float) -> bool:
    """A residual above ``suspect_rms`` px, or a view the model fits badly (:func:`_misfit`)."""
    return bool(par["rms"] > suspect_rms or any(_misfit(par, k, share) for k in others))


def _better_order(trial: dict, best: dict, k, others: list) -> bool:
    """Whether camera ``k``'s trial order fits at least twice its points (and
    :data:`TURN_MIN_POINTS`), without fewer fitting points over all the cameras."""
    got = trial["fitting"][k]
    return (got >= max(TURN_MIN_POINTS, 2 * best["fitting"][k])
            and _fitting_total(trial, others) >= _fitting_total(best, others))


def _reference_turned(now: dict, best: dict, others: list, board: BoardSpec, parallax,
                      suspect_rms: float, share: float):
    """Every camera but the reference tried in each order at once; the best taken when it
    at least doubles the points that fit over all of them, fits :data:`TURN_MIN_POINTS` or
    more per camera, and leaves a model that is not poor (:func:`_model_poor`). Returns
    ``(corners, parallax)``.

    The others are first put in the order of the one that fits most: against a reference
    turned by a quarter, a board that is not square runs either way along the others'
    rows, and each of them may have taken another of the two."""
    pivot = max(others, key=best["fitting"].get)
    aligned = orders_like({k: now[k] for k in others}, pivot, board)
    trials = [{**now, **{k: aligned[k][s] for k in others}}
              for s in grid_symmetries(board.cols, board.rows)]
    pars = [parallax(t) for t in trials]
    totals = [_fitting_total(p, others) for p in pars]
    i = int(np.argmax(totals))
    if totals[i] >= max(TURN_MIN_POINTS * len(others), 2 * _fitting_total(best, others)) \
            and not _model_poor(pars[i], others, suspect_rms, share):
        return trials[i], pars[i]
    return now, best


def nearest_spacing(offsets: np.ndarray) -> float:
    """Median distance from a camera to its nearest neighbour, for offsets ``(N, 2)``."""
    o = np.asarray(offsets, np.float64)
    dd = np.linalg.norm(o[:, None] - o[None], axis=-1)
    np.fill_diagonal(dd, np.inf)
    return float(np.median(dd.min(axis=1)))


#: Cosine between the offsets from parallax and the board poses' centres below which the
#: poses do not tell the positions' sign (near from far) with confidence; ``hyperlf
#: calibrate`` then says so.
SIGN_AGREEMENT_MIN = 0.5


def resolve_positions(offsets: Mapping, pose_centres: Mapping, reference) -> tuple[dict, float]:
    """Positions (baselines, reference at ``(0, 0)``) and the sign-consistency score.

    ``offsets`` (any common scale and sign) are scaled so that the median distance from a
    camera to its nearest neighbour is 1, and signed to agree with the board-pose centres'
    ``(x, y)`` (the physical direction). The score is the cosine between the two sets of
    offsets: near 1 when they agree, near 0 when the pose centres cannot tell the sign.

    Examples
    --------
    Offsets of a row of three cameras at an arbitrary scale and with the opposite sign of the
    board-pose centres; they become positions one baseline apart, signed like the centres:

    >>> offsets = {(0, 0): np.array([0.0, 0.0]), (0, 1): np.array([-2.0, 0.0]),
    ...            (0, 2): np.array([-4.0, 0.0])}
    >>> centres = {(0, 0): np.zeros(3), (0, 1): np.array([40.0, 1.0, 0.0]),
    ...            (0, 2): np.array([80.0, -1.0, 0.0])}
    >>> positions, agreement = resolve_positions(offsets, centres, (0, 0))
    >>> [(positions[k] + 0.0).tolist() for k in sorted(positions)]   # + 0.0: no -0.0
    [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]
    >>> round(float(agreement), 3)
    1.0
    """
    check_keys(offsets, "offsets")
    check_keys(pose_centres, "pose_centres")
    _in(reference, offsets)
    for k in offsets:
        o, c = _opt.real_array(offsets[k], "offsets"), _opt.real_array(pose_centres.get(k),
                                                                         "pose_centres")
        if o.shape != (2,) or c.ndim != 1 or len(c) < 2 or not (np.isfinite(o).all()
                                                                and np.isfinite(c[:2]).all()):
            raise InvalidInputError(f"offsets and pose_centres must hold finite (x, y) for "
                                    f"every camera; camera {camera_label(k)} has "
                                    f"{_opt.shown(offsets[k])} and {_opt.shown(pose_centres.get(k))}")
    keys = list(offsets)
    o = np.stack([offsets[k] for k in keys])
    c = np.stack([np.asarray(pose_centres[k])[:2] for k in keys])
    b = nearest_spacing(o)
    if not np.isfinite(b) or b <= 0:
        raise InvalidInputError("the cameras' offsets are degenerate (all at one place)")
    dot = float(np.sum(o * c))
    cos = dot / max(np.linalg.norm(o) * np.linalg.norm(c), 1e-12)
    sign = 1.0 if dot >= 0 else -1.0
    return {k: sign * o[i] / b for i, k in enumerate(keys)}, abs(cos)


#: The longest focal length (px) a plane registration takes: a thousand times a large
#: sensor's side; OpenCV's solver fails far beyond it.
MAX_FOCAL_PX = 1e7

#: What :func:`register_plane`'s options take (:mod:`hyperlf._options`).
_PLANE_RULES = {
    "focal_px": _opt.rule(_opt.number, positive=True, optional=True, at_least=1.0,
                          at_most=MAX_FOCAL_PX),
    "positions_from": _opt.rule(_opt.choice, choices=("auto", "parallax", "board")),
    **SEARCH_RULES,
    "min_parallax_px": _opt.number,
}


def register_plane(shots: Mapping, board: BoardSpec, *, reference=None, names=None,
                   focal_px: float | None = None, positions_from: str = "auto",
                   work_size: int = SEARCH_DEFAULTS["work_size"],
                   max_parallax: float = SEARCH_DEFAULTS["max_parallax"],
                   min_parallax_px: float = 0.5) -> Calibration:
    """Register every camera onto the reference view at the board plane (one board pose).

    Parameters
    ----------
    shots : mapping (row, col) -> ndarray (H, W)
        One board shot per camera, keyed by the user's grid place (a naming only: positions
        come from the images).
    board : BoardSpec
    reference : (int, int), optional
        Default: the centre camera of the grid.
    names : mapping (row, col) -> str, optional
        Names for messages (file names).
    focal_px : float, optional
        Known focal length in px (else estimated from the board's perspective).
    positions_from : {"auto", "parallax", "board"}
        ``parallax``: from the off-board scene content (needs scene texture at depths other
        than the board's); ``board``: from the board poses only (blurred by camera rotations);
        ``auto``: parallax when at least a few points give a flow of ``min_parallax_px``.
    work_size : int
        Largest image side for the parallax search.
    max_parallax : float
        Parallax searched, as a fraction of the larger image side (the scene's largest shift
        from the board plane between the reference and its neighbours; a camera farther out
        that it does not reach is searched again up to three times as far).
    min_parallax_px : float
        Median flow below which parallax cannot tell the directions (``auto`` then uses the
        board poses).

    Returns
    -------
    Calibration
        ``mode="plane"``; positions in baselines with the SPEC §1 sign: a point nearer than the
        board (``d_rel > 0``) moves by ``-d_rel (p_v - p_ref)`` from the reference.

    Raises
    ------
    InvalidInputError
        The board is missing in some cameras (named), images differ in size, the grid has
        holes, ``positions_from="parallax"`` found no usable parallax, or the positions from
        parallax contradict the board poses (:data:`POSITION_DISAGREEMENT`: files that are
        not the cameras the grid says).

    Examples
    --------
    >>> from hyperlf.calibration.rig import make_rig
    >>> rig = make_rig(seed=0, imperfect=0.3)
    >>> cal = register_plane(rig.render(rig.board_pose(450.0), supersample=2), rig.board)
    >>> cal.mode, cal.grid
    ('plane', (3, 3))
    """
    _opt.check_values(dict(focal_px=focal_px, positions_from=positions_from,
                           work_size=work_size, max_parallax=max_parallax,
                           min_parallax_px=min_parallax_px), _PLANE_RULES)
    check_board(board)
    _opt.mapping(names, "names")
    grid, ref = check_grid(_opt.mapping(shots, "shots", optional=False).keys(), reference)
    size = check_images(shots, names, what="board shot")
    corners = orders_like(detect_boards(shots, board, names=names, partial=True), ref, board)
    par = None
    if positions_from != "board":
        par, corners = turned_cameras(shots, corners, board, ref, names=names,
                                      work_size=work_size, max_parallax=max_parallax)[1:]
    Hs, errs, resid = board_homographies(corners, ref, names)
    geo = board_geometry(corners, board, size, ref, focal_px=focal_px)
    info = _board_info(geo, corners, board, ref, names, focal_px)
    if not info["focal_determined"]:   # centres at a short focal length (UNDETERMINED_FOCAL)
        geo["centres"] = board_geometry(corners, board, size, ref,
                                        focal_px=UNDETERMINED_FOCAL * max(size))["centres"]
    offsets = {k: np.asarray(v[:2]) for k, v in geo["centres"].items()}
    if par is not None:  # measured by turned_cameras on these corners
        offsets = _parallax_offsets(par, offsets, info, positions_from, min_parallax_px,
                                    names)
    pos, agree = resolve_positions(offsets, geo["centres"], ref)
    info["sign_agreement"] = agree
    cal = _plane_calibration(grid, ref, size, Hs, errs, pos, geo, board, names, info)
    _check_positions_agree(cal.info)
    cal.residuals, cal.corners = resid, corners
    return cal


def _board_info(geo: dict, corners: dict, board: BoardSpec, ref, names, focal_px) -> dict:
    """The calibration's ``info`` from the board poses (and the cameras found turned)."""
    n_z = min(abs(float(geo["plane"][2])), 1.0)   # the board's normal against the optical axis
    info = {"board_pose_rms": geo["rms"], "positions_from": "board",
            "focal_given": bool(focal_px), "focal_std_px": geo["focal_std"],
            "board_tilt_deg": float(np.degrees(np.arccos(n_z))),
            **turn_report({k: c for k, c in corners.items() if k != ref},
                          {k: corners[ref] for k in corners}, board, names)}
    # a board facing the cameras squarely leaves the focal length (and so every metric
    # figure) undetermined: its standard deviation says so (OpenCV reports 0, or next to
    # nothing, when the problem is singular)
    info["focal_determined"] = bool(focal_px) or bool(
        np.isfinite(geo["focal_std"])
        and SINGULAR_FOCAL_STD < geo["focal_std"] < FOCAL_TOLERANCE * geo["focal"])
    return info


def _parallax_offsets(par: dict, offsets: dict, info: dict, positions_from: str,
                      min_parallax_px: float, names=None) -> dict:
    """The cameras' offsets from the scene's parallax when it is usable, else ``offsets``
    (the board poses'; with ``positions_from="parallax"`` that is refused); ``info`` takes
    what was measured, the disparity range it implies, or why it was not used."""
    info.update(parallax_points=par["n_points"], parallax_rms=par["rms"],
                parallax_median_flow=par["median_flow"])
    unknown = [k for k, o in par["offsets"].items() if not np.all(np.isfinite(o))]
    enough = par["n_points"] >= 8 and par["median_flow"] >= min_parallax_px
    loose = [k for k in par.get("fitting", {}) if _misfit(par, k, MISFIT_SHARE)]
    if enough and not unknown and not loose:
        info["positions_from"] = "parallax"
        if np.isfinite(par["reach"]):  # |d| of 99 % of the points, px per baseline
            m = float(np.ceil(1.25 * par["reach"]))
            info["disparity_range"] = [-m, m]
        return par["offsets"]
    if enough and unknown:   # but some camera's flows fit the others' parallax nowhere
        why = (f"the flows of camera(s) {', '.join(camera_label(k, names) for k in unknown)} "
               "fit the other cameras' parallax nowhere")
    elif enough:
        why = (f"the common parallax model fits the flows of camera(s) "
               f"{', '.join(camera_label(k, names) for k in loose)} at few of their points")
    else:
        why = (f"{par['n_points']} points off the board plane with a median flow of "
               f"{par['median_flow']:.2f} px; at least 8 points and {min_parallax_px:g} px "
               "are needed")
    if positions_from == "auto":  # why not, for the user (calibrate says it)
        info["parallax_unused"] = why
        return offsets
    raise InvalidInputError(
        f"no usable parallax around the board ({why}); the scene beside the board needs "
        "texture at other depths, or use positions from the board poses")


#: Largest RMS (baselines) by which the positions from parallax may differ from the board
#: poses' centres; the lab capture's differ by 0.04, the synthetic rigs' by under 0.1.
POSITION_DISAGREEMENT = 0.5


#: Tilt (degrees, the board's normal against the reference's optical axis) that the
#: messages advise: below it a long lens's board poses may not separate the cameras'
#: small rotations from their positions (synthetic rig, focal length 2.8 times the image
#: side: 4 degrees did not fix the focal length, 10 did, to 0.14 baselines).
ADVISED_TILT_DEG = 10.0


def _check_positions_agree(info: dict) -> None:
    """Refuse positions from parallax that the board poses contradict (when the poses fix the
    focal length, and so their centres): the files are not the cameras the grid says."""
    rms = info.get("pose_position_rms", 0.0)
    if info.get("positions_from") != "parallax" or not info.get("focal_determined") \
            or not rms > POSITION_DISAGREEMENT:
        return
    tilt = info.get("board_tilt_deg", 90.0)
    raise InvalidInputError(
        f"the cameras' positions from the scene's parallax and from the board's poses disagree "
        f"by {rms:.2f} baselines (RMS); check --grid and --pattern: each file must be the "
        "camera at its place in the grid" + (
            f"; if it is, the board, tilted by only {tilt:.1f} degrees, cannot place the "
            f"cameras: tilt it by {ADVISED_TILT_DEG:g} degrees or more" if tilt <
            ADVISED_TILT_DEG else ""))


def _plane_calibration(grid, ref, size, Hs, errs, pos, geo, board, names, info) -> Calibration:
    W, H = size
    base = np.array([ref[1], ref[0]], np.float64)
    cams = {k: CameraCalibration(name=camera_label(k, names), position=base + pos[k],
                                 reprojection_error=errs[k], homography=Hs[k]) for k in Hs}
    f = geo["focal"]
    K = np.array([[f, 0, (W - 1) / 2], [0, f, (H - 1) / 2], [0, 0, 1.0]])
    cen = np.stack([geo["centres"][k][:2] for k in Hs])
    p = np.stack([pos[k] for k in Hs])
    baseline = float(np.sum(cen * p) / max(np.sum(p * p), 1e-12))
    info["pose_position_rms"] = float(np.sqrt(np.mean(np.sum((cen / baseline - p) ** 2, 1))))
    return Calibration(mode="plane", grid=grid, reference=ref, image_size=(W, H),
                       output_size=(W, H), camera_matrix=K, cameras=cams, board=board,
                       baseline=abs(baseline), board_plane=geo["plane"], info=info)
