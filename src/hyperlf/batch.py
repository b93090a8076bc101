"""Many captures at once (SPEC §12): ``hyperlf batch`` on dask.distributed.

A batch runs ``hyperlf depth`` on every capture it is given (capture folders, ``.h5`` light
fields, a folder of them such as the frames of an H-LF video, or a glob pattern) and collects
one result set per capture under one output folder, plus a summary (``summary.csv`` and
``summary.html``, written whole together).

How the work is made safe to lose:

* every capture runs as its own ``hyperlf depth`` process, so its outputs are a whole result
  set (:mod:`hyperlf.outputs`) and its memory is returned when it ends; on Linux the process
  gets SIGTERM when the worker that started it goes, so a dead worker leaves no writer behind
  and the process removes its own staging folder (a batch stopped by SIGTERM or Ctrl-C leaves
  no hidden folders);
* a capture whose result set exists is finished and never recomputed (a re-run submits only
  the missing ones); the depth options of the batch are recorded in the folder
  (:data:`BATCH_FILE`), and a re-run with other options is refused unless ``overwrite``;
* a worker that dies loses only the capture it was running: the scheduler gives that task to
  another worker (dask's ``allowed-failures``); a staging folder left all the same (a depth
  process killed outright) is removed by the next run that writes beside it.

The scheduler is a :class:`dask.distributed.LocalCluster` of ``workers`` processes with one
thread each unless ``scheduler`` names an existing one.  dask.distributed is an optional
dependency (``pip install "hyperlf[batch]"``); nothing else of hyperlf needs it.
"""

from __future__ import annotations

import contextlib
import csv
import functools
import glob
import html
import io
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

from . import _options as _opt
from .errors import DataNotFoundError, HyperLFError, InvalidInputError

__all__ = ["BATCH_FILE", "CaptureTask", "find_captures", "plan_batch", "run_capture",
           "run_batch", "write_summary", "finish_batch"]

#: The file that marks a batch output folder and records its depth options.
BATCH_FILE = ".hyperlf-batch.json"
#: The columns of ``summary.csv``.
SUMMARY_COLUMNS = ("capture", "input", "status", "seconds", "rmse_px", "badpix_007_pct",
                   "range_limit_pct", "exit_code", "message")


@dataclass(frozen=True)
class CaptureTask:
    """One capture of a batch: where it is read, where its result set goes, what runs."""

    name: str
    capture: str
    output: str
    depth_args: tuple = ()
    overwrite: bool = False
    disparity_range: tuple | None = None  # the batch's --disparity-range, if given
    downscale: int = 1  # the batch's --downscale: results at 1 / downscale of the capture

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InvalidInputError(f"name must be a non-empty text, got {_opt.shown(self.name)}")
        _opt.path_like(self.capture, "capture", folder=None)
        _opt.path_like(self.output, "output", folder=None)
        _opt.check_fields(self, {"depth_args": _args, "overwrite": _opt.flag,
                                 "disparity_range": _range, "downscale": _downscale})


def _args(value, label: str) -> tuple:
    """Command-line arguments: a list or tuple of text, as a tuple."""
    if not isinstance(value, (list, tuple)) or not all(isinstance(a, str) for a in value):
        raise InvalidInputError(f"{label} must be a list of text (command-line arguments), got "
                                f"{_opt.shown(value)}")
    return tuple(value)


def _range(value, label: str) -> tuple | None:
    """A disparity range ``(dmin, dmax)`` or None."""
    return None if value is None else _opt.real_pair(value, label, "(dmin, dmax)")


def _downscale(value, label: str) -> int:
    return _opt.integer(value, label, 1, maximum=2 ** 16)


def _rows(rows) -> list:
    """The :class:`CaptureResult` rows of a summary."""
    if not isinstance(rows, (list, tuple)) or not all(isinstance(r, CaptureResult) for r in rows):
        raise InvalidInputError(f"rows must be a list of hyperlf.batch.CaptureResult, got "
                                f"{_opt.shown(rows)}")
    return list(rows)


@dataclass
class CaptureResult:
    """What became of one capture (a row of the summary)."""

    capture: str
    input: str
    status: str  # "done", "done before" or "failed"
    seconds: float = 0.0
    rmse_px: float | None = None
    badpix_007_pct: float | None = None
    range_limit_pct: float | None = None
    exit_code: int = 0
    message: str = ""


# ----------------------------------------------------------------------------- inputs
def _is_capture(path: Path) -> bool:
    """A capture folder, an HDF5 light field or an HCI scene folder."""
    if path.is_file():
        return path.suffix.lower() in (".h5", ".hdf5")
    return path.is_dir() and ((path / "capture.toml").is_file()
                              or (path / "parameters.cfg").is_file())


def find_captures(inputs: Sequence[str | os.PathLike]) -> list[Path]:
    """Every capture named by ``inputs``, in order, each once.

    An input is a capture (folder with ``capture.toml``, ``.h5`` file or HCI scene folder), a
    folder of captures (its captures in name order: the frames of a video), or a glob pattern
    (``frames/*.h5``; its matches in name order).

    Raises
    ------
    DataNotFoundError
        An input that does not exist, or inputs that hold no capture.

    Examples
    --------
    A folder of two capture folders (each with its ``capture.toml``; a real one holds the
    capture's description) and a light field file:

    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> for name in ("frame1", "frame0"):
    ...     (root / "frames" / name).mkdir(parents=True)
    ...     (root / "frames" / name / "capture.toml").touch()
    >>> (root / "frames" / "notes.txt").touch()
    >>> (root / "extra.h5").touch()
    >>> [p.name for p in find_captures([root / "frames", root / "extra.h5"])]
    ['frame0', 'frame1', 'extra.h5']
    >>> [p.name for p in find_captures(str(root / "frames" / "frame*"))]
    ['frame0', 'frame1']
    >>> find_captures(root / "missing")
    Traceback (most recent call last):
        ...
    hyperlf.errors.DataNotFoundError: .../missing: no such capture, folder or pattern
    """
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    if not isinstance(inputs, (list, tuple)) or not inputs:
        raise InvalidInputError(f"inputs must be a list of at least one capture, folder or "
                                f"pattern, got {_opt.shown(inputs)}")
    for raw in inputs:
        _opt.path_like(raw, "inputs", folder=None)
    found: list[Path] = []
    for raw in inputs:
        text = os.fspath(raw)
        if any(ch in text for ch in "*?["):
            paths = [Path(p) for p in sorted(glob.glob(text))]
            found += [p for p in paths if _is_capture(p)]
            continue
        p = Path(text)
        if not p.exists():
            raise DataNotFoundError(f"{p}: no such capture, folder or pattern")
        if _is_capture(p):
            found.append(p)
        elif p.is_dir():
            found += [c for c in sorted(p.iterdir()) if not c.name.startswith(".")
                      and not c.is_symlink() and _is_capture(c)]
    unique = list(dict.fromkeys(p.resolve() for p in found))
    if not unique:
        raise DataNotFoundError(f"no capture in {', '.join(map(os.fspath, inputs))}: give "
                                "capture folders, .h5 files, a folder of them or a pattern")
    return unique


def _names(captures: Sequence[Path]) -> list[str]:
    """One output name per capture: its file or folder name without suffix, made unique (a
    ``-2``, ``-3``, ... that no other capture's own name takes) and never a name the batch
    folder itself uses (the summary, the marker)."""
    stems = []
    for p in captures:
        stem = p.stem if p.suffix.lower() in (".h5", ".hdf5") else p.name
        stems.append(stem if stem and not stem.startswith(".") else "capture")
    taken = {"summary.csv", "summary.html", BATCH_FILE}
    names = []
    for i, stem in enumerate(stems):
        name, k = stem, 1
        while name in taken or (k > 1 and name in stems[i + 1:]):
            k += 1
            name = f"{stem}-{k}"
        taken.add(name)
        names.append(name)
    return names


def _record_options(out: Path, depth_args: Sequence[str], overwrite: bool) -> None:
    """Make ``out`` a batch folder recording ``depth_args``; refuse another batch's folder
    with other options (unless ``overwrite``, or it holds no result yet), a folder that is not
    a batch's, and, without ``overwrite``, a folder whose last ``overwrite`` run did not
    finish (some of its result sets may still come from the old options)."""
    marker = out / BATCH_FILE
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise InvalidInputError(f"-o {out}: not a folder; give a folder for the batch results")
    if out.exists() and not marker.is_file():
        if any(out.iterdir()):
            raise InvalidInputError(f"-o {out}: a folder that is not a hyperlf batch output "
                                    "and not empty; give a new or empty folder")
    elif marker.is_file() and not overwrite and _holds_results(out):
        before = _read_marker(marker)
        if before.get("overwrite_unfinished"):
            raise InvalidInputError(f"-o {out}: an --overwrite run into it did not finish, so "
                                    "some results may have other options; run it again with "
                                    "--overwrite")
        if before.get("depth_args") != list(depth_args):
            old = _recorded_args(before.get("depth_args"))
            raise InvalidInputError(
                f"-o {out}: made with other depth options ({old}); give another folder, the "
                "same options, or --overwrite to recompute")
    out.mkdir(parents=True, exist_ok=True)
    _write_marker(marker, {"depth_args": list(depth_args), "overwrite_unfinished": overwrite})


def _recorded_args(args) -> str:
    """The depth options a batch folder's marker records, on one line ("none" without any;
    a marker edited by hand may hold anything)."""
    text = " ".join(args) if isinstance(args, list) and all(isinstance(a, str) for a in args) \
        else _opt.shown(args) if args else ""
    return " ".join(text.split()) or "none"


def _holds_results(out: Path) -> bool:
    """Whether a batch folder holds anything but its marker (and hidden unfinished result
    sets): a run that computed nothing (an unreachable scheduler) binds no later run."""
    return any(p.name != BATCH_FILE and not p.name.startswith(".hyperlf-")
               for p in out.iterdir())


def _read_marker(marker: Path) -> dict:
    try:
        doc = json.loads(marker.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return doc if isinstance(doc, dict) else {}


def _write_marker(marker: Path, doc: dict) -> None:
    from ._atomic import atomic_write_bytes

    atomic_write_bytes(marker, (json.dumps(doc, indent=1) + "\n").encode("utf-8"))


def finish_batch(out: str | os.PathLike, rows: Sequence["CaptureResult"]) -> None:
    """After a run: the folder's results all have its recorded options once every capture
    is done (clears the mark an ``overwrite`` run leaves until then).

    Examples
    --------
    An ``overwrite`` plan marks the folder unfinished until every capture is done:

    >>> import json, tempfile, pathlib
    >>> from hyperlf.batch import CaptureResult
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> (root / "frames" / "frame0").mkdir(parents=True)
    >>> (root / "frames" / "frame0" / "capture.toml").touch()
    >>> tasks = plan_batch([root / "frames"], root / "results", overwrite=True)
    >>> marker = root / "results" / BATCH_FILE
    >>> json.loads(marker.read_text())["overwrite_unfinished"]
    True
    >>> finish_batch(root / "results", [CaptureResult("frame0", tasks[0].capture, "done")])
    >>> json.loads(marker.read_text())["overwrite_unfinished"]
    False
    """
    marker = Path(_opt.path_like(out, "out", folder=True)) / BATCH_FILE
    _rows(rows)
    doc = _read_marker(marker)
    if doc.get("overwrite_unfinished") and all(r.status != "failed" for r in rows):
        _write_marker(marker, {**doc, "overwrite_unfinished": False})


def plan_batch(inputs, out: str | os.PathLike, *, depth_args: Sequence[str] = (),
               disparity_range: tuple[float, float] | None = None,
               downscale: int = 1, overwrite: bool = False) -> list[CaptureTask]:
    """The tasks of a batch: one per capture of ``inputs`` (:func:`find_captures`), its
    result set at ``out / name``; ``disparity_range`` (optional) is passed to every depth run
    and used for its range-limit figure, ``downscale`` (depth's ``--downscale``) to every run
    and to the measuring of its results.  Checks and marks ``out`` first (nothing is
    computed).

    Examples
    --------
    Two captures, one result set each under ``results``; nothing is computed, but the folder is
    made and records the depth options:

    >>> import json, tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> for name in ("frame0", "frame1"):
    ...     (root / "frames" / name).mkdir(parents=True)
    ...     (root / "frames" / name / "capture.toml").touch()
    >>> tasks = plan_batch([root / "frames"], root / "results", disparity_range=(-2, 2))
    >>> [(t.name, pathlib.Path(t.output).name) for t in tasks]
    [('frame0', 'frame0'), ('frame1', 'frame1')]
    >>> tasks[0].depth_args
    ('--disparity-range=-2,2',)
    >>> json.loads((root / "results" / BATCH_FILE).read_text())["depth_args"]
    ['--disparity-range=-2,2']
    """
    out = Path(_opt.path_like(out, "out", folder=True))
    args = list(_args(depth_args, "depth_args"))
    disparity_range = _range(disparity_range, "disparity_range")
    downscale = _downscale(downscale, "downscale")
    overwrite = _opt.flag(overwrite, "overwrite")
    captures = find_captures(inputs)
    if downscale != 1:
        args.insert(0, f"--downscale={int(downscale)}")
    if disparity_range is not None:
        args.insert(0, "--disparity-range={:g},{:g}".format(*disparity_range))
    _record_options(out, args, overwrite)
    return [CaptureTask(name=n, capture=os.fspath(c), output=os.fspath(out / n),
                        depth_args=tuple(args), overwrite=overwrite,
                        disparity_range=disparity_range, downscale=downscale)
            for n, c in zip(_names(captures), captures)]


def is_finished(task: CaptureTask) -> bool:
    """Whether the capture's result set is in place (result sets appear whole)."""
    from .outputs import MANIFEST

    return (Path(task.output) / MANIFEST).is_file()


def _done_before(task: CaptureTask) -> CaptureResult | None:
    """The row of a capture finished by an earlier run (None: it is to be computed)."""
    if task.overwrite or not is_finished(task):
        return None
    return _measure(task, CaptureResult(task.name, task.capture, "done before"))


# ----------------------------------------------------------------------------- one capture
def _die_with_parent(parent: int) -> None:  # pragma: no cover - runs in the child before exec
    """Linux: the child gets SIGTERM when the worker thread that started it dies, and so
    removes its staging folder itself, as after any SIGTERM (a batch stopped by SIGTERM or
    Ctrl-C leaves no hidden folders behind).  A worker ``parent`` that died between the fork
    and the request sends no signal: the child then exits before it starts (it has made
    nothing yet), instead of running on unsignalled after the batch is gone."""
    try:
        import ctypes
        import signal

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:
        os._exit(143)


def run_capture(task: CaptureTask) -> CaptureResult:
    """Run ``hyperlf depth`` on one capture (unless finished) and measure its result.

    Runs in a dask worker; the depth command is its own process, so the result set is whole
    whatever happens to the worker.  A failure of the command is reported, not raised.

    Examples
    --------
    A capture whose ``capture.toml`` is empty: ``hyperlf depth`` fails, and the failure comes
    back as a row of the summary, not as an exception:

    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> (root / "frames" / "frame0").mkdir(parents=True)
    >>> (root / "frames" / "frame0" / "capture.toml").touch()
    >>> task = plan_batch([root / "frames"], root / "results")[0]
    >>> row = run_capture(task)
    >>> row.capture, row.status, row.exit_code != 0
    ('frame0', 'failed', True)
    >>> row.message
    'hyperlf depth: error: ...capture.toml: ...'
    """
    if not isinstance(task, CaptureTask):
        raise InvalidInputError(f"task must be a hyperlf.batch.CaptureTask, got "
                                f"{type(task).__name__}")
    done = _done_before(task)  # a retried task whose first run had finished
    if done is not None:
        return done
    argv = [sys.executable, "-m", "hyperlf", "-q", "depth", task.capture, "-o", task.output,
            *task.depth_args] + (["--overwrite"] if task.overwrite else [])
    t0 = time.perf_counter()
    proc = subprocess.run(argv, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True, errors="replace",
                          preexec_fn=functools.partial(_die_with_parent, os.getpid())
                          if sys.platform == "linux" else None)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
        msg = lines[-1] if lines else f"exited with status {proc.returncode}"
        if proc.returncode < 0:
            msg = f"killed by signal {-proc.returncode}"
        return CaptureResult(task.name, task.capture, "failed", seconds,
                             exit_code=proc.returncode, message=msg)
    return _measure(task, CaptureResult(task.name, task.capture, "done", seconds))


def _measure(task: CaptureTask, row: CaptureResult) -> CaptureResult:
    """Scores of a finished capture: range-limit share, and RMSE / BadPix(0.07) without the
    HCI border where the capture has ground truth."""
    from . import metrics
    from .formats import load_lightfield, read_pfm
    from .lightfield import downscale

    try:
        d = read_pfm(Path(task.output) / "disparity.pfm")
        lf = load_lightfield(task.capture, cube=False)
    except (HyperLFError, OSError) as exc:
        row.message = f"result not measured: {exc}"
        return row
    if task.disparity_range is not None:
        lf = lf.replace(disparity_range=task.disparity_range)
    if task.downscale > 1:  # what depth --downscale matched: block means, range and truth
        lf = downscale(lf, task.downscale, truth=True)
    rng = lf.disparity_range  # the range depth used, in the px of its map
    shares = None if rng is None else metrics.range_limit_shares(
        d, rng, None if lf.valid is None else lf.valid[lf.reference])
    if shares is not None:
        row.range_limit_pct = round(sum(shares), 3)
    gt = lf.reference_gt_disparity
    sc = None if gt is None else metrics.hci_scores(d, gt)
    if sc is not None:
        row.rmse_px = round(float(sc.rmse), 5)
        row.badpix_007_pct = round(float(sc.badpix_007), 3)
    return row


# ----------------------------------------------------------------------------- the batch
#: Prefix of the scratch folder a local dask cluster gets inside the batch folder.
SCRATCH_PREFIX = ".hyperlf-dask-"


def _remove_stale_scratch(home: Path) -> None:
    """Remove the scratch folders of batch runs into ``home`` whose process is gone."""
    for stale in home.glob(SCRATCH_PREFIX + "*"):
        try:
            os.kill(int(stale.name[len(SCRATCH_PREFIX):].split("-")[0]), 0)
        except ProcessLookupError:
            shutil.rmtree(stale, ignore_errors=True)
        except (ValueError, PermissionError):
            continue


def discard_unused(out: str | os.PathLike) -> None:
    """Remove a batch folder that holds nothing but its marker (a run that failed before its
    first capture, into a folder it created)."""
    out = Path(out)
    with contextlib.suppress(OSError):  # called while another error propagates: never mask it
        if out.is_dir() and not out.is_symlink() and \
                [p.name for p in out.iterdir()] == [BATCH_FILE]:
            (out / BATCH_FILE).unlink()
            out.rmdir()


def _connect_once(scheduler: str) -> None:
    """Open and close one TCP connection to a ``tcp://`` or ``tls://`` scheduler address:
    an address nothing listens at fails at once (dask's client retries it for its whole
    timeout).  Other transports, and addresses dask parses differently, are left to dask."""
    from distributed.comm import parse_address
    from distributed.comm.addressing import parse_host_port

    try:
        scheme, location = parse_address(scheduler)
        host, port = parse_host_port(location)
    except ValueError:
        return
    if scheme in ("tcp", "tls"):
        socket.create_connection((host, port), timeout=20).close()


#: The local scheduler's HTTP server (health checks; no dashboard) on a free port of this
#: machine only: without an address it takes port 8787, and a second batch running at the same
#: time warned that the port was in use.
_PRIVATE_HTTP = {"dashboard": False, "dashboard_address": "127.0.0.1:0"}


def _client(workers: int, scheduler: str | None, scratch: Path | None = None):
    """A dask client of an existing scheduler or of a new LocalCluster (one thread a worker:
    numba parallelises inside each capture) whose scratch files go to ``scratch`` (dask's
    default is a shared folder of the system's, which it leaves behind)."""
    try:
        import dask
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise InvalidInputError("hyperlf batch needs dask.distributed: pip install "
                                "'hyperlf[batch]'") from None
    import logging

    if scheduler:
        try:
            _connect_once(scheduler)
            return Client(scheduler, timeout="20s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InvalidInputError(f"--scheduler {scheduler}: cannot connect ({exc}); give "
                                    "the address a dask scheduler prints, e.g. "
                                    "tcp://scheduler-host:8786") from None
    # The workers start with Ctrl-C ignored (a terminal sends it to the whole process group):
    # this process closes the cluster on an interrupt, and the workers print no traceback.
    main = threading.current_thread() is threading.main_thread()  # signal() works only there
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    here = {} if scratch is None else {"temporary-directory": os.fspath(scratch)}
    try:  # the scheduler's scratch too (it takes dask's temporary-directory, not the option)
        with dask.config.set(here):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR,
                                   local_directory=None if scratch is None else os.fspath(scratch),
                                   scheduler_kwargs=_PRIVATE_HTTP)
    finally:
        if main:
            signal.signal(signal.SIGINT, previous)
    return Client(cluster), cluster


def run_batch(tasks: Sequence[CaptureTask], *, workers: int = 2, scheduler: str | None = None,
              progress: bool = True) -> list[CaptureResult]:
    """Run every unfinished task on dask and return one :class:`CaptureResult` per task, in
    the order of ``tasks`` (finished ones are measured here, not resubmitted)."""
    if not isinstance(tasks, (list, tuple)) or not all(isinstance(t, CaptureTask)
                                                       for t in tasks):
        raise InvalidInputError(f"tasks must be a list of hyperlf.batch.CaptureTask, got "
                                f"{_opt.shown(tasks)}")
    workers = _opt.integer(workers, "workers", 1, maximum=1024)
    if scheduler is not None and not isinstance(scheduler, str):
        raise InvalidInputError(f"scheduler must be an address (text) or None, got "
                                f"{_opt.shown(scheduler)}")
    progress = _opt.flag(progress, "progress")
    results: dict[int, CaptureResult] = {}
    todo = []
    for i, t in enumerate(tasks):
        done = _done_before(t)
        if done is None:
            todo.append(i)
        else:
            results[i] = done
    if todo:
        home = None if scheduler else Path(tasks[0].output).parent
        with _cluster(workers, scheduler, home) as client:
            results.update(_run_on(client, tasks, todo, progress))
    return [results[i] for i in range(len(tasks))]


@contextlib.contextmanager
def _cluster(workers: int, scheduler: str | None, home: Path | None):
    """A dask client (:func:`_client`), closed with its local cluster at the end; a local
    cluster's scratch folder is made in ``home`` (the batch folder) and removed with it."""
    scratch = None
    if home is not None:  # the local workers' scratch files, inside the batch folder
        _remove_stale_scratch(home)
        scratch = Path(tempfile.mkdtemp(prefix=f"{SCRATCH_PREFIX}{os.getpid()}-", dir=home))
    try:
        client, cluster = _client(workers, scheduler, scratch)
        try:
            yield client
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    finally:
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)


def _run_on(client, tasks: Sequence[CaptureTask], todo: list[int],
            progress: bool) -> dict[int, CaptureResult]:
    """Each task of ``todo`` run on ``client``: its result, or its failure as a result."""
    from dask.distributed import as_completed

    from ._progress import progress_bar

    token = uuid.uuid4().hex[:12]  # keys unique on a shared scheduler
    futures = {client.submit(run_capture, tasks[i], key=f"hyperlf-depth-{token}-{i}",
                             pure=False): i for i in todo}
    results = {}
    for fut in progress_bar(as_completed(futures), "captures", total=len(futures),
                            enabled=progress, unit="capture"):
        i = futures[fut]
        try:
            results[i] = fut.result()
        except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker after retries
            results[i] = CaptureResult(tasks[i].name, tasks[i].capture, "failed",
                                       message=" ".join(str(exc).split())[:300])
    return results


def write_summary(out: str | os.PathLike, rows: Sequence[CaptureResult]) -> list[Path]:
    """``summary.csv`` and ``summary.html`` (a table with each capture's disparity picture)
    in ``out``, replaced together as one result set.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from hyperlf.batch import CaptureResult
    >>> out = pathlib.Path(tempfile.mkdtemp())
    >>> rows = [CaptureResult("frame0", "frames/frame0", "done", 12.5, rmse_px=0.21),
    ...         CaptureResult("frame1", "frames/frame1", "failed", 0.8, exit_code=2,
    ...                       message="no views")]
    >>> [p.name for p in write_summary(out, rows)]
    ['summary.csv', 'summary.html']
    >>> print((out / "summary.csv").read_text().rstrip())
    capture,input,status,seconds,rmse_px,badpix_007_pct,range_limit_pct,exit_code,message
    frame0,frames/frame0,done,12.5,0.21,,,0,
    frame1,frames/frame1,failed,0.8,,,,2,no views
    """
    from .outputs import result_files

    out = Path(_opt.path_like(out, "out", folder=True))
    rows = _rows(rows)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(SUMMARY_COLUMNS)
    for r in rows:
        d = asdict(r)
        w.writerow(["" if d[c] is None else d[c] for c in SUMMARY_COLUMNS])
    targets = [out / "summary.csv", out / "summary.html"]
    with result_files(targets, overwrite=True, command="batch") as (csv_path, html_path):
        csv_path.write_text(buf.getvalue(), encoding="utf-8")
        html_path.write_text(_summary_html(rows), encoding="utf-8")
    return targets


def _summary_html(rows: Sequence[CaptureResult]) -> str:
    def cell(v):
        return "" if v is None else html.escape(str(v))

    head = "".join(f"<th>{c}</th>" for c in SUMMARY_COLUMNS) + "<th>disparity</th>"
    body = []
    for r in rows:
        d = asdict(r)
        pic = "" if r.status == "failed" else (
            f'<a href="{html.escape(r.capture)}/disparity.png"><img src="'
            f'{html.escape(r.capture)}/disparity.png" height="96"></a>')
        cls = ' class="failed"' if r.status == "failed" else ""
        body.append(f"<tr{cls}>" + "".join(f"<td>{cell(d[c])}</td>" for c in SUMMARY_COLUMNS)
                    + f"<td>{pic}</td></tr>")
    n_failed = sum(r.status == "failed" for r in rows)
    return ("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>hyperlf batch</title>"
            "<style>body{font-family:sans-serif}td,th{padding:2px 8px;border-bottom:1px solid "
            "#ddd;text-align:left}tr.failed{background:#fdd}</style></head><body>"
            f"<h1>hyperlf batch: {len(rows)} captures, {n_failed} failed</h1>"
            f"<table><tr>{head}</tr>{''.join(body)}</table></body></html>\n")
