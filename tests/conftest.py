"""Shared fixtures and markers.

Tests that need real data skip with a clear message when HYPERLF_DATA is unset, and carry the
``data`` marker (added here at collection, see :func:`pytest_collection_modifyitems`), so
``python -m pytest -m data`` selects exactly them and ``-m "not data"`` leaves them out.
"""

from __future__ import annotations

import ast
import contextlib
import functools
import inspect
import os
import textwrap
import types


def _share_the_cores_among_workers() -> None:
    """Under pytest-xdist (``-n N``, the README's test command) each of the N workers runs
    numba's kernels and hyperlf's thread pools. With a full core count of threads each, they
    oversubscribe the machine, and numba's OpenMP threads spin while they wait. So each worker
    gets ``cores // N`` threads, unless ``NUMBA_NUM_THREADS`` or ``HYPERLF_THREADS`` is set
    already. This runs before anything imports numba, which reads the variable once."""
    workers = os.environ.get("PYTEST_XDIST_WORKER_COUNT", "")
    if workers.isdigit() and int(workers) > 1:
        try:
            cores = len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not Linux
            cores = os.cpu_count() or 1
        for var in ("NUMBA_NUM_THREADS", "HYPERLF_THREADS"):
            os.environ.setdefault(var, str(max(1, cores // int(workers))))


_share_the_cores_among_workers()  # before numpy, hyperlf and numba are imported

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from hyperlf.datasets import ENV_VAR, has_data, dataset_path  # noqa: E402


def _reproducible_examples() -> None:
    """Every hypothesis test draws the same examples on every run (CI must not fail on a
    draw that the next run would not make: half the tests were random until a CI run drew a
    pair of weights whose sum overflows). Random draws find new cases, and every session runs
    them on purpose: ``python -m pytest --hypothesis-profile random`` (BENCHMARKS.md,
    "Random seeds for every hypothesis test")."""
    from hypothesis import settings

    settings.register_profile("reproducible", derandomize=True)
    settings.register_profile("random", derandomize=False)
    settings.load_profile("reproducible")  # --hypothesis-profile replaces it


_reproducible_examples()


def pytest_sessionstart(session):
    """Give the test process the signal dispositions of a terminal.

    A shell ignores SIGINT in its background jobs (``cmd &`` without job control) and
    ``nohup`` ignores SIGHUP; both are inherited, and hyperlf rightly keeps an ignored signal
    ignored, so the signal tests would see no interrupt at all (three of them failed when the
    suite was started that way).  Tests that need an ignored signal set it themselves.
    """
    import signal

    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    for name in ("SIGTERM", "SIGHUP"):
        if signal.getsignal(getattr(signal, name)) is signal.SIG_IGN:
            signal.signal(getattr(signal, name), signal.SIG_DFL)


#: Calls that mean "this test reads the real data in HYPERLF_DATA".
_DATA_CALLS = frozenset({"require_dataset", "has_data"})


def require_dataset(name: str):
    """Return the dataset's path or skip the test, saying how to enable it."""
    if not has_data(name):
        pytest.skip(f"needs the real data: set {ENV_VAR} to the shared data folder ({name})")
    return dataset_path(name)


def benchmark_script(name: str):
    """A script of ``benchmarks/`` imported as a module (that folder put on ``sys.path``, as
    the scripts import their ``_common`` helpers by name)."""
    import importlib
    import sys
    from pathlib import Path

    folder = str(Path(__file__).resolve().parents[1] / "benchmarks")
    if folder not in sys.path:
        sys.path.insert(0, folder)
    return importlib.import_module(name)


def write_shifted_pair(folder, *, seed: int = 0, rows: int = 30, width: int = 40,
                       start: int = 5, shift: int = 3):
    """A rectified pair of 16-bit PNGs cut from one random texture, the right one ``shift``
    px further along it (left x matches right x - shift); returns their paths."""
    from hyperlf.formats import write_image

    tex = np.random.default_rng(seed).random((rows, start + width + shift)).astype(np.float32)
    left, right = folder / "l.png", folder / "r.png"
    write_image(left, tex[:, start:start + width], bit_depth=16)
    write_image(right, tex[:, start + shift:start + shift + width], bit_depth=16)
    return left, right


def sparsification(conf, loss, *, rmse: bool = False) -> float:
    """The mean ``loss`` of the most confident 5, 10, ..., 100 % of the pixels, averaged (ties
    kept in raster order); with ``rmse`` the loss is a squared error and each mean its root."""
    order = np.argsort(-np.asarray(conf).ravel(), kind="stable")
    running = np.cumsum(np.asarray(loss).ravel()[order]) / np.arange(1, np.size(loss) + 1)
    picked = running[(np.linspace(0.05, 1, 20) * np.size(loss)).astype(int) - 1]
    return float(np.mean(np.sqrt(picked) if rmse else picked))


# ----------------------------------------------------------------------------- long work
class LongWork(BaseException):
    """Raised where long work would start (not an Exception: nothing may swallow it)."""


@functools.lru_cache(maxsize=1)
def _long_work_sites() -> tuple:
    """``(module, name)`` of every module's progress bar and solver: long work starts at the
    first step of a progress bar or at a call of :func:`hyperlf.regularisers.optimise`."""
    import importlib
    import pkgutil

    import hyperlf
    from hyperlf import regularisers

    out = []
    for info in pkgutil.walk_packages(hyperlf.__path__, "hyperlf."):
        mod = importlib.import_module(info.name)
        if hasattr(mod, "progress_bar"):
            out.append((mod, "progress_bar"))
        if getattr(mod, "optimise", None) is regularisers.optimise:
            out.append((mod, "optimise"))
    return tuple(out)


@contextlib.contextmanager
def _long_work_replaced(wrap):
    """Each site's function replaced by ``wrap(name, original)`` for the block."""
    saved = [(mod, name, getattr(mod, name)) for mod, name in _long_work_sites()]
    try:
        for mod, name, original in saved:
            setattr(mod, name, wrap(name, original))
        yield
    finally:
        for mod, name, original in saved:
            setattr(mod, name, original)


def _at_start(name, original, then):
    """``original`` that calls ``then()`` where long work starts."""
    if name == "optimise":
        def solve(*args, **kwargs):
            then()
            return original(*args, **kwargs)
        return solve

    def bar(items, *args, **kwargs):
        for item in original(items, *args, **kwargs):
            then()
            yield item
    return bar


def _stop():
    raise LongWork


def long_work_stopped():
    """A context in which the start of long work raises :class:`LongWork`."""
    return _long_work_replaced(lambda name, original: _at_start(name, original, _stop))


@contextlib.contextmanager
def long_work_seen():
    """A context in which long work runs; yields a namespace whose ``started`` turns true
    where it starts."""
    seen = types.SimpleNamespace(started=False)

    def mark():
        seen.started = True

    with _long_work_replaced(lambda name, original: _at_start(name, original, mark)):
        yield seen


# ----------------------------------------------------------------------------- temp folder
@pytest.fixture(scope="session", autouse=True)
def _private_temp_folder(tmp_path_factory):
    """The system's temporary folder, for this test process only (``TMPDIR`` and ``tempfile``
    pointed into pytest's own base folder), so that :func:`_nothing_left_in_temp` can see
    what a test leaves there and the machine's ``/tmp`` gets nothing."""
    import tempfile

    folder = tmp_path_factory.mktemp("system-temp")
    saved = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"], tempfile.tempdir = str(folder), None
    try:
        yield folder
    finally:
        if saved[0] is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = saved[0]
        tempfile.tempdir = saved[1]


@pytest.fixture(autouse=True)
def _nothing_left_in_temp(_private_temp_folder):
    """A test (and the commands it runs) leaves nothing in the system's temporary folder:
    a command writes only its output, and a test's own files go to ``tmp_path``."""
    before = set(os.listdir(_private_temp_folder))
    yield
    left = sorted(set(os.listdir(_private_temp_folder)) - before)
    assert not left, f"left in the temporary folder: {left[:5]}"


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture
def batch_depth_args(monkeypatch, tmp_path):
    """``run(*options)``: the depth options ``hyperlf batch ... *options`` hands to each capture
    (``hyperlf.batch.plan_batch`` stubbed to record them and stop with exit 2); ``run.calls``
    every list recorded so far."""
    from hyperlf import batch
    from hyperlf.cli import main
    from hyperlf.errors import InvalidInputError

    seen = []

    def plan(inputs, out, *, depth_args=(), **kw):
        seen.append(list(depth_args))
        raise InvalidInputError("stop here")

    monkeypatch.setattr(batch, "plan_batch", plan)

    def run(*options):
        assert main(["-q", "batch", str(tmp_path), *options, "-o", str(tmp_path / "o")]) == 2
        return seen[-1]

    run.calls = seen
    return run


def refused_while_parsing_and_handed_on(capsys, batch_depth_args, cap, out, option, bad,
                                        good) -> None:
    """``depth CAP OPTION BAD`` is refused while parsing (exit 2, the option named, nothing
    written at ``out``); ``batch`` hands ``OPTION GOOD`` on to each capture only when given."""
    from hyperlf.cli import main

    with pytest.raises(SystemExit) as info:
        main(["-q", "depth", str(cap), option, bad, "-o", str(out)])
    assert info.value.code == 2 and option in capsys.readouterr().err
    assert not out.exists()
    assert option not in batch_depth_args()
    given = batch_depth_args(option, good)
    assert given[given.index(option) + 1] == good


# ----------------------------------------------------------------------------- data marker
def _called_names(func) -> set[str]:
    """Names of the functions ``func`` calls (decorators included), from its source."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    except (OSError, TypeError, SyntaxError):
        return set()
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            names.add(f.id if isinstance(f, ast.Name) else getattr(f, "attr", ""))
    return names


def _data_helpers(module) -> frozenset[str]:
    """``_DATA_CALLS`` plus the module's own helpers that call one of them."""
    found = set(_DATA_CALLS)
    for name, obj in vars(module).items():
        if inspect.isfunction(obj) and obj.__module__ == module.__name__ \
                and not name.startswith("test_") and _called_names(obj) & _DATA_CALLS:
            found.add(name)
    return frozenset(found)


def _needs_data(item, helpers: frozenset[str]) -> bool:
    funcs = [item.function]
    for name in getattr(item, "fixturenames", ()):
        for fixturedef in item._fixtureinfo.name2fixturedefs.get(name, ()):
            funcs.append(fixturedef.func)
    return any(_called_names(f) & helpers for f in funcs)


def pytest_collection_modifyitems(config, items):
    """Mark every test that (directly, through a fixture or a helper) needs HYPERLF_DATA."""
    helpers: dict[str, frozenset[str]] = {}
    for item in items:
        module = getattr(item, "module", None)
        if module is None or not hasattr(item, "function"):
            continue
        if module.__name__ not in helpers:
            helpers[module.__name__] = _data_helpers(module)
        if _needs_data(item, helpers[module.__name__]):
            item.add_marker(pytest.mark.data)
