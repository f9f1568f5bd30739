"""Warnings raised while a command runs, held and told in one line each: never between the lines of an error.

numpy's RuntimeWarnings and tifffile's log records (a strange image) would otherwise be printed by Python
as they happen, several lines each with the source line, in the middle of what a command tells.  Held
here, they are printed once each as ``warning: MESSAGE (WHO)`` when the command goes on to its end, and
dropped when the input is refused: a bad input prints only its own lines.  Log records are held only where
Python would have printed them itself (no handler configured: `logging.lastResort`).
"""
from __future__ import annotations

import contextlib
import logging
import warnings
from typing import Iterator


class _Holder(logging.Handler):
    def __init__(self, held: list[str]):
        super().__init__(logging.WARNING)
        self.held = held

    def emit(self, record: logging.LogRecord) -> None:
        self.held.append(f"{record.getMessage()} ({record.name})")


@contextlib.contextmanager
def held_warnings() -> Iterator[list[str]]:
    """The block's warnings and unhandled log records of level WARNING and above, as lines (each once)."""
    held: list[str] = []
    root = logging.getLogger()
    holder = None if root.handlers else _Holder(held)
    if holder is not None:
        root.addHandler(holder)
    try:
        with warnings.catch_warnings(record=True) as caught:  # the filters as they are: ignored stay ignored
            yield held
    finally:
        if holder is not None:
            root.removeHandler(holder)
        held[:0] = [f"{w.message} ({w.category.__name__})" for w in caught]
        held[:] = list(dict.fromkeys(held))
