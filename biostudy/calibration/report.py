"""What a calibration found, as DIR/calibration.nc and its table (calibration.md, printed too).

calibration.nc (docs/calibrate.md):

* dimension `parameter` (names: g, r, r[half]): `estimate`, `standard_error`
  (from the Jacobian at the optimum, to first order in the parameter's units),
  `lower`, `upper` (the 95 % profile interval), `identifiable` (bool), the
  bounds `low`, `high`, the fit's scale (`scale`: linear or log; `estimate_scaled`,
  `standard_error_scaled` in log10 units for a log parameter), the scene `key`,
  `units` per parameter; `correlation` (parameter, parameter_other);
* the profiles: `profile_value`, `profile_chi2` (parameter, profile_point), NaN-padded;
* dimension `measurement` (the table's rows, in order): `observable`, `condition`,
  `time` (T*), `time_measured` (the table's own unit), `measured`, `sigma`,
  `fitted`, `band_lower`, `band_upper` (the 95 % band of the fitted model from
  the Jacobian's covariance), `residual`; `measurement_units`; PEtab's `dataset`,
  `replicate`, `datapoint` (`petab`: text, empty where the table has none);
* dimension `start`: where each start began and ended, its chi², whether it was
  stopped because it joined another;
* attributes: chi2, dof, chi2_minimum (profiles included), simulations run and
  reused, rounds, wall time and where it went, the statements of `statements`,
  the table's PEtab columns (`measurement_columns`);
* a posterior (`posterior_variables`): dimension `sample` with `posterior_<name>`
  per parameter; per parameter `posterior_median`, `posterior_lower`,
  `posterior_upper` (2.5 %, 97.5 %), `autocorrelation_time`, `effective_samples`,
  the surrogate's box; per measurement `surrogate_error` (held out, units of
  sigma), `sigma_likelihood`, `posterior_band_lower`, `posterior_band_upper`;
  the sampler's and the surrogate's counts and `posterior_statements` as attributes;
* estimated σs (`noise_variables`): dimension `noise_parameter`, `noise_name` per
  measurement, `sigma` σ̂ there; then chi2 is -2 log L (`objective`), no p-value.

Values of different observables have different units: each such variable's
`units` is "1" and `measurement_units` says each one's.  Parameters: see
`units` (no units on the mixed variables; `units`, `units_model`
coordinates; ``estimate_r`` etc. per parameter, ``estimate_r_real`` per hour
with a t_ref).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr
from scipy.stats import chi2 as chi2_distribution

from solver.output import cf_units

from ..data import provenance
from ..errors import Failed
from ..fitting.least_squares import PENALTY
from ..fitting.profiles import THRESHOLD
from ..fitting.uncertainty import band, natural
from ..formatting import number
from ..inputs.scene import key_info
from ..quantities import alerts, observables
from .methods import chosen
from .petab import datasets_text, id_variables
from .report_noise import estimated, fit_line, noise_text, noise_variables, sigma_used
from .report_posterior import posterior_text
from .units import MIXED, clock_of, model_units, real_rows, scalar_variables, shown

if TYPE_CHECKING:
    from ..fitting.estimate import Estimate
    from .methods import Result
    from .problem import CalibrationPlan

TEXT = {"units": "1"}
LOWER = 0.5  # a profile point this much below the fit's chi² means the starts missed a lower minimum


def _text(values) -> np.ndarray:
    return np.array([str(v) for v in values], dtype=object)


def statements(plan: CalibrationPlan, found: Estimate) -> list[str]:
    """Plain words for what the profiles say: which parameters the data do not determine, and how far."""
    said = []
    for p, prof in zip(plan.parameters, found.profiles):
        if prof.identifiable:
            continue
        low, high = p.value(prof.lower), p.value(prof.upper)
        if prof.open_below and prof.open_above:
            where = f"anywhere in its bounds [{number(low)}, {number(high)}]"
        elif prof.open_above:
            where = f"from {number(low)} up to its upper bound {number(high)}"
        else:
            where = f"from its lower bound {number(low)} up to {number(high)}"
        said.append(f"the data do not determine {p.name}: its profile stays within {THRESHOLD:.2f} of the smallest "
                    f"chi² {where}")
    if found.starts_chi2 is not None:
        said.append(f"the profiles found chi² = {found.best.chi2:.4g}, below the {found.starts_chi2:.4g} where the "
                    "starts ended (on a flat stretch of chi²): the estimate is from a fit repeated from there")
    if found.profiles and found.minimum < found.best.chi2 - LOWER:
        said.append(f"a profile found chi² = {found.minimum:.4g}, below the fit's {found.best.chi2:.4g}: the "
                    "intervals are against the lower one (more starts may find it: [method] starts)")
    return said


def _too_few(n: int, k: int) -> list[str]:
    """Words for a fit with no degrees of freedom left (n measurements, k parameters)."""
    rows = f"{n} measurement{'s' if n != 1 else ''} for {k} parameter{'s' if k != 1 else ''}"
    if n < k:
        return [f"{rows}: the data cannot determine them all, and chi² says nothing of how well the model fits"]
    if n == k:
        return [f"{rows}: no degree of freedom is left, so chi² says nothing of how well the model fits"]
    return []


def _no_fit(plan: CalibrationPlan, model: np.ndarray, failed: dict[str, str]) -> str:
    """Why the best fit is no better than failed simulations: they all failed, or the model, finished, lies
    so many σ from the data that σ is likely in another unit."""
    if np.isnan(model).any() or not len(model):
        return (f"every evaluation of the calibration failed (e.g. {next(iter(failed.values()), '')}); the case "
                "files under cases/ say why")
    rows = plan.measurements
    residual = (model - np.array([m.value for m in rows])) / np.array([m.sigma for m in rows])
    i = int(np.nanargmax(np.abs(residual)))  # a row whose σ is estimated (NaN) is no evidence of a unit
    m = rows[i]
    return (f"the best fit lies {abs(residual[i]):.3g} σ from the measurement of line {m.line} ({m.observable} "
            f"{number(m.value)} ± {number(m.sigma)}, the model {number(model[i])}), though its simulations "
            f"finished: is σ (noiseParameters) in the measurement's units?")


def _parameter_variables(plan: CalibrationPlan, found: Estimate) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
    """Per parameter: the estimate, its standard error, the profile interval, identifiability, bounds, scale,
    key, correlations and the profiles; also the estimate, lower and upper ends as arrays."""
    params = plan.parameters
    k = len(params)
    each = MIXED
    estimate = np.array([p.value(u) for p, u in zip(params, found.best.x)])
    scaled = np.array([math.log10(v) if p.log else v for p, v in zip(params, estimate)])
    errors = [natural(float(e), p.range.low, p.range.high, p.log, v)
              for p, e, v in zip(params, found.local.standard_error, estimate)]
    profiled = bool(found.profiles)
    lower = np.array([p.value(prof.lower) for p, prof in zip(params, found.profiles)]) if profiled \
        else np.full(k, np.nan)
    upper = np.array([p.value(prof.upper) for p, prof in zip(params, found.profiles)]) if profiled \
        else np.full(k, np.nan)
    identifiable = np.array([prof.identifiable for prof in found.profiles]) if profiled \
        else np.isfinite(found.local.standard_error)
    length = max((len(prof.u) for prof in found.profiles), default=1)
    profile_value = np.full((k, length), np.nan)
    profile_chi2 = np.full((k, length), np.nan)
    for j, (p, prof) in enumerate(zip(params, found.profiles)):
        profile_value[j, :len(prof.u)] = [p.value(u) for u in prof.u]
        profile_chi2[j, :len(prof.u)] = prof.chi2
    data = {
        "estimate": ("parameter", estimate, {**each, "long_name": "estimated value (least squares)"}),
        "standard_error": ("parameter", np.array([e[1] for e in errors]),
                           {**each, "long_name": "standard error from the Jacobian at the optimum (first order)"}),
        "lower": ("parameter", lower, {**each, "long_name": "lower end of the 95 % profile-likelihood interval"}),
        "upper": ("parameter", upper, {**each, "long_name": "upper end of the 95 % profile-likelihood interval"}),
        "identifiable": ("parameter", identifiable.astype(bool),
                         {"long_name": "the data determine the parameter: its profile crosses the 95 % threshold on "
                                       "both sides inside the bounds"}),
        "estimate_scaled": ("parameter", scaled, {"units": "1", "long_name": "estimate on the fit's scale (log10 of "
                                                                            "the value for a log parameter)"}),
        "standard_error_scaled": ("parameter", np.array([e[0] for e in errors]),
                                  {"units": "1", "long_name": "standard error on the fit's scale (log10 units for a "
                                                              "log parameter)"}),
        "low": ("parameter", np.array([p.range.low for p in params]), {**each, "long_name": "lower bound"}),
        "high": ("parameter", np.array([p.range.high for p in params]), {**each, "long_name": "upper bound"}),
        "scale": ("parameter", _text(p.range.scale for p in params), {**TEXT, "long_name": "scale of the fit"}),
        "key": ("parameter", _text(p.key for p in params), {**TEXT, "long_name": "scene key"}),
        "conditions": ("parameter", _text(", ".join(p.conditions) for p in params),
                       {**TEXT, "long_name": "conditions the parameter applies to"}),
        "correlation": (("parameter", "parameter_other"), found.local.correlation,
                        {"units": "1", "long_name": "correlation of the estimates (Jacobian at the optimum)"}),
        "profile_value": (("parameter", "profile_point"), profile_value,
                          {**each, "long_name": "profiled parameter value"}),
        "profile_chi2": (("parameter", "profile_point"), profile_chi2,
                         {"units": "1", "long_name": "chi² with the other parameters re-optimised"}),
    }
    return data, estimate, lower, upper


def _measurement_variables(plan: CalibrationPlan, found: Estimate, model: np.ndarray) -> dict:
    """Per row of the table: what was measured, its sigma, the fitted model, its band and the residual."""
    rows = plan.measurements
    measured = np.array([m.value for m in rows])
    sigma = sigma_used(plan, found)
    half = band(found.best.jacobian, found.local.covariance, sigma)
    mapped = {"units": "1", "comment": "each in its observable's units: see measurement_units"}
    return {
        "observable": ("measurement", _text(m.observable for m in rows), {**TEXT, "long_name": "observableId"}),
        "condition": ("measurement", _text(m.condition for m in rows),
                      {**TEXT, "long_name": "simulationConditionId"}),
        "line": ("measurement", np.array([m.line for m in rows], dtype=np.int32),
                 {"units": "1", "long_name": "line of the measurement table"}),
        "time_measured": ("measurement", np.array([m.time for m in rows]),
                          {"units": cf_time(plan.spec.data.time_unit), "long_name": "time of the measurement, "
                                                                                   "as the table gives it"}),
        "measured": ("measurement", measured, {**mapped, "long_name": "measurement"}),
        "sigma": ("measurement", sigma, {**mapped, "long_name": "standard deviation of the measurement "
                                                                "(noiseParameters)"}),
        "fitted": ("measurement", model, {**mapped, "long_name": "model at the estimate"}),
        "band_lower": ("measurement", model - half, {**mapped, "long_name": "lower end of the 95 % band of the "
                                                                           "fitted model (Jacobian covariance)"}),
        "band_upper": ("measurement", model + half, {**mapped, "long_name": "upper end of the 95 % band of the "
                                                                           "fitted model (Jacobian covariance)"}),
        "residual": ("measurement", np.divide(model - measured, sigma, out=np.full(len(rows), np.nan),
                                              where=sigma > 0),
                     {"units": "1", "long_name": "weighted residual (fitted - measured) / sigma (NaN where an "
                                                 "estimated sigma is 0: the model fits its rows exactly)"}),
    }


def _start_variables(plan: CalibrationPlan, result: Result) -> dict:
    """Per start of the optimiser: where it began and ended, its chi², whether it joined another."""
    params, fits = plan.parameters, result.estimate.fits
    return {
        "start_point": (("start", "parameter"), np.array([[p.value(u) for p, u in zip(params, s)]
                                                          for s in result.starts]),
                        {**MIXED, "long_name": "where the start began"}),
        "start_end": (("start", "parameter"), np.array([[p.value(u) for p, u in zip(params, f.x)] if f is not None
                                                        else [np.nan] * len(params) for f in fits]),
                      {**MIXED, "long_name": "where the start ended"}),
        "start_chi2": ("start", np.array([f.chi2 if f is not None else np.nan for f in fits]),
                       {"units": "1", "long_name": "chi² where the start ended"}),
        "start_stopped": ("start", np.array([f is None or f.stopped for f in fits]),
                          {"long_name": "stopped early: it joined another start"}),
    }


def _coordinates(plan: CalibrationPlan, result: Result, units: list[str], length: int) -> dict:
    params, rows = plan.parameters, plan.measurements
    names = [p.name for p in params]
    return {
        "parameter": ("parameter", _text(names), {**TEXT, "long_name": "estimated parameter"}),
        "parameter_other": ("parameter_other", _text(names), {**TEXT, "long_name": "estimated parameter"}),
        "units": ("parameter", _text(units), {**TEXT, "long_name": "units of each parameter (udunits)"}),
        "units_model": ("parameter", _text(model_units(p.key) for p in params),
                        {**TEXT, "long_name": "units of each parameter in the model's terms (per T*)"}),
        "measurement": ("measurement", np.arange(len(rows)), {"units": "1", "long_name": "row of the measurement "
                                                                                          "table"}),
        "time": ("measurement", plan.times, {"units": "1", "long_name": "normalised time T* of the measurement"}),
        "measurement_units": ("measurement", _text(observables.get(m.observable).units for m in rows),
                              {**TEXT, "long_name": "units of each measurement (udunits)"}),
        "start": ("start", np.arange(len(result.starts)), {"units": "1", "long_name": "start of the optimiser"}),
        "profile_point": ("profile_point", np.arange(length), {"units": "1", "long_name": "point of a profile"}),
    }


def _attributes(plan: CalibrationPlan, found: Estimate, cost: dict, failed: dict[str, str],
                raised: dict[str, dict[str, str]]) -> dict:
    """chi² and what it says, what the calibration cost, its statements, and where its inputs are."""
    params = plan.parameters
    n, k = len(plan.measurements), len(params)
    dof = n - k - len(plan.noise)
    profiled = bool(found.profiles)
    clock = clock_of(plan)
    return {
        "Conventions": "CF-1.10",
        "title": f"calibration: {plan.spec.name}",
        "method": "weighted least squares (Levenberg-Marquardt, bounded), multi-start, finite-difference Jacobian"
                  + (", profile likelihoods (95 %: chi² + 3.84)" if profiled else ""),
        "chi2": found.best.chi2, "dof": dof,
        "chi2_p_value": float(chi2_distribution.sf(found.best.chi2, dof)) if dof > 0 and not plan.noise
        else float("nan"),
        "chi2_minimum": found.minimum,
        "profiles": int(profiled),
        **cost,
        "simulations_failed": len(failed),
        "finite_difference_steps": ", ".join(f"{p.name} {s:.3g}" for p, s in zip(params, found.best.steps)),
        "statements": "; ".join((statements(plan, found) if profiled else []) + _too_few(n, k)),
        **{name: ", ".join(sorted(raised.get(name, {}))) for name in alerts.ATTRIBUTES},  # the simulations' ids
        "calibration": plan.file.read_text(encoding="utf-8"),
        "calibration_file": str(plan.file.resolve()),
        "measurements_file": str(plan.data_file.resolve()),
        "scene": plan.base.to_toml(),
        "scene_file": str(plan.scene_file.resolve()),
        "time_unit": plan.spec.data.time_unit or "T*",
        "t_ref": clock.text if clock else "1 T*",
    }


def dataset(plan: CalibrationPlan, result: Result, model: np.ndarray, cost: dict, failed: dict[str, str],
            raised: dict[str, dict[str, str]]) -> xr.Dataset:
    """calibration.nc's contents (module docstring) from the method's `result`: `model` at the estimate per
    measurement, `cost` the counts and times (simulations, simulations_reused, rounds, wall_time, ...), `failed`
    the failed simulations (id -> why), `raised` the simulations `quantities.alerts` spoke of (attribute -> id ->
    sentence)."""
    found = result.estimate
    if found.best.chi2 >= len(model) * PENALTY**2:
        raise Failed(_no_fit(plan, model, failed))
    params = plan.parameters
    units = [cf_units(key_info(p.key)[1]) for p in params]
    data, estimate, lower, upper = _parameter_variables(plan, found)
    data.update(_measurement_variables(plan, found, model))
    data.update(_start_variables(plan, result))
    ids, columns = id_variables(plan)
    data.update(ids)
    data.update(scalar_variables([p.name for p in params], [p.key for p in params], {
        "estimate": (estimate, "estimated value"), "lower": (lower, "lower end of the 95 % profile interval"),
        "upper": (upper, "upper end of the 95 % profile interval")}, clock_of(plan)))
    coords = _coordinates(plan, result, units, data["profile_value"][1].shape[1])
    attrs = {**_attributes(plan, found, cost, failed, raised), **columns}
    method = chosen(plan.spec.method)  # what the method adds (`methods.Method.variables`)
    for part, extra in zip((data, coords, attrs), method.variables(plan, result, units)):
        part.update(extra)
    attrs["method"] += method.described()
    for part, noise in zip((data, coords, attrs), noise_variables(plan, found)):
        part.update(noise)
    return xr.Dataset(data, coords=coords, attrs=provenance.with_provenance(attrs))


def cf_time(unit: str | None) -> str:
    """A unit of time as udunits spells the common ones (pint's own spelling otherwise); T* is '1'."""
    if unit is None:
        return "1"
    return {"h": "h", "hour": "h", "hours": "h", "min": "min", "minute": "min", "minutes": "min", "s": "s",
            "d": "d", "day": "d", "days": "d"}.get(unit.strip(), unit.strip())


def _interval(ds: xr.Dataset, j: int) -> str:
    lower, upper = float(ds.lower[j]), float(ds.upper[j])
    if math.isnan(lower):
        return "-"
    ends = [number(lower), number(upper)]
    if not bool(ds.identifiable[j]):
        if lower <= float(ds.low[j]):
            ends[0] += " (bound)"
        if upper >= float(ds.high[j]):
            ends[1] += " (bound)"
    return f"[{ends[0]}, {ends[1]}]"


def table_text(ds: xr.Dataset) -> str:
    """Markdown: the parameters, the fit's chi², the statements, the datasets and replicates, the correlations,
    what it cost."""
    lines = ["| parameter | estimate | standard error | 95 % profile interval | identifiable | bounds |",
             "|---|---|---|---|---|---|"]
    for j, name in enumerate(ds.parameter.values):
        unit = shown(ds, j)
        scaled = ""
        if str(ds.scale.values[j]) == "log":
            scaled = f" (log10 {number(ds.estimate_scaled[j], 4)} ± {number(ds.standard_error_scaled[j], 2)})"
        lines.append(f"| {name} | {number(ds.estimate[j])} {unit}{scaled} | {number(ds.standard_error[j], 2)} | "
                     f"{_interval(ds, j)} | {'yes' if bool(ds.identifiable[j]) else 'no'} | "
                     f"[{number(ds.low[j])}, {number(ds.high[j])}]{' log' if str(ds.scale.values[j]) == 'log' else ''}"
                     " |")
    lines += real_rows(ds) + noise_text(ds)
    attrs = ds.attrs
    lines += posterior_text(ds)
    fit = (f"for {attrs['dof']} degrees of freedom (p = {number(attrs['chi2_p_value'], 2)})" if attrs["dof"] > 0
           else "(no degree of freedom left)")
    fit = fit_line(ds) if estimated(ds) else f"chi² = {number(attrs['chi2'], 4)} {fit}"
    lines += ["", f"{fit}; {attrs['simulations']} simulations run, "
                  f"{attrs['simulations_reused']} reused, in {attrs['rounds']} rounds; wall time "
                  f"{number(attrs['wall_time'], 3)} s ({number(attrs['wall_time_simulations'], 3)} s in the rounds)"]
    for said in filter(None, str(attrs.get("statements", "")).split("; ")):
        lines += ["", f"**{said[0].upper() + said[1:]}.**"]
    lines += datasets_text(ds)
    if ds.sizes["parameter"] > 1:
        names = list(ds.parameter.values)
        lines += ["", "correlations (Jacobian at the optimum):", "", "| | " + " | ".join(names) + " |",
                  "|---|" + "---|" * len(names)]
        for j, name in enumerate(names):
            lines.append(f"| {name} | " + " | ".join(number(v, 2) for v in ds.correlation.values[j]) + " |")
    for alert in alerts.ALERTS:
        if attrs.get(alert.attribute):
            lines += ["", f"Simulations that {alert.runs}: {attrs[alert.attribute]}."]
    return "\n".join(lines) + "\n"
