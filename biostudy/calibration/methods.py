"""Calibration methods, each declared once: its [method] keys and rules, its maths, what it costs, adds to
calibration.nc, draws and warns about.  Nothing outside this module asks a method's name.

A method is a class (`Method`): its `name` (the [method] table's), `description`, its own `keys` (pydantic
fields; `method_spec.MethodSpec` is built from every method's), whether it takes a σ the table names to estimate,
and, made from the [method] table, `__call__(objective) -> Result` (the maths, in `fitting`: it sees the
simulations only through the `Objective`) and its answers to the rest of the calibration: the `pictures` it draws
beside calibration_fit.png, its `problems` with a problem of k parameters, the `memory` it holds in this process,
its `variables` in calibration.nc, its `cost` attributes and its `warnings`.

`LeastSquares`: multi-start Levenberg-Marquardt, the local uncertainty and the profile likelihoods
(`fitting.estimate`).  `PosteriorSampling`: least squares first, then the posterior sampled on a Gaussian-process
surrogate around its estimate (`fitting.posterior`, `report_posterior`); it takes σ as given.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from pydantic import Field

from ..errors import Failed
from ..fitting.estimate import Estimate, least_squares, starts
from ..fitting.objective import Objective
from ..fitting.posterior import Options, Posterior, posterior

if TYPE_CHECKING:
    import xarray as xr



@dataclass
class Result:
    """What a calibration method found: its starts (unit cube), the least-squares estimate with its local
    uncertainty and profiles, and the posterior when it was sampled."""

    starts: np.ndarray
    estimate: Estimate
    posterior: Posterior | None = None


@dataclass(frozen=True)
class Picture:
    """A picture a method draws into the calibration's directory: its file and the function of `pictures` that
    draws it from calibration.nc (imported when drawn: matplotlib only then)."""

    file: str
    figure: str

    def draw(self, ds: xr.Dataset):
        from . import pictures  # lazily

        return getattr(pictures, self.figure)(ds)


@dataclass(frozen=True)
class Held:
    """Memory a method holds in this process whatever runs the simulations: bytes, what holds them (`label` in
    `show`'s list), of what parts, and what to lower (a [method] `key`, `remedy` in words) if they cannot fit."""

    bytes: float
    what: str
    label: str
    parts: str
    key: str
    remedy: str


FIT = Picture("calibration_fit.png", "fit_figure")  # every method's: the data against the fitted model
PROFILES = Picture("calibration_profiles.png", "profiles_figure")


class Method:
    """A way to estimate parameters from the objective's residuals, made from the [method] table (`spec`); what
    the base class answers is that of a method adding nothing to least squares."""

    name: ClassVar[str]
    description: ClassVar[str]
    keys: ClassVar[dict[str, Any]] = {}  # its own [method] keys: name -> (type, pydantic Field; described without
    # the method's name, which `method_spec` puts before it)
    profiles: ClassVar[bool] = True  # [method] profiles when the table leaves it out
    estimates_sigma: ClassVar[bool] = True  # takes a σ the measurement table names to estimate
    seeds: ClassVar[str] = ""  # what [method] seed seeds besides the starts' design

    def __init__(self, spec: Any) -> None:
        self.spec = spec

    def __call__(self, objective: Objective) -> Result:
        raise NotImplementedError

    def pictures(self) -> tuple[Picture, ...]:
        """The pictures it draws, beside `FIT`."""
        return (PROFILES,) if self.spec.profiles else ()

    def problems(self, k: int) -> list[tuple[str, str]]:
        """(key of [method], why) for each of its settings that cannot work with k parameters."""
        return []

    def memory(self, k: int) -> Held | None:
        """What it holds in this process besides the simulations (whatever runs them) for k parameters."""
        return None

    def variables(self, plan: Any, result: Result, units: list[str]) -> tuple[dict, dict, dict]:
        """Its part of calibration.nc besides least squares' (`plan`: the `problem.CalibrationPlan`): variables,
        coordinates, attributes."""
        return {}, {}, {}

    def described(self) -> str:
        """What calibration.nc's `method` attribute adds to least squares' words for it."""
        return ""

    def cost(self, result: Result) -> dict[str, float]:
        """Its attributes of calibration.nc's cost (wall times) besides the simulations'."""
        return {}

    def warnings(self, result: Result) -> list[str]:
        """What its result says a user must know."""
        return []


class LeastSquares(Method):
    """Weighted least squares from `starts` points of a Latin hypercube (`seed`), profiles if asked for."""

    name = "least-squares"
    description = "weighted least squares, multi-start, profile likelihoods"

    def __call__(self, objective: Objective) -> Result:
        design = starts(objective.k, self.spec.starts, self.spec.seed)
        return Result(design, least_squares(design, objective, self.spec.profiles))


class PosteriorSampling(LeastSquares):
    """Least squares, then the posterior on a surrogate around its estimate (`fitting.posterior.Options`)."""

    name = "posterior"
    description = "least squares, then samples of the posterior on a Gaussian-process surrogate"
    keys = {
        "design": (int, Field(30, ge=4, le=2000, description="simulations of the surrogate's training design (the "
                                                            "least-squares fit's own join them)")),
        "held_out": (int, Field(8, ge=1, le=500, description="simulations held out to measure the surrogate's error")),
        "walkers": (int, Field(16, ge=4, le=1000, description="emcee's walkers (at least twice the parameters)")),
        "steps": (int, Field(2000, ge=100, le=1_000_000, description="steps of every walker")),
        "box": (float, Field(6.0, ge=2.0, le=1e6, description="the surrogate's box, the least-squares estimate ± this "
                                                             "many standard errors (within the bounds)")),
    }
    profiles = False
    estimates_sigma = False
    seeds = "its design and chains"
    CORNER = Picture("calibration_corner.png", "corner_figure")

    def __call__(self, objective: Objective) -> Result:
        found = super().__call__(objective)
        best = found.estimate
        options = Options(self.spec.design, self.spec.held_out, self.spec.walkers, self.spec.steps, self.spec.box,
                          self.spec.seed)
        try:
            sampled = posterior(objective, best.best.x, best.local.standard_error, options)
        except ValueError as error:  # too few successful simulations in the box
            raise Failed(f"the posterior's surrogate could not be trained: {error} (the failed simulations under "
                         "cases/ say why)") from None
        return replace(found, posterior=sampled)

    def pictures(self) -> tuple[Picture, ...]:
        return (*super().pictures(), self.CORNER)

    def problems(self, k: int) -> list[tuple[str, str]]:
        found = []
        if self.spec.walkers < 2 * k:
            found.append(("walkers", f"emcee needs at least twice as many walkers as parameters: {self.spec.walkers} "
                                      f"< 2 x {k}"))
        if self.spec.design < k + 2:
            found.append(("design", f"a surrogate of {k} parameters needs at least {k + 2} training runs "
                                    f"(got {self.spec.design})"))
        return found

    def memory(self, k: int) -> Held:
        """The chains: emcee's positions and log-probabilities (walkers x steps x (k + 1)), the kept samples and
        their values in the parameters' units (at most walkers x steps x k each)."""
        walkers, steps = self.spec.walkers, self.spec.steps
        return Held(8.0 * walkers * steps * (3 * k + 1), "the posterior's chains", "chains",
                    f"{walkers} walkers × {steps} steps × {k} parameters", "steps", "lower steps or walkers")

    def variables(self, plan: Any, result: Result, units: list[str]) -> tuple[dict, dict, dict]:
        from .report_posterior import posterior_variables

        assert result.posterior is not None
        return posterior_variables(plan, result.posterior, units)

    def described(self) -> str:
        return (f"; {self.name}: emcee on a Gaussian-process surrogate of the residuals, its held-out error added to "
                "sigma² (docs/calibration.md)")

    def cost(self, result: Result) -> dict[str, float]:
        return {"wall_time_sampling": result.posterior.seconds} if result.posterior is not None else {}

    def warnings(self, result: Result) -> list[str]:
        return list(result.posterior.verdicts) if result.posterior is not None else []


METHODS: dict[str, type[Method]] = {method.name: method for method in (LeastSquares, PosteriorSampling)}


def chosen(spec: Any) -> Method:
    """The method a [method] table (`method_spec.MethodSpec`) chooses, made from it."""
    return METHODS[spec.name](spec)
