"""Least squares with profiles, end to end on the unit cube: the starts, the best fit, its local uncertainty and the
profile likelihoods, every simulation asked for in rounds (`rounds.run`); the estimated σs and their intervals
(`likelihood`).

The starts run side by side, one round each at a time; a start whose best point comes within `MERGE` of
another's (in every coordinate of the unit cube) with a higher chi² is stopped: it is heading for the same
minimum, and its runs would only repeat the other's.  Then the profiles' 2k branches run side by side.  A
start can stop on a flat stretch of chi² (where a parameter hardly matters, the Gauss-Newton step promises
nothing); when a profile finds a point more than `REFIT` below it, the fit is repeated from that point, the
estimate and its Jacobian are taken from there, and every profile is stepped again from the new optimum (up to
`REFITS` times; the intervals are measured against the lowest chi² found).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import qmc

from . import rounds
from .least_squares import STEP, Fit, Problem, fit
from .likelihood import Sigma, sigma_intervals
from .objective import Objective, key
from .profiles import Branch, Profile, branch, profile
from .rounds import Stopped
from .uncertainty import Local, local

MERGE = 0.05  # starts this close (unit cube, every coordinate) are heading for the same minimum
REFIT = 0.1  # a profile point this much below the best start's chi²: the fit is repeated from it
REFITS = 3  # fits repeated from a profile's lower point, each followed by profiles from the new optimum
DESIGN_MARGIN = 0.05  # the starts' Latin hypercube fills [0.05, 0.95] of every range


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
    sigmas: list[Sigma] = field(default_factory=list)  # the estimated σs (`likelihood`), one per group


def starts(k: int, n: int, seed: int) -> np.ndarray:
    """n starts in the unit cube: a scrambled Latin hypercube over [DESIGN_MARGIN, 1 - DESIGN_MARGIN]^k."""
    design = qmc.LatinHypercube(d=k, scramble=True, rng=seed).random(n)
    return DESIGN_MARGIN + (1 - 2 * DESIGN_MARGIN) * design


def _best_point(problem: Problem) -> tuple[np.ndarray, float] | None:
    if not problem.path:
        return None
    point, value = min(problem.path, key=lambda item: item[1])
    return point, value


def _merge(problems: dict[str, Problem], waiting: list[str]) -> set[str]:
    """Of the starts waiting, those whose best point is within `MERGE` of another's with a higher chi²."""
    ends = {name: _best_point(problems[name]) for name in waiting}
    ends = {name: end for name, end in ends.items() if end is not None}
    stopped: set[str] = set()
    for a in sorted(ends):
        for b in sorted(ends):
            if a < b and a not in stopped and b not in stopped:
                if np.max(np.abs(ends[a][0] - ends[b][0])) < MERGE:
                    stopped.add(b if ends[b][1] >= ends[a][1] else a)
    return stopped


def _joined(problem: Problem, n: int, k: int) -> Fit | None:
    """A stopped start's best point, as a `Fit` marked stopped (None: it had evaluated nothing)."""
    found = _best_point(problem)
    if found is None:
        return None
    return problem.ended(found[0], problem.known[key(found[0])], np.zeros((n, k)), len(problem.path),
                         "stopped: joined another start", stopped=True)


def _from_starts(design: np.ndarray, objective: Objective) -> list[Fit | None]:
    """Every start's fit, side by side in rounds; a start heading for another's minimum is stopped (`_merge`)."""
    k = design.shape[1]
    problems = {f"start{i}": Problem(objective.n, objective.noise, np.full(k, STEP), objective.likelihood)
                for i in range(len(design))}
    outcome = rounds.run({name: fit(start, problems[name]) for name, start in zip(problems, design)},
                         objective.evaluate, lambda waiting: _merge(problems, waiting), objective.workers)
    return [_joined(problems[name], objective.n, k) if isinstance(outcome[name], Stopped) else outcome[name]
            for name in problems]  # type: ignore[misc]


def _branches(best: Fit, standard_error: np.ndarray, objective: Objective) -> dict[str, Branch]:
    """The 2k profile branches from `best`, side by side in rounds, by name ("profile0-", "profile0+", ...)."""
    names = {f"profile{j}{'-+'[d > 0]}": (j, d) for j in range(objective.k) for d in (-1, 1)}
    outcome = rounds.run({name: branch(best, j, d, objective.noise, float(standard_error[j]), objective.likelihood)
                          for name, (j, d) in names.items()}, objective.evaluate, workers=objective.workers)
    return {name: outcome[name] for name in names}  # type: ignore[misc]


def _profiles(estimate: Estimate, objective: Objective) -> None:
    """The 2k profile branches from the best fit side by side.  When they find a point more than `REFIT` below
    it, the fit is repeated from that point and every branch stepped again from the new optimum (at most
    `REFITS` times): a profile and its interval are read from branches centred on the estimate they are
    reported with, never on an optimum left behind.  The intervals are against the lowest chi² found."""
    for refits in range(REFITS + 1):
        best = estimate.best
        outcome = _branches(best, estimate.local.standard_error, objective)
        estimate.branches = list(outcome.values())
        estimate.minimum, estimate.lowest = best.chi2, best.x
        for b in estimate.branches:
            for _, value, point in b.points:
                if value < estimate.minimum:
                    estimate.minimum, estimate.lowest = value, point
        if estimate.minimum >= best.chi2 - REFIT or refits == REFITS:
            break
        again = rounds.run({"refit": fit(estimate.lowest, Problem(objective.n, objective.noise, best.steps,
                                                                  objective.likelihood))},
                           objective.evaluate, workers=objective.workers)["refit"]
        if not isinstance(again, Fit) or again.chi2 >= best.chi2:  # it starts below and only descends: never
            break
        if estimate.starts_chi2 is None:
            estimate.starts_chi2 = best.chi2
        estimate.best, estimate.local = again, local(again.jacobian)
    estimate.profiles = [profile(estimate.best, outcome[f"profile{j}-"], outcome[f"profile{j}+"], estimate.minimum)
                         for j in range(objective.k)]


def least_squares(design: np.ndarray, objective: Objective, with_profiles: bool = True) -> Estimate:
    """Fit from every start (rows of the unit cube), then profile every parameter of the best fit."""
    fits = _from_starts(design, objective)
    best = min((f for f in fits if f is not None and not f.stopped), key=lambda f: f.chi2)
    estimate = Estimate(fits, best, local(best.jacobian), minimum=best.chi2, lowest=best.x)
    if with_profiles:
        _profiles(estimate, objective)
    best = estimate.best  # its residuals and Jacobian are in units of its σ̂
    estimate.sigmas = sigma_intervals(objective.likelihood.in_units_of(best.sigma), best.residuals, best.jacobian,
                                      (best.x > 0.0) & (best.x < 1.0))
    return estimate
