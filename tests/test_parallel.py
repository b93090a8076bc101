"""hyperlf's own thread pools (`hyperlf._parallel`): the thread count, `map_threads`, and
`thread_pool`, whose threads have all ended when its block is left."""

from __future__ import annotations

import os
import threading
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf._parallel import map_threads, thread_pool, threads

CPUS = len(os.sched_getaffinity(0))


@settings(max_examples=80, deadline=None)
@given(value=st.one_of(st.text(st.characters(blacklist_categories=("Cs",),  # what an
                                             blacklist_characters="\x00"),  # environment holds
                                max_size=6),
                       st.integers(-5, 99).map(str)),
       cap=st.one_of(st.none(), st.integers(1, 8)))
def test_the_thread_count_setting(value, cap):
    os.environ["HYPERLF_THREADS"] = value
    try:
        n = threads(cap)
    finally:
        del os.environ["HYPERLF_THREADS"]
    s = value.strip()
    want = int(s) if s.isascii() and s.isdigit() and int(s) > 0 else CPUS
    assert n == (min(want, cap) if cap else want) and n >= 1


@pytest.mark.parametrize("value", ["\u00b2", "\u0663", "1\u00b2", " 0 ", "+2"])
def test_digits_that_are_not_ascii_fall_back_to_the_cpus(monkeypatch, value):
    monkeypatch.setenv("HYPERLF_THREADS", value)
    assert threads() == CPUS


@pytest.mark.parametrize("n", ["1", "3"])
def test_map_threads_keeps_order_and_uses_the_threads(monkeypatch, n):
    monkeypatch.setenv("HYPERLF_THREADS", n)
    seen = set()

    def work(x):
        seen.add(threading.get_ident())
        time.sleep(0.01)
        return x * 10

    assert map_threads(work, range(12)) == [x * 10 for x in range(12)]
    assert len(seen) == (1 if n == "1" else 3)
    assert map_threads(work, []) == []


def test_a_failing_task_cancels_the_rest(monkeypatch):
    monkeypatch.setenv("HYPERLF_THREADS", "2")
    started = []

    def work(x):
        started.append(x)
        if x == 0:
            raise ValueError("task 0")
        time.sleep(0.05)
        return x

    with pytest.raises(ValueError, match="task 0"):
        map_threads(work, range(40))
    assert len(started) < 40  # the queued ones never ran


def interrupt_the_first_start(monkeypatch, began):
    """Make an interrupt land in the first ``Thread.start`` of a pool, once the thread runs (and
    has begun its task, ``began``) but before the executor has recorded it: where a real Ctrl-C
    or SIGTERM landed in CI."""
    start = threading.Thread.start
    calls = []

    def start_then_interrupt(self):
        start(self)
        if not calls:
            calls.append(self)
            began.wait(5)
            raise KeyboardInterrupt

    monkeypatch.setattr(threading.Thread, "start", start_then_interrupt)
    return calls


def slow_task(began, done):
    def task(x):
        began.set()
        time.sleep(0.2)
        done.append(x)
    return task


def interrupted_pool(monkeypatch, make_pool):
    """Run eight slow tasks on ``make_pool(4)`` with the interrupt in its first thread's
    start; the thread the executor never recorded, and the tasks done when the block is left."""
    began, done = threading.Event(), []
    calls = interrupt_the_first_start(monkeypatch, began)
    with pytest.raises(KeyboardInterrupt):
        with make_pool(4) as pool:
            list(pool.map(slow_task(began, done), range(8)))
    return calls[0], done


def test_an_interrupt_while_a_pool_thread_starts_leaves_no_thread_running(monkeypatch):
    thread, done = interrupted_pool(monkeypatch, thread_pool)
    # the thread the executor never recorded ran its task to the end before the block was left
    assert not thread.is_alive() and done == [0]
    time.sleep(0.3)
    assert done == [0]  # and nothing ran afterwards


def test_the_executors_own_shutdown_misses_that_thread(monkeypatch):
    # the failure thread_pool exists for: with the plain executor the task outlives the block
    from concurrent.futures import ThreadPoolExecutor

    thread, done = interrupted_pool(monkeypatch, ThreadPoolExecutor)
    assert thread.is_alive() and done == []
    thread.join()
    assert done == [0]


def test_a_pool_finishes_every_task_on_a_normal_exit():
    done = []
    with thread_pool(3) as pool:
        for k in range(9):
            pool.submit(lambda k=k: (time.sleep(0.01), done.append(k)))
    assert sorted(done) == list(range(9))
    assert not [t for t in threading.enumerate() if t.name.startswith("hyperlf-pool-")]
