"""Estimated σs in calibration.nc and its table (`report`): the noise parameters a measurement table
names (`noise`), their maximum-likelihood values and 95 % profile intervals
(`fitting.likelihood`).

calibration.nc gains the dimension `noise_parameter` (its names; `noise_units`, udunits of its measurements) with
`noise_estimate`, `noise_lower`, `noise_upper` (in those units: the variable's `units` when they are one, else none
and the coordinate says) and `noise_rows`; per measurement `noise_name` (the noise parameter, '' where σ is given)
and, in `sigma`, σ̂ of its noise parameter.  Without an estimated σ nothing is added.  With any σ estimated the fit's
`chi2` is -2 log L with σ profiled out, up to a constant (the attribute `objective` says so), and no p-value is
given: σ̂ is made to fit its rows' residuals, so their chi² is their count whatever the model does.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..fitting.likelihood import coverage
from ..formatting import number, units_text
from .units import MIXED

if TYPE_CHECKING:
    from ..fitting.estimate import Estimate
    from .problem import CalibrationPlan

SHORT = 0.93  # intervals holding the truth less often than this (with a linear model) are said to be short
LOG_LIKELIHOOD = "-2 log L"  # calibration.nc's `objective` with an estimated σ (without: absent, chi2 is chi²)


def sigma_used(plan: CalibrationPlan, found: Estimate) -> np.ndarray:
    """Per measurement the σ the fit weighed it with: the table's, or its noise parameter's σ̂."""
    sigma = np.array([m.sigma for m in plan.measurements], dtype=float)
    for parameter, estimated in zip(plan.noise, found.sigmas):
        sigma[list(parameter.rows)] = estimated.estimate
    return sigma


def noise_variables(plan: CalibrationPlan, found: Estimate) -> tuple[dict, dict, dict]:
    """calibration.nc's part of the estimated σs: variables, coordinates, attributes (module docstring)."""
    if not plan.noise:  # calibration.nc as before σ could be estimated
        return {}, {}, {}
    names = [m.noise for m in plan.measurements]
    data: dict = {"noise_name": ("measurement", np.array(names, dtype=object),
                                 {"units": "1", "long_name": "noiseParameters: the noise parameter whose σ was "
                                                             "estimated (sigma holds it; '' where the table gives σ)"})}
    attrs = {"objective": LOG_LIKELIHOOD, "noise_statements": "; ".join(_exact(plan, found) + _few(plan, found)),
             "noise_method": "σ named in noiseParameters: maximum likelihood, profiled out of -2 log L (chi2 holds "
                             "it); σ's 95 % interval: its profile, the parameters re-optimised on the model "
                             "linearised at the estimate (docs/calibration.md)"}
    units = [p.units for p in plan.noise]
    each = {"units": units[0]} if len(set(units)) == 1 else MIXED
    ends = {"noise_estimate": ("estimate", "σ of the measurements naming it: maximum likelihood"),
            "noise_lower": ("lower", "σ: lower end of its 95 % profile-likelihood interval"),
            "noise_upper": ("upper", "σ: upper end of its 95 % profile-likelihood interval")}
    for variable, (field, what) in ends.items():
        data[variable] = ("noise_parameter", np.array([getattr(s, field) for s in found.sigmas]),
                          {**each, "long_name": what})
    data["noise_rows"] = ("noise_parameter", np.array([s.rows for s in found.sigmas], dtype=np.int32),
                          {"units": "1", "long_name": "measurements sharing the σ"})
    coords = {"noise_parameter": ("noise_parameter", np.array([p.name for p in plan.noise], dtype=object),
                                  {"units": "1", "long_name": "noise parameter (noiseParameters)"}),
              "noise_units": ("noise_parameter", np.array(units, dtype=object),
                              {"units": "1", "long_name": "units of the σ (its measurements', udunits)"})}
    return data, coords, attrs


def _exact(plan: CalibrationPlan, found: Estimate) -> list[str]:
    """Words for a σ whose rows the model fits exactly (σ̂ = 0, `fitting.likelihood.Likelihood.exact`): it cannot
    be estimated; whether the parameters' estimate depends on those rows (their Jacobian at the optimum)."""
    said = []
    for parameter, sigma in zip(plan.noise, found.sigmas):
        if not sigma.exact:
            continue
        moved = bool(np.any(found.best.jacobian[list(parameter.rows)]))
        consequence = ("the fit is drawn to where the model goes through them, so its estimate and intervals mean "
                       "nothing until their σ is given" if moved else "they do not move with the parameters, so "
                       "the estimate and intervals are those of the other rows")
        said.append(f"the model fits the {sigma.rows} measurements of {parameter.name} exactly (σ̂ = 0): their σ "
                    f"cannot be estimated (the likelihood grows without bound as σ shrinks) and has no interval, "
                    f"and {consequence} (give their σ as a number in noiseParameters: the error you expect of "
                    "them)")  # no '; ': it joins statements
    return said


def _few(plan: CalibrationPlan, found: Estimate) -> list[str]:
    """Words for a σ estimated from so few rows that the 95 % intervals are short (`likelihood.coverage`)."""
    said, k = [], len(plan.parameters)
    for parameter, sigma in zip(plan.noise, found.sigmas):
        n = len(parameter.rows)
        if sigma.exact:  # said by `_exact`
            continue
        held, sigma = coverage(n, k)
        if not held >= SHORT:
            often = (f"hold the truth {held * 100:.0f} % of the time, σ's {sigma * 100:.0f} %" if held == held else
                     "mean nothing: there is no degree of freedom left")
            said.append(f"the noise parameter {parameter.name} is estimated from {n} measurements for {k} parameter"
                        f"{'s' if k != 1 else ''}: with so few the 95 % intervals are short (with a model linear in "
                        f"its parameters they would {often}: docs/calibration.md)")  # no '; ': it joins statements
    return said


def estimated(ds) -> bool:
    """Whether calibration.nc's fit estimated a σ (then its chi2 is -2 log L)."""
    return ds.attrs.get("objective") == LOG_LIKELIHOOD


def noise_text(ds) -> list[str]:
    """calibration.md's lines of the estimated σs: a table, and why there is no p-value."""
    if "noise_parameter" not in ds.coords:
        return []
    lines = ["", "| noise parameter | σ (maximum likelihood) | 95 % profile interval | measurements |",
             "|---|---|---|---|"]
    for j, name in enumerate(ds.noise_parameter.values):
        unit = units_text(str(ds.noise_units.values[j]))
        lines.append(f"| {name} | {number(ds.noise_estimate[j])} {unit} | [{number(ds.noise_lower[j])}, "
                     f"{number(ds.noise_upper[j])}] | {int(ds.noise_rows[j])} |")
    for said in filter(None, str(ds.attrs.get("noise_statements", "")).split("; ")):
        lines += ["", f"**{said[0].upper() + said[1:]}.**"]
    return lines


def fit_line(ds) -> str:
    """How well the model fits, in words that hold when σ is estimated: -2 log L, no p-value."""
    attrs = ds.attrs
    rows = int(np.sum(ds.noise_name.values != ""))
    return (f"-2 log L = {number(attrs['chi2'], 4)} (up to a constant; σ estimated for {rows} of the "
            f"{ds.sizes['measurement']} measurements, so chi² and its p-value are not given: σ̂ is fitted to "
            "those rows' residuals and makes their chi² equal to their count whatever the model does)")
