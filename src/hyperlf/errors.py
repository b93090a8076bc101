"""Exceptions raised by hyperlf.

Every error a user can provoke with bad input is a :class:`HyperLFError` whose message is one
line saying what is wrong and how to fix it. The command-line tool prints that line and exits with
a meaningful code instead of showing a traceback.
"""

from __future__ import annotations

__all__ = ["HyperLFError", "InvalidInputError", "FormatError", "DataNotFoundError", "Terminated"]


class HyperLFError(Exception):
    """Base class of every error hyperlf raises on purpose.

    ``exit_code`` is the process exit status the CLI uses for this kind of error. A message
    that quotes a value whose ``repr`` spans lines (a 2-D array) is joined into one line.

    Examples
    --------
    >>> import numpy as np
    >>> str(HyperLFError(f"bad value {np.zeros((2, 2))!r}"))
    'bad value array([[0., 0.], [0., 0.]])'
    """

    exit_code = 1

    def __init__(self, *args):
        if len(args) == 1 and isinstance(args[0], str) and "\n" in args[0]:
            args = (" ".join(args[0].split()),)
        super().__init__(*args)


class InvalidInputError(HyperLFError, ValueError):
    """Input arrays or parameters are impossible (wrong shape, NaN, bad range, ...)."""

    exit_code = 2


class FormatError(HyperLFError):
    """A file could not be read or has malformed content."""

    exit_code = 3


class DataNotFoundError(HyperLFError, FileNotFoundError):
    """A file, folder or dataset the operation needs does not exist."""

    exit_code = 4


class Terminated(KeyboardInterrupt):
    """The process received SIGTERM or SIGHUP (see :func:`hyperlf.outputs.signals_as_exceptions`).

    A subclass of ``KeyboardInterrupt``, so every clean-up that runs on Ctrl-C runs here too.
    ``exit_code`` is the shell's convention, 128 + the signal number (143 for SIGTERM).
    """

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = int(signum)
        self.exit_code = 128 + self.signum
