"""The ``hyperlf`` command (and ``python -m hyperlf``).

SIGINT, SIGTERM and SIGHUP become clean exits (130, 143, 129, one line, no traceback) before the
heavy imports start, so that even an interrupt during start-up gets the documented exit status.
The command itself is :func:`hyperlf.cli.main`.
"""

from __future__ import annotations

import sys


def main() -> int:
    """Run the ``hyperlf`` command line; return its exit status."""
    from .outputs import signals_as_exceptions

    try:
        with signals_as_exceptions():
            from .cli import main as cli_main

            return cli_main()
    except KeyboardInterrupt as exc:  # before the command started (cli.main handles the rest)
        what = "terminated" if hasattr(exc, "signum") else "interrupted"
        print(f"hyperlf: {what} while starting; nothing was written", file=sys.stderr)
        return getattr(exc, "exit_code", 130)
    finally:  # the work is done (or refused): a late signal must not change the exit status
        _ignore_signals()


def _ignore_signals() -> None:
    import signal

    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
