"""A team of threads that run one piece of work on N parts at once: the threads of one run.

The compiled kernels release the GIL (numba's ``nogil``), so Python threads run them truly in parallel.  A
`Team` of N keeps N - 1 helper threads waiting on their inboxes; `run(work)` hands part p to helper p and
runs part 0 in the calling thread, then waits for every part and re-raises the first error.  All N parts run
at the same time, which the pipelined Gauss-Seidel sweeps (`sweeps.py`) rely on: a part may wait for another.

Not numba's own ``parallel=True``: its threading layer on Linux is GNU OpenMP, which aborts a process forked
after it was used (a worker forked by a sweep, a test's fork), and its fork-safe alternative aborts when two
threads of one process (two runs from the Python API) launch kernels at once.  A team is per run: its helpers
start with the first parallel call, are recreated in a forked child and end when the team is collected.

What is computed does not depend on the team: every kernel computes each entry of its result in the order of
the serial loop, whichever thread computes it (docs/transport.md, "Threads").  Nor on whether the parts run at
once: parts that do not wait for one another may as well run one after another in the calling thread, and
do, while that has been the faster (a machine whose processors are busy with other work starts the helpers
late: measured, a 30^3 run on 2 threads at load 17 took 2.7 times one thread's time).  The team keeps, for
each kind of work (its `site`, by default the name of the work's function), a running mean of how long the
parts took at once against as many times the calling thread's own part, and while that is above 1 it runs them
in turn, trying them at once again after `PROBE` times, and after twice as many each time that did not pay (up
to `PATIENCE`): on a machine that stays busy the trials cost little.  A trial's ratio replaces the mean (the old
one is stale), so threads are back at the first trial that pays.  Kinds apart, a kind whose parts are uneven
(or whose calls are short, the ~25 µs of a handoff weighing) does not send the others in turn: with one mean
for all, a 64^3 run at load 0.5 kept half of its products in turn (mean 1.56).
"""
from __future__ import annotations

import os
import queue
import threading
import time
import weakref
from typing import Callable

PROBE = 16  # while parts run in turn, after this many times they run at once again, to see whether that pays ...
PATIENCE = 1024  # ... and after twice as many each time it did not, up to this many
WEIGHT = 0.1  # of a new ratio in the running mean
SHORT = 2e-5  # seconds: a caller's part shorter than this says nothing about the threads


class Team:
    """`size` threads (the caller's included) that run work(part) for every part in range(size) at once."""

    def __init__(self, size: int = 1):
        if int(size) < 1:
            raise ValueError(f"a team needs at least one thread, got {size}")
        self.size = int(size)
        self._lock = threading.Lock()
        self._inboxes: list[queue.SimpleQueue] = []
        self._done: queue.SimpleQueue = queue.SimpleQueue()
        self._pid = -1
        self._finalizer: weakref.finalize | None = None
        self._seconds = [0.0] * self.size  # CPU seconds each helper spent in work (slot 0 unused: the caller's)
        # per kind of work ("site"): running mean of (time of the parts at once) / (size x time of the caller's part)
        self.ratios: dict[str, float] = {}
        self._calls: dict[str, int] = {}
        self._probes: dict[str, tuple[int, int]] = {}  # per site: (the call that probes next, the interval)

    def run(self, work: Callable[[int], None], together: bool = False, site: str = "") -> None:
        """work(part) for part 0 .. size - 1 (part 0 in this thread); returns when every part has, re-raising the
        first exception a part raised.  `together`: the parts wait for one another, so they run at once; else they
        may run one after another here (module docstring), as the running mean of their `site` says (by default
        the name of work's function: each kind of work its own)."""
        if self.size == 1:
            work(0)
            return
        site = site or kind(work)
        calls = self._calls[site] = self._calls.get(site, 0) + 1
        ratio = self.ratios.get(site, 0.0)
        probe, interval = self._probes.get(site, (PROBE, PROBE // 2))
        in_turn = not together and ratio > 1.0
        if in_turn and calls < probe:
            for part in range(self.size):
                work(part)
            return
        with self._lock:
            self._start()
            began = time.perf_counter()
            for part, inbox in enumerate(self._inboxes, start=1):
                inbox.put((work, part))
            failure: BaseException | None = None
            try:
                work(0)
            except BaseException as error:  # noqa: B036 - the helpers are waited for before it is re-raised
                failure = error
            own = time.perf_counter() - began
            for _ in self._inboxes:
                error = self._done.get()
                failure = failure or error
            if not together and own > SHORT:
                now = (time.perf_counter() - began) / (self.size * own)
                self.ratios[site] = now if in_turn or not ratio else (1 - WEIGHT) * ratio + WEIGHT * now
            if in_turn:  # a probe: the next one later (in turn or not from now, as the mean says)
                interval = min(2 * interval, PATIENCE)
                self._probes[site] = (calls + interval, interval)
            elif self.ratios.get(site, 0.0) > 1.0:  # in turn from now on
                self._probes[site] = (calls + PROBE, PROBE)
            if failure is not None:
                raise failure

    def _start(self) -> None:
        """The helpers, started on first use and again in a forked child (threads do not survive a fork)."""
        if self._pid == os.getpid():
            return
        self._pid = os.getpid()
        self._inboxes = [queue.SimpleQueue() for _ in range(self.size - 1)]
        self._done = queue.SimpleQueue()
        for part, inbox in enumerate(self._inboxes, start=1):
            threading.Thread(target=_serve, args=(inbox, self._done, self._seconds, part), daemon=True,
                             name="biostudy-team").start()
        self._finalizer = weakref.finalize(self, _stop, self._inboxes)

    def helper_seconds(self) -> float:
        """CPU seconds the helper threads have spent in work so far (the calling thread's are its own)."""
        return sum(self._seconds)

    def close(self) -> None:
        """End the helpers now (they also end when the team is collected)."""
        if self._finalizer is not None:
            self._finalizer()


def kind(work: Callable) -> str:
    """The name of work's function (``product.<locals>.<lambda>``): the site of a kind of work by default."""
    code = getattr(work, "__code__", None)
    return code.co_qualname if code is not None else type(work).__qualname__


def _serve(inbox: queue.SimpleQueue, done: queue.SimpleQueue, seconds: list[float], slot: int) -> None:
    """A helper's loop: take (work, part), run it, add its CPU time to seconds[slot], report None or the exception;
    None in the inbox ends it."""
    while True:
        task = inbox.get()
        if task is None:
            return
        work, part = task
        began = time.thread_time()
        failure: BaseException | None = None
        try:
            work(part)
        except BaseException as error:  # noqa: B036 - handed to the caller, which re-raises it
            failure = error
        seconds[slot] += time.thread_time() - began  # before the caller hears that the work is done
        done.put(failure)


def _stop(inboxes: list[queue.SimpleQueue]) -> None:
    for inbox in inboxes:
        inbox.put(None)


def cores() -> int:
    """The processors this process may run on (its affinity: what taskset, a cpuset or a batch job's binding
    leaves it), the solver's thread count when a run names none."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # no affinity on this platform (macOS)
        return os.cpu_count() or 1


SERIAL = Team(1)  # the team of a caller that asks for none
