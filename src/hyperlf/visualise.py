"""Pictures people can look at: colour-mapped disparity with a colour bar, view mosaics,
false-colour renderings of spectral light fields, error maps and spectral plots.

Matplotlib is imported lazily with the non-interactive ``Agg`` backend; every file is written
atomically.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np

from . import _options as _opt
from ._atomic import atomic_path
from .errors import InvalidInputError

__all__ = [
    "pyplot",
    "save_figure",
    "display_step",
    "save_disparity_png",
    "save_error_png",
    "save_mosaic_png",
    "save_spectrum_plot",
    "false_colour",
    "wavelength_to_rgb",
]


def pyplot():
    """matplotlib's ``pyplot`` on the non-interactive Agg backend (imported on first use).

    Examples
    --------
    >>> plt = pyplot()
    >>> plt.get_backend().lower()
    'agg'
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path) -> Path:
    """Write a matplotlib figure atomically (format from the suffix, PNG by default), close it
    and return the path: every picture hyperlf draws is written here.

    Examples
    --------
    The figure is closed once written:

    >>> import tempfile, pathlib
    >>> plt = pyplot()
    >>> fig = plt.figure()
    >>> path = save_figure(fig, pathlib.Path(tempfile.mkdtemp()) / "f.png")
    >>> path.is_file(), plt.fignum_exists(fig.number)
    (True, False)
    """
    plt = pyplot()
    if not hasattr(fig, "savefig"):
        raise InvalidInputError(f"fig must be a matplotlib figure, got {type(fig).__name__}")
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, bbox_inches="tight",
                        format=Path(path).suffix.lstrip(".") or "png")
    finally:  # a refused or failed write leaves no figure open
        plt.close(fig)
    return Path(path)


def display_step(rows: int, cols: int, max_side: int) -> int:
    """The stride (1, 2, ...) that brings a picture of ``rows`` x ``cols`` pixels to at most
    ``max_side`` on its longer side: a grid of views is subsampled to what a figure shows
    before it is drawn, so that a picture of large images costs what a small one does.

    Examples
    --------
    A 1600 x 1200 mosaic is drawn from every second pixel to fit 800 px:

    >>> display_step(1200, 1600, 800), display_step(100, 100, 800)
    (2, 1)
    """
    rows, cols = (_opt.integer(n, name, maximum=2 ** 31) for n, name in ((rows, "rows"),
                                                                         (cols, "cols")))
    max_side = _opt.integer(max_side, "max_side", 1)
    return max(1, int(np.ceil(max(rows, cols) / max_side)))


def _robust_range(values: np.ndarray, vmin=None, vmax=None) -> tuple[float, float]:
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return 0.0, 1.0
    lo = float(np.percentile(finite, 0.5)) if vmin is None else _opt.real(vmin, "vmin")
    hi = float(np.percentile(finite, 99.5)) if vmax is None else _opt.real(vmax, "vmax")
    if hi <= lo:
        hi = lo + 1e-6
    return lo, hi


def _figure_texts(**texts) -> None:
    """Titles and labels of a figure are printable text (None for no title): a control or
    unassigned character has no glyph in any font."""
    for label, value in texts.items():
        _opt.text(value, label, optional=True, printable=True)


def save_disparity_png(path: str | os.PathLike, disparity: np.ndarray, *, title: str = "disparity",
                       vmin: float | None = None, vmax: float | None = None,
                       cmap: str = "turbo", label: str = "disparity (px / baseline)") -> Path:
    """Colour-mapped disparity map with a colour bar (PNG). Unknown (NaN) pixels are black.

    Parameters
    ----------
    path : path-like
        Output PNG (parent folders are created).
    disparity : ndarray, shape (H, W)
        Values to show.
    title, label : str
        Figure title and colour-bar label.
    vmin, vmax : float, optional
        Colour range; default a robust (percentile) range of the finite values.
    cmap : str
        Matplotlib colour map.

    Returns
    -------
    Path
        The written PNG.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "new" / "d.png"  # "new" is created
    >>> save_disparity_png(out, np.eye(8)).is_file()
    True
    """
    d = _opt.real_array(disparity, "disparity")
    if d.ndim != 2:
        raise InvalidInputError(f"disparity must be 2-D, got shape {d.shape}")
    _opt.path_like(path)
    _figure_texts(title=title, label=label)
    plt = pyplot()
    _opt.choice(cmap, "cmap", tuple(plt.colormaps()))
    lo, hi = _robust_range(d, vmin, vmax)
    H, W = d.shape
    fig, ax = plt.subplots(figsize=(min(10, 2 + 6 * W / max(H, W)), 6 * H / max(H, W) + 0.6))
    cm = plt.get_cmap(cmap).with_extremes(bad="black")
    im = ax.imshow(np.ma.masked_invalid(d), cmap=cm, vmin=lo, vmax=hi, interpolation="nearest")
    ax.set_title(title)
    ax.set_axis_off()
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03, label=label, extend=_clipped(d, lo, hi))
    return save_figure(fig, path)


def _clipped(d: np.ndarray, lo: float, hi: float) -> str:
    """The colour bar's ``extend``: arrows at the ends that values pass (a robust or given
    range shows them in the end colours)."""
    finite = d[np.isfinite(d)]
    below = bool(finite.size) and float(finite.min()) < lo
    above = bool(finite.size) and float(finite.max()) > hi
    return {(False, False): "neither", (True, False): "min", (False, True): "max"}.get(
        (below, above), "both")


def save_error_png(path: str | os.PathLike, estimate: np.ndarray, truth: np.ndarray,
                   *, title: str = "absolute error", vmax: float = 1.0) -> Path:
    """Absolute disparity error map with a colour bar; unknown ground truth is black.

    Parameters
    ----------
    path : path-like
        Output PNG.
    estimate, truth : ndarray, shape (H, W)
        Estimated and true disparity.
    title : str
        Figure title.
    vmax : float
        Error (px) shown at the top of the colour map.

    Returns
    -------
    Path
        The written PNG.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "error.png"
    >>> save_error_png(out, np.zeros((8, 8)), np.ones((8, 8))).is_file()
    True
    """
    est, tru = _opt.real_array(estimate, "estimate"), _opt.real_array(truth, "truth")
    if est.shape != tru.shape:
        raise InvalidInputError(f"estimate and truth must have one shape, got {est.shape} and "
                                f"{tru.shape}")
    err = np.abs(est - tru)
    return save_disparity_png(path, err, title=title, vmin=0.0, vmax=vmax, cmap="magma",
                              label="|error| (px)")


def wavelength_to_rgb(wavelengths: np.ndarray) -> np.ndarray:
    """Display sRGB colour (in [0, 1]) of monochromatic light, for plots and false colour.

    Uses the CIE 1931 colour matching functions, maps to sRGB, desaturates out-of-gamut colours
    by adding white and normalises each colour's maximum to 1.

    Parameters
    ----------
    wavelengths : array_like
        Wavelengths in nm, any shape.

    Returns
    -------
    ndarray, shape (..., 3)
        Display sRGB in [0, 1].

    Examples
    --------
    >>> wavelength_to_rgb([650.0]).argmax(axis=-1)  # red
    array([0])
    """
    from . import spectral

    wl = np.atleast_1d(_opt.real_array(wavelengths, "wavelengths"))
    xyz = spectral.cmfs(wl.ravel())
    rgb = spectral.xyz_to_srgb_linear(xyz)
    rgb = rgb - np.minimum(rgb.min(axis=-1, keepdims=True), 0.0)
    peak = rgb.max(axis=-1, keepdims=True)
    rgb = np.where(peak > 0, rgb / np.where(peak > 0, peak, 1.0), 0.0)
    return spectral.linear_to_srgb(rgb).reshape(wl.shape + (3,))


def false_colour(views: np.ndarray, wavelengths: np.ndarray) -> np.ndarray:
    """Tint each monochrome view with the display colour of its wavelength.

    Parameters
    ----------
    views : ndarray, shape (..., H, W)
    wavelengths : ndarray, shape (...) matching the leading axes of ``views``

    Returns
    -------
    ndarray, shape (..., H, W, 3), sRGB-encoded in [0, 1]

    Examples
    --------
    A view behind a 450 nm filter is tinted blue, one behind 650 nm red:

    >>> tinted = false_colour(np.ones((2, 4, 4)), np.array([450.0, 650.0]))
    >>> tinted.shape, int(tinted[0, 0, 0].argmax()), int(tinted[1, 0, 0].argmax())
    ((2, 4, 4, 3), 2, 0)
    """
    v = _opt.real_array(views, "views", np.float32)
    if v.ndim < 2 or not np.isfinite(v).all():
        raise InvalidInputError(f"views must be finite images (..., H, W), got "
                                f"{_opt.shown(views)}")
    tint = wavelength_to_rgb(wavelengths)
    try:
        fits = np.broadcast_shapes(tint.shape[:-1], v.shape[:-2]) == v.shape[:-2]
    except ValueError:
        fits = False
    if not fits:
        raise InvalidInputError(f"wavelengths must have one value per view, shape "
                                f"{v.shape[:-2]}; got {tint.shape[:-1]}")
    return np.clip(v[..., None] * tint[..., None, None, :], 0.0, 1.0)


def save_mosaic_png(path: str | os.PathLike, views: np.ndarray,
                    wavelengths: np.ndarray | None = None, *, title: str | None = None,
                    max_side: int = 1600) -> Path:
    """Grid of all views as one picture; spectral views are tinted by their wavelength.

    Parameters
    ----------
    path : path-like
        Output PNG.
    views : ndarray, shape (R, C, H, W) or (R, C, H, W, 3)
        The views; labelled with their wavelength when known.
    wavelengths : ndarray, shape (R, C), optional
        Filter wavelengths (nm) for the tint and the labels.
    title : str, optional
        Figure title.
    max_side : int
        Longest side of the mosaic in pixels (views are subsampled to fit).

    Returns
    -------
    Path
        The written PNG.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> views = np.random.default_rng(0).random((2, 3, 16, 16))
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "views.png"
    >>> save_mosaic_png(out, views, np.full((2, 3), 550.0)).is_file()
    True
    """
    _opt.path_like(path)
    v = _opt.real_array(views, "views", np.float32)
    if v.ndim not in (4, 5):
        raise InvalidInputError(f"views must be (R, C, H, W[, 3]), got {v.shape}")
    R, C, H, W = v.shape[:4]
    if wavelengths is not None and _opt.real_array(wavelengths, "wavelengths").shape != (R, C):
        raise InvalidInputError(f"wavelengths must be one per view, shape {(R, C)}")
    _figure_texts(title=title)
    step = display_step(R * H, C * W, max_side)
    v = v[:, :, ::step, ::step]
    if v.ndim == 4:
        peak = float(np.percentile(v, 99.5)) or 1.0
        v = v / peak
        rgb = false_colour(v, wavelengths) if wavelengths is not None else np.repeat(
            np.clip(v, 0, 1)[..., None], 3, axis=-1)
    else:
        rgb = np.clip(v, 0, 1)
    plt = pyplot()
    fig, axes = plt.subplots(R, C, figsize=(1.8 * C, 1.8 * R * H / W + 0.3 * bool(title)),
                             squeeze=False)
    for r in range(R):
        for c in range(C):
            ax = axes[r, c]
            ax.imshow(rgb[r, c], interpolation="nearest")
            ax.set_axis_off()
            if wavelengths is not None:
                ax.set_title(f"{float(np.asarray(wavelengths)[r, c]):.0f} nm", fontsize=7, pad=2)
    if title:
        fig.suptitle(title)
    fig.subplots_adjust(wspace=0.05, hspace=0.25)
    return save_figure(fig, path)


def save_share_mosaic_png(path: str | os.PathLike, shares: np.ndarray, *, title: str,
                          label: str, max_side: int = 1600) -> Path:
    """Grid of per-view maps of a share in [0, 1] on one fixed colour scale, each view named
    ``(row, col)``, with one colour bar (e.g. the share of bands completed per pixel).

    Parameters
    ----------
    path : path-like
        Output PNG.
    shares : ndarray, shape (R, C, H, W)
        Values in [0, 1].
    title, label : str
        Figure title; colour-bar label.
    max_side : int
        As in :func:`save_mosaic_png`.

    Returns
    -------
    Path
        The PNG.
    """
    _opt.path_like(path)
    _figure_texts(title=title, label=label)
    v = _opt.real_array(shares, "shares", np.float32)
    if v.ndim != 4:
        raise InvalidInputError(f"shares must be (R, C, H, W), got {v.shape}")
    R, C, H, W = v.shape
    step = display_step(R * H, C * W, max_side)
    plt = pyplot()
    fig, axes = plt.subplots(R, C, figsize=(1.8 * C + 0.8, 1.8 * R * H / W + 0.4),
                             squeeze=False)
    for (r, c), ax in np.ndenumerate(axes):
        im = ax.imshow(v[r, c, ::step, ::step], vmin=0, vmax=1, cmap="viridis",
                       interpolation="nearest")
        ax.set_axis_off()
        ax.set_title(f"view ({r}, {c})", fontsize=7, pad=2)
    fig.suptitle(title)
    fig.colorbar(im, ax=axes, fraction=0.03, pad=0.02, label=label)
    return save_figure(fig, path)


def save_spectrum_plot(path: str | os.PathLike, wavelengths: np.ndarray,
                       spectra: Sequence[np.ndarray] | np.ndarray,
                       *, labels: Sequence[str] | None = None, title: str = "spectral profile",
                       ylabel: str = "relative intensity") -> Path:
    """Line plot of one or more spectra against wavelength (nm), with a spectrum-coloured band.

    Parameters
    ----------
    path : path-like
        Output PNG.
    wavelengths : ndarray, shape (B,)
        Wavelengths in nm; all NaN when unknown: the bands are then plotted against their
        index (the cameras in raster order, :func:`hyperlf.completion.band_order`).
    spectra : ndarray, shape (B,) or (N, B), or a sequence of them
        The spectra.
    labels : sequence of str, optional
        One legend entry per spectrum.
    title, ylabel : str
        Figure title and y-axis label.

    Returns
    -------
    Path
        The written PNG.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "spectrum.png"
    >>> wavelengths = np.array([450.0, 550.0, 650.0])
    >>> save_spectrum_plot(out, wavelengths, np.array([0.2, 0.5, 0.9])).is_file()
    True
    """
    _opt.path_like(path)
    wl = _opt.real_array(wavelengths, "wavelengths")
    sp = np.atleast_2d(_opt.real_array(spectra, "spectra"))
    if labels is not None and (isinstance(labels, str) or not isinstance(labels, Sequence)
                               or len(labels) != len(sp)):
        raise InvalidInputError(f"labels must be one text per spectrum ({len(sp)}), got "
                                f"{_opt.shown(labels)}")
    _figure_texts(title=title, ylabel=ylabel, **{f"labels[{i}]": t
                                                 for i, t in enumerate(labels or ())})
    if sp.shape[-1] != wl.size:
        raise InvalidInputError(
            f"spectra have {sp.shape[-1]} samples but there are {wl.size} wavelengths"
        )
    from .spectral import wavelengths_unknown

    unknown = wavelengths_unknown(wl)
    x = np.arange(wl.size, dtype=np.float64) if unknown else wl
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    order = np.argsort(x)
    for i, s in enumerate(sp):  # bands of unknown order: points, no line between them
        ax.plot(x[order], s[order], marker="o", ms=5 if unknown else 3,
                ls="none" if unknown else "-", label=None if labels is None else labels[i])
    if unknown:
        ax.set_xticks(x)
        ax.set_xlabel("band = camera in raster order (wavelengths unknown)")
    else:
        colours = wavelength_to_rgb(wl[order])
        lo = ax.get_ylim()[0]
        ax.scatter(wl[order], np.full(wl.size, lo), c=colours, marker="s", s=40, zorder=3)
        ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if labels is not None:
        ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return save_figure(fig, path)
