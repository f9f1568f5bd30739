"""Pictures of a sensitivity analysis and of a sampled study.

* `indices_figure`: per output, the indices of each parameter as bars with
  their intervals (Sobol': S1 and ST; Morris: mu*; otherwise Spearman and
  PRCC).
* `scatter_figure`: every output against every parameter, one point per
  finished case (log axes for log ranges); failed or missing cases as red
  crosses on the horizontal axis.
"""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from ..data import real_time
from ..formatting import number, units_text
from ..reports.cases import cases_of
from .style import axis_label, suptitle, time_axis
from .sweep import panels, solved_points

COLUMNS = 3  # panels per row of the indices figure


def _bars(result: xr.Dataset) -> list[tuple[str, str, str]]:
    """(variable, its interval: '_conf' half-width or '_low/_high', label) drawn side by side."""
    if "S1" in result:
        return [("S1", "_conf", "first order S1"), ("ST", "_conf", "total ST")]
    if "mu_star" in result:
        return [("mu_star", "_conf", "Morris mu*")]
    return [("spearman", "_range", "Spearman rho"), ("prcc", "_range", "PRCC")]


def indices_figure(result: xr.Dataset):
    """Bars with intervals, a panel per output (at the last analysed time)."""
    part = result.isel(time=-1) if "time" in result.dims else result
    outputs = list(part.output.values)
    params = list(part.parameter.values)
    bars = _bars(part)
    rows = -(-len(outputs) // COLUMNS)
    cols = min(COLUMNS, len(outputs))
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.8 * rows), layout="constrained", squeeze=False)
    width = 0.8 / len(bars)
    positions = np.arange(len(params))
    for ax, (o, output) in zip(axes.flat, enumerate(outputs)):
        for b, (key, interval, label) in enumerate(bars):
            values = part[key].values[o]
            if interval == "_conf":
                error = part[f"{key}_conf"].values[o]
            else:
                error = np.abs(np.vstack([values - part[f"{key}_low"].values[o],
                                          part[f"{key}_high"].values[o] - values]))
            ax.bar(positions + (b - (len(bars) - 1) / 2) * width, np.nan_to_num(values), width,
                   yerr=np.nan_to_num(error), capsize=3, label=label)
        ax.axhline(0.0, color="0.3", lw=0.6)
        ax.set_xticks(positions, params)
        unit = units_text(str(part["output_units"].values[o])) if bars[0][0] == "mu_star" else ""
        ax.set_title(f"{output}" + (f" ({unit})" if unit else ""), fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(outputs):]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7)
    when = f" at T* = {number(part['time'].values)}" if "time" in part.coords else ""
    level = number(100 * float(result.attrs.get("confidence_level", 0.95)), 3)
    suptitle(fig, f"sensitivity ({result.attrs.get('method')}){when}: {level} % intervals",
             str(result.attrs.get("notes", "")))
    return fig


def scatter_figure(outputs: dict[str, np.ndarray], units: dict[str, str], parameters: dict[str, np.ndarray],
                   log: dict[str, bool], ok: np.ndarray, title: str):
    """Outputs (rows) against parameters (columns): finished cases as points, the others as red crosses."""
    names, params = list(outputs), list(parameters)
    fig, axes = plt.subplots(len(names), len(params), figsize=(2.8 * len(params), 2.2 * len(names)),
                             layout="constrained", squeeze=False, sharex="col")
    for r, name in enumerate(names):
        y = outputs[name]
        good = ok & np.isfinite(y)
        for c, param in enumerate(params):
            ax = axes[r, c]
            x = parameters[param]
            ax.plot(x[good], y[good], ".", ms=3, alpha=0.7)
            if (~good).any():
                ax.plot(x[~good], np.full((~good).sum(), 0.03), "x", color="red", ms=5,
                        transform=ax.get_xaxis_transform())
            if log.get(param):
                ax.set_xscale("log")
            if r == len(names) - 1:
                ax.set_xlabel(param)
            if c == 0:
                unit = units_text(units.get(name, "1"))
                ax.set_ylabel(f"{name}" + (f"\n({unit})" if unit else ""), fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
    suptitle(fig, title)
    return fig


def sample_figure(ds: xr.Dataset, names: list[str], index: int = -1):
    """A sampled study's outputs at one output time against each sampled parameter."""
    flat = cases_of(ds)
    outputs = {n: np.asarray(flat.values(ds[n].isel(time=index)), dtype=float) for n in names}
    units = {n: str(ds[n].attrs.get("units", "1")) for n in names}
    when = real_time.shown(ds, float(ds["time"].values[index]))
    return scatter_figure(outputs, units, flat.parameters, flat.log, flat.status == "done",
                          f"{ds.attrs.get('sample_method')} sample: outputs at {when} against each parameter "
                          f"({int((flat.status == 'done').sum())} of {len(flat.ids)} cases finished)")


def sample_series_figure(ds: xr.Dataset, names: list[str]):
    """Every case's time series of each output, thin lines (cases that did not finish: none drawn)."""
    flat = cases_of(ds)
    fig, axes = panels(len(names))
    time, time_label, _ = time_axis(ds)
    for ax, name in zip(axes, names):
        for row in flat.values(ds[name])[flat.status == "done"]:
            drawn, marker = solved_points(time, row)
            ax.plot(*drawn, color="C0", lw=0.6, alpha=0.5, marker=marker, ms=2)
        ax.set_xlabel(time_label)
        ax.set_ylabel(axis_label(ds[name]))
        ax.set_title(ds[name].attrs.get("long_name", name), fontsize=8)
        ax.grid(alpha=0.3)
    suptitle(fig, f"{ds.attrs.get('sample_method')} sample: time series of every finished case")
    return fig
