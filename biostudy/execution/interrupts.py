"""Interruptions (Ctrl-C, SIGTERM) that end a command wherever they land, and never cost a finished simulation.

Python runs a signal's handler in the main thread between two bytecodes, and the KeyboardInterrupt it raises
unwinds whatever runs there, with three exceptions this module closes:

- **Finalisers.** Raised inside a `__del__` (FiPy's `Solver.__del__`, run whenever a solver object is freed), a
  weakref callback or another place Python cannot propagate an exception from, it is printed as "Exception
  ignored in ..." and lost: the command went on, to its end with exit 0, or for 20 s more (3 of 59 interrupts
  of `calibrate`, issue 39).  `obeyed` replaces `sys.unraisablehook` for the command: an interruption lost so is
  delivered again a millisecond later (`_thread.interrupt_main`, from a thread of its own), and raised at the
  next bytecode outside the finaliser.
- **Anything else that swallows it** (a library's `except BaseException`): `obeyed` remembers the last signal
  received, and `Obeyed.lost` tells a command that returned although one was received and never reached it.
- **A finished simulation.** An interruption between a simulation's end and its case file being written threw
  the simulation away.  A job loop runs `deferred` (`backends.windowed`): interruptions received in the block
  are held and acted on when it ends, except inside `allowed` blocks, where a backend waits for its
  simulations (or runs one, here): what has finished is recorded first, then the command ends.

Signal handlers exist in the main thread only: elsewhere (a notebook's worker thread calling the API) the
blocks change nothing.
"""
from __future__ import annotations

import _thread
import contextlib
import signal
import sys
import threading
import time
from typing import Iterator

SIGNALS = (signal.SIGINT, signal.SIGTERM)
AGAIN_AFTER = 0.001  # seconds: an interruption lost in a finaliser is delivered again this soon


class Terminated(KeyboardInterrupt):
    """SIGTERM, unwinding as Ctrl-C does (temporary files are removed on the way out), told apart by its exit
    status: 143 (128 + 15), where Ctrl-C's is 130 (128 + 2)."""


def status(error: BaseException | None) -> int:
    """The exit status of an interruption: 143 for SIGTERM (`Terminated`), 130 for Ctrl-C."""
    return 128 + (signal.SIGTERM if isinstance(error, Terminated) else signal.SIGINT)


def interruption(signum: int) -> KeyboardInterrupt:
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def _main() -> bool:
    return threading.current_thread() is threading.main_thread()


class Obeyed:
    """What `obeyed` saw, and what acts on it: the last interruption received (`received`, a signal number), its
    handler, and the hook that delivers again one lost in a finaliser."""

    def __init__(self):
        self.received: int | None = None
        self.hooked = False  # inside the unraisable hook: an interruption raised here would be lost again
        self.again = threading.Event()  # set: deliver `received` again, from `courier`
        self.courier: threading.Thread | None = None
        self.ended = False

    def interrupt(self, signum, frame) -> None:
        self.received = signum
        if self.hooked:
            self.again.set()
            return
        raise interruption(signum)

    def lost(self) -> KeyboardInterrupt | None:
        """The interruption received that something swallowed (the command returned), to raise now; None."""
        return interruption(self.received) if self.received is not None else None

    def unraisable(self, previous):
        def hook(unraisable) -> None:
            if not (isinstance(unraisable.exc_value, KeyboardInterrupt) and self.received is not None):
                previous(unraisable)
                return
            self.hooked = True
            try:
                if self.courier is None:
                    self.courier = threading.Thread(target=self._deliver, daemon=True, name="interruptions")
                    self.courier.start()
                self.again.set()
            finally:
                self.hooked = False

        return hook

    def _deliver(self) -> None:
        """In a thread of its own: each time `again` is set, deliver `received` to the main thread a moment later,
        once the hook and the finaliser have returned (in the main thread the handler would run at once, inside
        them; landing in a finaliser once more, it comes back here)."""
        while self.again.wait() and not self.ended:
            self.again.clear()
            time.sleep(AGAIN_AFTER)
            if not self.ended and self.received is not None:
                _thread.interrupt_main(self.received)

    def end(self) -> None:
        self.ended = True
        self.again.set()


@contextlib.contextmanager
def obeyed() -> Iterator[Obeyed]:
    """For a command of the command line: SIGINT raises KeyboardInterrupt and SIGTERM `Terminated` wherever they
    land, an interruption raised in a finaliser is raised again outside it, and the one received is remembered
    (`Obeyed.lost`).  The handlers and the hook before are put back at the end."""
    seen = Obeyed()
    if not _main():
        yield seen
        return
    previous = {number: signal.signal(number, seen.interrupt) for number in SIGNALS}
    hook, sys.unraisablehook = sys.unraisablehook, seen.unraisable(sys.unraisablehook)
    try:
        yield seen
    finally:
        seen.end()
        sys.unraisablehook = hook
        for number, handler in previous.items():
            signal.signal(number, handler)


class _Held:
    """The signals received while interruptions are deferred, and the handlers that act on them."""

    def __init__(self, handlers: dict):
        self.handlers = handlers
        self.signals: list[int] = []

    def hold(self, signum, frame) -> None:
        self.signals.append(signum)

    def deliver(self) -> None:
        """The handlers that act back in place, and the first signal held delivered to them."""
        for number, handler in self.handlers.items():
            signal.signal(number, handler)
        held, self.signals = self.signals, []
        if held:
            signal.raise_signal(held[0])


_holding: list[_Held] = []  # the deferral in force (at most one: an inner `deferred` is part of the outer)


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Ctrl-C and SIGTERM received in the block are acted on when it ends (as the handlers in force would have),
    except inside `allowed`.  Inside another `deferred` block: part of it."""
    if not _main() or _holding:
        yield
        return
    held = _Held({number: signal.getsignal(number) for number in SIGNALS})
    for number in SIGNALS:
        signal.signal(number, held.hold)
    _holding.append(held)
    try:
        yield
    finally:
        _holding.pop()
        held.deliver()


@contextlib.contextmanager
def allowed() -> Iterator[None]:
    """Inside a `deferred` block, a stretch where an interruption acts at once (a backend waiting for its
    simulations, or running one here); one held before is acted on as the block begins.  Outside: nothing."""
    if not _main() or not _holding:
        yield
        return
    held = _holding[-1]
    held.deliver()
    try:
        yield
    finally:
        for number in SIGNALS:
            signal.signal(number, held.hold)
