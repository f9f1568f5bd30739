"""Noise parameters of a measurement table: a `noiseParameters` cell that names σ instead of giving it.

PEtab lets `noiseParameters` name a parameter (`sigma_biomass`); here every row naming the same one shares one
σ, estimated by maximum likelihood with the model's parameters (`fitting.likelihood`).  A group must be one
quantity: its rows' observables have the same units, or it is refused (σ in µm for one row, µm² for another is
no σ); it needs at least 2 rows (one row's residual is fitted by its own σ, and σ̂ → 0 makes the likelihood
unbounded); its name is not an estimated parameter's.  A method that takes σ as given (`Method.estimates_sigma`
false: the posterior's surrogate likelihood) with an estimated σ is refused before anything runs.

The residual of a group's row is (model - measurement) / `NoiseParameter.scale`: a fixed number in the
measurements' units (their root mean square, 1 if they are all 0) that keeps the residuals near 1 whatever the
units; what is fitted and reported does not depend on it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BadInput
from ..fitting.likelihood import Likelihood
from ..quantities import observables
from .measurements import Measurement
from .methods import METHODS, Method

MINIMUM_ROWS = 2


@dataclass(frozen=True)
class NoiseParameter:
    """One estimated σ: its name, its rows (indices into the table), its units (udunits) and the scale its rows'
    residuals are divided by."""

    name: str
    rows: tuple[int, ...]
    units: str
    scale: float


def groups(rows: list[Measurement]) -> dict[str, list[int]]:
    """Each noise parameter the table names and its rows (indices), in the order first named: one pass over the
    table (64,000 rows of as many names were validated in 97 s scanning the table per name, issue 39.11)."""
    found: dict[str, list[int]] = {}
    for i, m in enumerate(rows):
        if m.noise:
            found.setdefault(m.noise, []).append(i)
    return found


def noise_parameters(rows: list[Measurement]) -> list[NoiseParameter]:
    """The noise parameters the table names, in the order first named (rows checked by `noise_problems`)."""
    found = []
    for name, at in groups(rows).items():
        values = np.array([rows[i].value for i in at])
        rms = math.sqrt(float(np.mean(np.square(values))))
        found.append(NoiseParameter(name, tuple(at), _units(rows[at[0]]), rms if rms > 0 else 1.0))
    return found


def _units(m: Measurement) -> str:
    try:
        return observables.get(m.observable).units
    except ValueError:  # an unknown observable: refused on its own
        return ""


def noise_problems(rows: list[Measurement], method: type[Method], parameters: list[str], data_file: Path,
                   path: Path) -> list[BadInput]:
    """Why the table's noise parameters cannot be estimated, one `BadInput` each: a group of one row, a group of
    different units, a name that is an estimated parameter's, a method that takes σ as given."""
    problems = []
    for name, at in groups(rows).items():
        group = [rows[i] for i in at]
        if len(group) < MINIMUM_ROWS:
            problems.append(BadInput(f"{name} names the σ of this row alone: σ cannot be estimated from one row "
                                     "(name it on more rows, or give σ as a number)", data_file,
                                     f"line {group[0].line}: noiseParameters"))
        units = {_units(m): m for m in group if _units(m)}
        if len(units) > 1:
            (a, first), (b, other) = list(units.items())[:2]
            problems.append(BadInput(f"{name} is the σ of rows in different units: {first.observable} in {a} "
                                     f"(line {first.line}) and {other.observable} in {b}: one σ is one quantity "
                                     "(give each its own name)", data_file, f"line {other.line}: noiseParameters"))
        if name in parameters:
            problems.append(BadInput(f"{name} is an estimated parameter of the scene, not a noise parameter (give "
                                     "σ its own name)", data_file, f"line {group[0].line}: noiseParameters"))
    named = next((m for m in rows if m.noise), None)
    if named is not None and not method.estimates_sigma:
        others = " or ".join(f'name = "{m.name}"' for m in METHODS.values() if m.estimates_sigma)
        problems.append(BadInput(f"\"{method.name}\" takes σ as given, and {data_file.name} names σ to estimate "
                                 f"({named.noise}, line {named.line}): give σ as numbers, or use {others}", path,
                                 "method.name"))
    return problems


def divisors(rows: list[Measurement], noise: list[NoiseParameter]) -> np.ndarray:
    """Per row what its residual is divided by: its σ, or its noise parameter's scale where σ is estimated."""
    divisor = np.array([m.sigma for m in rows], dtype=float)
    for parameter in noise:
        divisor[list(parameter.rows)] = parameter.scale
    return divisor


def likelihood(noise: list[NoiseParameter]) -> Likelihood:
    """What the fit minimises (`fitting.likelihood`): chi², or -2 log L with these σs profiled out."""
    return Likelihood(tuple(np.array(p.rows) for p in noise), tuple(p.scale for p in noise))
