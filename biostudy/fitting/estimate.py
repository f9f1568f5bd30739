"""Least squares with profiles, end to end on the unit cube: the starts, the best fit, its local uncertainty and the
profile likelihoods, every simulation asked for in rounds (`rounds.run`).

The starts run side by side, one round each at a time; a start whose best point comes within `MERGE` of
another's (in every coordinate of the unit cube) with a higher chi² is stopped: it is heading for the same
minimum, and its runs would only repeat the other's.  Then the profiles' 2k branches run side by side.  A
start can stop on a flat stretch of chi² (where a parameter hardly matters, the Gauss-Newton step promises
nothing); when a profile finds a point more than `REFIT` below it, the fit is repeated from that point, the
estimate and its Jacobian are taken from there, and the intervals are measured against the lowest chi² found.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import rounds
from .least_squares import STEP, Fit, Problem, fit
from .profiles import Branch, Profile, branch, profile
from .rounds import Stopped
from .uncertainty import Local, local

MERGE = 0.05  # starts this close (unit cube, every coordinate) are heading for the same minimum
REFIT = 0.1  # a profile point this much below the best start's chi²: the fit is repeated from it


@dataclass
class Estimate:
    """What least squares found: every start's end, the best, its local uncertainty, the profiles."""

    fits: list[Fit | None]  # per start (None: stopped before it had evaluated anything)
    best: Fit
    local: Local
    profiles: list[Profile] = field(default_factory=list)
    branches: list[Branch] = field(default_factory=list)
    minimum: float = float("nan")  # the lowest chi² found, profiles included
    lowest: np.ndarray | None = None  # where
    starts_chi2: float | None = None  # the starts' best chi², when the profiles found lower and the fit was repeated


def _best_point(problem: Problem) -> tuple[np.ndarray, float] | None:
    if not problem.path:
        return None
    point, value = min(problem.path, key=lambda item: item[1])
    return point, value


def least_squares(starts: np.ndarray, n: int, noise: np.ndarray, evaluate: Callable[[list[np.ndarray]], list],
                  with_profiles: bool = True, workers: int = 1) -> Estimate:
    """Fit from every start (rows of the unit cube), then profile every parameter of the best fit; `workers`: how
    many simulations run at once (a fit asks for a point and its neighbours together when there are enough)."""
    k = starts.shape[1]
    problems: dict[str, Problem] = {}
    live = {"fits": len(starts)}  # fits in the last round: set between rounds, the same whatever the timing

    def speculate(free: int) -> bool:
        return workers >= live["fits"] * (free + 1)

    def counted(waiting: list[str], stopped: set[str] = frozenset()) -> None:
        live["fits"] = max(1, len(set(waiting) - set(stopped)))

    def start_task(name: str, start: np.ndarray):
        def task(ask):
            problems[name] = Problem(ask, n, noise, np.full(k, STEP), speculate)
            return fit(start, problems[name])
        return task

    names = [f"start{i}" for i in range(len(starts))]
    tasks = {name: start_task(name, start) for name, start in zip(names, starts)}

    def merge(waiting: list[str]) -> set[str]:
        ends = {name: _best_point(problems[name]) for name in waiting if name in problems}
        ends = {name: end for name, end in ends.items() if end is not None}
        stopped = set()
        for a in sorted(ends):
            for b in sorted(ends):
                if a < b and a not in stopped and b not in stopped:
                    if np.max(np.abs(ends[a][0] - ends[b][0])) < MERGE:
                        stopped.add(b if ends[b][1] >= ends[a][1] else a)
        counted(waiting, stopped)
        return stopped

    outcome = rounds.run(tasks, evaluate, merge)
    fits: list[Fit | None] = []
    for name in names:
        result = outcome[name]
        if isinstance(result, Stopped):
            found = _best_point(problems[name]) if name in problems else None
            fits.append(None if found is None else Fit(found[0], found[1], problems[name].known[
                tuple(np.round(found[0], 15))], np.zeros((n, k)), problems[name].steps, len(problems[name].path),
                "stopped: joined another start", problems[name].failed, True))
        elif isinstance(result, BaseException):
            raise result
        else:
            fits.append(result)
    best = min((f for f in fits if f is not None and not f.stopped), key=lambda f: f.chi2)
    estimate = Estimate(fits, best, local(best.jacobian), minimum=best.chi2, lowest=best.x)
    if not with_profiles:
        return estimate
    branches = {f"profile{j}{'-+'[d > 0]}": (j, d) for j in range(k) for d in (-1, 1)}
    tasks = {name: (lambda ask, j=j, d=d: branch(best, j, d, ask, noise, speculate,
                                                   float(estimate.local.standard_error[j])))
             for name, (j, d) in branches.items()}
    live["fits"] = len(tasks)

    def profiles_counted(waiting: list[str]) -> set[str]:
        counted(waiting)
        return set()

    outcome = rounds.run(tasks, evaluate, profiles_counted)
    for result in outcome.values():
        if isinstance(result, BaseException):
            raise result
    estimate.branches = [outcome[name] for name in branches]
    for b in estimate.branches:
        for _, value, point in b.points:
            if value < estimate.minimum:
                estimate.minimum, estimate.lowest = value, point
    if estimate.minimum < best.chi2 - REFIT:
        live["fits"] = 1
        lowest = estimate.lowest
        again = rounds.run({"refit": lambda ask: fit(lowest, Problem(ask, n, noise, best.steps, speculate))},
                           evaluate, profiles_counted)["refit"]
        if isinstance(again, BaseException):
            raise again
        if again.chi2 < best.chi2:
            estimate.starts_chi2, estimate.best, estimate.local = best.chi2, again, local(again.jacobian)
        if again.chi2 < estimate.minimum:
            estimate.minimum, estimate.lowest = again.chi2, again.x
    estimate.profiles = [profile(best, outcome[f"profile{j}-"], outcome[f"profile{j}+"], estimate.minimum)
                         for j in range(k)]  # the branches start from `best`, the starts' best
    return estimate
