"""Pictures of a calibration for users: detected corners, registered views, residual vectors.

Matplotlib is imported inside the functions (Agg backend); files are written atomically. Every
view is stretched on its own (0.5-99.5 percentiles): the cameras see different bands with
different exposures, and a shared scale would hide the dim ones.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping

import numpy as np

from .. import _options as _opt
from ..errors import InvalidInputError
from ..visualise import display_step, pyplot, save_figure
from .board import camera_label
from .grid import check_images
from .model import Calibration, check_calibration


def _title(value, optional: bool = False):
    return _opt.text(value, "title", optional=optional, printable=True)


def _stretch(img: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    a = np.asarray(img, np.float64)
    sel = a[valid] if valid is not None and valid.any() else a
    lo, hi = np.percentile(sel, [0.5, 99.5]) if sel.size else (0.0, 1.0)
    return np.clip((a - lo) / max(hi - lo, 1e-12), 0, 1)


#: Longest side, in px, of a grid of views as drawn (views are subsampled to it first).
MAX_SIDE = 1600


def _show(ax, img, size, **kw):
    """``img`` (a view subsampled for display) on ``ax``, placed in the full image's pixel
    coordinates (``size`` ``(W, H)``), so that corners and guide lines land as measured."""
    W, H = size
    ax.imshow(img, extent=(-0.5, W - 0.5, H - 0.5, -0.5), **kw)


def _grid_axes(keys, size, title):
    """The figure and axes of a grid of views of ``size`` ``(W, H)``, and the stride that
    subsamples each view to what the grid shows (:data:`MAX_SIDE`)."""
    plt = pyplot()
    R = max(k[0] for k in keys) + 1
    C = max(k[1] for k in keys) + 1
    W, H = size
    fig, axes = plt.subplots(R, C, figsize=(2.6 * C, 2.6 * R * H / W + 0.4), squeeze=False)
    for ax in axes.ravel():
        ax.set_axis_off()
    if title:
        fig.suptitle(title)
    return fig, axes, display_step(R * H, C * W, MAX_SIDE)


def save_corner_pictures(path: str | os.PathLike, shots: Mapping, corners: Mapping, *,
                         names: Mapping | None = None, title: str = "detected board corners"
                         ) -> Path:
    """One picture of every camera's shot with its detected corners.

    Corners are coloured by their canonical index (the first one circled in red), so the same
    colour is the same physical corner in every camera; a camera without a detection is
    labelled "not found", one that saw part of the board (NaN corners) says how much.

    Parameters
    ----------
    path : path-like
        Output PNG.
    shots : mapping (row, col) -> ndarray (H, W)
    corners : mapping (row, col) -> ndarray (N, 2) or None
    names : mapping, optional
    title : str

    Returns
    -------
    Path
    """
    _opt.path_like(path)
    if not _opt.mapping(shots, "shots", optional=False):
        raise InvalidInputError("no shots to draw")
    for k in shots:
        _opt.int_pair(k, "a camera of shots", 0, what="(row, col)")
    check_images(shots, names, what="shot")
    _opt.mapping(corners, "corners", optional=False)
    for k, c in corners.items():
        a = None if c is None else _opt.real_array(c, f"corners of camera {camera_label(k, names)}")
        if a is not None and (a.ndim != 2 or a.shape[1] != 2):
            raise InvalidInputError(f"corners of camera {camera_label(k, names)} must be (N, 2) "
                                    f"or None, got shape {a.shape}")
    _title(title)
    keys = list(shots)
    H, W = np.asarray(shots[keys[0]]).shape[:2]
    fig, axes, step = _grid_axes(keys, (W, H), title)
    for key in keys:
        ax = axes[key[0], key[1]]
        shot = np.asarray(shots[key])
        _show(ax, _stretch(shot[::step, ::step]), shot.shape[1::-1], cmap="gray",
              interpolation="nearest")
        c = corners.get(key)
        if c is None:
            ax.set_title(f"{camera_label(key, names)}: not found", fontsize=7, color="red")
            continue
        ax.scatter(c[:, 0], c[:, 1], c=np.arange(len(c)), cmap="viridis", s=4)
        ax.scatter(c[:1, 0], c[:1, 1], s=40, facecolors="none", edgecolors="red")
        seen = int(np.all(np.isfinite(c), axis=1).sum())
        part = "" if seen == len(c) else f": {seen} of {len(c)} corners (board partly out of view)"
        ax.set_title(camera_label(key, names) + part, fontsize=7)
    return save_figure(fig, path)


def save_registration_picture(path: str | os.PathLike, views: np.ndarray, valid: np.ndarray, *,
                              names: Mapping | None = None, lines: int = 6,
                              title: str = "registered views") -> Path:
    """Registered/rectified views side by side, with the same guide lines drawn on each.

    A scene point on the board (plane mode) or at infinity (full mode) sits at the same pixel
    in every view; the guide lines make misalignment visible. Invalid pixels (outside a
    camera's image) are tinted red.

    Parameters
    ----------
    path : path-like
    views, valid : ndarray, shape (R, C, H, W)
        From :func:`~hyperlf.calibration.apply.apply_calibration`.
    names : mapping, optional
    lines : int
        Guide lines per direction.
    title : str

    Returns
    -------
    Path
    """
    _opt.path_like(path)
    v = _opt.real_array(views, "views", None)
    if v.ndim != 4 or not v.size or not (np.issubdtype(v.dtype, np.number) or v.dtype == bool):
        raise InvalidInputError(f"views must be numbers (R, C, H, W), got shape {v.shape}")
    m = _opt.bool_mask(valid, "valid", v.shape, of="the views")
    _opt.mapping(names, "names")
    lines = _opt.integer(lines, "lines", maximum=100)
    _title(title)
    R, C, H, W = v.shape
    keys = [(r, c) for r in range(R) for c in range(C)]
    fig, axes, step = _grid_axes(keys, (W, H), title)
    for r, c in keys:
        vv, mm = v[r, c, ::step, ::step], m[r, c, ::step, ::step]
        g = _stretch(vv, mm)
        rgb = np.stack([g, g, g], -1)
        rgb[~mm] = 0.5 * rgb[~mm] + [0.5, 0.0, 0.0]
        ax = axes[r, c]
        _show(ax, rgb, (W, H), interpolation="nearest")
        for x in np.linspace(0, W - 1, lines + 2)[1:-1]:
            ax.axvline(x, color="cyan", lw=0.4)
        for y in np.linspace(0, H - 1, lines + 2)[1:-1]:
            ax.axhline(y, color="cyan", lw=0.4)
        ax.set_title(camera_label((r, c), names), fontsize=7)
    return save_figure(fig, path)


def save_residual_picture(path: str | os.PathLike, calibration: Calibration, *,
                          scale: float | None = None, title: str | None = None) -> Path:
    """Corner residual vectors of every camera, magnified, with each camera's RMS.

    Parameters
    ----------
    path : path-like
    calibration : Calibration
        Fresh from :func:`~hyperlf.calibration.calibrate` (the residuals are not stored in
        the calibration file).
    scale : float, optional
        Arrow magnification; default: the largest residual is drawn 1/20 of the image wide.
    title : str, optional

    Returns
    -------
    Path

    Raises
    ------
    InvalidInputError
        The calibration has no residuals (it was read from a file).
    """
    _opt.path_like(path)
    check_calibration(calibration)
    scale = _opt.number(scale, "scale", positive=True, optional=True, at_most=1e6)
    _title(title, optional=True)
    res = calibration.residuals
    if not res:
        raise InvalidInputError("this calibration carries no corner residuals (they are not "
                                "stored in the file); draw them right after calibrating")
    W, H = calibration.image_size
    peak = max((float(np.abs(v).max()) for _, v in res.values() if len(v)), default=0.0)
    k = scale if scale is not None else (0.05 * W / peak if peak > 0 else 1.0)
    title = title or f"corner residuals ({calibration.mode} mode, arrows x{k:.0f})"
    fig, axes, _ = _grid_axes(list(calibration.cameras), (W, H), title)
    for key, cam in calibration.cameras.items():
        ax = axes[key[0], key[1]]
        ax.set_axis_on()
        ax.set_xlim(0, W - 1)
        ax.set_ylim(H - 1, 0)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_aspect("equal")
        if key in res and len(res[key][0]):
            p, v = res[key]
            ax.quiver(p[:, 0], p[:, 1], k * v[:, 0], k * v[:, 1], angles="xy",
                      scale_units="xy", scale=1, width=0.004, color="crimson")
        ax.set_title(f"{cam.name}: {cam.reprojection_error:.3f} px", fontsize=7)
    return save_figure(fig, path)
