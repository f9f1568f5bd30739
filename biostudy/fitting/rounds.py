"""Rounds: fits written as generators ask for points by yielding them; one loop evaluates every fit's request at once.

A calibration's fits are independent of each other (the starts of a multi-start
optimisation, the branches of the profile likelihoods) but each is sequential:
it needs the residuals at one point (and its finite-difference neighbours)
before it knows the next.  A fit is therefore a generator: it yields an `Ask`
(the points it needs, and points it would need soon if workers are idle) and
is sent the results.  `run` advances every fit to its next request, evaluates
all of a round's requests in one call (`evaluate`, which hands them to the
workers or the Dask cluster at once) and sends each fit its answers.  A round
holds exactly one request of every live fit, and fits are asked in the order
of their names: the sequence of rounds, and so the result, is deterministic.
Between rounds `stop` may end fits (a start that has joined another); they are
closed and end as `Stopped`.  Nothing runs in a thread: Ctrl-C ends the loop
where it is, as everywhere else.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Generator, TypeVar

import numpy as np

from .objective import Evaluate

T = TypeVar("T")


@dataclass(frozen=True)
class Ask:
    """What a fit needs before it can go on (`points`), and what it will need next if the round has room for it
    (`soon`: finite-difference neighbours, evaluated only when workers would otherwise wait)."""

    points: list[np.ndarray]
    soon: list[np.ndarray] = field(default_factory=list)


Asking = Generator[Ask, list, T]  # yields what it needs; sent one result per point asked (and `soon` point taken)


class Stopped:
    """The outcome of a fit that `run`'s stop ended (it joined another)."""


def _room(workers: int, fits: int, ask: Ask) -> bool:
    """Take a fit's `soon` points too when the workers would otherwise wait: at least one worker per point for
    every fit of the round."""
    return bool(ask.soon) and workers >= fits * (len(ask.points) + len(ask.soon))


def _taken(asked: dict[str, Ask], workers: int) -> dict[str, list[np.ndarray]]:
    """The points each fit of a round is evaluated at: those it needs, its `soon` ones where there is room for
    every fit's (`_room`), and then, while the round's last simulations would leave workers waiting, the first
    `soon` points of the fits in order (a fit is sent results for the points it asked and a first part of its
    `soon` ones)."""
    taken = {name: ask.points + (ask.soon if _room(workers, len(asked), ask) else []) for name, ask in asked.items()}
    idle = -sum(map(len, taken.values())) % workers
    for name, ask in asked.items():
        if len(taken[name]) == len(ask.points) and idle:
            taken[name] += ask.soon[:idle]
            idle -= len(ask.soon[:idle])
    return taken


def run(fits: dict[str, Asking], evaluate: Evaluate, stop: Callable[[list[str]], set[str]] | None = None,
        workers: int = 1) -> dict[str, object]:
    """Advance every fit in rounds until each has returned; name -> what it returned (or a `Stopped`).
    evaluate(points) -> one result each, in order; stop(waiting names) -> names to stop; `workers`: how many
    simulations run at once (whether a fit's `soon` points join the round)."""
    outcome: dict[str, object] = {}
    waiting: dict[str, Ask] = {}

    def advance(name: str, answer: list | None) -> None:
        try:
            waiting[name] = fits[name].send(answer)  # type: ignore[arg-type]  # None starts a generator
        except StopIteration as done:
            outcome[name] = done.value

    try:
        for name in fits:
            advance(name, None)
        while waiting:
            round_ = {name: waiting.pop(name) for name in sorted(waiting)}
            stopped = stop(list(round_)) if stop else set()
            for name in stopped & set(round_):
                fits[name].close()
                outcome[name] = Stopped()
            asked = {name: ask for name, ask in round_.items() if name not in stopped}
            taken = _taken(asked, workers)
            results = evaluate([point for points in taken.values() for point in points]) if taken else []
            at = 0
            for name, points in taken.items():
                advance(name, results[at:at + len(points)])
                at += len(points)
    finally:
        for fit in fits.values():  # an error or Ctrl-C ends every fit where it waits (a finished one: no-op)
            fit.close()
    return outcome
