"""Pictures of a sweep's combined dataset (`study.nc`): outputs against the swept parameters.

A sweep has one dimension per swept key (grid mode) or a `case` dimension with
the swept values as coordinates on it (zip mode), besides `time`.  Both are
flattened into a list of cases, each with its parameter values.  The first
parameter that varies goes on the horizontal axis; every combination of the
others is one line, except for parameters that change together with it (zip
mode), which are named on the axis.  Fields in study.nc are not drawn here:
plot a case file for them.  Failed cases (a `status` other than ok/done, or NaN
outputs) are marked with a red cross on the axis instead of a point.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from ..formatting import number, shown_units
from ..quantities.saturation import SATURATION, saturated
from .style import SERIES_NAMES, axis_label, suptitle, time_axis, time_title

OK_STATUS = {"ok", "done", "complete", "completed", "success", "succeeded", "finished", "0"}
NOT_PARAMETERS = {"status", "message", "error", "time"}
LINESTYLES = ("-", "--", ":", "-.")
COLUMNS = 3  # panels per row


def panels(count: int):
    """A figure with `count` panels, at most COLUMNS per row; returns it and the panels in order."""
    rows, cols = -(-count // COLUMNS), min(count, COLUMNS)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.8 * rows), layout="constrained", squeeze=False)
    for ax in axes.flat[count:]:
        ax.remove()
    return fig, list(axes.flat[:count])


@dataclass
class SweepPoint:
    """One case of a sweep as drawn: its swept values, its output time series, whether it finished."""

    params: dict  # swept key -> value, in sweep order
    series: dict  # output name -> values over time
    ok: bool


def is_sweep(ds: xr.Dataset) -> bool:
    """True for a combined dataset: the time series have dimensions besides time."""
    return any(name in ds and set(ds[name].dims) - {"time"} for name in SERIES_NAMES)


def _value(v):
    v = v.item() if hasattr(v, "item") else v
    return v.decode() if isinstance(v, bytes) else v


def _status_ok(status) -> bool:
    return str(_value(status)).strip().lower() in OK_STATUS


def cases(ds: xr.Dataset, names: list[str]) -> tuple[list[SweepPoint], list[str]]:
    """The sweep as a flat list of cases, and the names of the parameters that vary."""
    dims = [d for d in ds[names[0]].dims if d != "time"]
    keys = []
    for dim in dims:  # a case dimension carries its swept values as coordinates along it
        along = [c for c in ds.coords if ds[c].dims == (dim,) and c != dim and c not in NOT_PARAMETERS]
        keys += along if along else [dim]
    found = []
    for index in itertools.product(*(range(ds.sizes[d]) for d in dims)):
        at = dict(zip(dims, index))
        params = {k: _value(ds[k].isel({d: i for d, i in at.items() if d in ds[k].dims})) for k in keys}
        series = {n: np.atleast_1d(ds[n].isel(at).values.astype(float)) for n in names}
        ok = all(np.isfinite(s[-1]) for s in series.values())
        if "status" in ds:
            ok = ok and _status_ok(ds["status"].isel({d: i for d, i in at.items() if d in ds["status"].dims}))
        found.append(SweepPoint(params, series, ok))
    varying = [k for k in keys if len({repr(c.params[k]) for c in found}) > 1] or keys[:1]
    return found, varying


def roles(found: list[SweepPoint], varying: list[str]) -> tuple[str, list[str], list[str]]:
    """The horizontal-axis parameter, the ones that split cases into lines, and the ones that follow it.

    A parameter fixed by the first one (a zip sweep: g and r changing together) does not split
    the cases into lines of one point each; it is named on the axis instead.
    """
    x_key, follow, split = varying[0], [], []
    for key in varying[1:]:
        pairs = {(repr(c.params[x_key]), repr(c.params[key])) for c in found}
        (follow if len(pairs) == len({p[0] for p in pairs}) else split).append(key)
    return x_key, split, follow


def _layout(ds: xr.Dataset, names: list[str]):
    """What both sweep figures arrange by: the cases, the horizontal-axis parameter, the parameters that
    split lines and those that follow it, and the line groups (values of the splitting ones) in order."""
    found, varying = cases(ds, names)
    x_key, others, follow = roles(found, varying)
    groups = sorted({tuple(c.params[k] for k in others) for c in found}, key=_group_order)
    return found, x_key, others, follow, groups


def _x_axis_text(ds: xr.Dataset, found: list[SweepPoint], x_key: str, follow: list[str]) -> str:
    text = x_key
    if x_key in ds and shown_units(x_key, ds[x_key].attrs.get("units", "1")):
        text += f" ({shown_units(x_key, ds[x_key].attrs['units'])})"
    for key in follow:
        values = [c.params[key] for c in sorted(found, key=lambda c: _order(c.params[x_key]))]
        text += f"; with {key} = " + ", ".join(dict.fromkeys(_fmt(v) for v in values))
    return text


def _numeric(values) -> bool:
    return all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) for v in values)


def _fmt(value) -> str:
    return number(value, 6) if _numeric([value]) else str(value)


def _order(value):
    """Sort key: numbers by value, before any text."""
    return (0, value, "") if _numeric([value]) else (1, 0, str(value))


def _group_order(group: tuple):
    return tuple(_order(v) for v in group)


def _axis(ax, key: str, values: list):
    """Positions of the parameter values on the horizontal axis (log scale for wide positive ranges)."""
    unique = sorted(set(values), key=_order)
    if _numeric(unique):
        positive = min(unique) > 0
        if positive and max(unique) / min(unique) >= 20:
            ax.set_xscale("log")
        return {v: float(v) for v in unique}
    ax.set_xticks(range(len(unique)), [str(v) for v in unique])
    return {v: float(i) for i, v in enumerate(unique)}


def final_figure(ds: xr.Dataset, names: list[str], index: int = -1):
    """Outputs at one time (default the last) against the first varying parameter, a line per other combination."""
    found, x_key, others, follow, groups = _layout(ds, names)
    fig, axes = panels(len(names))
    for ax, name in zip(axes, names):
        where = _axis(ax, x_key, [c.params[x_key] for c in found])
        for g, group in enumerate(groups):
            members = sorted((c for c in found if tuple(c.params[k] for k in others) == group),
                             key=lambda c: where[c.params[x_key]])
            xs = [where[c.params[x_key]] for c in members]
            ys = [c.series[name][index] for c in members]
            text = ", ".join(f"{k} = {_fmt(v)}" for k, v in zip(others, group)) or None
            ax.plot(xs, ys, "o", ls=LINESTYLES[g % len(LINESTYLES)], label=text)
            top = saturated(ys, ds[name].attrs.get(SATURATION))
            if top.any():  # a height at the top of the box: a lower bound, not a measurement
                named = "reaches the top (saturated)" in ax.get_legend_handles_labels()[1]
                ax.plot(np.asarray(xs)[top], np.asarray(ys)[top], "^", ms=9, mfc="none", mec="C3", mew=1.5,
                        label=None if named else "reaches the top (saturated)")
            failed = [x for x, c in zip(xs, members) if not c.ok]
            if failed:  # the legend names the red crosses once, whichever line they belong to
                named = "failed" in ax.get_legend_handles_labels()[1]
                ax.plot(failed, [0.03] * len(failed), "x", color="red", ms=8, mew=2,
                        transform=ax.get_xaxis_transform(), label=None if named else "failed")
        ax.set_xlabel(_x_axis_text(ds, found, x_key, follow), fontsize=9)
        ax.set_ylabel(axis_label(ds[name]))
        ax.set_title(ds[name].attrs.get("long_name", name), fontsize=8)
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    suptitle(fig, f"sweep: outputs at {time_title(ds, index)} against {x_key}")
    return fig


def solved_points(time: np.ndarray, values: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], str | None]:
    """The points of a time series that have a value, and a marker when some have none: an observable of the
    mechanics (compression_max) is NaN between the outputs where it was solved, and a line through NaN draws
    nothing at all."""
    values = np.asarray(values, dtype=float)
    known = np.isfinite(values)
    return (np.asarray(time)[known], values[known]), (None if known.all() else "o")


def series_figure(ds: xr.Dataset, names: list[str]):
    """Every case's time series: colour = value of the first varying parameter, line style = the others."""
    found, x_key, others, follow, groups = _layout(ds, names)
    x_values = sorted({c.params[x_key] for c in found}, key=_order)
    colours = plt.get_cmap("viridis")(np.linspace(0, 0.9, len(x_values)))
    time, time_label, _ = time_axis(ds)
    fig, axes = panels(len(names))
    for ax, name in zip(axes, names):
        for c in found:
            colour = colours[x_values.index(c.params[x_key])]
            style = LINESTYLES[groups.index(tuple(c.params[k] for k in others)) % len(LINESTYLES)]
            drawn, marker = solved_points(time, c.series[name])
            ax.plot(*drawn, color=colour, ls=style, lw=1.2 if c.ok else 0.6, marker=marker, ms=3)
        ax.set_xlabel(time_label)
        ax.set_ylabel(axis_label(ds[name]))
        ax.grid(alpha=0.3)

    def case_label(v):
        match = next(c for c in found if c.params[x_key] == v)
        return ", ".join(f"{k} = {_fmt(match.params[k])}" for k in (x_key, *follow))

    legend = [plt.Line2D([], [], color=colours[i], label=case_label(v)) for i, v in enumerate(x_values)]
    legend += [plt.Line2D([], [], color="0.3", ls=LINESTYLES[g % len(LINESTYLES)],
                          label=", ".join(f"{k} = {_fmt(v)}" for k, v in zip(others, group)))
               for g, group in enumerate(groups) if others]
    axes[min(len(names), COLUMNS) - 1].legend(handles=legend, fontsize=7, loc="best")
    suptitle(fig, "sweep: time series of every case" + ("" if all(c.ok for c in found) else
                                                        " (thin lines: failed cases)"))
    return fig
