"""Error bars of a run: each observable's estimated discretisation error at every output time, from companions.

Given the run's dataset at (h, dt) and its companions' (`plans.companions`:
`coarse` at (2h, 2dt), `slow` at (2h, 4dt), `coarser` at (4h, 4dt)), all with
the same output times, for every observable Q of the run's dataset
(`richardson`, docs/accuracy.md "Error bars on a run"):

    time part   T = (Q_slow - Q_coarse) / (rho_slow - rho_coarse)          b dt^q, q = 1
    space part  S = (Q_coarse - Q_run - T (rho_coarse - 1)) / (2^p - 1)    a h^p
    Q_error     = |S| + |T|

where rho is the ratio of the run's accepted steps to the companion's (2 and 4
with fixed steps that land on the outputs; measured, so that bisected or
sub-stepped steps count as they were taken).  p is observed from `coarser`
when it ran, its extra time error T (rho_coarser - rho_coarse) taken off
(`richardson.space_order`, believed between `LOWEST` and the
scheme's formal order), the scheme's formal order otherwise.  Without `slow`
the time part is not separated: Q_error = |Q_coarse - Q_run| / (2^p - 1).

A companion that reports what the run does not (its biofilm retreated or its
dense biofilm vanished: `alerts`) solved a different model on its coarser
cells; so did one whose grid does not resolve the scene's regions (found
before it ran).  Without a usable `coarse` there is no estimate: every Q_error
is NaN and the dataset's ``error_estimate`` attribute says why.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np
import xarray as xr

from . import alerts, observables, richardson

SUFFIX = "_error"
ATTRIBUTE = "error_estimate"  # the dataset's sentence: how the error was estimated, or why it was not


def observables_of(ds: xr.Dataset) -> list[str]:
    """The observables the dataset holds as time series (its ``observables`` attribute, in order)."""
    names = [n.strip() for n in str(ds.attrs.get("observables", "")).split(",") if n.strip()]
    return [n for n in names if n in ds and ds[n].dims == ("time",)]


def _steps(ds: xr.Dataset) -> float:
    return float(ds.attrs["steps_taken"])


def different(run: xr.Dataset, companion: xr.Dataset) -> str:
    """'' or what the companion reports that the run does not (`alerts`): it solved another model."""
    mine = alerts.attrs(run)
    for name, sentence in alerts.attrs(companion).items():
        if name not in mine:
            return f"a different model: {sentence}"
    return ""


def usable(run: xr.Dataset, companions: Mapping[str, xr.Dataset | None], notes: dict[str, str]) -> dict:
    """The companions that can be compared with the run (same output times, same model); `notes` gets the reason
    for each one left out."""
    kept = {}
    times = run["time"].values
    for name, ds in companions.items():
        if ds is None:
            continue
        other = ds["time"].values
        if other.shape != times.shape or not np.allclose(other, times, rtol=1e-9, atol=1e-12):
            notes[name] = f"{name}: its output times differ from the run's"
            continue
        said = different(run, ds)
        if said:
            notes[name] = f"{name}: {said}"
            continue
        kept[name] = ds
    return kept


def series(ds: xr.Dataset, name: str) -> np.ndarray:
    """An observable over time: as the dataset holds it, or measured on its fields (one it does not keep)."""
    if name in ds and ds[name].dims == ("time",):
        return np.asarray(ds[name].values, dtype=float)
    return np.asarray(observables.evaluate(ds, name).values, dtype=float)


def estimate(run: xr.Dataset, companions: Mapping[str, xr.Dataset | None], notes: Mapping[str, str],
             scheme: str, names: list[str] | None = None) -> tuple[dict[str, xr.DataArray], dict[str, str]]:
    """({Q_error: DataArray on the run's time axis}, dataset attributes) for every observable of `run` (or those
    `names`).  `companions`: name -> dataset (None where it did not run); `notes`: name -> what each companion
    ran, or why it did not; `scheme`: the run's advection scheme (its formal order caps an observed one)."""
    notes = dict(notes)
    kept = usable(run, companions, notes)
    names = observables_of(run) if names is None else list(names)
    if "coarse" not in kept:
        why = notes.get("coarse", "coarse: did not run")
        said = f"not estimated: {why}"
        return {f"{n}{SUFFIX}": _variable(run, n, np.full(run.sizes["time"], np.nan), {"comment": said})
                for n in names}, {ATTRIBUTE: said}
    rho = {name: _steps(run) / _steps(ds) for name, ds in kept.items()}
    variables = {}
    for name in names:
        q = series(run, name)
        coarse = series(kept["coarse"], name)
        if "slow" in kept:
            time = richardson.time_part(coarse, series(kept["slow"], name), rho["coarse"], rho["slow"])
            difference = richardson.space_difference(q, coarse, time, rho["coarse"])
        else:
            time = np.zeros_like(q)
            difference = coarse - q
        observed = float("nan")
        if "coarser" in kept and "slow" in kept:
            extra = time * (rho["coarser"] - rho["coarse"])  # coarser's longer step (q = 1)
            observed = richardson.space_order(difference, series(kept["coarser"], name), coarse, extra_time=extra)
        order, seen = richardson.believed(observed, richardson.FORMAL.get(scheme, 1.0))
        space = difference / (2.0**order - 1.0)
        error = np.abs(space) + np.abs(time)
        attrs = {"space_order": order, "space_order_source": "observed" if seen else "assumed",
                 "time_order": richardson.TIME_ORDER}
        if np.isfinite(observed) and not seen:
            attrs["comment"] = (f"observed spatial order {observed:.3g} is below {richardson.LOWEST:g}: not in the "
                                f"asymptotic range, the scheme's order {order:g} assumed")
        variables[f"{name}{SUFFIX}"] = _variable(run, name, error, attrs)
    ran = "; ".join(notes.values())
    split = "space and time apart" if "slow" in kept else "space and time together (no time companion)"
    said = (f"Richardson from companion runs ({ran}); {split}; time order {richardson.TIME_ORDER:g} (backward "
            f"Euler), space order per variable (attribute space_order: observed from coarser, or the scheme's, "
            f"{scheme} {richardson.FORMAL.get(scheme, 1.0):g}); Q_error = |space part| + |time part| "
            "(docs/accuracy.md)")
    return variables, {ATTRIBUTE: said}


def _variable(run: xr.Dataset, name: str, values: np.ndarray, extra: dict) -> xr.DataArray:
    """Q_error on the run's time axis, in Q's units."""
    source = run[name].attrs if name in run else observables.get(name).attrs(run)
    attrs = {"units": source.get("units", "1"),
             "long_name": f"estimated discretisation error of the {source.get('long_name', name)}", **extra}
    return xr.DataArray(values, dims=("time",), coords={"time": run["time"]}, attrs=attrs)
