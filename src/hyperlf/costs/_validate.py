"""Argument checks shared by the cost evaluators (private module, public names)."""

from __future__ import annotations

import numpy as np

from .._options import array, choice, integer, number, shown, window
from ..errors import InvalidInputError

__all__ = ["IMPLS", "AUTO_IMPL", "MAX_VIEW_WINDOW", "MIN_SCALE", "check_pair", "check_disp",
           "check_window", "check_impl", "check_map", "check_shape", "check_bytes",
           "check_scale", "check_dmin", "map_side"]

IMPLS = ("auto", "numpy", "numba")
#: ``impl="auto"`` per evaluator: numba wherever a kernel exists (measured faster, BENCHMARKS.md).
AUTO_IMPL = {"ncc": "numba", "rsncc": "numba", "census": "numba", "bwncc": "numba",
             "normalise": "numba"}


def check_pair(left, right) -> tuple[np.ndarray, np.ndarray]:
    """Two finite, numeric, equally shaped 2-D images as float64 (InvalidInputError otherwise)."""
    L = np.asarray(left)
    R = np.asarray(right)
    if L.ndim != 2 or R.ndim != 2:
        raise InvalidInputError(
            f"left and right must be 2-D (H, W) images, got shapes {L.shape} and {R.shape}")
    if L.shape != R.shape:
        raise InvalidInputError(f"left and right must have the same shape, got {L.shape} and {R.shape}")
    if L.shape[0] < 1 or L.shape[1] < 1:
        raise InvalidInputError(f"images must be non-empty, got shape {L.shape}")
    if not (np.issubdtype(L.dtype, np.number) and np.issubdtype(R.dtype, np.number)):
        raise InvalidInputError("left and right must be numeric arrays")
    L = L.astype(np.float64)
    R = R.astype(np.float64)
    if not (np.isfinite(L).all() and np.isfinite(R).all()):
        raise InvalidInputError("left and right must be finite (no NaN/inf); fill or mask them first")
    return L, R


#: Largest disparity magnitude (px) a cost takes: far beyond any image, within int64.
MAX_DISPARITY = 2 ** 31


def check_disp(dmin, dmax, shape=None) -> tuple[int, int]:
    """Integer ``dmin <= dmax``; with the images' ``shape`` ``(H, W)``, a float32 volume of
    ``dmax - dmin + 1`` labels that fits in the memory available
    (:func:`hyperlf.tiling.check_memory`)."""
    try:
        a, b = (integer(v, "d", minimum=-MAX_DISPARITY, maximum=MAX_DISPARITY)
                for v in (dmin, dmax))
    except InvalidInputError:
        raise InvalidInputError(f"dmin and dmax must be integers within +-{MAX_DISPARITY:.3g}, "
                                f"got {shown(dmin)}, {shown(dmax)}") from None
    if b < a:
        raise InvalidInputError(f"dmax must be >= dmin, got dmin={a}, dmax={b}")
    if shape is not None:
        from ..tiling import check_memory, count_text

        check_memory(4 * (b - a + 1) * int(np.prod(shape[-2:])),
                     f"a cost volume of {count_text(b - a + 1)} disparities",
                     "narrow dmin..dmax to the disparities the scene has")
    return a, b


def check_dmin(dmin) -> int:
    """The lowest disparity of a volume: an integer within ``+-MAX_DISPARITY``."""
    return integer(dmin, "dmin", minimum=-MAX_DISPARITY, maximum=MAX_DISPARITY)


def check_window(n, name="window", *, side: int | None = None) -> int:
    """An odd integer window size ``>= 1`` (at most ``2 side + 1`` for an image of ``side``
    px on its longer side)."""
    return window(n, name, side=side)


def check_impl(impl, evaluator) -> str:
    """``"numpy"`` or ``"numba"`` (``"auto"`` resolved by :data:`AUTO_IMPL` for ``evaluator``)."""
    choice(impl, "impl", IMPLS)
    if impl == "auto":
        return AUTO_IMPL.get(evaluator, "numpy")
    return impl


#: Widest cost window the per-view evaluators take on views narrower than it (a window wider
#: than the view makes every column a border column; a huge one only pads memory away).
MAX_VIEW_WINDOW = 255


def map_side(shape) -> int:
    """The half-width up to which the window helpers take a window on maps of ``shape``
    ``(..., H, W)``: the maps' longer side, or ``MAX_VIEW_WINDOW // 2`` on smaller ones (as
    the per-view evaluators allow)."""
    return max(int(shape[-2]), int(shape[-1]), MAX_VIEW_WINDOW // 2)


def check_map(value, label: str, ndim, *, empty: bool = False) -> np.ndarray:
    """``value`` as a numpy array of real numbers (an ndarray is returned as it is, no copy)
    with ``ndim`` axes (an int, or a tuple of the ones allowed), non-empty unless ``empty``:
    :func:`hyperlf._options.array` without bools.  O(1) for an ndarray: nothing is scanned."""
    return array(value, label, ndim=ndim, kinds="iuf", empty=empty)


def check_shape(shape, label: str = "shape") -> tuple[int, int]:
    """``(H, W)``, the last two entries of ``shape`` (a sequence of at least two integers
    ``>= 1``, up to ``2**31``)."""
    try:
        items = tuple(shape) if not isinstance(shape, (str, bytes, dict)) else ()
        ok = len(items) >= 2
        H, W = (integer(v, label, 1, maximum=2 ** 31) for v in items[-2:]) if ok else (0, 0)
    except (TypeError, InvalidInputError):
        ok = False
    if not ok:
        raise InvalidInputError(f"{label} must be an image shape (..., H, W) of integers >= 1, "
                                f"got {shown(shape)}")
    return H, W


#: Arrays up to this many bytes are made without asking the memory (:func:`check_bytes`).
_SMALL_BYTES = 2 ** 26


def check_bytes(nbytes, what: str, remedy: str) -> None:
    """Refuse arrays of ``nbytes`` beyond the memory available
    (:func:`hyperlf.tiling.check_memory`); below 64 MiB without asking (O(1))."""
    if nbytes > _SMALL_BYTES:
        from ..tiling import check_memory

        check_memory(nbytes, what, remedy)


#: Smallest nonzero normalising scale (standard deviation of a cost volume) taken: below it
#: costs of order one would overflow float32 (a true standard deviation is 0 or far above).
MIN_SCALE = 1e-20


def check_scale(value, label: str, *, optional: bool = True) -> float | None:
    """A normalising scale: a finite number that is 0 or ``>= MIN_SCALE`` (None where
    ``optional``)."""
    sd = number(value, label, optional=optional)
    if sd is not None and 0 < sd < MIN_SCALE:
        raise InvalidInputError(f"{label} must be 0 or at least {MIN_SCALE:g} (a standard "
                                f"deviation of costs), got {shown(value)}")
    return sd
