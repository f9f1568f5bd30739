"""A sampled posterior's part of calibration.nc (`reports.calibration`): the samples, their summaries, the
surrogate's box and error, the predictive band and the sampler's diagnostics."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..fitting.sampling import quantiles
from .parameter_units import MIXED, clock_of, scalar_variables

if TYPE_CHECKING:
    from ..fitting.posterior import Posterior
    from ..plans.calibration import CalibrationPlan


def posterior_variables(plan: CalibrationPlan, sampled: Posterior, units: list[str]) -> tuple[dict, dict, dict]:
    """The posterior's part of calibration.nc: the samples (dimension `sample`, one variable per parameter), the
    summaries per parameter, the surrogate's error and the predictive band per measurement, the sampler's
    diagnostics."""
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
