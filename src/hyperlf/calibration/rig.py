"""A synthetic, deliberately imperfect camera array with exact ground truth (SPEC §11).

The rig renders raw images as a real multispectral array would give them: every camera has its
own focal length, principal point, radial distortion (``k1``, ``k2``), a rotation of a degree or
two, a gain and offset, vignetting, and a band in which the checkerboard's contrast may be
inverted. Everything is deterministic from a seed, and everything is known: intrinsics,
extrinsics, positions, the board's corners, and the depth of every reference pixel.

World frame: ``x`` right, ``y`` down, ``z`` forward (OpenCV's camera axes); the array lies in the
plane ``z = 0``; camera ``(r, c)`` sits near ``((c - c0) B, (r - r0) B, 0)`` (a little jitter
makes the grid non-uniform) and looks along ``+z``. A camera maps a world point ``X`` to its own
frame by ``R (X - centre)``.

The scene is a list of textured rectangles (:class:`Panel`): the checkerboard (white margin of
one square), a textured plane part-way back and a textured back wall. Each camera sees a band:
the textures' contrast changes from band to band, and in the bands listed in ``inverted`` the
board's dark squares are brighter than its light ones.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from .. import _options as _opt
from ..errors import InvalidInputError
from .board import BoardSpec, check_board
from .grid import grid_keys

__all__ = ["RigCamera", "Panel", "BoardPose", "SyntheticRig", "make_rig", "rotation_matrix"]


def _finite(value, label: str, shape) -> None:
    """Refuse ``value`` unless it is a finite real array of ``shape``."""
    _opt.array(value, label, shape, finite=True)


def rotation_matrix(rx: float, ry: float, rz: float) -> np.ndarray:
    """Rotation ``Rz @ Ry @ Rx`` from angles in degrees about the x, y and z axes.

    Examples
    --------
    >>> np.allclose(rotation_matrix(0, 0, 90) @ [1, 0, 0], [0, 1, 0])
    True
    """
    ax, ay, az = np.deg2rad([_opt.real(v, k) for v, k in ((rx, "rx"), (ry, "ry"), (rz, "rz"))])
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


@dataclass(frozen=True)
class RigCamera:
    """One camera of the rig (all values exact).

    ``K`` intrinsic matrix, ``dist`` OpenCV distortion ``(k1, k2, p1, p2, k3)``, ``R`` world to
    camera rotation, ``centre`` world position, ``gain``/``offset`` of the sensor response,
    ``vignetting`` the relative fall-off at the image corner, ``band`` in [0, 1] (which texture
    contrast it sees), ``inverted`` whether the board's contrast is inverted in its band.
    """

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    centre: np.ndarray
    gain: float
    offset: float
    vignetting: float
    band: float
    inverted: bool

    def __post_init__(self):
        for name, shape in (("K", (3, 3)), ("dist", (5,)), ("R", (3, 3)), ("centre", (3,))):
            _finite(getattr(self, name), name, shape)
        for name in ("gain", "offset", "vignetting"):
            _opt.real(getattr(self, name), name)
        _opt.share(self.band, "band")
        _opt.flag(self.inverted, "inverted")

    @property
    def rvec_tvec(self) -> tuple[np.ndarray, np.ndarray]:
        """OpenCV ``(rvec, tvec)`` of the world-to-camera transform."""
        import cv2

        return cv2.Rodrigues(self.R)[0].ravel(), -self.R @ self.centre


@dataclass(frozen=True)
class Panel:
    """A textured rectangle: ``origin + s * u + t * v`` for ``s`` in [0, width], ``t`` in
    [0, height]; ``kind`` is ``"board"`` or ``"texture"`` (``seed`` picks the texture)."""

    origin: np.ndarray
    u: np.ndarray
    v: np.ndarray
    width: float
    height: float
    kind: str = "texture"
    seed: int = 0

    def __post_init__(self):
        for name in ("origin", "u", "v"):
            _finite(getattr(self, name), name, (3,))
        for name in ("width", "height"):
            _opt.number(getattr(self, name), name, positive=True)
        _opt.choice(self.kind, "kind", ("board", "texture"))
        _opt.integer(self.seed, "seed")
        if not np.linalg.norm(np.cross(self.u, self.v)) > 0:
            raise InvalidInputError("a panel's u and v must span a plane")

    @property
    def normal(self) -> np.ndarray:
        n = np.cross(self.u, self.v)
        return n / np.linalg.norm(n)


@dataclass(frozen=True)
class BoardPose:
    """Pose of the board: board point ``(X, Y, 0)`` (board units, corner ``(0, 0)`` at the
    origin) is at ``R @ (X, Y, 0) + t`` in the world."""

    R: np.ndarray
    t: np.ndarray

    def __post_init__(self):
        _finite(self.R, "R", (3, 3))
        _finite(self.t, "t", (3,))

    def corners_world(self, board: BoardSpec) -> np.ndarray:
        """World coordinates of the inner corners in canonical order, shape ``(N, 3)``."""
        return board.object_points() @ self.R.T + self.t


def _texture_field(seed: int, n: int = 256) -> np.ndarray:
    """Two smooth random patterns (fine and coarse), each normalised to [0, 1]."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    out = []
    for sigma in (1.6, 5.0):
        t = gaussian_filter(rng.random((n, n)), sigma, mode="wrap")
        t = (t - t.min()) / (t.max() - t.min())
        out.append(t)
    return np.stack(out)


@dataclass
class SyntheticRig:
    """A known camera array and scene; build it with :func:`make_rig`.

    Attributes
    ----------
    cameras : dict[(int, int), RigCamera]
        Keyed by the camera's true grid place ``(row, col)``.
    grid : (int, int)
        ``(R, C)``.
    reference : (int, int)
        The reference camera.
    image_size : (int, int)
        ``(W, H)`` of every raw image.
    baseline : float
        Nominal grid pitch (board units).
    board : BoardSpec
        The checkerboard.
    panels : list of Panel
        The scene behind the board (the board itself is added per pose).
    texture_period : float
        World size of one texture cell.
    noise : float
        Standard deviation of the sensor noise.
    seed : int
    """

    cameras: dict
    grid: tuple[int, int]
    reference: tuple[int, int]
    image_size: tuple[int, int]
    baseline: float
    board: BoardSpec
    panels: list
    texture_period: float
    noise: float
    seed: int
    _textures: dict = dataclasses.field(default_factory=dict, repr=False)
    _rays_cache: dict = dataclasses.field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------ geometry
    def project(self, key: tuple[int, int], points: np.ndarray) -> np.ndarray:
        """Exact raw pixel coordinates ``(N, 2)`` of world points ``(N, 3)`` in camera ``key``."""
        import cv2

        cam = self.cameras[key]
        rvec, tvec = cam.rvec_tvec
        pts, _ = cv2.projectPoints(np.asarray(points, np.float64).reshape(-1, 1, 3), rvec, tvec,
                                   cam.K, cam.dist)
        return pts.reshape(-1, 2)

    def reference_frame_centres(self) -> dict:
        """Camera centres in the reference camera's frame, keyed like ``cameras``."""
        ref = self.cameras[self.reference]
        return {k: ref.R @ (c.centre - ref.centre) for k, c in self.cameras.items()}

    def true_positions(self, frame: str = "reference") -> dict:
        """Exact positions ``(px, py)`` in baselines, keyed like ``cameras``.

        ``frame="reference"``: the reference camera's axes (plane registration);
        ``frame="array"``: the rectified frame of full calibration (``z`` normal to the array
        plane, ``x`` the reference camera's ``x`` axis projected onto the array plane).
        The baseline is the median distance from a camera to its nearest neighbour.
        """
        ref = self.cameras[self.reference]
        cen = {k: c.centre - ref.centre for k, c in self.cameras.items()}
        if frame == "reference":
            axes = ref.R
        elif frame == "array":
            z = np.array([0.0, 0.0, 1.0])
            x = ref.R[0] - (ref.R[0] @ z) * z
            x /= np.linalg.norm(x)
            axes = np.stack([x, np.cross(z, x), z])
        else:
            raise InvalidInputError(f"frame must be 'reference' or 'array', got {frame!r}")
        allc = np.stack(list(cen.values()))
        dd = np.linalg.norm(allc[:, None] - allc[None], axis=-1)
        np.fill_diagonal(dd, np.inf)
        b = float(np.median(dd.min(axis=1)))
        return {k: (axes @ v)[:2] / b for k, v in cen.items()}

    # ------------------------------------------------------------------ rendering
    def _rays(self, key, supersample: int):
        """World ray directions ``(H, W, s*s, 3)`` of camera ``key`` (distortion inverted)."""
        import cv2

        cam = self.cameras[key]
        W, H = self.image_size
        o = (np.arange(supersample) + 0.5) / supersample - 0.5
        oy, ox = np.meshgrid(o, o, indexing="ij")
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
        px = (xx[..., None] + ox.ravel()).ravel()
        py = (yy[..., None] + oy.ravel()).ravel()
        pts = np.stack([px, py], -1).reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 60, 1e-12)
        und = cv2.undistortPoints(pts, cam.K, cam.dist, None, None, None, crit).reshape(-1, 2)
        dirs = np.concatenate([und, np.ones((und.shape[0], 1))], axis=1) @ cam.R  # R^T d
        return dirs.reshape(H, W, supersample * supersample, 3).astype(np.float32)

    def _panel_hit(self, panel: Panel, origin: np.ndarray, dirs: np.ndarray):
        """Ray parameter (inf where missed) and panel coordinates ``(s, t)``."""
        n = panel.normal
        rel = origin - panel.origin
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = np.float32(-(rel @ n)) / (dirs @ n.astype(np.float32))
        s = np.float32(rel @ panel.u) + lam * (dirs @ panel.u.astype(np.float32))
        t = np.float32(rel @ panel.v) + lam * (dirs @ panel.v.astype(np.float32))
        ok = (lam > 0) & (s >= 0) & (s <= panel.width) & (t >= 0) & (t <= panel.height)
        return np.where(ok, lam, np.float32(np.inf)), s, t

    def _texture(self, panel: Panel, s, t, band: float) -> np.ndarray:
        import cv2

        if panel.seed not in self._textures:
            tex = _texture_field(self.seed * 1000 + panel.seed)
            self._textures[panel.seed] = (0.6 * tex[0] + 0.4 * tex[1]).astype(np.float32)
        tex = self._textures[panel.seed]
        n = s.size
        cols = 1024
        pad = (-n) % cols
        mu = np.pad((s / self.texture_period).astype(np.float32), (0, pad)).reshape(-1, cols)
        mv = np.pad((t / self.texture_period).astype(np.float32), (0, pad)).reshape(-1, cols)
        tex_v = cv2.remap(tex, mu % tex.shape[1], mv % tex.shape[0], cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_WRAP).ravel()[:n].astype(np.float64)
        # band-dependent reflectance: contrast and gamma change with the band, and on
        # odd-seeded panels the contrast is inverted in the upper half of the bands
        a = 0.6 + 0.3 * np.cos(np.pi * band)
        if panel.seed % 2 and band > 0.6:
            a = -a
        return np.clip(0.5 + a * (tex_v ** (0.8 + 0.4 * band) - 0.5) * 1.6, 0.02, 0.98)

    def _board_value(self, s, t, inverted: bool) -> np.ndarray:
        sq = self.board.square
        ix = np.floor(s / sq).astype(int) - 1  # margin of one square
        iy = np.floor(t / sq).astype(int) - 1
        inside = (ix >= 0) & (ix <= self.board.cols) & (iy >= 0) & (iy <= self.board.rows)
        dark = inside & ((ix + iy) % 2 == 0)
        lo, hi = (0.75, 0.2) if inverted else (0.08, 0.85)
        return np.where(dark, lo, hi)

    def board_panel(self, pose: BoardPose) -> Panel:
        """The board (with its one-square white margin) as a panel in the world."""
        sq = self.board.square
        u, v = pose.R[:, 0], pose.R[:, 1]
        origin = pose.t - sq * (2 * u + 2 * v)
        return Panel(origin, u, v, (self.board.cols + 3) * sq, (self.board.rows + 3) * sq,
                     kind="board")

    def _shade(self, key, pose: BoardPose | None, supersample: int, scene: bool = True):
        """Scene radiance (before sensor effects) and depth along the optical axis."""
        cam = self.cameras[key]
        if (key, supersample) not in self._rays_cache:
            self._rays_cache[(key, supersample)] = self._rays(key, supersample)
        dirs = self._rays_cache[(key, supersample)].reshape(-1, 3)
        panels = (list(self.panels) if scene else []) + (
            [self.board_panel(pose)] if pose is not None else [])
        hits = [self._panel_hit(panel, cam.centre, dirs) for panel in panels]
        lams = np.stack([h[0] for h in hits])
        which = np.argmin(lams, axis=0)
        best = lams[which, np.arange(lams.shape[1])]
        value = np.full(best.shape, 0.5)
        for i, (panel, (lam, s, t)) in enumerate(zip(panels, hits)):
            sel = (which == i) & np.isfinite(best)
            if not sel.any():
                continue
            if panel.kind == "board":
                value[sel] = self._board_value(s[sel], t[sel], cam.inverted)
            else:
                value[sel] = self._texture(panel, s[sel], t[sel], cam.band)
        shape = self._rays_cache[(key, supersample)].shape[:-1]
        depth = (best * (dirs @ cam.R[2])).reshape(shape)
        return value.reshape(shape).mean(axis=-1), np.median(depth, axis=-1)

    def _sensor(self, key, radiance: np.ndarray, salt: int) -> np.ndarray:
        cam = self.cameras[key]
        W, H = self.image_size
        yy, xx = np.mgrid[0:H, 0:W]
        r2 = ((xx - cam.K[0, 2]) ** 2 + (yy - cam.K[1, 2]) ** 2) / (0.25 * (W * W + H * H))
        img = cam.offset + cam.gain * radiance * (1.0 - cam.vignetting * r2)
        rng = np.random.default_rng([self.seed, salt, key[0], key[1]])
        img = img + rng.normal(0.0, self.noise, img.shape)
        return np.clip(img, 0.0, 1.0).astype(np.float32)

    def render(self, pose: BoardPose | None = None, *, supersample: int = 3,
               salt: int = 0, scene: bool = True) -> dict:
        """Raw images of every camera, float32 ``(H, W)`` in [0, 1], keyed ``(row, col)``.

        ``pose=None`` renders the scene without the board; ``scene=False`` the board in front
        of a plain grey background. ``salt`` changes the noise only.
        """
        return {k: self._sensor(k, self._shade(k, pose, supersample, scene)[0], salt)
                for k in self.cameras}

    def depth(self, key, pose: BoardPose | None = None) -> np.ndarray:
        """Depth along camera ``key``'s optical axis of every pixel, ``(H, W)``."""
        return self._shade(key, pose, 1)[1]

    # ------------------------------------------------------------------ poses
    def board_pose(self, distance: float, *, tilt: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   centre_offset: tuple[float, float] = (0.0, 0.0)) -> BoardPose:
        """A board pose whose centre sits ``distance`` in front of the array centre, shifted by
        ``centre_offset`` (world x, y) and rotated by ``tilt`` (degrees about x, y, z)."""
        R = rotation_matrix(*tilt)
        half = 0.5 * np.array([(self.board.cols - 1) * self.board.square,
                               (self.board.rows - 1) * self.board.square, 0.0])
        centre = np.array([centre_offset[0], centre_offset[1], distance])
        return BoardPose(R, centre - R @ half)

    def in_view(self, pose: BoardPose, keys=None, *, margin: float = 4.0) -> bool:
        """Whether the whole board (with its white margin) is inside the images of ``keys``
        (default: every camera)."""
        panel = self.board_panel(pose)
        quad = np.array([panel.origin + a * panel.width * panel.u + b * panel.height * panel.v
                         for a in (0, 1) for b in (0, 1)])
        W, H = self.image_size
        for key in (self.cameras if keys is None else keys):
            q = self.project(key, quad)
            if (q[:, 0].min() < margin or q[:, 1].min() < margin
                    or q[:, 0].max() > W - 1 - margin or q[:, 1].max() > H - 1 - margin):
                return False
        return True

    def calibration_poses(self, n: int = 12, distance: float = 500.0, *,
                          n_shared: int = 5) -> list:
        """``n`` board poses for full calibration, tilted by about 20 degrees.

        The first ``n_shared`` (one in the middle, the rest on a ring) are seen whole by every
        camera; the others sit on a wider ring, as far out as the reference camera still sees
        the whole board, so that each camera's image edges are covered and some cameras miss
        the board in some poses (as in a real session).
        """
        rng = np.random.default_rng([self.seed, 7])
        W, H = self.image_size
        f = float(np.mean([c.K[0, 0] for c in self.cameras.values()]))
        poses = []
        for i in range(n):
            shared = i < n_shared
            m = max(n_shared - 1, 1) if shared else max(n - n_shared, 1)
            a = 2 * np.pi * (i - 1 if shared else i - n_shared) / m + (0.0 if shared else 0.4)
            tilt = (20 * np.sin(a + 1.3) + rng.uniform(-3, 3),
                    20 * np.cos(a + 1.3) + rng.uniform(-3, 3), rng.uniform(-6, 6))
            dist = distance * (0.8 + 0.5 * ((i * 0.618) % 1.0))  # near and far poses
            reach = 0.0 if i == 0 else 0.6 * dist / f
            keys = None if shared else [self.reference]
            for _ in range(40):
                pose = self.board_pose(dist, tilt=tilt,
                                       centre_offset=(reach * W * np.cos(a), reach * H * np.sin(a)))
                if self.in_view(pose, keys):
                    break
                reach, dist = reach * 0.92, dist * 1.02
            else:
                raise InvalidInputError(f"board pose {i} does not fit the cameras' view")
            poses.append(pose)
        return poses


def _camera(rng, key, ref, baseline, focal, image_size, n_bands, index, inverted, imperfect,
            distortion):
    W, H = image_size
    r, c = key
    j = rng.uniform(-0.03, 0.03, 2) * baseline * imperfect
    centre = np.array([(c - ref[1]) * baseline + j[0], (r - ref[0]) * baseline + j[1], 0.0])
    ang = rng.uniform(-2.0, 2.0, 3) * imperfect
    f = focal * (1 + rng.uniform(-0.04, 0.04) * imperfect)
    cx = (W - 1) / 2 + rng.uniform(-6, 6) * imperfect
    cy = (H - 1) / 2 + rng.uniform(-5, 5) * imperfect
    K = np.array([[f, 0, cx], [0, f * (1 + rng.uniform(-0.002, 0.002) * imperfect), cy],
                  [0, 0, 1.0]])
    dist = np.array([rng.uniform(-0.12, -0.04), rng.uniform(0.0, 0.05), 0, 0, 0]) * distortion
    return RigCamera(K=K, dist=dist, R=rotation_matrix(*ang), centre=centre,
                     gain=float(1 + rng.uniform(-0.25, 0.1) * imperfect),
                     offset=float(rng.uniform(0, 0.05) * imperfect),
                     vignetting=float(rng.uniform(0.1, 0.35) * imperfect),
                     band=index / max(n_bands - 1, 1), inverted=index in inverted)


#: What :func:`make_rig`'s options take: imperfections and distortion up to ten times the
#: modelled ones (rotations of 20 degrees), images up to 8192 px a side.
_RIG_RULES = {
    "seed": _opt.rule(_opt.integer, maximum=2 ** 63),
    "image_size": _opt.rule(_opt.int_pair, minimum=16, maximum=8192, what="(W, H) px"),
    "baseline": _opt.rule(_opt.number, positive=True, at_most=1e9),
    "focal": _opt.rule(_opt.number, at_least=1.0, at_most=1e7),
    "imperfect": _opt.rule(_opt.number, at_most=10),
    "noise": _opt.rule(_opt.number, at_most=1),
    "distortion": _opt.rule(_opt.number, at_most=10, optional=True),
}


def make_rig(rows: int = 3, cols: int = 3, *, seed: int = 0,
             image_size: tuple[int, int] = (320, 240), baseline: float = 40.0,
             focal: float = 300.0, board: BoardSpec | None = None,
             inverted: Sequence[int] = (2, 6), imperfect: float = 1.0,
             scene_depths: tuple[float, float] = (700.0, 1000.0),
             noise: float = 0.004, distortion: float | None = None) -> SyntheticRig:
    """A deliberately imperfect ``rows x cols`` array and its scene.

    Parameters
    ----------
    rows, cols : int
        Grid of cameras.
    seed : int
        Everything random (camera errors, textures, noise) follows from it.
    image_size : (int, int)
        ``(W, H)`` of the raw images.
    baseline : float
        Grid pitch in board units (the board's ``square`` is in the same units, e.g. mm).
    focal : float
        Nominal focal length in pixels; each camera differs by up to 4 %.
    board : BoardSpec, optional
        Default: 8 x 6 inner corners, 20-unit squares.
    inverted : sequence of int
        Raster indices of the cameras whose band inverts the board's contrast.
    imperfect : float
        Scales every imperfection (rotations up to 2 degrees, principal point offsets up to
        6 px, distortion ``k1`` in [-0.12, -0.04] and ``k2`` in [0, 0.05], gain, offset,
        vignetting, position jitter up to 3 % of the baseline); ``0`` gives an ideal array.
    scene_depths : (float, float)
        Depths of the middle textured plane (left part of the view) and of the back wall.
    noise : float
        Sensor noise standard deviation.
    distortion : float, optional
        Scales the lens distortion alone (default: ``imperfect``).

    Returns
    -------
    SyntheticRig

    Examples
    --------
    >>> rig = make_rig(seed=1)
    >>> rig.grid, rig.reference, len(rig.cameras)
    ((3, 3), (1, 1), 9)
    """
    keys = grid_keys(rows, cols)
    if len(keys) < 2:
        raise InvalidInputError(f"a rig needs at least two cameras, got {rows} x {cols}")
    o = _opt.check_values(dict(seed=seed, image_size=image_size, baseline=baseline, focal=focal,
                               imperfect=imperfect, noise=noise, distortion=distortion),
                          _RIG_RULES)
    seed, image_size, baseline, focal, imperfect, noise, distortion = o.values()
    board = BoardSpec(8, 6, 20.0) if board is None else check_board(board)
    if isinstance(inverted, (str, bytes, Mapping)) or not hasattr(inverted, "__iter__"):
        raise InvalidInputError(f"inverted must be raster indices of cameras, got "
                                f"{_opt.shown(inverted)}")
    inverted = [_opt.integer(i, "an inverted camera's index") for i in inverted]
    scene_depths = _opt.real_pair(scene_depths, "scene_depths", "two depths (near, far) > 0")
    if not min(scene_depths) > 0:
        raise InvalidInputError(f"scene_depths must be two depths (near, far) > 0, got "
                                f"{_opt.shown(scene_depths)}")
    rng = np.random.default_rng(seed)
    ref = ((rows - 1) // 2, (cols - 1) // 2)
    dist = imperfect if distortion is None else distortion
    cams = {k: _camera(rng, k, ref, baseline, focal, image_size, len(keys), i, set(inverted),
                       imperfect, dist) for i, k in enumerate(keys)}
    zmid, zfar = scene_depths
    big = 4.0 * zfar
    ex, ey = np.eye(3)[0], np.eye(3)[1]
    panels = [Panel(np.array([-big / 2, -big / 2, zfar]), ex, ey, big, big, seed=1),
              Panel(np.array([-big / 2, -0.25 * zmid, zmid]), ex, ey, big / 2 - 0.22 * zmid,
                    0.7 * zmid, seed=2)]
    return SyntheticRig(cameras=cams, grid=(rows, cols), reference=ref, image_size=image_size,
                        baseline=baseline, board=board, panels=panels,
                        texture_period=zfar / focal * 1.2, noise=noise, seed=seed)
