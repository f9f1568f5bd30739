"""Rounds: several fits (threads) ask for points, and each round evaluates what all of them asked for at once.

A calibration's fits are independent of each other (the starts of a multi-start
optimisation, the branches of the profile likelihoods) but each is sequential:
it needs the residuals at one point (and its finite-difference neighbours)
before it knows the next.  Each fit runs in its own thread and calls
``ask(points)``, which blocks; when every live fit is waiting, the round's
points are evaluated together (`evaluate`, which hands them to the workers or
the Dask cluster at once) and every fit gets its answers.  A round therefore
holds exactly one request of every live fit, whatever the timing: the
sequence of rounds, and so the result, is deterministic.  `stop` may end
fits between rounds (a start that has joined another); their `ask` raises
`Stopped`.  An exception in this thread (Ctrl-C) ends every fit (`Aborted`).
"""
from __future__ import annotations

import threading
from typing import Callable, Sequence

import numpy as np

Ask = Callable[[Sequence[np.ndarray]], list]  # points -> one result each (residuals, or None: a failed run)


class Aborted(Exception):
    """The calibration ends (interrupted, or a round failed): every fit ends with it."""


class Stopped(Exception):
    """This fit is no longer needed (`Rounds.run`'s stop chose it)."""


def run(tasks: dict[str, Callable[[Ask], object]], evaluate: Callable[[list[np.ndarray]], list],
        stop: Callable[[list[str]], set[str]] | None = None) -> dict[str, object]:
    """Run every task(ask) in a thread of its own, in rounds; returns name -> what the task returned (or the
    exception it raised).  evaluate(points) -> results, in order; stop(waiting names) -> names to stop."""
    lock = threading.Condition()
    pending: dict[str, list[np.ndarray]] = {}
    answers: dict[str, object] = {}
    alive = set(tasks)
    outcome: dict[str, object] = {}
    state = {"aborted": False}

    def asker(name: str) -> Ask:
        def ask(points):
            with lock:
                if state["aborted"]:
                    raise Aborted
                pending[name] = [np.asarray(p, dtype=float) for p in points]
                lock.notify_all()
                while name not in answers and not state["aborted"]:
                    lock.wait()
                if state["aborted"]:
                    raise Aborted
                answer = answers.pop(name)
            if isinstance(answer, Stopped):
                raise answer
            return answer

        return ask

    def body(name: str, task) -> None:
        try:
            result = task(asker(name))
        except BaseException as error:  # noqa: B036 -- handed to the caller, which decides
            result = error
        with lock:
            outcome[name] = result
            alive.discard(name)
            lock.notify_all()

    threads = [threading.Thread(target=body, args=(name, task), daemon=True, name=f"fit-{name}")
               for name, task in tasks.items()]
    for thread in threads:
        thread.start()
    try:
        while True:
            with lock:
                while alive and set(pending) != alive:
                    lock.wait(0.5)  # a timeout, so that Ctrl-C reaches this thread
                if not alive:
                    break
                batch = {name: pending.pop(name) for name in sorted(pending)}
            stopped = stop(list(batch)) if stop else set()
            asked = [(name, points) for name, points in batch.items() if name not in stopped]
            flat = [p for _, points in asked for p in points]
            results = evaluate(flat) if flat else []
            with lock:
                at = 0
                for name, points in asked:
                    answers[name] = results[at:at + len(points)]
                    at += len(points)
                for name in stopped & set(batch):
                    answers[name] = Stopped()
                lock.notify_all()
    except BaseException:
        with lock:
            state["aborted"] = True
            lock.notify_all()
        for thread in threads:
            thread.join(5)
        raise
    for thread in threads:
        thread.join()
    return outcome
