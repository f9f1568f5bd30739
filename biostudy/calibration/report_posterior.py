"""A sampled posterior's part of calibration.nc and calibration.md (`report`): the samples, their summaries, the
surrogate's box and error, the predictive band and the sampler's diagnostics."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..fitting.sampling import quantiles
from ..formatting import number
from .units import MIXED, clock_of, real_rows, scalar_variables, shown

if TYPE_CHECKING:
    from ..fitting.posterior import Posterior


def posterior_variables(plan: Any, sampled: Posterior, units: list[str]) -> tuple[dict, dict, dict]:
    """The posterior's part of calibration.nc (`plan`: the `problem.CalibrationPlan`): the samples (dimension
    `sample`, one variable per parameter), the summaries per parameter, the surrogate's error and the predictive
    band per measurement, the sampler's diagnostics."""
    params = plan.parameters
    measured = np.array([m.value for m in plan.measurements])
    sigma = np.array([m.sigma for m in plan.measurements])
    chains = sampled.chains
    values = np.stack([p.range.values(chains.samples[:, j]) for j, p in enumerate(params)], axis=1)
    median, low, high = quantiles(values)
    each = MIXED
    mapped = {"units": "1", "comment": "each in its observable's units: see measurement_units"}
    data = {f"posterior_{p.name}": ("sample", values[:, j], {"units": units[j], "long_name": f"posterior sample "
                                                              f"of {p.name} ({p.key})"}) for j, p in enumerate(params)}
    error = sampled.held.error
    data.update({
        "posterior_median": ("parameter", median, {**each, "long_name": "posterior median"}),
        "posterior_lower": ("parameter", low, {**each, "long_name": "posterior 2.5 % quantile"}),
        "posterior_upper": ("parameter", high, {**each, "long_name": "posterior 97.5 % quantile"}),
        "autocorrelation_time": ("parameter", chains.autocorrelation,
                                 {"units": "1", "long_name": "integrated autocorrelation time, in steps"}),
        "effective_samples": ("parameter", chains.effective, {"units": "1", "long_name": "effective sample size"}),
        "surrogate_low": ("parameter", np.array([p.value(u) for p, u in zip(params, sampled.low)]),
                          {**each, "long_name": "lower edge of the surrogate's box"}),
        "surrogate_high": ("parameter", np.array([p.value(u) for p, u in zip(params, sampled.high)]),
                           {**each, "long_name": "upper edge of the surrogate's box"}),
        "surrogate_error": ("measurement", error, {"units": "1", "long_name": "root-mean-square error of the "
                                                   "surrogate on held-out simulations, in units of sigma"}),
        "sigma_likelihood": ("measurement", sigma * np.sqrt(1.0 + sampled.inflation),
                             {**mapped, "long_name": "standard deviation in the posterior's likelihood: sigma with "
                                                     "the surrogate's error added in quadrature"}),
        "posterior_band_lower": ("measurement", measured + sigma * sampled.band[0],
                                 {**mapped, "long_name": "2.5 % quantile of the model over the posterior samples "
                                                         "(surrogate)"}),
        "posterior_band_upper": ("measurement", measured + sigma * sampled.band[1],
                                 {**mapped, "long_name": "97.5 % quantile of the model over the posterior samples "
                                                         "(surrogate)"}),
    })
    data.update(scalar_variables([p.name for p in params], [p.key for p in params], {
        "median": (median, "posterior median"), "credible_lower": (low, "posterior 2.5 % quantile"),
        "credible_upper": (high, "posterior 97.5 % quantile")}, clock_of(plan)))
    coords = {"sample": ("sample", np.arange(len(values)), {"units": "1", "long_name": "posterior sample"})}
    attrs = {
        "posterior_samples": len(values), "posterior_walkers": chains.walkers, "posterior_steps": chains.steps,
        "posterior_burn_in": chains.burn, "posterior_thin": chains.thin,
        "acceptance_fraction": chains.acceptance, "posterior_converged": int(chains.converged),
        "surrogate_training_runs": sampled.trained_on, "surrogate_training_from_fit": sampled.from_fit,
        "surrogate_design_runs": sampled.designed, "surrogate_box_widened": sampled.widened,
        "surrogate_held_out_runs": sampled.held.count, "surrogate_failed_runs": sampled.failed,
        "surrogate_error_max": float(np.nanmax(error)) if np.isfinite(error).any() else float("nan"),
        "posterior_statements": "; ".join(sampled.verdicts),
    }
    return data, coords, attrs


def posterior_text(ds) -> list[str]:
    """calibration.md's lines of a sampled posterior (none without one): the medians and credible intervals, the
    sampler's and the surrogate's counts, rates in real time, and what the posterior says in words."""
    if "posterior_median" not in ds:
        return []
    attrs = ds.attrs
    lines = ["", "| parameter | posterior median | 95 % credible interval (2.5-97.5 %) | autocorrelation "
                 "time (steps) | effective samples |", "|---|---|---|---|---|"]
    for j, name in enumerate(ds.parameter.values):
        unit = shown(ds, j)
        lines.append(f"| {name} | {number(ds.posterior_median[j])} {unit} | [{number(ds.posterior_lower[j])}, "
                     f"{number(ds.posterior_upper[j])}] | {number(ds.autocorrelation_time[j], 3)} | "
                     f"{number(ds.effective_samples[j], 3)} |")
    lines += ["", f"posterior: {attrs['posterior_samples']} samples of {attrs['posterior_walkers']} walkers x "
                  f"{attrs['posterior_steps']} steps (burn-in {attrs['posterior_burn_in']}, thinned by "
                  f"{attrs['posterior_thin']}), acceptance fraction {number(attrs['acceptance_fraction'], 2)}; "
                  f"surrogate trained on {attrs['surrogate_training_runs']} simulations "
                  f"({attrs['surrogate_training_from_fit']} of them the fit's; its box widened "
                  f"{attrs['surrogate_box_widened']} times), its error on "
                  f"{attrs['surrogate_held_out_runs']} held-out ones up to "
                  f"{number(attrs['surrogate_error_max'], 2)} sigma (added to sigma² in the likelihood)"]
    lines += real_rows(ds, ("median", "credible_lower", "credible_upper"), "posterior median",
                       "95 % credible interval")
    for said in filter(None, str(attrs.get("posterior_statements", "")).split("; ")):
        lines += ["", f"**{said[0].upper() + said[1:]}.**"]
    return lines
