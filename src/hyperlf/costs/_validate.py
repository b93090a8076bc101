"""Argument checks shared by the cost evaluators (private module, public names)."""

from __future__ import annotations

import numpy as np

from .._options import choice, integer, shown, window
from ..errors import InvalidInputError

__all__ = ["IMPLS", "AUTO_IMPL", "check_pair", "check_disp", "check_window", "check_impl"]

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
