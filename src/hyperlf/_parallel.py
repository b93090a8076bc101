"""hyperlf's own thread pools: how many threads, and running independent tasks on them.

numba's kernels run on numba's threads (``NUMBA_NUM_THREADS``). Some work stays in numpy or
zlib, which release the GIL, and is independent item by item: the chunks of an HDF5 dataset
(:mod:`hyperlf.formats._h5chunks`) and the source views registered into one view
(:func:`hyperlf.completion.register_view`). That work runs in Python threads, as many as the
CPUs the process may use, or ``HYPERLF_THREADS``.

Every pool is made by :func:`thread_pool`, whose threads have all ended when its block is left,
also when an interrupt (Ctrl-C, SIGTERM) ends the block: a task still writing into a result
set's staging folder while the command removes it would leave files behind.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Iterable, Iterator, TypeVar

T = TypeVar("T")
R = TypeVar("R")

__all__ = ["threads", "thread_pool", "map_threads", "pipeline"]

#: Tasks :func:`pipeline` keeps in flight per thread: bounds the results waiting in memory.
DEPTH_PER_THREAD = 2

#: Seconds to wait for a pool thread that was being started when an interrupt came to run.
START_WAIT_S = 1.0

_POOL_NUMBERS = itertools.count()


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


@contextlib.contextmanager
def thread_pool(n: int) -> Iterator[ThreadPoolExecutor]:
    """A :class:`~concurrent.futures.ThreadPoolExecutor` of ``n`` threads, every one of which
    has ended when the block is left.

    On a normal exit every submitted task runs to its end, as with the executor's own ``with``.
    When the block raises (an error, Ctrl-C, :class:`~hyperlf.errors.Terminated`) the tasks not
    yet started are cancelled and the running ones finish, with SIGINT, SIGTERM and SIGHUP held
    back meanwhile (:func:`hyperlf.outputs.deferred_signals`): a task still writing into a
    staging folder as the command removes it would leave files behind.

    The executor's own ``shutdown`` waits only for the threads it has recorded; a thread whose
    start an interrupt cut short (in ``Thread.start``, before the executor records it) runs on
    unrecorded, and its first task with it. Here every thread of the pool is found by its name.

    Examples
    --------
    >>> with thread_pool(2) as pool:
    ...     list(pool.map(abs, [-1, 2, -3]))
    [1, 2, 3]
    """
    prefix = f"hyperlf-pool-{os.getpid()}-{next(_POOL_NUMBERS)}"
    pool = ThreadPoolExecutor(max(int(n), 1), thread_name_prefix=prefix)
    try:
        yield pool
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    finally:
        pool.shutdown(wait=False)
        _join_threads(prefix + "_")


def _join_threads(prefix: str) -> None:
    """Wait, with interrupts held back, for every thread whose name starts with ``prefix``."""
    from .outputs import deferred_signals

    with deferred_signals():
        for t in [t for t in threading.enumerate() if t.name.startswith(prefix)]:
            deadline = time.monotonic() + START_WAIT_S
            while True:
                try:
                    t.join()
                    break
                except RuntimeError:  # not started yet, or its start never came
                    if time.monotonic() > deadline:
                        break
                    time.sleep(0.001)


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
    with thread_pool(n) as pool:
        return list(pool.map(fn, items))


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
    with thread_pool(n) as pool:
        pending: deque = deque()
        for task in tasks:
            pending.append(pool.submit(task))
            if len(pending) >= n * DEPTH_PER_THREAD:
                then(pending.popleft().result())
        while pending:
            then(pending.popleft().result())
