"""Sub-pixel image shifts and warps (SPEC §1 "Sub-pixel sampling").

Bilinear interpolation; samples that fall outside the image are *invalid* (returned in a mask,
value set to ``fill``), never silently zero-filled. All functions work on single 2-D images or on
stacks whose last two axes are ``(H, W)``... except where noted; channel-last colour images are
handled by passing ``channel_axis=-1``.
"""

from __future__ import annotations

import numpy as np

from .errors import InvalidInputError

__all__ = [
    "sample_bilinear",
    "shift_image",
    "shift_map",
    "axis_taps",
    "axis_valid",
    "warp_to_reference",
    "forward_warp_disparity",
]

#: Tolerance (px) within which a sample just outside ``[0, n - 1]`` still counts as inside.
INSIDE_EPS = 1e-6


def sample_bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray,
                    fill: float = np.nan) -> tuple[np.ndarray, np.ndarray]:
    """Sample ``image`` at float coordinates by bilinear interpolation.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, K)
    x, y : ndarray, same shape (any)
        Column and row coordinates in pixels (pixel centres at integers).
    fill : float
        Value given to samples outside ``[0, W-1] x [0, H-1]``.

    Returns
    -------
    values : ndarray, shape x.shape (+ (K,))
    valid : ndarray of bool, shape x.shape
        True where the sample lies inside the image.
    """
    img = np.asarray(image)
    if img.ndim not in (2, 3):
        raise InvalidInputError(f"image must be (H, W) or (H, W, K), got shape {img.shape}")
    H, W = img.shape[:2]
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    eps = 1e-6
    valid = (x >= -eps) & (x <= W - 1 + eps) & (y >= -eps) & (y <= H - 1 + eps)
    xc = np.clip(x, 0, W - 1)
    yc = np.clip(y, 0, H - 1)
    x0 = np.minimum(np.floor(xc).astype(np.intp), max(W - 2, 0))
    y0 = np.minimum(np.floor(yc).astype(np.intp), max(H - 2, 0))
    x1 = np.minimum(x0 + 1, W - 1)
    y1 = np.minimum(y0 + 1, H - 1)
    fx = xc - x0
    fy = yc - y0
    if img.ndim == 3:
        fx = fx[..., None]
        fy = fy[..., None]
    out = ((img[y0, x0] * (1 - fx) + img[y0, x1] * fx) * (1 - fy)
           + (img[y1, x0] * (1 - fx) + img[y1, x1] * fx) * fy)
    out = out.astype(np.result_type(img.dtype, np.float32), copy=False)
    if not valid.all():
        out[~valid] = fill
    return out, valid


def shift_image(image: np.ndarray, dx: float, dy: float,
                fill: float = np.nan) -> tuple[np.ndarray, np.ndarray]:
    """Resample ``image`` at ``(x + dx, y + dy)`` for every pixel ``(x, y)``.

    Returns ``(shifted, valid)``; samples from outside the image are invalid.
    """
    H, W = np.asarray(image).shape[:2]
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    return sample_bilinear(image, xx + dx, yy + dy, fill=fill)


def warp_to_reference(image: np.ndarray, disparity: np.ndarray, offset: tuple[float, float],
                      fill: float = np.nan) -> tuple[np.ndarray, np.ndarray]:
    """Backward-warp a view into the reference view's frame (SPEC §1 sign convention).

    A reference pixel ``(x, y)`` with disparity ``d`` appears in the view at
    ``(x - d * dx, y - d * dy)`` where ``(dx, dy) = pos_view - pos_ref``.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, K)
        The other view.
    disparity : ndarray, shape (H, W) or scalar
        Disparity of the reference view (px per baseline).
    offset : (dx, dy)
        View position minus reference position, in baselines.

    Returns
    -------
    warped : ndarray, same shape as ``image``
    valid : ndarray of bool, shape (H, W)
    """
    img = np.asarray(image)
    H, W = img.shape[:2]
    d = np.broadcast_to(np.asarray(disparity, dtype=np.float64), (H, W))
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    dx, dy = offset
    valid_d = np.isfinite(d)
    d = np.where(valid_d, d, 0.0)
    out, valid = sample_bilinear(img, xx - d * dx, yy - d * dy, fill=fill)
    valid &= valid_d
    if not valid_d.all():
        out[~valid_d] = fill
    return out, valid


def forward_warp_disparity(disparity: np.ndarray, offset: tuple[float, float]) -> np.ndarray:
    """Forward-warp a reference disparity map into another view (z-buffer, SPEC §7.1).

    Each reference pixel lands at the nearest pixel of ``(x - d dx, y - d dy)``; where several
    land on the same pixel the larger disparity (nearer surface) wins. Pixels nothing lands on
    are NaN (holes).

    Returns
    -------
    ndarray of float32, shape (H, W)
    """
    d = np.asarray(disparity, dtype=np.float64)
    H, W = d.shape
    yy, xx = np.mgrid[0:H, 0:W]
    dx, dy = offset
    ok = np.isfinite(d)
    tx = np.rint(xx - d * dx)
    ty = np.rint(yy - d * dy)
    ok &= (tx >= 0) & (tx < W) & (ty >= 0) & (ty < H)
    out = np.full(H * W, -np.inf)
    idx = (ty[ok].astype(np.intp) * W + tx[ok].astype(np.intp))
    np.maximum.at(out, idx, d[ok])
    out[~np.isfinite(out)] = np.nan
    return out.reshape(H, W).astype(np.float32)


def axis_taps(n: int, shift: float, pad: int = 0):
    """Separable bilinear taps along one axis, coordinates clamped (replicated border).

    For ``i = -pad .. n - 1 + pad`` the sample ``i + shift`` is
    ``(1 - f) a[i0] + f a[i1]`` with the returned ``(i0, i1, f)`` (int64, int64, float64).
    Clamping makes every window pixel outside the image take the nearest border value.
    """
    coord = np.clip(np.arange(-pad, n + pad, dtype=np.float64) + shift, 0.0, n - 1)
    i0 = np.minimum(np.floor(coord).astype(np.int64), max(n - 2, 0))
    i1 = np.minimum(i0 + 1, n - 1)
    f = coord - i0
    return i0, i1, f


def axis_valid(n: int, shift: float) -> np.ndarray:
    """True where ``i + shift`` (``i = 0 .. n - 1``) lies inside ``[0, n - 1]`` (within
    :data:`INSIDE_EPS`)."""
    c = np.arange(n, dtype=np.float64) + shift
    return (c >= -INSIDE_EPS) & (c <= n - 1 + INSIDE_EPS)


def shift_map(img: np.ndarray, sx: float, sy: float, pad: int = 0):
    """Sample ``img[..., y + sy, x + sx]`` bilinearly on a grid padded by ``pad`` pixels.

    The grid is ``y = -pad .. H - 1 + pad``, ``x = -pad .. W - 1 + pad``; coordinates are
    clamped (replicated border, :func:`axis_taps`), the result is float64.  Also returns the
    validity ``(H, W)`` of the unpadded samples (inside the image, :func:`axis_valid`).
    Leading axes are carried along (channel stacks ``(..., H, W)``).
    """
    a = np.asarray(img, dtype=np.float64)
    H, W = a.shape[-2:]
    y0, y1, fy = axis_taps(H, sy, pad)
    x0, x1, fx = axis_taps(W, sx, pad)
    rows = a[..., y0, :] * (1 - fy)[:, None] + a[..., y1, :] * fy[:, None]
    out = rows[..., x0] * (1 - fx) + rows[..., x1] * fx
    valid = axis_valid(H, sy)[:, None] & axis_valid(W, sx)[None, :]
    return out, valid
