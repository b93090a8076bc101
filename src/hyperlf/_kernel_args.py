"""How arrays are handed to hyperlf's numba kernels (private).

numba compiles a kernel once per combination of its arguments' types, and an array's type
includes its dtype, layout and read-only flag. Inputs handed over through
:func:`kernel_input` are always C-contiguous and read-only, so that a kernel is compiled once
for them, whatever the caller's array was (each compilation of a parallel kernel costs
seconds on first use).
"""

from __future__ import annotations

import numpy as np

__all__ = ["kernel_input"]


def kernel_input(a, dtype=None) -> np.ndarray:
    """``a`` C-contiguous (as ``dtype`` when given) and read-only, for a numba kernel that only
    reads it: numba compiles a kernel once per read-only flag of each argument, so this keeps
    one compiled signature whether the caller's array was writable or not (a view, no copy,
    where ``a`` already fits).

    Examples
    --------
    >>> a = np.zeros((2, 3))
    >>> b = kernel_input(a)
    >>> b.flags.writeable, np.shares_memory(a, b), a.flags.writeable
    (False, True, True)
    """
    out = np.ascontiguousarray(a, dtype=dtype).view()
    out.flags.writeable = False
    return out
