"""`-q`/`-v`: how much the command line says on stderr, one setting for every command.

The library logs to the ``biostudy`` logger (`logging`; a `NullHandler` in
`biostudy/__init__.py`, so from Python nothing is printed unless the caller
configures logging).  The command line puts one handler on it, writing to
stderr as it is when a record comes (a test that replaces stderr gets it):
by default warnings only, ``-v`` adds the library's detail (DEBUG: a scene's
size, where a run's time went), ``-q`` also silences the progress bar and
lines.  Given before the command (``biostudy -q run``) or after it
(``biostudy run -q``), they mean the same.
"""
from __future__ import annotations

import logging
import sys

LOGGER = "biostudy"
_state = {"level": logging.WARNING, "quiet": False}


class _Stderr(logging.Handler):
    """Records as lines on this process's stderr: detail plain, warnings and errors prefixed as the CLI's own."""

    def emit(self, record: logging.LogRecord) -> None:
        prefix = f"{record.levelname.lower()}: " if record.levelno >= logging.WARNING else ""
        print(prefix + record.getMessage(), file=sys.stderr, flush=True)


def start(quiet_: bool, verbose_: bool) -> None:
    """Where a command line starts: the default, then the global -q/-v, and the handler on the logger."""
    stop()
    quiet(quiet_)
    verbose(verbose_)
    logging.getLogger(LOGGER).addHandler(_Stderr())


def stop() -> None:
    """Where a command line ends: the logger as the library leaves it (an in-process caller, a test, runs
    several command lines and calls the library between them)."""
    _state.update(level=logging.WARNING, quiet=False)
    logger = logging.getLogger(LOGGER)
    for handler in [h for h in logger.handlers if isinstance(h, _Stderr)]:
        logger.removeHandler(handler)
    logger.setLevel(logging.NOTSET)


def quiet(value: bool) -> bool:
    """The callback of -q: no progress bar or lines (warnings and errors still)."""
    if value:
        _state["quiet"] = True
    return value


def verbose(value: bool) -> bool:
    """The callback of -v: the library's detail (DEBUG) too."""
    if value:
        _state["level"] = logging.DEBUG
    logging.getLogger(LOGGER).setLevel(_state["level"])
    return value


def is_quiet() -> bool:
    return bool(_state["quiet"])
