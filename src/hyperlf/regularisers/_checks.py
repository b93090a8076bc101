"""Input checks shared by the regulariser modules (private to :mod:`hyperlf.regularisers`)."""

from __future__ import annotations

import numpy as np

from .._options import real_array
from ..errors import InvalidInputError


def check_cost(cost, name: str = "cost", dtype=np.float32) -> np.ndarray:
    """A finite real ``(L, H, W)`` volume as ``dtype``; anything else raises InvalidInputError."""
    c = np.asarray(cost)
    if c.ndim != 3:
        raise InvalidInputError(
            f"{name} must be a cost volume of shape (L, H, W), got shape {c.shape}")
    if min(c.shape) < 1:
        raise InvalidInputError(f"{name} must not be empty, got shape {c.shape}")
    if not np.issubdtype(c.dtype, np.number) or np.iscomplexobj(c):
        raise InvalidInputError(f"{name} must be a real numeric array, got dtype {c.dtype}")
    c = np.asarray(c, dtype=dtype)
    finite = np.isfinite(c)
    if not finite.all():
        n_nan = int(np.isnan(c).sum())
        n_inf = int(c.size - finite.sum() - n_nan)
        raise InvalidInputError(
            f"{name} contains {n_nan} NaN and {n_inf} infinite entries; give invalid candidates "
            "a finite value first (SPEC §4: the pixel's worst valid cost, see "
            "hyperlf.regularisers.fill_invalid)")
    return c


def check_label_map(label_map, L: int, H: int, W: int, name: str = "label map") -> np.ndarray:
    """An ``(H, W)`` map of label indices in ``[0, L)`` as ``intp``."""
    f = np.asarray(label_map)
    if f.shape != (H, W):
        raise InvalidInputError(f"{name} must have shape {(H, W)}, got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        if np.issubdtype(f.dtype, np.floating) and np.all(np.isfinite(f)) and np.all(f == np.round(f)):
            f = f.astype(np.int64)
        else:
            raise InvalidInputError(f"{name} must hold integer label indices, got dtype {f.dtype}")
    if f.size and (f.min() < 0 or f.max() >= L):
        raise InvalidInputError(
            f"{name} values must lie in [0, {L - 1}], got range [{f.min()}, {f.max()}]")
    return f.astype(np.intp, copy=False)


def check_labels(labels, L: int) -> np.ndarray:
    """The ``(L,)`` label disparities as float64 (default ``0..L-1``)."""
    if labels is None:
        return np.arange(L, dtype=np.float64)
    lv = real_array(labels, "labels")
    if lv.ndim != 1 or lv.shape[0] != L:
        raise InvalidInputError(
            f"labels must be a 1-D array of the {L} label disparities, got shape {lv.shape}")
    if not np.all(np.isfinite(lv)):
        raise InvalidInputError("labels must be finite")
    return lv


def check_guide(guide, H: int, W: int, label: str = "guide") -> np.ndarray:
    """A finite guide image as float64 ``(H, W, K)``."""
    g = real_array(guide, label)
    if g.ndim == 2:
        g = g[:, :, None]
    if g.ndim != 3 or g.shape[:2] != (H, W):
        raise InvalidInputError(
            f"{label} must be an image of shape {(H, W)} or {(H, W)} + (K,), got {np.shape(guide)}")
    if not np.all(np.isfinite(g)):
        raise InvalidInputError(f"{label} image contains NaN or infinite values")
    return g


def gather(c: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``c[f[y, x], y, x]`` as float64 ``(H, W)``."""
    return np.take_along_axis(c, f[None], axis=0)[0].astype(np.float64)
