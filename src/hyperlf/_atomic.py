"""Atomic file output: write to a temporary file beside the target, then rename.

An interrupted run therefore never leaves a half-written file that looks complete. The final file
gets the mode a plain ``open(path, "w")`` would give it (``0o666`` less the umask), not the
``0o600`` of the temporary file.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import threading
from pathlib import Path
from typing import Iterator

from ._options import path_like

__all__ = ["atomic_path", "atomic_write_bytes", "atomic_write_text", "current_umask",
           "publish", "temporary_beside"]

#: The longest file name, in bytes, that the common file systems take (ext4, XFS, APFS, NTFS).
NAME_MAX = 255

_UMASK_LOCK = threading.Lock()


def current_umask() -> int:
    """The process's umask, read without changing it for other threads.

    Returns
    -------
    int
        The umask bits (e.g. ``0o022``).

    Notes
    -----
    Linux reports the umask in ``/proc/self/status``; elsewhere it is read with a set-and-restore
    of :func:`os.umask` under a lock, setting the restrictive ``0o077`` meanwhile so that a file
    another thread creates in that instant is never more open than intended.
    """
    with contextlib.suppress(OSError, ValueError):
        with open("/proc/self/status", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    with _UMASK_LOCK:
        old = os.umask(0o077)
        os.umask(old)
    return old


def publish(tmp: str | os.PathLike, target: str | os.PathLike) -> None:
    """Give a finished temporary file the umask's mode and rename it onto ``target``.

    Parameters
    ----------
    tmp : path-like
        The finished temporary file (``tempfile.mkstemp`` makes it ``0o600``), in the target's
        folder.
    target : path-like
        Its final name; an existing file there is replaced atomically.
    """
    os.chmod(tmp, 0o666 & ~current_umask())
    os.replace(tmp, target)


def temporary_beside(target: Path, suffix: str, *, tag: str = "partial") -> tuple[int, str]:
    """``tempfile.mkstemp`` in ``target``'s folder, named ``.<target's name>.<tag>-XXXXXXXX``
    and ``suffix``: an open descriptor and the path.  The target's name is shortened in the
    temporary one where the whole would pass :data:`NAME_MAX` bytes, so that every name a
    command accepts for its output can be written (a 236-byte name failed once the work was
    done).

    Examples
    --------
    >>> import os, tempfile
    >>> from pathlib import Path
    >>> folder = Path(tempfile.mkdtemp())
    >>> fd, tmp = temporary_beside(folder / ("x" * 250 + ".h5"), ".h5")
    >>> os.close(fd); len(os.fsencode(Path(tmp).name)) <= 255, Path(tmp).name[:3]
    (True, '.xx')
    >>> os.unlink(tmp); folder.rmdir()
    """
    room = NAME_MAX - len(os.fsencode(f"..{tag}-{suffix}")) - 8  # mkstemp's 8 characters
    name = target.name
    while len(os.fsencode(name)) > room:  # whole characters, never half of one
        name = name[:-1]
    return tempfile.mkstemp(prefix=f".{name}.{tag}-", suffix=suffix, dir=target.parent)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success.

    On any exception the temporary file is removed and ``path`` is left untouched. The parent
    folder is created when missing. ``suffix`` defaults to the target's suffix, so libraries that
    pick a codec from the extension (OpenCV, tifffile) still work on the temporary name. The
    renamed file's mode is ``0o666`` less the process's umask, as for any newly created file.
    """
    target = Path(path_like(path))  # a bad name is one line, whoever writes
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temporary_beside(target, target.suffix if suffix is None else suffix)
    try:  # from the file's first moment: an interrupt anywhere below removes it
        os.close(fd)
        yield Path(tmp)
        publish(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically and return the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically and return the path."""
    return atomic_write_bytes(path, text.encode(encoding))
