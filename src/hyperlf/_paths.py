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
