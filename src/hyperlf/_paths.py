"""Paths that must stay inside a folder: the one test that input readers share."""

from __future__ import annotations

import os


def leads_outside(root: str | os.PathLike, path: str | os.PathLike) -> bool:
    """Whether ``path`` resolves (symlinks and ``..`` followed) outside the folder ``root``,
    or to ``root`` itself.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> leads_outside(root, root / "a.png"), leads_outside(root, root / ".." / "a.png")
    (False, True)
    """
    real, real_root = os.path.realpath(path), os.path.realpath(root)
    return os.path.commonpath([real, real_root]) != real_root or real == real_root


def check_inside(root, files, what: str) -> None:
    """Refuse, before anything is read, a file of ``files`` (those that exist, as links or
    files) that leads outside the folder ``root`` by a symlink; ``what`` names the folder's
    kind in the message (``"HCI scene"``)."""
    from .errors import InvalidInputError

    for f in files:
        if os.path.lexists(f) and leads_outside(root, f):
            raise InvalidInputError(f"{what} {root}: {os.path.basename(f)} leads outside the "
                                    "folder (a symlink); copy the files into the folder")
