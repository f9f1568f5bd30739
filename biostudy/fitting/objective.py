"""The objective a calibration minimises or samples: weighted residuals at points of the unit cube, many at a time.

Every method works on the unit cube of the bounds (`plans.designs.Range`: log10 for log bounds) and sees the model
only through `Objective.evaluate`: a batch of points -> per point the residuals (model - measurement) / sigma, or
None for a failed simulation (where σ is estimated, / a fixed scale: `likelihood`).  The batch is the unit of
parallel work: the execution backend runs its simulations at once.  `Objective` remembers every point it evaluated
under one identity (`key`), so the posterior reuses least squares' simulations and nothing is asked twice.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .likelihood import Likelihood

Evaluate = Callable[[list[np.ndarray]], list]  # points -> one result each (residuals, or None: a failed run)
DIGITS = 15  # a point's identity: its coordinates in the unit cube rounded to this many decimals


def key(point: np.ndarray) -> tuple[float, ...]:
    """A point's identity: two points with the same key are the same simulation for every fit."""
    return tuple(np.round(np.asarray(point, dtype=float), DIGITS).tolist())


@dataclass
class Objective:
    """The weighted residuals of the model (`run`: a batch of points -> results), the size of the problem, the
    residuals' own resolution (`noise`: per residual the smallest change that is not noise) and the workers that
    evaluate a batch at once; every point evaluated so far; the `likelihood`: which residuals share an
    estimated σ (those are scaled by a fixed number, not by σ) and what a fit minimises."""

    run: Evaluate
    n: int  # residuals
    noise: np.ndarray
    names: tuple[str, ...]  # the parameters, one per coordinate of the unit cube
    workers: int = 1
    evaluated: dict[tuple, tuple[np.ndarray, np.ndarray | None]] = field(default_factory=dict)
    likelihood: Likelihood = Likelihood()  # what a fit minimises: chi², or -2 log L with σs estimated

    @property
    def k(self) -> int:
        return len(self.names)

    def evaluate(self, points: list[np.ndarray]) -> list[np.ndarray | None]:
        """The residuals at every point (None: its simulation failed), each point evaluated once."""
        new = list({key(p): np.asarray(p, dtype=float) for p in points if key(p) not in self.evaluated}.values())
        if new:
            for point, result in zip(new, self.run(new)):
                self.evaluated[key(point)] = (point, None if result is None else np.asarray(result, dtype=float))
        return [self.evaluated[key(p)][1] for p in points]

    def known(self) -> list[tuple[np.ndarray, np.ndarray | None]]:
        """Every point evaluated so far, in the order first asked, with its residuals (None: failed)."""
        return list(self.evaluated.values())
