"""Which parameter matters (`biostudy analyze DIR`): sensitivity of a study's observables to its parameters.

* A Sobol' design (`[sample] method = "sobol"`): first-order and total
  indices S1, ST (and second-order S2 when the design has the cross-samples)
  with bootstrap confidence intervals, by SALib's Saltelli/Jansen estimators.
* A Morris design: mu* (mean absolute elementary effect), mu and sigma, with
  a bootstrap interval of mu*; effects are per whole range (per decade span of
  a log range), so mu* of different parameters compare directly.
* Any design, grids and zips too: rank correlations as a quick screen,
  Spearman's rho and the partial rank correlation (PRCC: the correlation of
  the ranks of parameter and output once the ranks of the other parameters
  are regressed out), each with a Fisher-z interval (scipy.stats.pearsonr on
  the ranks).

Cases that failed or have not run are left out: a single case from the
rank correlations; a whole base sample from Sobol' indices (its 2k + 2 cases
form one estimate) and a whole trajectory from Morris.  What was left out,
and what that does to the indices, is written into the result's `notes`.
"""
from __future__ import annotations

import contextlib
import warnings

import numpy as np
import xarray as xr
from scipy import stats

from ..data.provenance import with_provenance
from ..formatting import number
from ..plans.designs import Sample
from ..quantities import observables
from .cases import Cases, cases_of
from .sensitivity_notes import complete_blocks, left_out, sobol_warning, undefined

CONFIDENCE = 0.95
RESAMPLES = 1000


def output_names(ds: xr.Dataset, flat: Cases, asked: list[str] | None) -> list[str]:
    """The outputs to analyse: as asked (a variable of study.nc or an observable), or every observable
    study.nc has with a finite value in some finished case."""
    if asked:
        for name in asked:
            if name not in ds.data_vars:
                observables.get(name)  # ValueError for an unknown name
        return list(asked)
    done = flat.status == "done"
    names = []
    for name in observables.REGISTRY:
        if name in ds.data_vars and np.isfinite(flat.values(ds[name])[done]).any():
            names.append(name)
    return names


def variable(ds: xr.Dataset, name: str) -> xr.DataArray:
    """A study.nc variable, or an observable computed from its fields; ValueError if it cannot be had."""
    if name in ds.data_vars:
        return ds[name]
    try:
        return observables.evaluate(ds, name)
    except ValueError as error:
        raise ValueError(f"cannot compute output {name!r} from study.nc ({error})") from None


def time_indices(ds: xr.Dataset, times: list[float] | None) -> list[int]:
    """Output indices nearest the asked times (default: the last output)."""
    if "time" not in ds.dims:
        return [0]
    available = ds["time"].values
    if not times:
        return [available.size - 1]
    slack = 1e-9 * max(1.0, abs(available[-1]))
    for t in times:
        if not available[0] - slack <= t <= available[-1] + slack:
            raise ValueError(f"--time {t:g} is outside the study's outputs (T* from {available[0]:g} to "
                             f"{available[-1]:g})")
    return sorted({int(np.argmin(np.abs(available - t))) for t in times})


# ---------------------------------------------------------------------------------------------
# The estimators (SALib, scipy.stats)


def rank_correlations(x: np.ndarray, y: np.ndarray, confidence: float = CONFIDENCE) -> dict[str, np.ndarray]:
    """Spearman's rho and PRCC of every column of x with y, each with a Fisher-z interval; NaN where too few."""
    n, k = x.shape
    out = {name: np.full(k, np.nan) for name in ("spearman", "spearman_low", "spearman_high", "prcc", "prcc_low",
                                                 "prcc_high")}
    if n < 4 or np.ptp(y) == 0:
        return out
    rx = np.column_stack([stats.rankdata(x[:, j]) for j in range(k)])
    ry = stats.rankdata(y)
    for j in range(k):
        if np.ptp(rx[:, j]) == 0:
            continue
        result = stats.pearsonr(rx[:, j], ry)  # Spearman's rho: Pearson's r of the ranks
        low, high = result.confidence_interval(confidence)
        out["spearman"][j], out["spearman_low"][j], out["spearman_high"][j] = result.statistic, low, high
        others = np.column_stack([np.ones(n), np.delete(rx, j, axis=1)])
        if n <= others.shape[1] + 2:
            continue
        residual_x = rx[:, j] - others @ np.linalg.lstsq(others, rx[:, j], rcond=None)[0]
        residual_y = ry - others @ np.linalg.lstsq(others, ry, rcond=None)[0]
        if np.ptp(residual_x) < 1e-12 * n or np.ptp(residual_y) < 1e-12 * n:
            continue
        result = stats.pearsonr(residual_x, residual_y)
        low, high = result.confidence_interval(confidence)
        out["prcc"][j], out["prcc_low"][j], out["prcc_high"][j] = result.statistic, low, high
    return out


@contextlib.contextmanager
def _quiet():
    """SALib's estimators on a constant or degenerate output divide by zero: NaN, not a screen of warnings."""
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        yield


def sobol_indices(design: Sample, y: np.ndarray, ok: np.ndarray, seed: int = 0,
                  confidence: float = CONFIDENCE, resamples: int = RESAMPLES) -> tuple[dict, int]:
    """S1, ST (S2) with intervals from the complete base samples; returns them and how many blocks were used."""
    from SALib.analyze import sobol

    rows, kept, _ = complete_blocks(design, ok)
    k = len(design.ranges)
    empty = {name: np.full(k, np.nan) for name in ("S1", "S1_conf", "ST", "ST_conf")}
    empty |= {name: np.full((k, k), np.nan) for name in ("S2", "S2_conf")}
    if kept < 2 or np.ptp(y[rows]) == 0:
        return empty, kept
    with _quiet():
        found = sobol.analyze(design.unit_problem(), y[rows], calc_second_order=design.with_second_order,
                              num_resamples=resamples, conf_level=confidence, seed=seed)
    result = {name: np.asarray(found[name], dtype=float) for name in ("S1", "S1_conf", "ST", "ST_conf")}
    for name in ("S2", "S2_conf"):
        result[name] = np.asarray(found[name], dtype=float) if name in found else empty[name]
    return result, kept


def morris_indices(design: Sample, unit: np.ndarray, y: np.ndarray, ok: np.ndarray, seed: int = 0,
                   confidence: float = CONFIDENCE, resamples: int = RESAMPLES) -> tuple[dict, int]:
    """mu*, its interval, mu and sigma from the complete trajectories; returns them and how many were used."""
    from SALib.analyze import morris

    rows, kept, _ = complete_blocks(design, ok)
    if kept < 2:
        return {name: np.full(len(design.ranges), np.nan) for name in ("mu_star", "mu_star_conf", "mu", "sigma")}, kept
    with _quiet():
        found = morris.analyze(design.unit_problem(), unit[rows], y[rows], num_resamples=resamples,
                               conf_level=confidence,
                               num_levels=design.morris_levels, seed=seed)
    return {name: np.asarray(found[name], dtype=float) for name in ("mu_star", "mu_star_conf", "mu", "sigma")}, kept


# ---------------------------------------------------------------------------------------------


def analyze(ds: xr.Dataset, outputs: list[str] | None = None, times: list[float] | None = None,
            confidence: float = CONFIDENCE, resamples: int = RESAMPLES) -> xr.Dataset:
    """analysis.nc of a study's combined dataset: dims output, parameter (and time if several)."""
    flat = cases_of(ds)
    names = output_names(ds, flat, outputs)
    if not names:
        raise ValueError("no output to analyse: no finished case has a finite observable yet")
    indices = time_indices(ds, times)
    params = list(flat.parameters)
    design = flat.design
    x = np.column_stack([flat.parameters[p] for p in params])
    unit = np.column_stack([flat.unit[p] for p in params]) if design is not None else None
    done = flat.status == "done"
    seed = design.seed if design is not None else 0
    shape = (len(indices), len(names))
    data: dict[str, np.ndarray] = {}

    def put(name: str, t: int, o: int, values: np.ndarray):
        if name not in data:
            data[name] = np.full((*shape, *np.shape(values)), np.nan)
        data[name][t, o] = values

    used = np.zeros(shape, dtype=int)
    blocks = np.zeros(shape, dtype=int)
    for o, name in enumerate(names):
        found = variable(ds, name)
        rows = flat.values(found)
        for t, index in enumerate(indices):
            y = rows[:, index] if rows.ndim == 2 else rows
            y = np.asarray(y, dtype=float)
            ok = done & np.isfinite(y)
            used[t, o] = int(ok.sum())
            for key, values in rank_correlations(x[ok], y[ok], confidence).items():
                put(key, t, o, values)
            if design is not None and design.method == "sobol":
                found, blocks[t, o] = sobol_indices(design, y, ok, seed, confidence, resamples)
            elif design is not None and design.method == "morris":
                found, blocks[t, o] = morris_indices(design, unit, y, ok, seed, confidence, resamples)
            else:
                found = {}
            for key, values in found.items():
                put(key, t, o, values)
    return _dataset(ds, flat, names, indices, params, data, used, blocks, confidence)


OUTPUT_UNITS = None  # Morris effects are in each output's units (coordinate output_units): no one units attribute
LONG_NAMES = {
    "S1": ("first-order Sobol' index (share of the output's variance due to the parameter alone)", "1"),
    "S1_conf": ("half-width of the S1 bootstrap confidence interval", "1"),
    "ST": ("total Sobol' index (share of the variance involving the parameter, interactions included)", "1"),
    "ST_conf": ("half-width of the ST bootstrap confidence interval", "1"),
    "S2": ("second-order Sobol' index of the parameter pair (upper triangle)", "1"),
    "S2_conf": ("half-width of the S2 bootstrap confidence interval", "1"),
    "mu_star": ("Morris mu*: mean |elementary effect| per whole range (log ranges: per their span in log10)",
                OUTPUT_UNITS),
    "mu_star_conf": ("half-width of the mu* bootstrap confidence interval", OUTPUT_UNITS),
    "mu": ("Morris mu: mean elementary effect per whole range", OUTPUT_UNITS),
    "sigma": ("Morris sigma: standard deviation of the elementary effects (nonlinearity, interactions)",
              OUTPUT_UNITS),
    "spearman": ("Spearman rank correlation of parameter and output", "1"),
    "spearman_low": ("lower end of the Spearman confidence interval (Fisher z)", "1"),
    "spearman_high": ("upper end of the Spearman confidence interval (Fisher z)", "1"),
    "prcc": ("partial rank correlation coefficient (other parameters' ranks regressed out)", "1"),
    "prcc_low": ("lower end of the PRCC confidence interval (Fisher z)", "1"),
    "prcc_high": ("upper end of the PRCC confidence interval (Fisher z)", "1"),
}


def _dataset(ds, flat: Cases, names, indices, params, data, used, blocks, confidence) -> xr.Dataset:
    several = len(indices) > 1
    lead = ("time", "output") if several else ("output",)

    def squeeze(values):
        return values if several else values[0]

    variables = {}
    for key, values in data.items():
        dims = (*lead, "parameter") + (("parameter2",) if values.ndim == 4 else ())
        long_name, units = LONG_NAMES[key]
        attrs = {"long_name": long_name, "units": units} if units is not OUTPUT_UNITS else {
            "long_name": f"{long_name}, in the units of each output (output_units)"}
        variables[key] = (dims, squeeze(values), attrs)
    variables["cases_used"] = (lead, squeeze(used), {"long_name": "finished cases the output was analysed from",
                                                      "units": "1"})
    design = flat.design
    if design is not None and design.method in ("sobol", "morris"):
        variables["blocks_used"] = (lead, squeeze(blocks), {
            "long_name": ("complete base samples" if design.method == "sobol" else "complete trajectories")
            + " the indices were estimated from", "units": "1"})
    coords = {
        "output": ("output", np.array(names, dtype=object), {"long_name": "observable or study variable",
                                                             "units": "1"}),
        "parameter": ("parameter", np.array(params, dtype=object), {"long_name": "swept or sampled parameter",
                                                                    "units": "1"}),
        "output_units": ("output", np.array([str(ds[n].attrs.get("units", "1")) if n in ds else
                                             observables.get(n).units for n in names], dtype=object),
                         {"long_name": "units of the output", "units": "1"}),
    }
    if any(v[0][-1] == "parameter2" for v in variables.values()):
        coords["parameter2"] = ("parameter2", np.array(params, dtype=object),
                                {"long_name": "second parameter of a pair", "units": "1"})
    if "time" in ds.dims:
        times = ds["time"].values[indices]
        coords["time"] = (("time",), times, ds["time"].attrs) if several else ((), times[0], ds["time"].attrs)
    notes = left_out(flat, design) + undefined(flat, names, ds["time"].values[indices] if "time" in ds.dims
                                               else [None], used, blocks)
    warning = sobol_warning(data, names, params, blocks, design) if design is not None else ""
    attrs = with_provenance({
        "Conventions": "CF-1.10", "title": f"sensitivity analysis of {ds.attrs.get('title', 'a study')}",
        "method": design.method if design is not None else str(ds.attrs.get("sweep_mode", "sweep")),
        "confidence_level": confidence, "cases": len(flat.ids), "cases_done": int((flat.status == "done").sum()),
        "cases_failed": int((flat.status == "failed").sum()), "cases_missing": int((flat.status == "missing").sum()),
        "notes": " ".join([warning, *notes] if warning else notes), "study_file": str(ds.attrs.get("study_file", "")),
        **({"warning": warning} if warning else {}),
        **({k: v for k, v in design.attrs().items()} if design is not None else {}),
        "parameter_scales": ", ".join(f"{p}: {'log' if flat.log.get(p) else 'linear'}" for p in params),
    })
    return xr.Dataset(variables, coords=coords, attrs=attrs)


def table_text(result: xr.Dataset) -> str:
    """analysis.md: one table per analysed time, a row per output and parameter."""
    method = str(result.attrs.get("method"))
    lines = [f"# Sensitivity analysis ({method})", "", str(result.attrs.get("notes", "")), ""]
    confidence = number(100 * float(result.attrs.get("confidence_level", CONFIDENCE)), 3)
    columns = [("spearman", "Spearman rho"), ("prcc", "PRCC")]
    if "S1" in result:
        columns = [("S1", "S1"), ("ST", "ST")] + columns
    if "mu_star" in result:
        columns = [("mu_star", "mu*"), ("sigma", "sigma")] + columns
    times = result["time"].values if "time" in result.dims else [result["time"].item() if "time" in result.coords
                                                                 else None]
    for t, when in enumerate(np.atleast_1d(times)):
        part = result.isel(time=t) if "time" in result.dims else result
        lines.append(f"## T* = {number(when)}" if when is not None else "## outputs")
        lines.append("")
        lines.append(f"Intervals: {confidence} % ({'bootstrap' if method in ('sobol', 'morris') else ''}"
                     f"{' for indices, ' if method in ('sobol', 'morris') else ''}Fisher z for rank correlations).")
        lines.append("")
        head = ["output", "parameter", *(label for _, label in columns), "cases"]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for o, output in enumerate(part.output.values):
            for j, parameter in enumerate(part.parameter.values):
                cells = [str(output), str(parameter)]
                for key, _ in columns:
                    cells.append(_with_interval(part, key, o, j))
                cells.append(str(int(part["cases_used"].values[o])))
                lines.append("| " + " | ".join(cells) + " |")
        if "S2" in part and np.isfinite(part["S2"].values).any():
            lines += ["", "Second-order indices S2 (pairs):", "", "| output | pair | S2 |", "|---|---|---|"]
            for o, output in enumerate(part.output.values):
                params = list(part.parameter.values)
                for a in range(len(params)):
                    for b in range(a + 1, len(params)):
                        value = part["S2"].values[o, a, b]
                        conf = part["S2_conf"].values[o, a, b]
                        lines.append(f"| {output} | {params[a]} × {params[b]} | {_pm(value, conf)} |")
        lines.append("")
    return "\n".join(lines)


def _pm(value: float, conf: float) -> str:
    return "-" if not np.isfinite(value) else f"{number(value, 2)} ± {number(conf, 2)}"


def _with_interval(part: xr.Dataset, key: str, o: int, j: int) -> str:
    if key not in part:
        return "-"
    value = float(part[key].values[o, j])
    if f"{key}_conf" in part:
        return _pm(value, float(part[f"{key}_conf"].values[o, j]))
    if f"{key}_low" in part and np.isfinite(value):
        return f"{number(value, 2)} [{number(part[f'{key}_low'].values[o, j], 2)}, " \
               f"{number(part[f'{key}_high'].values[o, j], 2)}]"
    return number(value, 3)
