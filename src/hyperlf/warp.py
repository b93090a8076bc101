"""Sub-pixel sampling: the only place where bilinear taps and weights are computed (SPEC §1).

Every module that resamples an image (two-view and light-field costs, the baselines, rendering,
cube completion) goes through this module, so the interpolation rule exists once.

Conventions
-----------
* Pixel centres sit at integer coordinates; ``x`` is the column, ``y`` the row.
* A coordinate ``c`` along an axis of length ``n`` is sampled from the taps
  ``i0 = min(floor(clip(c, 0, n - 1)), n - 2)``, ``i1 = min(i0 + 1, n - 1)`` with weight
  ``f = clip(c, 0, n - 1) - i0`` on ``i1`` (:func:`coordinate_taps`). The last pixel is reached
  with ``f = 1`` on the pair ``(n - 2, n - 1)``.
* A sample is **valid** when both coordinates are finite and lie inside ``[0, n - 1]`` within
  :data:`INSIDE_EPS`. Validity is always returned; the **edge rule** decides what an invalid
  sample's value is:

  - ``edge="mask"``: the value is ``fill`` (default NaN), never a silent zero;
  - ``edge="clamp"``: the coordinate is clamped to the image (replicated border), so the value is
    the border value; only non-finite coordinates get ``fill``.

* ``dtype`` is the precision of the interpolation weights (float64 by default). The arithmetic
  follows numpy's promotion of the image dtype with ``dtype``: float32 weights on a float32
  image compute in float32, float64 weights compute in float64.
* Separable shifts (:func:`shift_map`) interpolate one axis after the other; ``order`` says which
  axis comes first (the rounding differs in the last bit). General coordinate maps
  (:func:`sample_bilinear`) interpolate along x, then y. :func:`bilinear_taps` returns the four
  flat indices and product weights of each sample for callers that check or accumulate taps
  themselves (:func:`gather_taps`).
"""

from __future__ import annotations

import numpy as np

from . import _options as _opt
from .errors import InvalidInputError

__all__ = [
    "INSIDE_EPS",
    "EDGE_RULES",
    "coordinate_taps",
    "axis_taps",
    "axis_valid",
    "shift_map",
    "sample_bilinear",
    "bilinear_taps",
    "gather_taps",
    "shift_image",
    "warp_to_reference",
    "forward_warp_disparity",
    "visible_in_view",
    "occlusion_zbuffer",
    "visible_at_labels",
    "occluder_excess",
]

#: Tolerance (px) within which a sample just outside ``[0, n - 1]`` still counts as inside.
INSIDE_EPS = 1e-6

#: The edge rules every sampler accepts (module docstring).
EDGE_RULES = ("mask", "clamp")


def _check_edge(edge: str) -> str:
    return _opt.choice(edge, "edge", EDGE_RULES)


def _disparity_map(disparity) -> np.ndarray:
    """``disparity`` as an ``(H, W)`` float64 map (NaN allowed: unknown)."""
    d = _opt.real_array(disparity, "disparity")
    if d.ndim != 2:
        raise InvalidInputError(f"disparity must be an (H, W) map, got shape {d.shape}")
    return d


def _offset_px(sx, sy) -> tuple[float, float]:
    return _opt.real(sx, "sx (px)"), _opt.real(sy, "sy (px)")


#: The widest ``pad`` (px) :func:`shift_map` adds on each side.
MAX_PAD = 4096

#: The longest image axis (px) the taps take (:func:`axis_taps` builds a grid that long).
MAX_AXIS = 1 << 20


def _axis_length(n) -> int:
    """An axis length ``n``, ``1 <= n <=`` :data:`MAX_AXIS` (O(1): the taps are per view)."""
    return _opt.integer(n, "n", 1, maximum=MAX_AXIS)


def _offset(offset) -> tuple[float, float]:
    return _opt.real_pair(offset, "offset", "(dx, dy) in baselines, finite")


def _image(image) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim not in (2, 3):
        raise InvalidInputError(f"image must be (H, W) or (H, W, K), got shape {img.shape}")
    return img


def _broadcast_xy(x, y) -> None:
    """``x`` and ``y`` broadcast to one shape (O(1): their shapes only)."""
    try:
        np.broadcast_shapes(np.shape(x), np.shape(y))
    except ValueError:
        raise InvalidInputError(f"x and y must broadcast to one shape, got {np.shape(x)} and "
                                f"{np.shape(y)}") from None


def coordinate_taps(coord, n: int, *, dtype=np.float64):
    """Bilinear taps of coordinates along one axis of length ``n``.

    Parameters
    ----------
    coord : array_like of float
        Coordinates in pixels (pixel centres at integers), any shape.
    n : int
        Length of the axis (>= 1).
    dtype : numpy dtype, optional
        Precision of the returned weights ``f`` (default float64).

    Returns
    -------
    i0, i1 : ndarray of intp, shape coord.shape
        The two taps; the sample is ``(1 - f) a[i0] + f a[i1]``.
    f : ndarray of ``dtype``, shape coord.shape
        Weight of ``i1``, computed in float64 on the clamped coordinate and then cast.
    valid : ndarray of bool, shape coord.shape
        True where the coordinate is finite and inside ``[0, n - 1]`` within
        :data:`INSIDE_EPS`. Non-finite coordinates get the taps of coordinate 0.

    Examples
    --------
    >>> i0, i1, f, valid = coordinate_taps([-0.5, 0.25, 3.0], 4)
    >>> i0.tolist(), i1.tolist(), f.tolist(), valid.tolist()
    ([0, 0, 2], [1, 1, 3], [0.0, 0.25, 1.0], [False, True, True])
    """
    c = _opt.real_array(coord, "coordinates")
    n = _axis_length(n)
    _opt.float_dtype(dtype)
    finite = np.isfinite(c)
    valid = finite & (c >= -INSIDE_EPS) & (c <= n - 1 + INSIDE_EPS)
    cc = np.clip(c, 0.0, n - 1)
    if not finite.all():
        cc = np.where(finite, cc, 0.0)
    i0 = np.minimum(np.floor(cc).astype(np.intp), max(n - 2, 0))
    i1 = np.minimum(i0 + 1, n - 1)
    f = cc - i0
    if np.dtype(dtype) != f.dtype:
        f = f.astype(dtype)
    return i0, i1, f, valid


def axis_taps(n: int, shift: float, pad: int = 0, *, dtype=np.float64):
    """Taps of the shifted grid ``i + shift``, ``i = -pad .. n - 1 + pad`` (clamped).

    Parameters
    ----------
    n : int
        Axis length.
    shift : float
        Shift in pixels.
    pad : int, optional
        Extra samples on each side of the grid.
    dtype : numpy dtype, optional
        Precision of the weights (default float64).

    Returns
    -------
    i0, i1, f : ndarray, shape (n + 2 pad,)
        As :func:`coordinate_taps`; clamping makes every sample outside the image take the
        nearest border value (replicated border).

    Examples
    --------
    >>> i0, i1, f = axis_taps(3, 0.5)
    >>> i0.tolist(), i1.tolist(), f.tolist()
    ([0, 1, 1], [1, 2, 2], [0.5, 0.5, 1.0])
    """
    n, shift = _axis_length(n), _opt.real(shift, "shift")
    pad = _opt.integer(pad, "pad", maximum=MAX_PAD)
    i0, i1, f, _ = coordinate_taps(np.arange(-pad, n + pad, dtype=np.float64) + shift, n,
                                   dtype=dtype)
    return i0, i1, f


def axis_valid(n: int, shift: float) -> np.ndarray:
    """True where ``i + shift`` (``i = 0 .. n - 1``) lies inside ``[0, n - 1]``.

    Within :data:`INSIDE_EPS`; the ``valid`` of :func:`coordinate_taps` on the shifted grid.

    Examples
    --------
    >>> axis_valid(3, 0.5).tolist()
    [True, True, False]
    """
    n, shift = _axis_length(n), _opt.real(shift, "shift")
    return coordinate_taps(np.arange(n, dtype=np.float64) + shift, n)[3]


def _interp_axis(a: np.ndarray, axis: int, i0, i1, f, skip_zero: bool) -> np.ndarray:
    """``(1 - f) a[i0] + f a[i1]`` along ``axis`` (``f`` broadcast along it)."""
    if skip_zero and not np.any(f != 0):
        return np.take(a, i0, axis=axis)
    shape = [1] * a.ndim
    shape[axis] = -1
    f = f.reshape(shape)
    return np.take(a, i0, axis=axis) * (1 - f) + np.take(a, i1, axis=axis) * f


def shift_map(img, sx: float, sy: float, pad: int = 0, *, edge: str = "clamp",
              fill: float = np.nan, dtype=np.float64, order: str = "yx",
              channel_axis: int | None = None, skip_zero: bool = False):
    """Sample ``img`` at ``(x + sx, y + sy)`` for every pixel: a separable bilinear shift.

    Parameters
    ----------
    img : array_like, shape (..., H, W), or (H, W, K) with ``channel_axis=-1``
        Leading axes (channel stacks) are carried along.
    sx, sy : float
        Shift in pixels along x (columns) and y (rows).
    pad : int, optional
        Sample the grid ``y = -pad .. H - 1 + pad``, ``x = -pad .. W - 1 + pad`` (only with
        ``edge="clamp"``).
    edge : {"clamp", "mask"}, optional
        Edge rule (module docstring). Default ``"clamp"``: replicated border.
    fill : float, optional
        Value of the invalid samples with ``edge="mask"`` (default NaN).
    dtype : numpy dtype, optional
        Precision of the weights (default float64); the result has the promoted dtype of
        ``img`` and ``dtype``.
    order : {"yx", "xy"}, optional
        Interpolate along y first (default), or along x first.
    channel_axis : {None, -1}, optional
        ``-1`` for channel-last images ``(H, W, K)``.
    skip_zero : bool, optional
        Where every weight along an axis is 0 (a negative integer shift) take the ``i0``
        samples as they are instead of computing ``1 * a + 0 * b`` (faster; differs only for
        non-finite neighbours and the sign of zero).

    Returns
    -------
    out : ndarray
        The shifted image (padded grid when ``pad > 0``).
    valid : ndarray of bool, shape (H, W)
        True where the unpadded sample lies inside the image.

    Examples
    --------
    >>> ramp = np.arange(4.0)[None, :].repeat(2, axis=0)
    >>> out, valid = shift_map(ramp, 0.5, 0.0)
    >>> out[0].tolist(), valid[0].tolist()
    ([0.5, 1.5, 2.5, 3.0], [True, True, True, False])
    """
    _check_edge(edge)
    a = np.asarray(img)
    _opt.choice(channel_axis, "channel_axis", (None, -1))
    _opt.choice(order, "order", ("yx", "xy"))
    sx, sy = _offset_px(sx, sy)
    fill = _opt.real(fill, "fill", nan=True)
    pad = _opt.integer(pad, "pad", maximum=MAX_PAD)
    _opt.flag(skip_zero, "skip_zero")
    _opt.float_dtype(dtype)
    if a.ndim < (3 if channel_axis == -1 else 2):
        raise InvalidInputError(f"img must be (..., H, W){' x K' if channel_axis == -1 else ''}"
                                f", got shape {a.shape}")
    if edge == "mask" and pad:
        raise InvalidInputError("pad needs edge='clamp' (the padded samples are outside)")
    ay, ax = (a.ndim - 3, a.ndim - 2) if channel_axis == -1 else (a.ndim - 2, a.ndim - 1)
    H, W = a.shape[ay], a.shape[ax]
    y0, y1, fy, vy = coordinate_taps(np.arange(-pad, H + pad, dtype=np.float64) + sy, H,
                                     dtype=dtype)
    x0, x1, fx, vx = coordinate_taps(np.arange(-pad, W + pad, dtype=np.float64) + sx, W,
                                     dtype=dtype)
    if order == "yx":
        out = _interp_axis(_interp_axis(a, ay, y0, y1, fy, skip_zero), ax, x0, x1, fx, skip_zero)
    else:
        out = _interp_axis(_interp_axis(a, ax, x0, x1, fx, skip_zero), ay, y0, y1, fy, skip_zero)
    valid = vy[pad:pad + H, None] & vx[None, pad:pad + W]
    if edge == "mask" and not valid.all():
        out = np.where(valid[..., None] if channel_axis == -1 else valid, out, fill)
    return out, valid


def sample_bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray,
                    fill: float = np.nan, *, edge: str = "mask",
                    dtype=np.float64) -> tuple[np.ndarray, np.ndarray]:
    """Sample ``image`` at float coordinates by bilinear interpolation.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, K)
    x, y : ndarray, same shape (any)
        Column and row coordinates in pixels (pixel centres at integers).
    fill : float
        Value of the invalid samples (``edge="mask"``; with ``"clamp"`` only non-finite
        coordinates get it).
    edge : {"mask", "clamp"}, optional
        Edge rule (module docstring). Default ``"mask"``.
    dtype : numpy dtype, optional
        Precision of the weights (default float64).

    Returns
    -------
    values : ndarray, shape x.shape (+ (K,))
        dtype ``result_type(image.dtype, float32)``.
    valid : ndarray of bool, shape x.shape
        True where the sample lies inside the image.

    Examples
    --------
    >>> img = np.array([[0.0, 1.0], [2.0, 3.0]])
    >>> vals, valid = sample_bilinear(img, np.array([0.5, 2.0]), np.array([0.5, 0.0]))
    >>> vals.tolist(), valid.tolist()
    ([1.5, nan], [True, False])
    """
    _check_edge(edge)
    fill = _opt.real(fill, "fill", nan=True)
    _opt.float_dtype(dtype)
    x, y = _opt.real_array(x, "x"), _opt.real_array(y, "y")
    _broadcast_xy(x, y)
    img = _image(image)
    H, W = img.shape[:2]
    x0, x1, fx, vx = coordinate_taps(x, W, dtype=dtype)
    y0, y1, fy, vy = coordinate_taps(y, H, dtype=dtype)
    valid = vx & vy
    if img.ndim == 3:
        fx = fx[..., None]
        fy = fy[..., None]
    out = ((img[y0, x0] * (1 - fx) + img[y0, x1] * fx) * (1 - fy)
           + (img[y1, x0] * (1 - fx) + img[y1, x1] * fx) * fy)
    out = out.astype(np.result_type(img.dtype, np.float32), copy=False)
    bad = ~valid if edge == "mask" else ~(np.isfinite(x) & np.isfinite(y))
    if bad.any():
        out[bad] = fill
    return out, valid


def bilinear_taps(x, y, shape: tuple[int, int], *, dtype=np.float64):
    """The four taps of each bilinear sample at ``(x, y)`` in an ``(H, W)`` image.

    Parameters
    ----------
    x, y : array_like of float, same shape
        Column and row coordinates.
    shape : (H, W)
    dtype : numpy dtype, optional
        Precision of the weights (default float64).

    Returns
    -------
    valid : ndarray of bool
        Inside the image (as :func:`sample_bilinear`); taps of invalid samples are clamped
        and must be ignored by the caller.
    idx : tuple of 4 ndarrays of intp
        Flat indices ``y * W + x`` of the taps (top-left, top-right, bottom-left, bottom-right).
    wts : tuple of 4 ndarrays
        Their weights ``(1-fx)(1-fy), fx(1-fy), (1-fx)fy, fx fy``.

    Examples
    --------
    >>> valid, idx, wts = bilinear_taps(np.array([0.5]), np.array([1.0]), (3, 2))
    >>> [int(i[0]) for i in idx], [float(w[0]) for w in wts]
    ([2, 3, 4, 5], [0.5, 0.5, 0.0, 0.0])
    """
    H, W = _opt.int_pair(shape, "shape", 1, what="(H, W), two integers")
    _broadcast_xy(x, y)
    x0, x1, fx, vx = coordinate_taps(x, W, dtype=dtype)
    y0, y1, fy, vy = coordinate_taps(y, H, dtype=dtype)
    idx = (y0 * W + x0, y0 * W + x1, y1 * W + x0, y1 * W + x1)
    wts = ((1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy)
    return vx & vy, idx, wts


def gather_taps(flat: np.ndarray, idx, wts) -> np.ndarray:
    """Bilinear samples from the taps of :func:`bilinear_taps`: ``sum_k flat[idx_k] wts_k``.

    Parameters
    ----------
    flat : ndarray (H * W,)
        The image, flattened (row-major).
    idx, wts : tuples of 4 ndarrays
        From :func:`bilinear_taps`.

    Returns
    -------
    ndarray, shape of the taps
        dtype: promotion of ``flat`` and the weights.

    Examples
    --------
    >>> img = np.array([[0.0, 1.0], [2.0, 3.0]])
    >>> valid, idx, wts = bilinear_taps(np.array([0.5]), np.array([0.5]), img.shape)
    >>> gather_taps(img.ravel(), idx, wts).tolist()
    [1.5]
    """
    # O(1) checks (called per view and band): types and shapes; the indices' range is
    # checked by numpy's own gather, whose IndexError is turned into our message
    if not isinstance(flat, np.ndarray) or flat.ndim != 1 or flat.dtype.kind not in "biuf":
        raise InvalidInputError(f"flat must be a 1-D real image array (image.ravel()), got "
                                f"{_opt.shown(flat)}")
    for name, taps, kinds in (("idx", idx, "iu"), ("wts", wts, "biuf")):
        if not (isinstance(taps, (tuple, list)) and len(taps) == 4 and all(
                isinstance(t, np.ndarray) and t.dtype.kind in kinds for t in taps)):
            raise InvalidInputError(f"{name} must be the 4 {'index' if name == 'idx' else 'weight'}"
                                    f" arrays of bilinear_taps, got {_opt.shown(taps)}")
    shape = idx[0].shape
    if any(t.shape != shape for t in (*idx, *wts)):
        raise InvalidInputError("idx and wts must be 8 arrays of one shape (from bilinear_taps)")
    try:
        return (flat[idx[0]] * wts[0] + flat[idx[1]] * wts[1]
                + flat[idx[2]] * wts[2] + flat[idx[3]] * wts[3])
    except IndexError:
        raise InvalidInputError(f"idx holds indices beyond the {flat.size} pixels of flat (taps "
                                f"of another image shape?)") from None


def shift_image(image: np.ndarray, dx: float, dy: float, fill: float = np.nan, *,
                edge: str = "mask") -> tuple[np.ndarray, np.ndarray]:
    """Resample ``image`` at ``(x + dx, y + dy)`` for every pixel ``(x, y)``.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, K)
    dx, dy : float
        Shift in pixels.
    fill : float, optional
        Value of the invalid samples.
    edge : {"mask", "clamp"}, optional
        Edge rule (module docstring).

    Returns
    -------
    shifted, valid
        As :func:`sample_bilinear`.

    Examples
    --------
    >>> shift_image(np.array([[0.0, 1.0, 2.0]]), 1.0, 0.0)[0].tolist()
    [[1.0, 2.0, nan]]
    """
    H, W = _image(image).shape[:2]
    dx, dy = _offset((dx, dy))
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    return sample_bilinear(image, xx + dx, yy + dy, fill=fill, edge=edge)


def warp_to_reference(image: np.ndarray, disparity: np.ndarray, offset: tuple[float, float],
                      fill: float = np.nan, *, edge: str = "mask") -> tuple[np.ndarray, np.ndarray]:
    """Backward-warp a view into the reference view's frame (SPEC §1 sign convention).

    A reference pixel ``(x, y)`` with disparity ``d`` appears in the view at
    ``(x - d * dx, y - d * dy)`` where ``(dx, dy) = pos_view - pos_ref``.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, K)
        The other view.
    disparity : ndarray, shape (H, W) or scalar
        Disparity of the reference view (px per baseline); non-finite = invalid, set to ``fill``.
    offset : (dx, dy)
        View position minus reference position, in baselines.
    fill : float, optional
        Value of the invalid samples.
    edge : {"mask", "clamp"}, optional
        Edge rule for samples outside the view (module docstring).

    Returns
    -------
    warped : ndarray, same shape as ``image``
    valid : ndarray of bool, shape (H, W)

    Examples
    --------
    >>> view = np.tile(np.arange(5.0), (3, 1))
    >>> warped, valid = warp_to_reference(view, 1.0, (1.0, 0.0))
    >>> warped[0].tolist()
    [nan, 0.0, 1.0, 2.0, 3.0]
    """
    img = _image(image)
    H, W = img.shape[:2]
    d = _opt.real_array(disparity, "disparity")
    if d.shape not in ((), (H, W)):
        raise InvalidInputError(f"disparity must be a scalar or an ({H}, {W}) map, got shape "
                                f"{d.shape}")
    d = np.broadcast_to(d, (H, W))
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    dx, dy = _offset(offset)
    valid_d = np.isfinite(d)
    d = np.where(valid_d, d, 0.0)
    out, valid = sample_bilinear(img, xx - d * dx, yy - d * dy, fill=fill, edge=edge)
    valid &= valid_d
    if not valid_d.all():
        out[~valid_d] = fill
    return out, valid


def forward_warp_disparity(disparity: np.ndarray, offset: tuple[float, float]) -> np.ndarray:
    """Forward-warp a reference disparity map into another view (z-buffer, SPEC §7.1).

    Each reference pixel lands at the nearest pixel of ``(x - d dx, y - d dy)``; where several
    land on the same pixel the larger disparity (nearer surface) wins. Pixels nothing lands on
    are NaN (holes).

    Parameters
    ----------
    disparity : ndarray, shape (H, W)
        Reference disparity (px per baseline); NaN = unknown.
    offset : (dx, dy)
        View position minus reference position, in baselines.

    Returns
    -------
    ndarray of float32, shape (H, W)

    Examples
    --------
    >>> forward_warp_disparity(np.ones((1, 3)), (1.0, 0.0)).tolist()
    [[1.0, 1.0, nan]]
    """
    d = _disparity_map(disparity)
    H, W = d.shape
    ok, idx = _forward_targets(d, offset)
    out = np.full(H * W, -np.inf)
    np.maximum.at(out, idx[ok], d[ok])
    out[~np.isfinite(out)] = np.nan
    return out.reshape(H, W).astype(np.float32)


def _forward_targets(d: np.ndarray, offset, rounding=(np.rint, np.rint)):
    """``(ok, idx)``: where each reference pixel lands in the view (flat index of the pixel
    ``rounding`` (x, y) gives, the nearest by default; ``ok`` False for unknown disparities and
    landings outside the image)."""
    H, W = d.shape
    yy, xx = np.mgrid[0:H, 0:W]
    dx, dy = _offset(offset)
    ok = np.isfinite(d)
    with np.errstate(invalid="ignore"):
        tx = rounding[0](xx - d * dx)
        ty = rounding[1](yy - d * dy)
        ok &= (tx >= 0) & (tx < W) & (ty >= 0) & (ty < H)
    idx = np.where(ok, ty, 0).astype(np.intp) * W + np.where(ok, tx, 0).astype(np.intp)
    return ok, idx


def occlusion_zbuffer(disparity: np.ndarray, offset: tuple[float, float]) -> np.ndarray:
    """The nearest reference surface at every pixel of another view, splatted for z-tests.

    Each reference pixel lands at ``(x - d dx, y - d dy)``; its disparity is written onto the
    2 x 2 pixels around the landing point (an occluder's edge, which pixel centres sample only
    to half a pixel, is not missed) and the largest (nearest) wins.  The z-buffer of
    :func:`visible_in_view` and :func:`visible_at_labels`.

    Parameters
    ----------
    disparity : ndarray, shape (H, W)
        Reference disparity (px per baseline); NaN = unknown (lands nowhere).
    offset : (dx, dy)
        View position minus reference position, in baselines.

    Returns
    -------
    ndarray of float64, shape (H, W)
        ``-inf`` where nothing lands.

    Examples
    --------
    >>> occlusion_zbuffer(np.array([[0.0, 2.0, 0.0]]), (0.25, 0.0)).tolist()  # lands at 0.5
    [[2.0, 2.0, 0.0]]
    """
    d = _disparity_map(disparity)
    H, W = d.shape
    z = np.full(H * W, -np.inf)
    for rounding in ((np.floor, np.floor), (np.floor, np.ceil), (np.ceil, np.floor),
                     (np.ceil, np.ceil)):  # every pixel the landing point touches
        ok, idx = _forward_targets(d, offset, rounding)
        np.maximum.at(z, idx[ok], d[ok])
    return z.reshape(H, W)


def visible_in_view(disparity: np.ndarray, offset: tuple[float, float], *,
                    margin: float = 0.5) -> np.ndarray:
    """Which reference pixels another view sees (SPEC §5.6 a): the z-test of
    :func:`forward_warp_disparity`.

    Reference pixel ``p`` lands at the nearest pixel ``t`` of ``p - d(p) (dx, dy)``; the view
    sees it when no reference pixel whose landing point touches ``t`` (lies within one pixel
    of it along each axis: the z-buffer is splatted onto the 2 x 2 pixels around every landing
    point, so that an occluder's edge, which pixel centres sample only to half a pixel, is not
    missed) is nearer by more than ``margin`` (px per baseline): ``d(p) >= max d(t) - margin``.
    The test errs on the side of "hidden": a view dropped near an edge costs one vote, a view
    that cannot see the pixel would cast a wrong one.  A pixel landing outside the image, or with an
    unknown disparity, is not seen.  Surfaces the reference does not see cannot occlude here.

    Parameters
    ----------
    disparity : ndarray, shape (H, W)
        Reference disparity; NaN = unknown.
    offset : (dx, dy)
        View position minus reference position, in baselines.
    margin : float
        Disparity difference below which two surfaces count as one (>= 0).

    Returns
    -------
    ndarray of bool, shape (H, W)

    Examples
    --------
    >>> d = np.array([[0.0, 0.0, 1.0, 1.0]])  # a nearer surface on the right
    >>> visible_in_view(d, (1.0, 0.0)).tolist()   # the view 1 baseline right: x - d
    [[True, False, True, True]]
    """
    d = _disparity_map(disparity)
    margin = _opt.real(margin, "margin")
    H, W = d.shape
    z = occlusion_zbuffer(d, offset).ravel()
    ok, idx = _forward_targets(d, offset)
    seen = np.zeros(H * W, bool)
    flat = d.ravel()
    sel = ok.ravel()
    seen[sel] = flat[sel] >= z[idx.ravel()[sel]] - float(margin)
    return seen.reshape(H, W)


def visible_at_labels(zbuffer: np.ndarray, offset: tuple[float, float], labels, *,
                      rows: tuple[int, int] | None = None, margin: float = 0.5,
                      impl: str = "auto") -> np.ndarray:
    """Which reference pixels another view would see *at each candidate disparity*.

    The z-test of :func:`visible_in_view` asked of every hypothesis instead of the current
    estimate only: reference pixel ``p`` at disparity ``d`` lands at the nearest pixel ``t`` of
    ``p - d (dx, dy)``, and the view sees it there when the nearest surface that the current
    estimate puts at ``t`` (``zbuffer``, :func:`occlusion_zbuffer`) is not nearer than ``d`` by
    more than ``margin``: ``d >= zbuffer[t] - margin``.  A background pixel that the estimate
    gave the foreground (a fattened edge) is then matched, at the background's disparity,
    over the views that see the background there, and the foreground's disparity over all.
    Landing outside the image: not seen.

    Parameters
    ----------
    zbuffer : ndarray, shape (H, W)
        :func:`occlusion_zbuffer` of the current estimate for this view.
    offset : (dx, dy)
        View position minus reference position, in baselines.
    labels : array_like, shape (L,)
        Candidate disparities.
    rows : (int, int), optional
        Reference rows ``[a, b)`` to answer for (default all).
    margin : float
        Disparity difference below which two surfaces count as one (>= 0).
    impl : {"auto", "numba", "numpy"}
        ``numpy`` is the reference the numba kernel is tested against.

    Returns
    -------
    ndarray of bool, shape (L, b - a, W)

    Examples
    --------
    A nearer surface on the left, seen from a view that shifts content right (``x + d``):
    at disparity 0 the two background pixels beside it are hidden, at 2 they are seen (the
    last two would land outside the image).

    >>> z = occlusion_zbuffer(np.array([[2.0, 2.0, 0.0, 0.0, 0.0]]), (-1.0, 0.0))
    >>> visible_at_labels(z, (-1.0, 0.0), [0.0, 2.0], impl="numpy")[:, 0].tolist()
    [[True, True, False, False, True], [True, True, True, False, False]]
    """
    z, dx, dy, lab, a, b = _label_test_inputs(zbuffer, offset, labels, rows, impl)
    margin = _opt.real(margin, "margin")
    if impl == "numpy":
        return _visible_at_labels_reference(z, dx, dy, lab, a, b, float(margin))
    from . import _warp_kernels

    out = np.empty((lab.size, b - a, z.shape[1]), np.bool_)
    _warp_kernels.visible_at_labels(z, dx, dy, lab, a, b, float(margin), out)
    return out


def occluder_excess(zbuffer: np.ndarray, offset: tuple[float, float], labels, *,
                    rows: tuple[int, int] | None = None, impl: str = "auto") -> np.ndarray:
    """How much nearer than each candidate disparity the surface is that would hide a
    reference pixel from another view: ``zbuffer[t] - d``.

    The quantity that :func:`visible_at_labels` compares with its margin: reference pixel
    ``p`` at disparity ``d`` lands at the nearest pixel ``t`` of ``p - d (dx, dy)``, and the
    view sees it with margin ``m`` when the excess is at most ``m``.  Where fewer views than
    needed see a hypothesis, the views whose occluders are the least nearer are the ones to
    ask (:class:`hyperlf.hlf.LabelVisibility`, ``DepthParams.nearest_occluders``).

    Parameters
    ----------
    zbuffer, offset, labels, rows, impl
        As for :func:`visible_at_labels`.

    Returns
    -------
    ndarray of float32, shape (L, b - a, W)
        px per baseline (computed in float64); ``+inf`` where ``p`` at ``d`` lands outside
        the image, ``-inf`` where no surface of the estimate lands near ``t``.

    Examples
    --------
    The nearer surface on the left of :func:`visible_at_labels`' example hides the two
    background pixels beside it by 2 px at disparity 0 (where the first two land, nothing
    does); at disparity 2 nothing hides them:

    >>> z = occlusion_zbuffer(np.array([[2.0, 2.0, 0.0, 0.0, 0.0]]), (-1.0, 0.0))
    >>> occluder_excess(z, (-1.0, 0.0), [0.0, 2.0], impl="numpy")[:, 0].tolist()
    [[-inf, -inf, 2.0, 2.0, 0.0], [0.0, 0.0, -2.0, inf, inf]]
    """
    z, dx, dy, lab, a, b = _label_test_inputs(zbuffer, offset, labels, rows, impl)
    if impl == "numpy":
        return _occluder_excess_reference(z, dx, dy, lab, a, b)
    from . import _warp_kernels

    out = np.empty((lab.size, b - a, z.shape[1]), np.float32)
    _warp_kernels.occluder_excess(z, dx, dy, lab, a, b, out)
    return out


def _label_test_inputs(zbuffer, offset, labels, rows, impl):
    """:func:`visible_at_labels`' and :func:`occluder_excess`'s inputs checked:
    ``(z, dx, dy, labels, a, b)``."""
    _opt.choice(impl, "impl", ("auto", "numba", "numpy"))
    z = np.asarray(zbuffer)  # float32 as kept by LabelVisibility: no copy per call
    if z.ndim != 2 or z.dtype.kind not in "biuf":  # O(1) checks: called once per view
        raise InvalidInputError(f"zbuffer must be an (H, W) map of disparities "
                                f"(occlusion_zbuffer), got {_opt.shown(zbuffer)}")
    z = np.ascontiguousarray(z, z.dtype if z.dtype in (np.float32, np.float64) else np.float64)
    H = z.shape[0]
    a, b = (0, H) if rows is None else _opt.int_pair(rows, "rows", 0, maximum=H,
                                                     what="(first, end) reference rows")
    if a > b:
        raise InvalidInputError(f"rows must be (first, end) with first <= end, got {rows}")
    lab = np.ascontiguousarray(_opt.real_array(labels, "labels").ravel())
    if not np.isfinite(lab).all():  # L values, not a map
        raise InvalidInputError("labels must be finite disparities")
    dx, dy = _offset(offset)
    return z, dx, dy, lab, a, b


def _visible_at_labels_reference(z, dx, dy, labels, a, b, margin):
    """The numpy reference of :func:`visible_at_labels` (one label at a time)."""
    out = np.zeros((labels.size, b - a, z.shape[1]), bool)
    for i, d in enumerate(labels):
        ok, near = _landing_zbuffer(z, dx, dy, d, a, b)
        out[i] = ok & (d >= near - margin)  # as the kernel: in float64
    return out


def _occluder_excess_reference(z, dx, dy, labels, a, b):
    """The numpy reference of :func:`occluder_excess` (one label at a time)."""
    out = np.full((labels.size, b - a, z.shape[1]), np.inf, np.float32)
    for i, d in enumerate(labels):
        ok, near = _landing_zbuffer(z, dx, dy, d, a, b)
        out[i][ok] = (near - d)[ok]  # as the kernel: in float64, stored as float32
    return out


def _landing_zbuffer(z, dx, dy, d, a, b):
    """Where reference rows ``[a, b)`` at disparity ``d`` land inside the image, and the
    z-buffer there (float64; 0 elsewhere)."""
    H, W = z.shape
    yy, xx = np.mgrid[a:b, 0:W].astype(np.float64)
    tx, ty = np.rint(xx - d * dx), np.rint(yy - d * dy)
    ok = (tx >= 0) & (tx < W) & (ty >= 0) & (ty < H)
    near = z[np.where(ok, ty, 0).astype(np.intp), np.where(ok, tx, 0).astype(np.intp)]
    return ok, near.astype(np.float64)
