"""Calibration methods behind one interface: a method takes the `Objective` and returns one `Result`.

`LeastSquares`: multi-start Levenberg-Marquardt, the local uncertainty and the profile likelihoods
(`estimate`).  `PosteriorSampling`: least squares first, then the posterior sampled on a Gaussian-process
surrogate around its estimate (`posterior`).  Reports and pictures read the `Result` (what is absent was not
computed); a new method is a class with `name`, `products` and `__call__(objective) -> Result`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from .estimate import Estimate, least_squares, starts
from .objective import Objective
from .posterior import Options, Posterior, Untrainable, posterior


@dataclass
class Result:
    """What a calibration method found: its starts (unit cube), the least-squares estimate with its local
    uncertainty and profiles, and the posterior when it was sampled."""

    starts: np.ndarray
    estimate: Estimate
    posterior: Posterior | None = None


class Method(Protocol):
    """A way to estimate parameters from the objective's residuals."""

    name: str

    @property
    def products(self) -> tuple[str, ...]:
        """What it computes besides the estimate: "profiles", "posterior"."""
        ...

    def __call__(self, objective: Objective) -> Result:
        ...


@dataclass(frozen=True)
class LeastSquares:
    """Weighted least squares from `starts` points of a Latin hypercube (`seed`), profiles if asked for."""

    starts: int = 4
    profiles: bool = True
    seed: int = 0
    name: str = "least-squares"

    @property
    def products(self) -> tuple[str, ...]:
        return ("profiles",) if self.profiles else ()

    def __call__(self, objective: Objective) -> Result:
        design = starts(objective.k, self.starts, self.seed)
        return Result(design, least_squares(design, objective, self.profiles))


@dataclass(frozen=True)
class PosteriorSampling:
    """Least squares, then the posterior on a surrogate around its estimate (`posterior.Options`)."""

    fit: LeastSquares
    options: Options
    name: str = "posterior"

    @property
    def products(self) -> tuple[str, ...]:
        return (*self.fit.products, "posterior")

    def __call__(self, objective: Objective) -> Result:
        found = self.fit(objective)
        best = found.estimate
        try:
            sampled = posterior(objective, best.best.x, best.local.standard_error, self.options)
        except ValueError as error:
            raise Untrainable(str(error)) from None
        return replace(found, posterior=sampled)
