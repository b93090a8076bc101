"""The hyperspectral light field (H-LF) data model (SPEC §1).

A :class:`LightField` is a grid of ``R x C`` views, each ``H x W``. In a hyperspectral light
field every view is monochrome and sees one narrow band centred at ``wavelengths[r, c]`` (nm).
An ordinary RGB light field (an HCI scene, say) has a trailing channel axis and no wavelengths.

Conventions (SPEC §1)
---------------------
* ``views[r, c, y, x]`` (or ``views[r, c, y, x, k]`` for multi-channel views), float32, linear
  intensity in [0, 1]. Row ``r`` grows downwards, column ``c`` to the right.
* ``positions[r, c] = (px, py)`` in units of one baseline; default ``(c, r)``.
* Reference view default ``((R - 1) // 2, (C - 1) // 2)``.
* A reference pixel ``(x, y)`` with disparity ``d`` appears in view ``(r, c)`` at
  ``(x - d * (px[r, c] - px0), y - d * (py[r, c] - py0))``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ._options import (flag, index, instance, integer, int_pair, mapping, number, real_array,
                       real_pair, shown)
from .errors import InvalidInputError
from .imageops import block_reduce

__all__ = ["LightField", "raster_wavelengths", "filter_layout", "view_offsets",
           "grid_positions", "centre_view", "check_disparity_range", "resolve_disparity_range",
           "check_disparity_reach", "downscale", "downscale_disparity", "BlockMeanCube",
           "capture_signature", "signature_mismatch"]


def _finite(name: str, arr: np.ndarray) -> None:
    if not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise InvalidInputError(
            f"{name} contains {bad} NaN or infinite value(s); replace them (e.g. np.nan_to_num) "
            "or mask those pixels before building the light field"
        )


def _grid(rows, cols) -> tuple[int, int]:
    """A grid of ``rows x cols`` views: two ints >= 1 whose per-view arrays fit in memory."""
    from .tiling import check_memory

    rows, cols = integer(rows, "rows", 1, maximum=2 ** 31), integer(cols, "cols", 1,
                                                                    maximum=2 ** 31)
    check_memory(32.0 * rows * cols, f"a {rows} x {cols} grid of views", "use a smaller grid")
    return rows, cols


def check_light_field(lf) -> "LightField":
    """``lf`` when it is a :class:`LightField` (the one check of a light-field argument)."""
    return instance(lf, "lf", LightField, "a hyperlf.LightField")


def filter_layout(rows: int, cols: int, order: str | Sequence[int] = "raster",
                  *, seed: int = 0) -> np.ndarray:
    """Band index of every view of an ``rows x cols`` array.

    Parameters
    ----------
    rows, cols : int
        Grid shape.
    order : {"raster", "serpentine", "random"} or sequence of int
        ``raster`` (paper): view ``(r, c)`` gets band ``r * cols + c``. ``serpentine``: odd rows
        run right to left, so every step along the path changes the band by one. ``random``: a
        permutation drawn from ``seed``. A sequence of ``rows * cols`` distinct band indices in
        raster order of the views gives a custom map.
    seed : int
        Seed of the ``random`` layout.

    Returns
    -------
    ndarray of int, shape (rows, cols)

    Examples
    --------
    >>> filter_layout(2, 3).tolist()
    [[0, 1, 2], [3, 4, 5]]
    >>> filter_layout(2, 3, "serpentine").tolist()  # the second row runs right to left
    [[0, 1, 2], [5, 4, 3]]
    >>> sorted(filter_layout(2, 3, "random", seed=1).ravel().tolist())  # each band once
    [0, 1, 2, 3, 4, 5]
    """
    rows, cols = _grid(rows, cols)
    seed = integer(seed, "seed", maximum=2 ** 63)
    n = rows * cols
    if isinstance(order, str):
        if order == "raster":
            return np.arange(n).reshape(rows, cols)
        if order == "serpentine":
            k = np.arange(n).reshape(rows, cols)
            k[1::2] = k[1::2, ::-1]
            return k
        if order == "random":
            return np.random.default_rng(seed).permutation(n).reshape(rows, cols)
        raise InvalidInputError(
            f"unknown filter layout {order!r}; use 'raster', 'serpentine', 'random' "
            "or a list of band indices"
        )
    k = real_array(order, "order")
    if k.size != n or sorted(k.ravel().tolist()) != list(range(n)):
        raise InvalidInputError(
            f"a custom filter layout must list each band index 0..{n - 1} exactly once "
            f"(got {k.size} values)"
        )
    return k.reshape(rows, cols).astype(int)


def raster_wavelengths(rows: int = 5, cols: int = 6, *, lambda_min: float = 410.0,
                       lambda_max: float = 700.0,
                       order: str | Sequence[int] = "raster", seed: int = 0) -> np.ndarray:
    """Centre wavelengths (nm) of an ``rows x cols`` filter array in equal steps (SPEC §1).

    For 5 x 6 and 410..700 nm with the raster layout, view ``(2, 2)`` sees 550 nm. A single
    view gets ``lambda_min``.

    Parameters
    ----------
    rows, cols : int
        Grid of views.
    lambda_min, lambda_max : float
        Band range in nm; ``rows * cols`` bands in equal steps.
    order : {"raster", "serpentine", "random"} or sequence of int
        Filter layout (:func:`filter_layout`).
    seed : int
        Seed of a random layout.

    Returns
    -------
    ndarray of float64, shape (rows, cols)

    Examples
    --------
    >>> float(raster_wavelengths(5, 6)[2, 2])
    550.0
    """
    rows, cols = _grid(rows, cols)
    lambda_min = number(lambda_min, "lambda_min", positive=True)
    lambda_max = number(lambda_max, "lambda_max", positive=True)
    if not (0 < lambda_min <= lambda_max):
        raise InvalidInputError(
            f"band range must satisfy 0 < min <= max, got {lambda_min}..{lambda_max} nm"
        )
    n = rows * cols
    bands = np.linspace(lambda_min, lambda_max, n) if n > 1 else np.array([lambda_min])
    return bands[filter_layout(rows, cols, order, seed=seed)]


def view_offsets(positions: np.ndarray, reference: tuple[int, int]) -> np.ndarray:
    """Offsets ``pos[r, c] - pos[ref]`` of every view, as ``(dx, dy)``.

    Parameters
    ----------
    positions : ndarray, shape (R, C, 2)
        View positions ``(px, py)`` in baselines.
    reference : (int, int)
        Reference view ``(row, col)``.

    Returns
    -------
    ndarray, shape (R, C, 2)

    Examples
    --------
    >>> pos = np.stack(np.meshgrid(np.arange(3.0), np.arange(2.0)), axis=-1)
    >>> view_offsets(pos, (1, 1))[0, 0].tolist()
    [-1.0, -1.0]
    """
    pos = real_array(positions, "positions", None)
    if pos.ndim != 3 or pos.shape[2] != 2 or pos.dtype.kind not in "biuf":
        raise InvalidInputError(f"positions must be (R, C, 2) numbers, got {shown(positions)}")
    return _view_offsets(pos, index(reference, "reference", pos.shape[:2]))


def _view_offsets(positions: np.ndarray, reference: tuple[int, int]) -> np.ndarray:
    """:func:`view_offsets` of checked values."""
    return positions - positions[reference][None, None, :]


def grid_positions(rows: int, cols: int) -> np.ndarray:
    """The default view positions: the regular grid ``(c, r)``, in baselines.

    Parameters
    ----------
    rows, cols : int
        Grid size ``R x C``.

    Returns
    -------
    ndarray of float64, shape (R, C, 2)
        ``positions[r, c] = (c, r)``.

    Examples
    --------
    >>> grid_positions(2, 3)[1, 2].tolist()
    [2.0, 1.0]
    """
    return _grid_positions(*_grid(rows, cols))


def _grid_positions(rows: int, cols: int) -> np.ndarray:
    """:func:`grid_positions` of a checked grid."""
    cc, rr = np.meshgrid(np.arange(cols, dtype=np.float64), np.arange(rows, dtype=np.float64))
    return np.stack([cc, rr], axis=-1)


def centre_view(rows: int, cols: int) -> tuple[int, int]:
    """The default reference view of an ``R x C`` grid: ``((R - 1) // 2, (C - 1) // 2)``.

    Examples
    --------
    >>> centre_view(5, 6)
    (2, 2)
    """
    rows, cols = (integer(n, label, 1) for n, label in ((rows, "rows"), (cols, "cols")))
    return _centre_view(rows, cols)


def _centre_view(rows: int, cols: int) -> tuple[int, int]:
    """:func:`centre_view` of a checked grid."""
    return (rows - 1) // 2, (cols - 1) // 2


def check_disparity_range(disparity_range) -> tuple[float, float]:
    """A disparity range checked and converted: two finite numbers with ``dmin < dmax``.

    Parameters
    ----------
    disparity_range : (float, float)
        ``(dmin, dmax)``, px per baseline.

    Returns
    -------
    (float, float)

    Raises
    ------
    InvalidInputError
        Not a pair of numbers, not finite, or ``dmin >= dmax``.

    Examples
    --------
    >>> check_disparity_range([-2, 2])
    (-2.0, 2.0)
    """
    dmin, dmax = real_pair(disparity_range, "disparity_range", "(dmin, dmax), finite")
    if not dmin < dmax:
        raise InvalidInputError(
            f"disparity_range must be finite with min < max, got {shown(disparity_range)}")
    return dmin, dmax


def resolve_disparity_range(lf: "LightField", disparity_range=None) -> tuple[float, float]:
    """``disparity_range`` if given, else the light field's own; checked ``(dmin, dmax)``.

    Parameters
    ----------
    lf : LightField
        Supplies the default range.
    disparity_range : (float, float), optional
        Explicit range (px per baseline).

    Returns
    -------
    (float, float)
        ``(dmin, dmax)``.

    Raises
    ------
    InvalidInputError
        Neither is set, the range is not two finite numbers with ``dmin < dmax``, or it reaches
        disparities at which even the nearest view is shifted entirely out of the image (such
        labels can match nothing; a typo such as ``1e30`` is the usual cause).

    Examples
    --------
    >>> lf = LightField(np.zeros((3, 3, 24, 32), np.float32), disparity_range=(-2, 2))
    >>> resolve_disparity_range(lf), resolve_disparity_range(lf, (0, 1.5))
    ((-2.0, 2.0), (0.0, 1.5))

    The nearest views are one baseline away, so beyond ``max(H, W) / 1 = 32`` px per baseline
    they would leave the image altogether:

    >>> resolve_disparity_range(lf, (0, 1e30))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hyperlf.errors.InvalidInputError: a disparity of 1e+30 px ... (the limit is +-32)...
    """
    check_light_field(lf)
    rng = disparity_range if disparity_range is not None else lf.disparity_range
    if rng is None:
        raise InvalidInputError(
            "no disparity range: pass disparity_range=(dmin, dmax) or set lf.disparity_range")
    dmin, dmax = check_disparity_range(rng)
    offsets = _view_offsets(np.asarray(lf.positions), lf.reference)
    _disparity_reach((dmin, dmax), offsets, lf.image_shape)
    return dmin, dmax


def check_disparity_reach(disparities, offsets: np.ndarray, image_shape) -> None:
    """Refuse disparities at which even the nearest view is shifted entirely out of the image.

    Such a disparity can match or refocus nothing; a typo such as ``1e30`` is the usual cause.

    Parameters
    ----------
    disparities : array_like
        Disparities (px per baseline), e.g. a range's two ends.
    offsets : ndarray, shape (R, C, 2)
        View offsets from the reference, baselines (:func:`view_offsets`).
    image_shape : (int, int)
        ``(H, W)`` of the views.

    Raises
    ------
    InvalidInputError
        A disparity reaches beyond ``max(H, W) / (nearest view's distance)``; or the
        arguments are not numbers of these shapes.

    Examples
    --------
    On a 3 x 3 grid the nearest views are one baseline from the centre, and the limit on
    24 x 32 px views is 32 px per baseline; with the views spaced twice as far it halves:

    >>> off = view_offsets(grid_positions(3, 3), (1, 1))
    >>> check_disparity_reach([-2.0, 2.0], off, (24, 32)) is None  # well inside: no error
    True
    >>> check_disparity_reach([20.0], 2 * off, (24, 32))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hyperlf.errors.InvalidInputError: a disparity of 20 px ... (the limit is +-16)...
    """
    d = real_array(disparities, "disparities")
    off = real_array(offsets, "offsets")
    if d.size == 0 or np.isnan(d).any():
        raise InvalidInputError(f"disparities must be numbers (at least one), got "
                                f"{shown(disparities)}")
    if off.ndim < 1 or off.shape[-1] != 2 or not np.isfinite(off).all():
        raise InvalidInputError(f"offsets must be finite (dx, dy) pairs, shape (R, C, 2); got "
                                f"{shown(offsets)}")
    _disparity_reach(d, off, int_pair(image_shape, "image_shape", what="(H, W)"))


def _disparity_reach(disparities, offsets: np.ndarray, image_shape) -> None:
    """:func:`check_disparity_reach` of checked values."""
    off = np.hypot(*np.moveaxis(np.asarray(offsets, dtype=np.float64), -1, 0))
    nearest = float(off[off > 0].min()) if (off > 0).any() else 1.0
    limit = max(image_shape) / nearest
    worst = float(np.max(np.abs(np.asarray(disparities, dtype=np.float64))))
    if not worst <= limit:
        raise InvalidInputError(
            f"a disparity of {worst:g} px per baseline shifts every view out of the "
            f"{image_shape[1]} x {image_shape[0]} px image (the limit is +-{limit:g}); use a "
            "smaller one")


def _check_valid(valid, shape) -> np.ndarray:
    """The validity mask as a C-contiguous bool array of ``shape``, or InvalidInputError."""
    try:
        m = np.asarray(valid)
    except (TypeError, ValueError) as exc:  # ragged lists
        raise InvalidInputError(f"valid is not a regular array: {exc}") from None
    if m.shape != tuple(shape):
        raise InvalidInputError(
            f"valid must be one bool per view pixel, shape {tuple(shape)}; got {m.shape}")
    if m.dtype != np.bool_:
        if not (np.issubdtype(m.dtype, np.number) or m.dtype == object) or np.iscomplexobj(m):
            raise InvalidInputError(f"valid must be a bool array, got dtype {m.dtype}")
        try:
            mf = m.astype(np.float64)
        except (TypeError, ValueError):
            raise InvalidInputError(f"valid must be a bool array, got dtype {m.dtype}") from None
        if not np.all(np.isfinite(mf)):
            raise InvalidInputError("valid contains NaN or infinite values; use True / False")
        m = mf != 0
    return np.ascontiguousarray(m, dtype=bool)


@dataclass
class LightField:
    """A (hyperspectral) light field: ``R x C`` views with their filters and geometry.

    Parameters
    ----------
    views : array_like, shape (R, C, H, W) or (R, C, H, W, K)
        Linear intensities, stored as float32. Monochrome views (4-D) form a hyperspectral light
        field; a trailing channel axis (e.g. ``K = 3``) an ordinary colour light field.
        A float32 array is kept, not copied (a paper-size capture is gigabytes): changing it
        afterwards changes the light field; pass ``views.copy()`` to keep the two apart.
    wavelengths : array_like, shape (R, C), optional
        Centre wavelength (nm) of each view's band-pass filter. Required to be positive; may be
        ``None`` for colour light fields.
    positions : array_like, shape (R, C, 2), optional
        Camera positions ``(px, py)`` in baselines. Default ``(c, r)``.
    reference : (int, int), optional
        Reference view ``(r0, c0)``. Default ``((R - 1) // 2, (C - 1) // 2)``.
    disparity_range : (float, float), optional
        ``(dmin, dmax)`` in pixels per baseline, when known (from a capture's manifest).
    gt_disparity : array_like, shape (H, W) or (R, C, H, W), optional
        Ground-truth disparity of the reference view, or of every view.
    gt_cube : array_like, shape (R, C, B, H, W), optional
        Ground-truth plenoptic cube: every band seen from every view.
    cube_wavelengths : array_like, shape (B,), optional
        Wavelengths of the cube's bands; required with ``gt_cube``.
    metadata : dict
        Free-form provenance (source, licence, synthesis parameters, calibration, ...).
    valid : array_like of bool, shape (R, C, H, W), optional
        Per-view validity mask: True where a view's pixel holds real data, False where it was
        warped in from outside the camera's image, is saturated, or the camera is dead
        (SPEC §11). Matching, normalisation and completion ignore the False pixels. ``None``
        (default) means every pixel is valid. Coerced to bool.

    Raises
    ------
    InvalidInputError
        When shapes disagree, values are NaN/inf, wavelengths are non-positive, the reference is
        outside the grid, or the views are empty.
    """

    views: np.ndarray
    wavelengths: np.ndarray | None = None
    positions: np.ndarray | None = None
    reference: tuple[int, int] | None = None
    disparity_range: tuple[float, float] | None = None
    gt_disparity: np.ndarray | None = None
    gt_cube: np.ndarray | None = None
    cube_wavelengths: np.ndarray | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    valid: np.ndarray | None = None

    def __post_init__(self) -> None:
        self._check_views()
        R, C, H, W = self.views.shape[:4]
        self._check_wavelengths(R, C)
        self._check_positions(R, C)
        self._check_reference(R, C)
        if self.disparity_range is not None:
            self.disparity_range = check_disparity_range(self.disparity_range)
        self._check_truth(R, C, H, W)
        if not isinstance(self.metadata, dict):
            raise InvalidInputError("metadata must be a dict")
        if self.valid is not None:
            self.valid = _check_valid(self.valid, (R, C, H, W))

    def _check_views(self) -> None:
        """``views`` as a regular, non-empty, finite float32 array of 4 or 5 dimensions."""
        try:
            views = np.asarray(self.views)
        except (TypeError, ValueError) as exc:  # ragged lists
            raise InvalidInputError(f"views are not a regular array: {exc}") from None
        if views.ndim not in (4, 5):
            raise InvalidInputError(
                f"views must have shape (R, C, H, W) or (R, C, H, W, K), got {views.shape}"
            )
        if views.size == 0 or min(views.shape) == 0:
            raise InvalidInputError(f"views are empty (shape {views.shape})")
        if not np.issubdtype(views.dtype, np.number) or np.iscomplexobj(views):
            raise InvalidInputError(f"views must be real numbers, got dtype {views.dtype}")
        if np.issubdtype(views.dtype, np.integer):  # 0..255 taken as intensities misleads
            raise InvalidInputError(
                f"views must be linear intensities as floats (1 = full scale), got "
                f"{views.dtype}; divide by the sensor's full scale (e.g. 255 or 65535) first, "
                "or read the files with hyperlf.load")
        views = views.astype(np.float32, copy=False)
        _finite("views", views)
        self.views = views

    def _check_wavelengths(self, R: int, C: int) -> None:
        """One positive centre wavelength per view; None is a grey or colour light field (not
        spectral)."""
        if self.wavelengths is None:
            return
        wl = real_array(self.wavelengths, "wavelengths")
        if wl.shape != (R, C):
            raise InvalidInputError(
                f"wavelengths must have one value per view, shape ({R}, {C}); got {wl.shape}"
            )
        _finite("wavelengths", wl)
        if np.any(wl <= 0):
            raise InvalidInputError("wavelengths must be positive (nm)")
        self.wavelengths = wl

    def _check_positions(self, R: int, C: int) -> None:
        """Camera positions ``(R, C, 2)``; None: the grid's own."""
        if self.positions is None:
            self.positions = _grid_positions(R, C)
            return
        pos = real_array(self.positions, "positions")
        if pos.shape != (R, C, 2):
            raise InvalidInputError(
                f"positions must have shape ({R}, {C}, 2) as (px, py); got {pos.shape}"
            )
        _finite("positions", pos)
        self.positions = pos

    def _check_reference(self, R: int, C: int) -> None:
        """The reference view as ``(row, col)`` inside the grid; None: the centre view."""
        if self.reference is None:
            self.reference = _centre_view(R, C)
            return
        try:
            r0, c0 = (int(v) for v in self.reference)
            exact = all(float(v) == int(v) for v in self.reference)
        except (TypeError, ValueError, OverflowError):
            exact = False
        if not exact:
            raise InvalidInputError(
                f"reference must be a pair of integers (row, col), got {shown(self.reference)}")
        if not (0 <= r0 < R and 0 <= c0 < C):
            raise InvalidInputError(
                f"reference view ({r0}, {c0}) is outside the {R} x {C} grid; "
                f"rows run 0..{R - 1}, columns 0..{C - 1}"
            )
        self.reference = (r0, c0)

    def _check_truth(self, R: int, C: int, H: int, W: int) -> None:
        """``gt_disparity``, ``gt_cube`` and ``cube_wavelengths``."""
        if self.gt_disparity is not None:
            gt = real_array(self.gt_disparity, "gt_disparity", np.float32)
            if gt.shape not in ((H, W), (R, C, H, W)):
                raise InvalidInputError(
                    f"gt_disparity must have shape ({H}, {W}) or ({R}, {C}, {H}, {W}); "
                    f"got {gt.shape}"
                )
            self.gt_disparity = gt  # may hold NaN/inf for unknown pixels by convention

        if self.gt_cube is not None:
            cube = real_array(self.gt_cube, "gt_cube", np.float32)
            if cube.ndim != 5 or cube.shape[:2] != (R, C) or cube.shape[3:] != (H, W):
                raise InvalidInputError(
                    f"gt_cube must have shape ({R}, {C}, B, {H}, {W}); got {cube.shape}"
                )
            _finite("gt_cube", cube)
            if self.cube_wavelengths is None:
                raise InvalidInputError("gt_cube needs cube_wavelengths (one per band)")
            self.gt_cube = cube
        if self.cube_wavelengths is not None:
            cw = real_array(self.cube_wavelengths, "cube_wavelengths").ravel()
            _finite("cube_wavelengths", cw)
            if np.any(cw <= 0) or len(np.unique(cw)) != cw.size:
                raise InvalidInputError("cube_wavelengths must be positive and distinct (nm)")
            if self.gt_cube is not None and cw.size != self.gt_cube.shape[2]:
                raise InvalidInputError(
                    f"cube_wavelengths has {cw.size} values but gt_cube has "
                    f"{self.gt_cube.shape[2]} bands"
                )
            self.cube_wavelengths = cw

    # ------------------------------------------------------------------ shape helpers
    @property
    def grid_shape(self) -> tuple[int, int]:
        """``(R, C)``: rows and columns of views."""
        return self.views.shape[0], self.views.shape[1]

    @property
    def image_shape(self) -> tuple[int, int]:
        """``(H, W)`` of every view."""
        return self.views.shape[2], self.views.shape[3]

    @property
    def n_views(self) -> int:
        return self.views.shape[0] * self.views.shape[1]

    @property
    def channels(self) -> int:
        """Number of channels per view (1 for a hyperspectral light field)."""
        return 1 if self.views.ndim == 4 else self.views.shape[4]

    @property
    def is_spectral(self) -> bool:
        """True for monochrome views with one filter wavelength each."""
        return self.views.ndim == 4 and self.wavelengths is not None

    @property
    def reference_view(self) -> np.ndarray:
        """The reference view's image."""
        return self.views[self.reference]

    @property
    def offsets(self) -> np.ndarray:
        """``positions - positions[reference]``, shape ``(R, C, 2)`` as ``(dx, dy)``."""
        return _view_offsets(self.positions, self.reference)

    @property
    def reference_gt_disparity(self) -> np.ndarray | None:
        """Ground-truth disparity of the reference view, or ``None``."""
        if self.gt_disparity is None:
            return None
        if self.gt_disparity.ndim == 4:
            return self.gt_disparity[self.reference]
        return self.gt_disparity

    def replace(self, **changes: Any) -> "LightField":
        """A copy with some fields replaced (validated again)."""
        return dataclasses.replace(self, **changes)

    def describe(self, *, cube: tuple[int, np.ndarray | None] | None = None) -> str:
        """Human-readable multi-line summary (used by ``hyperlf info``).

        ``cube``: the band count and wavelengths of a ground-truth cube left on disk (a light
        field loaded with ``cube=False``), described as if it were loaded.
        """
        R, C = self.grid_shape
        H, W = self.image_shape
        lines = [
            f"grid        : {R} x {C} views ({self.n_views})",
            f"image size  : {W} x {H} px (W x H)"
            + ("" if self.channels == 1 else f", {self.channels} channels"),
            f"reference   : view {self.reference}",
            *_describe_bands(self.wavelengths, self.reference),
            _describe_baselines(self.offsets),
        ]
        if self.disparity_range is not None:
            lines.append(
                f"disparity   : {self.disparity_range[0]:g}..{self.disparity_range[1]:g} px/baseline"
            )
        if self.gt_cube is not None:
            cube = (self.gt_cube.shape[2], self.cube_wavelengths)
        lines += _describe_truth(self.reference_gt_disparity, self.gt_disparity, cube)
        if self.valid is not None:
            lines.append(_describe_valid(self.valid))
        vmin, vmax = float(self.views.min()), float(self.views.max())
        lines.append(f"intensity   : {vmin:.4g}..{vmax:.4g}")
        lines += [f"{k:<12}: {v}" for k, v in self.metadata.items()
                  if isinstance(v, (str, int, float, bool))]
        return "\n".join(lines)


def _describe_bands(wl: np.ndarray | None, reference: tuple[int, int]) -> list[str]:
    """The lines of :meth:`LightField.describe` on the filters: range, step, the grid's."""
    if wl is None:
        return ["bands       : none (colour / grey light field)"]
    step = np.diff(np.sort(wl.ravel()))
    step_txt = f", step {step.min():g} nm" if step.size and np.allclose(step, step[0]) else ""
    distinct = np.unique(wl).size
    rows = ["  " + " ".join(f"{v:6.1f}" for v in row) for row in wl]
    return [f"bands       : {wl.size} filter{'s' if wl.size > 1 else ''}"
            + (f" ({distinct} distinct)" if distinct < wl.size else "")
            + f", {wl.min():g}..{wl.max():g} nm{step_txt}",
            f"reference   : sees {wl[reference]:g} nm",
            "wavelengths :\n" + "\n".join(rows)]


def _describe_baselines(off: np.ndarray) -> str:
    """The line of :meth:`LightField.describe` on the views' positions."""
    return (f"baselines   : x {off[..., 0].min():g}..{off[..., 0].max():g}, "
            f"y {off[..., 1].min():g}..{off[..., 1].max():g} (relative to reference)")


def _describe_truth(gt: np.ndarray | None, gt_all, cube) -> list[str]:
    """The lines of :meth:`LightField.describe` on the ground truth: the reference's
    disparity range and a cube's bands (``cube`` is ``(bands, wavelengths)`` or None)."""
    lines = []
    ok = None if gt is None else np.isfinite(gt)
    if ok is not None and ok.any():
        lines.append(
            f"ground truth: disparity {float(gt[ok].min()):.3f}..{float(gt[ok].max()):.3f} px"
            + (" (reference view; every view has its own)"
               if gt_all.ndim == 4 else " (reference view)")
        )
    if cube is not None:
        bands, cwl = cube
        known = cwl is not None and np.size(cwl) and np.isfinite(cwl).all()
        lines.append(f"ground truth: cube with {bands} bands per view"
                     + (f" ({np.min(cwl):g}..{np.max(cwl):g} nm)" if known else ""))
    return lines


def downscale(lf: LightField, factor: int = 2, *, truth: bool = False) -> LightField:
    """The light field at ``1 / factor`` of its resolution, for a quick first estimate.

    Each view becomes the means of its ``factor x factor`` pixel blocks (sizes rounded up: the
    last row and column are repeated); a block is valid where all its pixels are; the
    disparity range is divided by ``factor``; wavelengths, positions and reference are kept.
    The metadata are kept too, with the camera matrix of a calibrated capture
    (``metadata["calibration"]["camera_matrix"]``) moved to the block grid, so that metric
    depth from the small light field's disparities is the full-resolution one. The cube is
    dropped, and so is the ground truth unless ``truth``.

    Parameters
    ----------
    lf : LightField
    factor : int
        Integer >= 1 (1 returns ``lf``).
    truth : bool
        Keep the ground-truth disparity as its block means divided by ``factor`` (a block
        across a depth edge gets a value between the two sides).

    Returns
    -------
    LightField

    Examples
    --------
    >>> lf = LightField(np.ones((1, 2, 5, 8), np.float32), disparity_range=(-2, 4))
    >>> small = downscale(lf, 2)
    >>> small.image_shape, small.disparity_range
    ((3, 4), (-1.0, 2.0))
    """
    check_light_field(lf)
    factor = integer(factor, "factor", 1)
    truth = flag(truth, "truth")
    if factor == 1:
        return lf
    rng = lf.disparity_range
    views = np.moveaxis(lf.views, (2, 3), (-2, -1))  # colour views: channels before H, W
    views = np.moveaxis(block_reduce(views, factor), (-2, -1), (2, 3))
    gt = None
    if truth and lf.gt_disparity is not None:
        gt = downscale_disparity(lf.gt_disparity, factor)
    return LightField(
        views=views.astype(np.float32),
        wavelengths=lf.wavelengths, positions=lf.positions, reference=lf.reference,
        disparity_range=None if rng is None else (rng[0] / factor, rng[1] / factor),
        gt_disparity=gt, metadata=_downscaled_metadata(lf.metadata, factor),
        valid=None if lf.valid is None else block_reduce(lf.valid, factor, np.all))


def downscale_disparity(disparity, factor: int) -> np.ndarray:
    """A disparity map (``(..., H, W)``) on the block grid of :func:`downscale`: its block means
    divided by ``factor`` (disparities in the small views' px), float32.

    Examples
    --------
    >>> downscale_disparity(np.full((4, 6), 3.0), 2).tolist()
    [[1.5, 1.5, 1.5], [1.5, 1.5, 1.5]]
    """
    return (block_reduce(np.asarray(disparity), factor) / factor).astype(np.float32)


#: Blocks on each side of the reference view's thumbnail in :func:`capture_signature`.
SIGNATURE_BLOCKS = 8
#: Largest RMS of two thumbnails' log ratio, beyond a smooth shading, that
#: :func:`signature_mismatch` takes for one scene.
SIGNATURE_MAX_RESIDUAL = 0.1


def capture_signature(lf: LightField) -> dict:
    """What tells one capture from another, as JSON values: the grid, the view size, the
    reference view, the wavelengths, the positions and a thumbnail of the reference view
    (:data:`SIGNATURE_BLOCKS` x :data:`SIGNATURE_BLOCKS` means of its valid pixels; None where a
    block has none).

    ``hyperlf depth`` records it in its result's manifest, so that ``complete --disparity``
    can refuse a map made from another capture of the same size (:func:`signature_mismatch`).

    Examples
    --------
    >>> lf = LightField(np.ones((1, 2, 16, 16), np.float32), wavelengths=[[500.0, 600.0]])
    >>> sig = capture_signature(lf)
    >>> sig["grid"], sig["image_shape"], len(sig["thumbnail"])
    ([1, 2], [16, 16], 64)
    """
    ref = tuple(check_light_field(lf).reference)
    view = np.asarray(lf.views[ref], np.float64)
    view = view.mean(axis=-1) if view.ndim == 3 else view
    valid = np.ones(view.shape, bool) if lf.valid is None else np.asarray(lf.valid[ref])
    thumb = []
    for rows in np.array_split(np.arange(view.shape[0]), SIGNATURE_BLOCKS):
        for cols in np.array_split(np.arange(view.shape[1]), SIGNATURE_BLOCKS):
            block, ok = view[np.ix_(rows, cols)], valid[np.ix_(rows, cols)]
            thumb.append(float(block[ok].mean()) if ok.any() else None)
    return {"grid": list(lf.grid_shape), "image_shape": list(lf.image_shape),
            "reference": [int(i) for i in ref],
            "wavelengths": None if lf.wavelengths is None else np.asarray(
                lf.wavelengths, float).round(3).tolist(),
            "positions": np.asarray(lf.positions, float).round(4).tolist(),
            "thumbnail": thumb}


def signature_mismatch(recorded: dict, sig: dict) -> str | None:
    """Why two :func:`capture_signature` values name different captures, or None when they may
    name the same one (also when ``recorded`` is malformed: nothing can be told then).

    Grid, view size and reference must agree exactly, wavelengths within 0.5 nm, positions
    within 0.05 baselines, and the thumbnails' ratio must be a smooth shading up to
    :data:`SIGNATURE_MAX_RESIDUAL` (another exposure, vignetting or a flat field of the same
    scene keeps it smooth; another scene does not).

    Examples
    --------
    >>> a = {"grid": [3, 3], "image_shape": [60, 80], "reference": [1, 1]}
    >>> signature_mismatch(a, dict(a, grid=[5, 6]))
    'its grid is 3 x 3, not 5 x 6'
    """
    mapping(sig, "sig", optional=False)
    try:
        for key, what, order in (("grid", "grid", 1), ("image_shape", "view size", -1),
                                 ("reference", "reference view", 1)):
            if [int(v) for v in recorded[key]] != [int(v) for v in sig[key]]:
                a, b = (" x ".join(str(int(v)) for v in s[key][::order])
                        for s in (recorded, sig))
                unit = " px (W x H)" if order < 0 else ""
                return f"its {what} is {a}{unit}, not {b}{unit}"
        return _geometry_mismatch(recorded, sig) or _thumbnail_mismatch(recorded, sig)
    except (KeyError, TypeError, ValueError, IndexError, OverflowError):
        return None


def _geometry_mismatch(recorded: dict, sig: dict) -> str | None:
    for key, tol, what in (("wavelengths", 0.5, "wavelengths"),
                           ("positions", 0.05, "view positions")):
        a, b = recorded.get(key), sig.get(key)
        if a is None and b is None:
            continue
        if a is None or b is None or np.shape(a) != np.shape(b) or not np.allclose(
                np.asarray(a, float), np.asarray(b, float), atol=tol):
            return f"its {what} differ"
    return None


def _thumbnail_mismatch(recorded: dict, sig: dict) -> str | None:
    """The thumbnails' log ratio less its best quadratic surface (exposure, vignetting and a
    flat field are smooth): its RMS above :data:`SIGNATURE_MAX_RESIDUAL` is another scene."""
    a, b = (np.array([np.nan if v is None else v for v in s["thumbnail"]], float)
            for s in (recorded, sig))
    n = SIGNATURE_BLOCKS
    if a.shape != (n * n,) or b.shape != (n * n,):
        return None
    both = np.isfinite(a) & np.isfinite(b) & (a > 0) & (b > 0)
    if both.sum() < 12:
        return None
    y, x = (g.ravel()[both] / n for g in np.mgrid[:n, :n])
    design = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)
    ratio = np.log(a[both] / b[both])
    fit, *_ = np.linalg.lstsq(design, ratio, rcond=None)
    rms = float(np.sqrt(np.mean((ratio - design @ fit) ** 2)))
    if rms > SIGNATURE_MAX_RESIDUAL:
        return (f"its reference view shows another scene (thumbnails differ by {100 * rms:.0f} % "
                "beyond shading)")
    return None


class BlockMeanCube:
    """A plenoptic cube seen at ``1 / factor`` of its resolution, read one view at a time.

    ``cube[r, c]`` is the block means (:func:`hyperlf.imageops.block_reduce`, as
    :func:`downscale` makes the views) of view ``(r, c)`` of ``cube``, which may be a lazy
    h5py dataset (:func:`hyperlf.formats.open_gt_cube`): a full-resolution ground truth can
    score a completion made at ``1 / factor`` (:func:`hyperlf.metrics.cube_scores`) without
    being read whole.

    Parameters
    ----------
    cube : array_like, shape (R, C, B, H, W)
    factor : int
        Block side (>= 1).

    Examples
    --------
    >>> small = BlockMeanCube(np.arange(24.0).reshape(1, 1, 1, 4, 6), 2)
    >>> small.shape, small[0, 0].tolist()
    ((1, 1, 1, 2, 3), [[[3.5, 5.5, 7.5], [15.5, 17.5, 19.5]]])
    """

    def __init__(self, cube, factor: int):
        if not hasattr(cube, "shape") or not hasattr(cube, "dtype"):  # a list: an array
            cube = real_array(cube, "cube")
        if len(cube.shape) != 5 or np.dtype(cube.dtype).kind not in "biuf":
            raise InvalidInputError(f"cube must be (R, C, B, H, W) numbers, got "
                                    f"{shown(cube)}")
        self.cube, self.factor = cube, integer(factor, "factor", 1)
        R, C, B, H, W = np.shape(cube)
        self.shape = (R, C, B, -(-H // self.factor), -(-W // self.factor))

    def __getitem__(self, view) -> np.ndarray:
        r, c = index(view, "view", self.shape[:2])
        return block_reduce(np.asarray(self.cube[r, c], dtype=np.float64), self.factor)


def _block_camera_matrix(K, factor: int) -> np.ndarray:
    """The camera matrix of an image made of the means of ``factor x factor`` pixel blocks.

    Block ``(x', y')`` is centred on full-resolution pixel ``factor x' + (factor - 1) / 2``,
    so the focal lengths and the skew are divided by ``factor`` and the principal point
    becomes ``(c - (factor - 1) / 2) / factor``.

    Examples
    --------
    >>> _block_camera_matrix([[100, 0, 49.5], [0, 100, 29.5], [0, 0, 1]], 2)[:2].tolist()
    [[50.0, 0.0, 24.5], [0.0, 50.0, 14.5]]
    """
    K = np.asarray(K, dtype=np.float64)
    S = np.array([[1.0 / factor, 0.0, -(factor - 1) / (2.0 * factor)],
                  [0.0, 1.0 / factor, -(factor - 1) / (2.0 * factor)],
                  [0.0, 0.0, 1.0]])
    return S @ K


def _downscaled_metadata(metadata: dict, factor: int) -> dict:
    """``metadata`` with a calibration's camera matrix on the block grid and the total
    ``downscale`` factor (a copy)."""
    meta = dict(metadata)
    before = meta.get("downscale", 1)
    meta["downscale"] = (before if isinstance(before, int) and before >= 1 else 1) * factor
    cal = meta.get("calibration")
    if isinstance(cal, dict) and "camera_matrix" in cal:
        try:
            K = _block_camera_matrix(cal["camera_matrix"], factor)
        except (TypeError, ValueError):
            return meta  # a malformed table stays as it is; metric depth reports it
        if K.shape == (3, 3):
            meta["calibration"] = {**cal, "camera_matrix": K.tolist()}
    return meta


def _describe_valid(valid: np.ndarray) -> str:
    """One ``describe()`` line: the valid fraction over all views and its range per view."""
    frac = valid.reshape(valid.shape[0], valid.shape[1], -1).mean(axis=2)
    dead = int((frac == 0).sum())
    return (f"valid mask  : {100 * float(valid.mean()):.1f} % of pixels valid "
            f"(per view {100 * float(frac.min()):.1f}..{100 * float(frac.max()):.1f} %"
            + (f", {dead} view(s) with none" if dead else "") + ")")
