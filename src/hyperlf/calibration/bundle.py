"""Joint refinement of a whole array's calibration over shared board poses (bundle adjustment).

Per-camera Zhang calibration sees each board pose through one camera only; but every pose is
one physical placement seen by many cameras at once. Refining all intrinsics, all poses
relative to the reference camera and all board poses together, on every detected corner,
makes the cameras agree with each other (what rectification needs) instead of each fitting its
own noise. The model is OpenCV's: pinhole, radial ``k1, k2`` and tangential ``p1, p2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import _options as _opt
from ..errors import InvalidInputError

__all__ = ["bundle_adjust", "BundleResult"]


def _rodrigues(rvec: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of rotation vectors ``(..., 3)`` (vectorised).

    Examples
    --------
    >>> np.allclose(_rodrigues(np.array([0.0, 0.0, np.pi / 2])) @ [1, 0, 0], [0, 1, 0])
    True
    """
    r = np.asarray(rvec, np.float64)
    theta = np.linalg.norm(r, axis=-1)[..., None, None]
    small = theta < 1e-6
    t = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta ** 2 / 6, np.sin(t) / t)
    b = np.where(small, 0.5 - theta ** 2 / 24, (1 - np.cos(t)) / (t * t))
    rx, ry, rz = r[..., 0], r[..., 1], r[..., 2]
    z = np.zeros_like(rx)
    S = np.stack([np.stack([z, -rz, ry], -1), np.stack([rz, z, -rx], -1),
                  np.stack([-ry, rx, z], -1)], -2)
    return np.eye(3) + a * S + b * (S @ S)


def _project(points_cam: np.ndarray, intr: np.ndarray) -> np.ndarray:
    """Pixels ``(N, 2)`` of camera-frame points ``(N, 3)`` with per-point intrinsics
    ``(N, 8)``: ``fx, fy, cx, cy, k1, k2, p1, p2`` (OpenCV's model)."""
    x = points_cam[:, 0] / points_cam[:, 2]
    y = points_cam[:, 1] / points_cam[:, 2]
    fx, fy, cx, cy, k1, k2, p1, p2 = intr.T
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([fx * xd + cx, fy * yd + cy], axis=1)


@dataclass
class BundleResult:
    """Refined parameters: ``intr`` (V, 8), ``rvec``/``tvec`` (V, 3) camera from reference,
    ``pose_rvec``/``pose_tvec`` (P, 3) board to reference, ``rms`` (V,) px per camera,
    ``residuals`` (M, 2) reprojected minus detected for the observed corners ``uv`` (M, 2) of
    cameras ``cam`` (M,)."""

    intr: np.ndarray
    rvec: np.ndarray
    tvec: np.ndarray
    pose_rvec: np.ndarray
    pose_tvec: np.ndarray
    rms: np.ndarray
    residuals: np.ndarray
    uv: np.ndarray
    cam: np.ndarray


class _Problem:
    """Observations and the parameter vector layout."""

    def __init__(self, obs, obj, n_cams, n_poses, ref):
        self.cam = np.concatenate([np.full(len(obj), c) for c, _, _ in obs])
        self.pose = np.concatenate([np.full(len(obj), p) for _, p, _ in obs])
        self.uv = np.concatenate([uv for _, _, uv in obs])
        self.X = np.tile(obj, (len(obs), 1))
        self.V, self.P, self.ref = n_cams, n_poses, ref

    def split(self, theta):
        V, P = self.V, self.P
        intr = theta[:8 * V].reshape(V, 8)
        ext = theta[8 * V:8 * V + 6 * V].reshape(V, 6)
        pose = theta[14 * V:].reshape(P, 6)
        return intr, ext, pose

    def residuals(self, theta):
        intr, ext, pose = self.split(theta)
        Rp = _rodrigues(pose[:, :3])[self.pose]
        Xr = np.einsum("nij,nj->ni", Rp, self.X) + pose[self.pose, 3:]
        Rc = _rodrigues(ext[:, :3])[self.cam]
        Xc = np.einsum("nij,nj->ni", Rc, Xr) + ext[self.cam, 3:]
        return (_project(Xc, intr[self.cam]) - self.uv).ravel()

    def sparsity(self):
        from scipy.sparse import lil_matrix

        n = len(self.cam)
        J = lil_matrix((2 * n, 14 * self.V + 6 * self.P), dtype=np.int8)
        rows = np.arange(2 * n)
        c = np.repeat(self.cam, 2)
        p = np.repeat(self.pose, 2)
        for j in range(8):
            J[rows, 8 * c + j] = 1
        for j in range(6):
            J[rows, 8 * self.V + 6 * c + j] = 1
            J[rows, 14 * self.V + 6 * p + j] = 1
        return J


def _finite_rows(value, label: str, width: int, rows: int | None = None) -> np.ndarray:
    """``value`` as a finite float64 array ``(n, width)``, ``n >= 1`` (``n == rows`` where
    given)."""
    a = _opt.real_array(value, label)
    if a.ndim != 2 or a.shape[1] != width or not len(a) or (rows is not None and len(a) != rows):
        n = "n" if rows is None else rows
        raise InvalidInputError(f"{label} must be an array ({n}, {width}), got shape {a.shape}")
    if not np.isfinite(a).all():
        raise InvalidInputError(f"{label} must be finite")
    return a


def _observations(obs, n_points: int, n_cams: int, n_poses: int) -> list:
    """``obs`` as a non-empty list of ``(camera, pose, (n_points, 2) finite corners)``, with
    every camera and every pose observed at least once (one that is not has nothing to fit
    its parameters to)."""
    what = (f"obs must be a non-empty list of (camera index < {n_cams}, pose index < {n_poses}, "
            f"({n_points}, 2) corners)")
    if isinstance(obs, (str, bytes, dict)) or not hasattr(obs, "__len__") or not len(obs):
        raise InvalidInputError(f"{what}, got {_opt.shown(obs)}")
    out = []
    for item in obs:
        try:
            c, p, uv = item
            c = _opt.integer(c, "camera", maximum=n_cams - 1)
            p = _opt.integer(p, "pose", maximum=n_poses - 1)
            uv = _opt.real_array(uv, "corners")
        except (TypeError, ValueError, InvalidInputError):
            raise InvalidInputError(f"{what}, got {_opt.shown(item)}") from None
        if uv.shape != (n_points, 2) or not np.isfinite(uv).all():
            raise InvalidInputError(f"{what}, got corners of shape {uv.shape} (or not finite)")
        out.append((c, p, uv))
    for kind, n, seen in (("camera", n_cams, {o[0] for o in out}),
                          ("pose", n_poses, {o[1] for o in out})):
        if len(seen) < n:
            lost = min(set(range(n)) - seen)
            raise InvalidInputError(f"obs holds no observation of {kind} {lost} (of {n}); "
                                    f"each {kind} needs at least one")
    return out


#: Relative change of the parameters and of the cost at which the bundle adjustment stops.
#: At 1e-10 it never stopped before its 60 evaluations, even on exact corners; at 1e-6 it
#: stops after 10-15 with the same residual to five digits and the focal length within
#: 0.01 % (synthetic rigs, BENCHMARKS.md, fifty-second session), in a fifth to a third of
#: the time.
BUNDLE_TOLERANCE = 1e-6


def bundle_adjust(obs, obj, intr0, rvec0, tvec0, pose_r0, pose_t0, ref: int) -> BundleResult:
    """Refine everything on every corner; the reference camera's pose stays the identity.

    Parameters
    ----------
    obs : list of (camera index, pose index, (N, 2) corners)
    obj : (N, 3) board points
    intr0 : (V, 8); rvec0, tvec0 : (V, 3); pose_r0, pose_t0 : (P, 3)
    ref : index of the reference camera

    Examples
    --------
    Two cameras 40 units apart and three board poses, observed exactly (OpenCV's projection);
    the refinement starts from focal lengths 3 % too long and board poses 2 % too far, and
    finds the true ones:

    >>> import cv2
    >>> from hyperlf.calibration.board import BoardSpec
    >>> obj = BoardSpec(5, 4, 20.0).object_points()
    >>> intr = np.array([[300.0, 300.0, 160.0, 120.0, -0.05, 0.01, 0.0, 0.0]] * 2)
    >>> rvec, tvec = np.zeros((2, 3)), np.array([[0.0, 0.0, 0.0], [-40.0, 0.0, 0.0]])
    >>> pose_r = np.array([[0.3, 0.0, 0.0], [0.0, 0.3, 0.1], [-0.2, -0.25, 0.0]])
    >>> pose_t = np.array([[-40.0, -30.0, 400.0], [-30.0, -40.0, 450.0], [-50.0, -20.0, 420.0]])
    >>> def corners(i, p):
    ...     r, t = cv2.composeRT(pose_r[p], pose_t[p], rvec[i], tvec[i])[:2]
    ...     K = np.array([[300.0, 0.0, 160.0], [0.0, 300.0, 120.0], [0.0, 0.0, 1.0]])
    ...     return cv2.projectPoints(obj, r, t, K, intr[i, 4:])[0].reshape(-1, 2)
    >>> obs = [(i, p, corners(i, p)) for i in range(2) for p in range(3)]
    >>> start = intr * [1.03, 1.03, 1, 1, 1, 1, 1, 1]
    >>> res = bundle_adjust(obs, obj, start, rvec, tvec, pose_r, pose_t * 1.02, ref=0)
    >>> bool(res.rms.max() < 1e-3), bool(np.abs(res.intr[:, :2] - 300.0).max() < 0.05)
    (True, True)
    >>> bool(np.abs(res.tvec[1] - [-40.0, 0.0, 0.0]).max() < 0.05), res.residuals.shape
    (True, (120, 2))
    """
    from scipy.optimize import least_squares

    obj = _finite_rows(obj, "obj", 3)
    intr0 = _finite_rows(intr0, "intr0", 8)
    V = len(intr0)
    rvec0, tvec0 = (_finite_rows(v, k, 3, V) for v, k in ((rvec0, "rvec0"), (tvec0, "tvec0")))
    pose_r0 = _finite_rows(pose_r0, "pose_r0", 3)
    pose_t0 = _finite_rows(pose_t0, "pose_t0", 3, len(pose_r0))
    ref = _opt.integer(ref, "ref", maximum=V - 1)
    obs = _observations(obs, len(obj), V, len(pose_r0))
    prob = _Problem(obs, obj, len(intr0), len(pose_r0), ref)
    ext0 = np.concatenate([rvec0, tvec0], axis=1)
    theta0 = np.concatenate([np.asarray(intr0, np.float64).ravel(), ext0.ravel(),
                             np.concatenate([pose_r0, pose_t0], axis=1).ravel()])
    fixed = np.zeros(theta0.size, bool)
    fixed[8 * prob.V + 6 * ref: 8 * prob.V + 6 * ref + 6] = True
    free = ~fixed

    def fun(x):
        th = theta0.copy()
        th[free] = x
        return prob.residuals(th)

    sol = least_squares(fun, theta0[free], jac_sparsity=prob.sparsity()[:, free],
                        method="trf", x_scale="jac", xtol=BUNDLE_TOLERANCE,
                        ftol=BUNDLE_TOLERANCE, max_nfev=60)
    theta = theta0.copy()
    theta[free] = sol.x
    intr, ext, pose = prob.split(theta)
    res = prob.residuals(theta).reshape(-1, 2)
    rms = np.array([np.sqrt(np.mean(np.sum(res[prob.cam == c] ** 2, 1)))
                    for c in range(prob.V)])
    return BundleResult(intr, ext[:, :3], ext[:, 3:], pose[:, :3], pose[:, 3:], rms, res,
                        prob.uv, prob.cam)
