"""hyperlf's own thread pools: how many threads, and running independent tasks on them.

numba's kernels run on numba's threads (``NUMBA_NUM_THREADS``). Some work stays in numpy or
zlib, which release the GIL, and is independent item by item: the chunks of an HDF5 dataset
(:mod:`hyperlf.formats._h5chunks`) and the source views registered into one view
(:func:`hyperlf.completion.register_view`). That work runs in Python threads, as many as the
CPUs the process may use, or ``HYPERLF_THREADS``.
"""

from __future__ import annotations

import os
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Iterable, TypeVar

T = TypeVar("T")
R = TypeVar("R")

__all__ = ["threads", "map_threads", "pipeline"]

#: Tasks :func:`pipeline` keeps in flight per thread: bounds the results waiting in memory.
DEPTH_PER_THREAD = 2


def threads(cap: int | None = None) -> int:
    """The threads hyperlf's pools use: ``HYPERLF_THREADS`` when it is a positive integer,
    else the CPUs this process may use; at most ``cap``.

    Examples
    --------
    >>> import os
    >>> os.environ["HYPERLF_THREADS"] = "3"
    >>> threads(), threads(cap=2)
    (3, 2)
    >>> del os.environ["HYPERLF_THREADS"]
    """
    env = os.environ.get("HYPERLF_THREADS", "").strip()
    if env.isascii() and env.isdigit() and int(env) > 0:  # '²' is a digit int() refuses
        n = int(env)
    else:
        try:
            n = len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not Linux
            n = os.cpu_count() or 1
    return max(1, min(n, cap) if cap else n)


def map_threads(fn: Callable[[T], R], items: Iterable[T], *, cap: int | None = None) -> list[R]:
    """``[fn(x) for x in items]``, on :func:`threads` threads (inline with one).

    When a task raises, or the caller is interrupted, the tasks not yet started are cancelled
    and the running ones finish before the exception goes on.

    Examples
    --------
    >>> map_threads(lambda x: x * x, range(5))
    [0, 1, 4, 9, 16]
    """
    items = list(items)
    n = min(threads(cap), max(len(items), 1))
    if n == 1:
        return [fn(x) for x in items]
    pool = ThreadPoolExecutor(n)
    try:
        return list(pool.map(fn, items))
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def pipeline(tasks: Iterable[Callable[[], R]], n_tasks: int,
             then: Callable[[R], None] | None = None) -> None:
    """Run the callables ``tasks`` (made one by one in this thread, e.g. reading each input)
    on :func:`threads` threads, a bounded number in flight (:data:`DEPTH_PER_THREAD` each),
    and ``then(result)`` in this thread in their order (e.g. writing each output); inline
    with one thread. ``n_tasks`` is how many ``tasks`` yields.

    Examples
    --------
    >>> out = []
    >>> pipeline((lambda k=k: k * k for k in range(5)), 5, then=out.append)
    >>> out
    [0, 1, 4, 9, 16]
    """
    n = min(threads(), max(n_tasks, 1))
    then = then or (lambda result: None)
    if n == 1:
        for task in tasks:
            then(task())
        return
    with ThreadPoolExecutor(n) as pool:
        pending: deque = deque()
        for task in tasks:
            pending.append(pool.submit(task))
            if len(pending) >= n * DEPTH_PER_THREAD:
                then(pending.popleft().result())
        while pending:
            then(pending.popleft().result())
