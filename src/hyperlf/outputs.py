"""Whole result sets: a command's outputs appear all together or not at all.

Every command of the command-line tool writes its outputs through :func:`result_folder` or
:func:`result_files`. The
files are written into a hidden staging folder beside the target (``.hyperlf-<token>.new``)
and moved into place only when the command has finished, so the target holds either the
previous complete result set or the new complete one, also when the run is interrupted, killed
or fails half-way. A folder output gets a manifest, :data:`MANIFEST`, listing the files of its
set; ``overwrite=True`` replaces a folder only when everything in it belongs to the set its
manifest lists, so a command never deletes or replaces a file it did not write, and never follows
a symlink inside the folder.

How a set is moved into place:

* a new name or an empty folder: one ``rename`` (atomic);
* a folder holding a previous result set: an atomic exchange of the two folders
  (``renameat2(RENAME_EXCHANGE)`` on Linux), then the old set is removed; where the exchange is
  not available the old folder is first renamed aside (a kill between the two renames is
  repaired by the next run, which puts the old folder back);
* single files (and their sidecars): one ``os.replace`` each;
* a target folder that is a mount point, the working folder, or whose parent folder is not
  writable: the staging folder lives inside the target and the files are moved one by one.

While a set is moved, SIGINT, SIGTERM and SIGHUP are held back (:func:`deferred_signals`) and
delivered afterwards. Only SIGKILL can interrupt the moves, and only in the last two cases.
Staging folders left by a killed run are found by their lock files (``.hyperlf-<token>.lock``,
held with ``flock`` while the run lives) and removed by the next run that writes beside them.
"""

from __future__ import annotations

import _thread
import contextlib
import ctypes
import errno
import json
import os
import secrets
import signal
import sys
import threading
from pathlib import Path
from typing import Iterable, Iterator, Sequence

from .errors import DataNotFoundError, InvalidInputError, Terminated

# hyperlf._options (and so numpy) is imported inside the functions that check their arguments:
# ``python -m hyperlf`` imports this module before its signal handlers are in place.

__all__ = [
    "MANIFEST",
    "result_folder",
    "result_files",
    "manifest_files",
    "read_manifest",
    "foreign_entries",
    "check_replaceable",
    "clean_stale",
    "deferred_signals",
    "signals_as_exceptions",
    "raise_if_interrupted",
    "received_interrupt",
]

MANIFEST = ".hyperlf-result.json"
"""Name of the manifest a folder output carries: the files of its result set."""

_PREFIX = ".hyperlf-"
_HELD_SIGNALS = tuple(s for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM",
                                                                     "SIGHUP")) if s)
#: The signal that wakes the main thread to look again at a deferred interrupt (below): real,
#: so that it ends a sleep or a wait, and ignored by default, so that a late one is harmless.
_WAKE = getattr(signal, "SIGURG", None)


# ----------------------------------------------------------------------------- signals
@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """Hold back SIGINT, SIGTERM and SIGHUP (and the wake-up of a deferred interrupt, see
    :func:`signals_as_exceptions`) in the block; deliver them when it ends.

    Used around the few system calls that move a finished result set into place, so that an
    interrupt can never leave it half moved. The signals are recorded by a Python handler (which
    always runs in the main thread, whichever thread the kernel picked) and raised again, under
    the previous handlers, when the block ends. Outside the main thread the block runs
    unprotected.

    Examples
    --------
    A SIGTERM that arrives while the results are moved waits for the move to end:

    >>> import signal
    >>> from hyperlf.errors import Terminated
    >>> events = []
    >>> try:
    ...     with signals_as_exceptions():
    ...         with deferred_signals():
    ...             signal.raise_signal(signal.SIGTERM)
    ...             events.append("moved")
    ... except Terminated:
    ...     events.append("stopped")
    >>> events
    ['moved', 'stopped']
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous = {}
    for sig in (*_HELD_SIGNALS, _WAKE):  # the wake-up of a deferred interrupt waits too
        if sig is not None and signal.getsignal(sig) not in (signal.SIG_IGN, None):
            previous[sig] = signal.signal(sig, lambda signum, frame: pending.append(signum))
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if pending:
            signal.raise_signal(next((s for s in pending if s != _WAKE), pending[0]))


#: Signals received inside :func:`signals_as_exceptions`, kept because the exception a handler
#: raises is lost when Python happens to run the handler inside a ``__del__`` or a weakref
#: callback ("Exception ignored in ..."): :func:`raise_if_interrupted` raises it again.
_RECEIVED: list[int] = []

#: Top-level packages inside whose code an interrupt is never raised: numba's compiler and
#: llvmlite hold LLVM objects whose destructors crash the interpreter (SIGSEGV) when their making
#: was cut short, and an import cut short leaves a module (a compiled extension too) half made,
#: which aborts the interpreter when it exits. Seen in CI, reproduced by :mod:`tests`.
FRAGILE_PACKAGES = frozenset({"numba", "llvmlite", "importlib"})

#: Seconds between two looks at whether the main thread has left the fragile code.
_RETRY_S = 0.05
#: Re-entrant: the handler may run again in the main thread while :func:`_defer` holds it
#: (a second signal while the timer thread starts); a plain lock deadlocked there, the process
#: hanging with its staging folder (seen in CI: a batch's depth process under SIGTERM).
_retry_lock = threading.RLock()
_deferred: dict[str, object] = {"signum": None, "timer": None, "wake": False}


def _in_fragile_code(frame) -> bool:
    """Whether ``frame`` or any frame that called it runs code of :data:`FRAGILE_PACKAGES`."""
    while frame is not None:
        if str(frame.f_globals.get("__name__") or "").partition(".")[0] in FRAGILE_PACKAGES:
            return True
        frame = frame.f_back
    return False


def _interrupt(signum: int) -> KeyboardInterrupt:
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)


def _retry() -> None:
    """Run in a timer thread: make the main thread run its handler again."""
    with _retry_lock:
        if _deferred["signum"] is None:
            return
        if _deferred["wake"]:
            signal.pthread_kill(threading.main_thread().ident, _WAKE)
        else:  # no wake signal of ours: simulated, so a sleep in C ends only when it ends
            _thread.interrupt_main(_deferred["signum"])


def _defer(signum: int) -> None:
    with _retry_lock:
        _deferred["signum"] = signum
        timer = _deferred["timer"] = threading.Timer(_RETRY_S, _retry)
        timer.daemon = True
        timer.start()


def _forget_deferred() -> None:
    with _retry_lock:
        if _deferred["timer"] is not None:
            _deferred["timer"].cancel()
        _deferred.update(signum=None, timer=None)


def _raise_interrupt(signum, frame):
    """The handler: raise the interrupt now, or as soon as the main thread has left code of
    :data:`FRAGILE_PACKAGES` (looked at every :data:`_RETRY_S` seconds)."""
    if signum == _WAKE:
        if _deferred["signum"] is None or not _RECEIVED:  # late, or somebody else's SIGURG
            return
    elif signum not in _RECEIVED:
        _RECEIVED.append(signum)
    if _in_fragile_code(frame):
        _defer(_RECEIVED[0])
        return
    _forget_deferred()
    raise _interrupt(_RECEIVED[0])  # the first signal names the interrupt


def raise_if_interrupted() -> None:
    """Raise the interrupt of a signal whose exception was swallowed (see :data:`_RECEIVED`)
    or is still deferred.

    Called before a result set is moved into place, so that a run whose interrupt was lost
    never publishes its results as if nothing had happened.

    Examples
    --------
    Nothing to raise when no signal came:

    >>> raise_if_interrupted() is None
    True
    """
    if _RECEIVED:
        _forget_deferred()
        raise _interrupt(_RECEIVED[0])


def received_interrupt() -> KeyboardInterrupt | None:
    """The interrupt of the first signal received in the current :func:`signals_as_exceptions`
    block (None if none came), for code that must tell an exception a signal turned into (C
    code that called back into Python when the handler raised, e.g. matplotlib's resampler:
    "ValueError: Invalid affine transformation matrix") from a genuine failure.

    Examples
    --------
    >>> received_interrupt() is None
    True
    """
    return _interrupt(_RECEIVED[0]) if _RECEIVED else None


def _quiet_unraisable(previous):
    """An ``unraisablehook`` that keeps interrupts lost in callbacks silent (they are raised
    again by :func:`raise_if_interrupted`) and passes everything else on."""
    def hook(args):
        if not isinstance(args.exc_value, KeyboardInterrupt):
            previous(args)
    return hook


@contextlib.contextmanager
def signals_as_exceptions() -> Iterator[None]:
    """Turn SIGINT into ``KeyboardInterrupt`` and SIGTERM / SIGHUP into
    :class:`~hyperlf.errors.Terminated` for the block, so that clean-up code runs alike.

    A signal the process ignores (``nohup``, a background job) stays ignored. The interrupt is
    never raised inside the code of :data:`FRAGILE_PACKAGES` (numba's compiler, llvmlite,
    imports): it waits until the main thread has left it, at most a compilation or an import
    later. An interrupt that Python loses (raised inside a ``__del__`` or weakref callback) is
    remembered and raised again by :func:`raise_if_interrupted`. The previous handlers are
    restored at the end. Outside the main thread this does nothing.

    Examples
    --------
    >>> import signal
    >>> from hyperlf.errors import Terminated
    >>> try:
    ...     with signals_as_exceptions():
    ...         signal.raise_signal(signal.SIGTERM)
    ... except Terminated as exc:
    ...     print("clean-up ran; exit status", exc.exit_code)
    clean-up ran; exit status 143
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    for sig in _HELD_SIGNALS:
        if signal.getsignal(sig) not in (signal.SIG_IGN, None):
            previous[sig] = signal.signal(sig, _raise_interrupt)
    if _WAKE is not None and signal.getsignal(_WAKE) in (signal.SIG_DFL, _raise_interrupt):
        previous[_WAKE] = signal.signal(_WAKE, _raise_interrupt)
    wake, _deferred["wake"] = _deferred["wake"], _WAKE in previous
    hook, received = sys.unraisablehook, list(_RECEIVED)  # nested: the outer block's signals
    sys.unraisablehook = _quiet_unraisable(hook)
    try:
        yield
        late = _deferred["signum"]  # came in fragile code just before the block ended
    finally:
        _forget_deferred()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        sys.unraisablehook, _RECEIVED[:], _deferred["wake"] = hook, received, wake
    if late is not None:
        raise _interrupt(late)


# ----------------------------------------------------------------------------- manifests
def _walk_files(folder: Path) -> list[str]:
    """Relative POSIX paths of the regular files under ``folder`` (symlinks not followed)."""
    out = []
    for root, dirs, files in os.walk(folder, followlinks=False):
        rel = Path(root).relative_to(folder)
        out += [(rel / f).as_posix() for f in files
                if not (Path(root) / f).is_symlink() and (Path(root) / f).is_file()]
        dirs[:] = [d for d in dirs if not (Path(root) / d).is_symlink()]
    return sorted(f for f in out if f != MANIFEST)


def _write_manifest(folder: Path, command: str | None, argv=None, provenance=None) -> None:
    from . import __version__
    from ._atomic import atomic_write_text

    doc = {"written_by": f"hyperlf {__version__}", "command": command,
           "files": _walk_files(folder)}
    if argv is not None:  # provenance: the command line that made it
        doc["argv"] = [str(a) for a in argv]
    for key, value in (provenance or {}).items():  # e.g. the input's signature
        doc.setdefault(key, value)
    atomic_write_text(folder / MANIFEST, json.dumps(doc, indent=1) + "\n")


def read_manifest(folder: str | os.PathLike) -> dict | None:
    """The manifest of the result set in ``folder``: ``written_by`` (str), ``command`` (str or
    None), ``files`` (relative POSIX paths), ``argv`` (list of str or None) and ``input`` (dict
    or None: what the result was made from); None when :data:`MANIFEST` is missing, a
    symlink, unreadable or malformed.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "result"
    >>> with result_folder(out, command="depth") as stage:
    ...     _ = (stage / "a.txt").write_text("1")
    >>> m = read_manifest(out)
    >>> m["command"], m["files"]
    ('depth', ['a.txt'])
    """
    from ._options import path_like

    man = Path(path_like(folder, "folder", folder=None)) / MANIFEST
    if man.is_symlink() or not man.is_file():
        return None
    try:
        doc = json.loads(man.read_text(encoding="utf-8"))
        files = doc["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
        return None
    command, by, argv = doc.get("command"), doc.get("written_by"), doc.get("argv")
    source = doc.get("input")
    return {"written_by": by if isinstance(by, str) else "hyperlf",
            "command": command if isinstance(command, str) else None, "files": files,
            "argv": argv if isinstance(argv, list) and all(isinstance(a, str) for a in argv)
            else None,
            "input": source if isinstance(source, dict) else None}


def manifest_files(folder: str | os.PathLike) -> set[str] | None:
    """The files of the result set a folder's manifest lists, or None (no valid manifest).

    Parameters
    ----------
    folder : path-like
        A folder written by a hyperlf command.

    Returns
    -------
    set of str or None
        Relative POSIX paths; None when :data:`MANIFEST` is missing, a symlink or unreadable.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "result"
    >>> with result_folder(out) as stage:
    ...     _ = (stage / "a.txt").write_text("1")
    >>> manifest_files(out)
    {'a.txt'}
    """
    doc = read_manifest(folder)
    return None if doc is None else set(doc["files"])


def foreign_entries(folder: str | os.PathLike) -> list[str]:
    """Entries of ``folder`` that do not belong to the result set its manifest lists.

    An entry belongs when it is a regular file the manifest lists (or the manifest itself), or a
    real folder (not a symlink) holding such files and nothing else. Without a manifest every
    entry is foreign.

    Returns
    -------
    list of str
        Relative POSIX paths, sorted; empty when the folder holds only its result set.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "notes.txt").write_text("mine")
    >>> foreign_entries(d)
    ['notes.txt']
    """
    from ._options import path_like

    root = Path(path_like(folder, "folder", folder=None))
    if not root.is_dir():
        raise DataNotFoundError(f"{root}: no such folder")
    files = manifest_files(root) or set()
    return sorted(f for f in _foreign_in(root, root, files | {MANIFEST}) if not _is_temporary(f))


def _is_temporary(name: str) -> bool:
    """A staging folder, set-aside folder or lock of a hyperlf run (see :func:`clean_stale`)."""
    return name.startswith(_PREFIX) and name.endswith((".new", ".old", ".lock"))


def _foreign_in(root: Path, folder: Path, files: set[str]) -> list[str]:
    out = []
    for entry in os.scandir(folder):
        rel = Path(entry.path).relative_to(root).as_posix()
        if entry.is_symlink():
            out.append(rel)
        elif entry.is_dir():
            inner = _foreign_in(root, Path(entry.path), files)
            owned = any(f.startswith(rel + "/") for f in files)
            out += inner if owned else [rel]
        elif not (entry.is_file() and rel in files):
            out.append(rel)
    return out


def check_replaceable(target: str | os.PathLike, *, overwrite: bool) -> None:
    """Refuse (:class:`~hyperlf.errors.InvalidInputError`) to replace what a command may not.

    A missing target or an empty folder may always be written. A file may be replaced with
    ``overwrite``. A folder may be replaced with ``overwrite`` only when it holds nothing but a
    previous result set (see :func:`foreign_entries`). A symlink is never replaced.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from hyperlf.errors import InvalidInputError
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "map.pfm"
    >>> _ = f.write_bytes(b"old")
    >>> try:
    ...     check_replaceable(f, overwrite=False)
    ... except InvalidInputError as exc:
    ...     print(str(exc).split("; ")[1])
    choose another name or pass --overwrite
    >>> check_replaceable(f, overwrite=True) is None
    True
    """
    from ._options import flag, path_like

    p = Path(path_like(target, "target", folder=None))
    flag(overwrite, "overwrite")
    if p.is_symlink():
        raise InvalidInputError(f"{p} is a symlink; hyperlf does not write through or replace "
                                "symlinks: give the real path or another name")
    if not p.exists():
        return
    if p.is_dir() and all(_is_temporary(e.name) for e in p.iterdir()):
        return  # empty but for hyperlf runs' temporaries
    if not overwrite:
        raise InvalidInputError(f"{p} exists; choose another name or pass --overwrite")
    if p.is_dir():
        foreign = foreign_entries(p)
        if foreign:
            shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more"
                                              if len(foreign) > 3 else "")
            raise InvalidInputError(
                f"{p} holds files hyperlf did not write ({shown}); --overwrite replaces only a "
                f"result set hyperlf wrote (listed in its {MANIFEST}): move them away or choose "
                "another folder")


# ----------------------------------------------------------------------------- stale runs
def _try_lock(path: Path, *, create: bool):
    """Open and ``flock`` ``path`` without waiting: the open file, or None when another live
    process holds it (or locking is unsupported and the file is not ours)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return open(path, "a") if create else None
    flags = os.O_RDWR | (os.O_CREAT | os.O_EXCL if create else 0) | getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags, 0o600)
    except OSError:
        return None
    f = os.fdopen(fd, "r+")
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        f.close()
        return None
    return f


def clean_stale(folder: str | os.PathLike) -> list[Path]:
    """Remove what killed hyperlf runs left in ``folder``; return what was removed or restored.

    A run's temporaries are ``.hyperlf-<token>.new`` (its staging folder) and
    ``.hyperlf-<token>.old`` (a previous result set being replaced), next to the lock file
    ``.hyperlf-<token>.lock`` that the run holds while it lives. A lock nobody holds marks a dead
    run: an ``.old`` entry whose target is missing is put back (the run died between the two
    renames of a replacement), everything else of that run is removed. Live runs are left alone.

    Examples
    --------
    A run killed while it wrote left its staging folder and an unheld lock:

    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> (d / ".hyperlf-abc.new").mkdir(); (d / ".hyperlf-abc.lock").touch()
    >>> [p.name for p in clean_stale(d)], list(d.iterdir())
    (['.hyperlf-abc.new'], [])
    """
    from ._options import path_like

    root = Path(path_like(folder, "folder", folder=None))
    done: list[Path] = []
    with contextlib.suppress(OSError):
        locks = [p for p in root.iterdir() if p.name.startswith(_PREFIX)
                 and p.name.endswith(".lock") and not p.is_symlink()]
        for lock in locks:
            held = _try_lock(lock, create=False)
            if held is None:
                continue
            with held:
                done += _recover_run(root, lock.name[: -len(".lock")])
                lock.unlink()
    return done


def _recover_run(root: Path, stem: str) -> list[Path]:
    done = []
    old = root / f"{stem}.old"
    if old.is_dir() and not old.is_symlink():
        for entry in list(old.iterdir()):
            if not os.path.lexists(root / entry.name):
                os.rename(entry, root / entry.name)
                done.append(root / entry.name)
    for tmp in (root / f"{stem}.new", old):
        if os.path.lexists(tmp):
            _remove_tree(tmp)
            done.append(tmp)
    return done


def _remove_tree(path: Path) -> None:
    """Remove a tree this module made: links are unlinked, never followed."""
    if path.is_symlink() or not path.is_dir():
        path.unlink(missing_ok=True)
        return
    for entry in list(os.scandir(path)):
        _remove_tree(Path(entry.path))
    path.rmdir()


# ----------------------------------------------------------------------------- moving sets
_RENAME_EXCHANGE = 2


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2``); False where that is not available."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd = -100
    rc = renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _copy_folder_mode(src: Path, dst: Path) -> None:
    with contextlib.suppress(OSError):
        os.chmod(dst, src.stat().st_mode & 0o7777)


def _replace_folder(staged: Path, target: Path, aside: Path) -> None:
    """Put the finished folder ``staged`` at ``target`` (missing, empty or a result set)."""
    if not os.path.lexists(target):
        os.rename(staged, target)
        return
    _copy_folder_mode(target, staged)
    if not any(target.iterdir()):
        os.rename(staged, target)  # rename replaces an empty folder
    elif _exchange(staged, target):
        _remove_tree(staged)  # now the old set
    else:
        aside.mkdir(exist_ok=True)
        os.rename(target, aside / target.name)
        os.rename(staged, target)
        _remove_tree(aside / target.name)


def _merge_into(staged: Path, target: Path) -> None:
    """In-place commit: drop the old set's files, move the new ones in one by one."""
    old = manifest_files(target) or set()
    new = set(_walk_files(staged)) | {MANIFEST}
    for rel in sorted(old - new):
        f = target / rel
        if f.is_file() and not f.is_symlink():
            f.unlink()
    for rel in sorted(new):
        dest = target / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        os.replace(staged / rel, dest)
    _remove_tree(staged)


# ----------------------------------------------------------------------------- the set
class _ResultSet:
    """The staging area of one command's outputs and the moves that publish it."""

    def __init__(self, targets: Sequence[Path], *, overwrite: bool, command: str | None,
                 inplace: bool = True, argv=None, provenance=None):
        self.targets = [Path(os.path.abspath(t)) for t in targets]
        self.overwrite, self.command, self.argv = overwrite, command, argv
        self.provenance = provenance
        self.parent = self.targets[0].parent
        if any(t.parent != self.parent for t in self.targets):
            raise InvalidInputError("the outputs of one result set must share one folder")
        if len({t.name for t in self.targets}) != len(self.targets):
            raise InvalidInputError("the outputs of one result set must have distinct names")
        self.inplace = inplace and self._needs_inplace(self.targets[0])
        self.home = self.targets[0] if self.inplace else self.parent
        self.created: list[Path] = []
        self.lock = self.stem = None

    @staticmethod
    def _needs_inplace(target: Path) -> bool:
        """Whether the set must be staged inside ``target`` rather than beside it: a mount
        point, a folder whose parent is not writable, or the working folder (or one holding
        it), which a rename would leave the process (and the user's shell) outside of."""
        if not target.is_dir() or target.is_symlink():
            return False
        cwd = Path(os.path.abspath(os.getcwd()))
        return (os.path.ismount(target) or not os.access(target.parent, os.W_OK | os.X_OK)
                or target == cwd or target in cwd.parents)

    def check(self) -> None:
        for t in self.targets:
            check_replaceable(t, overwrite=self.overwrite)

    def open(self) -> Path:
        """Create the staging folder (and missing parents); return it.

        The lock and the staging folder come to be with signals held back, so that an interrupt
        finds either neither or both recorded here, and :meth:`abort` removes what there is."""
        self.check()
        self.created = [p for p in (self.home, *self.home.parents) if not p.exists()]
        self.home.mkdir(parents=True, exist_ok=True)  # self.created: deepest first, for rmdir
        clean_stale(self.home)
        with deferred_signals():
            self._lock_and_stage()
        return self.stage

    def _lock_and_stage(self) -> None:
        for _ in range(100):
            stem = f"{_PREFIX}{os.getpid()}-{secrets.token_hex(4)}"
            self.lock = _try_lock(self.home / f"{stem}.lock", create=True)
            if self.lock is not None:
                break
        else:  # pragma: no cover - 100 collisions
            raise InvalidInputError(f"cannot create a staging folder in {self.home}")
        self.stem = stem
        self.stage = self.home / f"{self.stem}.new"
        self.stage.mkdir()

    def commit(self) -> None:
        """Move the staged outputs into place (signals held back meanwhile)."""
        raise_if_interrupted()
        with deferred_signals():
            self.check()
            if self.inplace:
                _write_manifest(self.stage, self.command, self.argv, self.provenance)
                _merge_into(self.stage, self.targets[0])
            else:
                for t in self.targets:
                    self._commit_one(self.stage / t.name, t)
            self.close()

    def _commit_one(self, staged: Path, target: Path) -> None:
        if not os.path.lexists(staged):
            return
        if staged.is_dir():
            _write_manifest(staged, self.command, self.argv, self.provenance)
            _replace_folder(staged, target, self.home / f"{self.stem}.old")
        else:
            os.replace(staged, target)

    def abort(self) -> None:
        """Remove the staging folder and the folders this run created, leave the rest."""
        with deferred_signals():
            self.close()
            for p in self.created:
                with contextlib.suppress(OSError):
                    p.rmdir()

    def close(self) -> None:
        """Remove this run's temporaries; a previous set still set aside (a move that failed
        half-way) is put back first."""
        if self.stem is None:  # interrupted before it had any
            return
        _recover_run(self.home, self.stem)
        if self.lock is not None:
            (self.home / f"{self.stem}.lock").unlink(missing_ok=True)
            self.lock.close()
            self.lock = None


def _as_targets(targets, label: str) -> list[Path]:
    """The targets of a result set: one path, or an iterable of at least one."""
    from ._options import path_list

    return [Path(t) for t in path_list(targets, label, single=True)]


def _check_record(overwrite, command, argv, provenance=None) -> None:
    """The options of a result set that its manifest records, checked before any work."""
    from ._options import flag, mapping, shown, text

    flag(overwrite, "overwrite")
    text(command, "command", optional=True)
    if argv is not None and not isinstance(argv, (list, tuple)):
        raise InvalidInputError(f"argv must be a list of str (the command line) or None, got "
                                f"{shown(argv)}")
    mapping(provenance, "provenance")


@contextlib.contextmanager
def _staged(rs: _ResultSet) -> Iterator[Path]:
    try:
        stage = rs.open()  # an interrupt delivered as it ends is cleaned up too
        yield stage
        rs.commit()
    except BaseException:
        rs.abort()
        raise


@contextlib.contextmanager
def result_folder(folder: str | os.PathLike, *, overwrite: bool = False,
                  command: str | None = None, argv=None,
                  provenance: dict | None = None) -> Iterator[Path]:
    """Write a command's output folder as one whole result set.

    Yields the folder to write into (a staging folder). When the block ends normally its
    content is moved into place at ``folder`` with a :data:`MANIFEST` listing the files; when it
    raises (an error, Ctrl-C, :class:`~hyperlf.errors.Terminated`) nothing is moved and the
    staging folder is removed. ``folder`` is checked with :func:`check_replaceable` before the
    block and again just before the move.

    Parameters
    ----------
    folder : path-like
        The output folder: missing, empty, or (with ``overwrite``) a previous result set.
    overwrite : bool
        Replace a previous result set.
    command : str, optional
        Recorded in the manifest.
    argv : sequence of str, optional
        The command line, recorded in the manifest (``hyperlf info`` shows it).
    provenance : dict, optional
        Further manifest entries (JSON values), e.g. ``"input"``: what the result was made
        from (:func:`read_manifest` returns it). Read when the set is published, so the block
        may fill it in.

    Yields
    ------
    Path
        Where to write the outputs. Usually a hidden sibling of ``folder``; when ``folder`` is a
        mount point or its parent is not writable, a hidden folder inside it (its files are then
        moved one by one at the end).

    Raises
    ------
    InvalidInputError
        ``folder`` exists and may not be replaced.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "result"
    >>> with result_folder(out) as stage:
    ...     _ = (stage / "a.txt").write_text("1")
    ...     out.exists()
    False
    >>> sorted(p.name for p in out.iterdir())
    ['.hyperlf-result.json', 'a.txt']
    """
    _check_record(overwrite, command, argv, provenance)
    rs = _ResultSet(_as_targets(folder, "folder"), overwrite=overwrite, command=command,
                    argv=argv, provenance=provenance)
    with _staged(rs) as stage:
        if rs.inplace:
            yield stage
        else:
            inner = stage / rs.targets[0].name
            inner.mkdir()
            yield inner


@contextlib.contextmanager
def result_files(paths: Iterable[str | os.PathLike], *, overwrite: bool = False,
                 command: str | None = None, argv=None) -> Iterator[list[Path]]:
    """Write single files (and sidecars, or a folder beside a file) as one result set.

    Yields one staging path per entry of ``paths``, in order; write each entry there (a file,
    or a folder with files). When the block ends normally every entry that was written is moved
    onto its target; when it raises nothing is moved. Entries must share one folder.

    Parameters
    ----------
    paths : iterable of path-like
        The outputs.
    overwrite : bool
        Replace existing files (a folder only when it holds a previous result set).
    command : str, optional
        Recorded in the manifest of folder entries.

    Yields
    ------
    list of Path
        Where to write each output.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with result_files([d / "s.png", d / "s.csv"]) as (png, csv):
    ...     _ = png.write_bytes(b"x")
    ...     _ = csv.write_text("wavelength_nm,value")
    >>> sorted(p.name for p in d.iterdir())
    ['s.csv', 's.png']
    """
    _check_record(overwrite, command, argv)
    rs = _ResultSet(_as_targets(paths, "paths"), overwrite=overwrite, command=command,
                    inplace=False, argv=argv)
    with _staged(rs) as stage:
        yield [stage / t.name for t in rs.targets]
