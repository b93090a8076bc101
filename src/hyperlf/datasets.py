"""Where the real benchmark data lives, and named access to it.

The data (Middlebury, the HCI 4D light field, spectral tables) is never copied into the
repository or the package. It is found through the environment variable ``HYPERLF_DATA``
(CI sets it to ``../shared/data``), or through an explicit ``root`` argument.

Registry (relative paths under the data root)
---------------------------------------------
``hci4d/antinous``                       HCI 4D light field scene (CC BY-NC-SA 4.0, Honauer 2016)
``middlebury/{tsukuba,teddy,venus}``     Middlebury v2 pairs (Scharstein & Szeliski)
``middlebury/art``                       Middlebury 2005 Art, half size
``spectral/camspec/camspec_database.txt`` 28 camera sensitivities (Jiang et al. 2013)
``spectral/munsell_uef_matt/munsell380_800_final.mat`` 1269 Munsell reflectances (Parkkinen 1989)
``spectral/thorlabs_10nm_bandpass/...csv`` measured band-pass filter transmissions
"""

from __future__ import annotations

import os
from pathlib import Path

from ._options import path_like
from .errors import DataNotFoundError

__all__ = ["ENV_VAR", "DATASETS", "data_root", "dataset_path", "has_data", "expand_user"]


def expand_user(path: str | os.PathLike) -> Path:
    """``path`` with a leading ``~`` or ``~user`` expanded, as a Path.

    Raises
    ------
    DataNotFoundError
        ``~user`` names no user (or the home folder cannot be found).
    InvalidInputError
        ``path`` is not a path (a non-empty str or os.PathLike).

    Examples
    --------
    >>> expand_user("data/x.csv")
    PosixPath('data/x.csv')
    """
    path_like(path, folder=None)
    try:
        return Path(path).expanduser()
    except RuntimeError:
        raise DataNotFoundError(f"cannot find the home folder in {str(path)!r}: no such user; "
                                "give the full path") from None

ENV_VAR = "HYPERLF_DATA"

#: Named datasets -> path relative to the data root.
DATASETS: dict[str, str] = {
    "antinous": "hci4d/antinous",
    "tsukuba": "middlebury/tsukuba",
    "teddy": "middlebury/teddy",
    "venus": "middlebury/venus",
    "art": "middlebury/art",
    "camspec": "spectral/camspec/camspec_database.txt",
    "munsell": "spectral/munsell_uef_matt/munsell380_800_final.mat",
    "thorlabs": "spectral/thorlabs_10nm_bandpass/FBH_10nm_transmission_percent_380-800nm_1nm.csv",
}


def data_root(root: str | os.PathLike | None = None) -> Path:
    """The data root: ``root`` if given, else ``$HYPERLF_DATA``.

    Parameters
    ----------
    root : path-like, optional
        Explicit data folder.

    Returns
    -------
    Path
        The existing folder.

    Raises
    ------
    DataNotFoundError
        When neither is set or the folder does not exist.

    Examples
    --------
    >>> import os, tempfile
    >>> from unittest import mock
    >>> folder = tempfile.mkdtemp()
    >>> data_root(folder) == Path(folder)                   # an explicit root wins
    True
    >>> with mock.patch.dict(os.environ, {ENV_VAR: folder}):    # restored after the block
    ...     print(data_root() == Path(folder))
    True
    >>> with mock.patch.dict(os.environ):
    ...     _ = os.environ.pop(ENV_VAR, None)
    ...     data_root()
    Traceback (most recent call last):
    ...
    hyperlf.errors.DataNotFoundError: the benchmark data location is unknown: set HYPERLF_DATA ...
    """
    if root is not None:
        path_like(root, "root", folder=None)
    value = root if root is not None else os.environ.get(ENV_VAR)
    if not value:
        raise DataNotFoundError(
            f"the benchmark data location is unknown: set {ENV_VAR} to the folder holding "
            "hci4d/, middlebury/ and spectral/ (e.g. export HYPERLF_DATA=../shared/data)"
        )
    path = expand_user(value)
    if not path.is_dir():
        raise DataNotFoundError(f"{ENV_VAR} points to {path}, which is not a folder")
    return path


def dataset_path(name: str, root: str | os.PathLike | None = None) -> Path:
    """Path of a named dataset (see :data:`DATASETS`) or of a relative path under the root.

    Parameters
    ----------
    name : str
        A key of :data:`DATASETS` (``"tsukuba"``, ``"antinous"``, ``"munsell"``, ...) or a
        path relative to the data root.
    root : path-like, optional
        Data root (default ``$HYPERLF_DATA``).

    Returns
    -------
    Path
        The existing file or folder.

    Raises
    ------
    DataNotFoundError
        When the root is unknown or the dataset is missing.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp()); (root / "hci4d" / "antinous").mkdir(parents=True)
    >>> dataset_path("antinous", root=root).name
    'antinous'
    """
    path_like(name, "name", folder=None)
    rel = DATASETS.get(name, name)
    path = data_root(root) / rel
    if not path.exists():
        known = ", ".join(sorted(DATASETS))
        raise DataNotFoundError(
            f"dataset {name!r} not found at {path}; known names: {known}"
        )
    return path


def has_data(name: str | None = None) -> bool:
    """True when the data root (and the named dataset, if given) is available.

    Parameters
    ----------
    name : str, optional
        A dataset name (see :func:`dataset_path`).

    Returns
    -------
    bool

    Raises
    ------
    InvalidInputError
        ``name`` is neither None nor a dataset name or path.

    Examples
    --------
    >>> import os, tempfile
    >>> from unittest import mock
    >>> root = Path(tempfile.mkdtemp())
    >>> with mock.patch.dict(os.environ, {ENV_VAR: str(root)}):     # restored after the block
    ...     before = has_data(), has_data("tsukuba")
    ...     (root / "middlebury" / "tsukuba").mkdir(parents=True)
    ...     after = has_data("tsukuba")
    >>> before, after
    ((True, False), True)
    >>> with mock.patch.dict(os.environ):
    ...     _ = os.environ.pop(ENV_VAR, None)
    ...     print(has_data())                               # no data root at all
    False
    """
    if name is not None:
        path_like(name, "name", folder=None)
    try:
        if name is None:
            data_root()
        else:
            dataset_path(name)
    except DataNotFoundError:
        return False
    return True
