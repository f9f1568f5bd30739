"""How a calibration's parameters are estimated: its [method] table (docs/calibrate.md)."""
from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..errors import InvalidAt
from ..fitting.methods import LeastSquares, Method, PosteriorSampling
from ..fitting.posterior import Options

METHODS = ("least-squares", "posterior")
POSTERIOR_KEYS = ("design", "held_out", "walkers", "steps", "box")  # [method] keys of "posterior" alone


class MethodSpec(BaseModel):
    """How the parameters are estimated."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)
    name: Literal[METHODS] = Field("least-squares", description="least-squares: weighted least squares, "
                                   "multi-start, profile likelihoods; posterior: least squares, then samples of "
                                   "the posterior on a Gaussian-process surrogate")
    starts: int = Field(4, ge=1, le=64, description="starts of the optimiser, from a Latin hypercube in the bounds")
    profiles: bool = Field(True, description="a profile likelihood per parameter: its 95 % interval (posterior: "
                                             "false unless set)")
    seed: int = Field(0, ge=0, description="seed of the starts' design (posterior: of its design and chains too)")
    design: int = Field(30, ge=4, le=2000, description="posterior: simulations of the surrogate's training design "
                                                       "(the least-squares fit's own join them)")
    held_out: int = Field(8, ge=1, le=500, description="posterior: simulations held out to measure the surrogate's "
                                                       "error")
    walkers: int = Field(16, ge=4, le=1000, description="posterior: emcee's walkers (at least twice the parameters)")
    steps: int = Field(2000, ge=100, le=1_000_000, description="posterior: steps of every walker")
    box: float = Field(6.0, ge=2.0, le=1e6, description="posterior: the surrogate's box, the least-squares "
                                                         "estimate ± this many standard errors (within the bounds)")

    @model_validator(mode="after")
    def _keys_of_the_method(self):
        if self.name != "posterior":
            given = [key for key in POSTERIOR_KEYS if key in self.model_fields_set]
            if given:
                raise InvalidAt(given[0], f"applies to name = \"posterior\" only (this method is {self.name!r})")
        elif "profiles" not in self.model_fields_set:
            self.profiles = False
        return self

    def method(self) -> Method:
        """The fitting method this table describes (`fitting.methods`)."""
        fit = LeastSquares(self.starts, self.profiles, self.seed)
        if self.name == "posterior":
            return PosteriorSampling(fit, Options(self.design, self.held_out, self.walkers, self.steps, self.box,
                                                  self.seed))
        return fit
