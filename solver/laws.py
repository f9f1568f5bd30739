"""Which form of the model's laws a simulation solves (the scene's ``[model]`` table; docs/model.md).

The paper states its model twice, and the two differ: as evolution equations (Eqs. 34-36, the nutrient
time-homogenised to a steady state) and as the algorithm it computed with (Table 1, whose local equation for
alpha is not Eq. 36).  Each choice is an `option` here, declared once; the scene's ``[model]`` keys are derived
from these declarations (`biostudy.inputs.declared.settings_model`), as ``[numerics]`` is from `Numerics`.

* consumption: the nutrient's sink, g phi c (first order, keeps 0 <= c <= 1) or the paper's g phi with c >= 0
  held as a constraint (departures 1 and 2 of docs/model.md).
* expansion: Eq. 36, d alpha/dt = k_alpha phi (alpha grows wherever there is biofilm), or Table 1's local
  residual R_alpha = (alpha' - alpha)/((1 + alpha') dt) - k_alpha (phi' - phi)/dt = 0 (alpha changes only where
  phi changes; the assumption on eta_alpha that this reading takes is in `transport/expansion.py`).
* nutrient: Eq. 35 without its time derivative (quasi-steady, the paper's time homogenisation) or with it,
  d c/dt = d lap(c) - g phi (c), by backward Euler with phi's step (a nutrient that is not fast against growth).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

from .declared import OptionError, option

Consumption = Literal["first-order", "zero-order"]
Expansion = Literal["eq36", "table1"]
NutrientDynamics = Literal["quasi-steady", "transient"]


@dataclass(frozen=True)
class Laws:
    """The form of the nutrient's sink, the expansion's evolution and the nutrient's dynamics; defaults are
    what biostudy computed before these choices existed (a default leaves a finished case's identity as it was)."""

    consumption: Consumption = option(
        "first-order", "first-order: g phi c (keeps 0 <= c <= 1); zero-order: g phi, the paper's Eq. 35, with c "
                       "held >= 0")
    expansion: Expansion = option(
        "eq36", "eq36: d alpha/dt = k_alpha phi (paper Eq. 36: alpha grows wherever there is biofilm); table1: the "
                "local equation of the paper's algorithm (its Table 1), (alpha' - alpha)/(1 + alpha') = k_alpha "
                "(phi' - phi) per step: alpha changes only where phi changes (docs/model.md)")
    nutrient: NutrientDynamics = option(
        "quasi-steady", "quasi-steady: Eq. 35 without dc/dt, c in equilibrium with phi at every step (the paper's "
                        "time homogenisation, d large); transient: Eq. 35 with dc/dt, backward Euler with phi's "
                        "step, c = 0 at the start outside the sources (a slow nutrient; docs/model.md)")

    def __post_init__(self):
        for name, kind in (("consumption", Consumption), ("expansion", Expansion), ("nutrient", NutrientDynamics)):
            if getattr(self, name) not in get_args(kind):
                raise OptionError(name, f"unknown {name} law {getattr(self, name)!r}; use one of {get_args(kind)}")
