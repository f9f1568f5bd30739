"""Pictures of a calibration (DIR/calibration.nc): the data against the fitted model, and the profiles.

* `fit_figure`: one panel per observable and condition: the measurements with
  error bars (± sigma) at their times (the table's own unit), the fitted model
  at the data times joined by a line, and its 95 % band (Jacobian covariance);
  a table with PEtab's `datasetId` or `replicateId` has its datasets drawn in
  their own colours and its replicates with their own open markers, each named
  in the panel's legend (replicates measured at the same time are told apart by
  their markers); a panel of more than `SHOWN_GROUPS` pairs draws its measurements
  as one series, the datasets and replicates counted in the legend.
* `profiles_figure`: one panel per parameter: chi² above its minimum along the
  profile (the others re-optimised), the 95 % threshold 3.84, the estimate and
  the interval; a log axis for a log parameter; the panel spans the profile (its
  bounds are in the title when the interval reaches one).
* `corner_figure`: a posterior's samples: a histogram per parameter on the
  diagonal (median and 95 % credible interval marked), every pair's samples
  below it as a 2-D histogram with the least-squares estimate; log axes for
  log parameters.
"""
from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr
from matplotlib.ticker import NullFormatter

from ..fitting.profiles import THRESHOLD
from ..formatting import number, units_text
from . import units


def _grid(count: int) -> tuple[int, int]:
    columns = min(count, 3)
    return math.ceil(count / columns), columns


MARKERS = "osD^v<>PX*"
COLOURS = ("C0", "C3", "C4", "C5", "C6", "C7", "C8", "C9")  # C1 is the fit, C2 the posterior band
SHOWN_GROUPS = 24  # (dataset, replicate) pairs a panel draws and names apart; more are drawn as one series


def _count(n: int, what: str) -> str:
    return f"{n} {what}" + ("s" if n != 1 else "")


def _measured(ax, ds: xr.Dataset, at: np.ndarray) -> bool:
    """The measurements `at` with error bars; a colour per dataset and a marker per replicate (PEtab's ids; the
    colour per replicate in a panel of one dataset) when the table names them.  Whether any was named (the panel
    then needs its own legend)."""
    dataset, replicate = ds["dataset"].values, ds["replicate"].values
    rows: dict[tuple[str, str], list[int]] = {}  # one pass (issue 39.11: a scan of the panel per dataset)
    for i in at:
        rows.setdefault((str(dataset[i]), str(replicate[i])), []).append(int(i))
    groups = list(rows)
    datasets = list(dict.fromkeys(d for d, _ in groups))
    replicates = list(dict.fromkeys(r for _, r in groups))
    if len(groups) > SHOWN_GROUPS:  # told apart by nobody, and 30 ms each: one series, counted
        ax.errorbar(ds.time_measured.values[at], ds.measured.values[at], yerr=ds.sigma.values[at], fmt="o", ms=3.5,
                    color=COLOURS[0], mfc="none", capsize=2,
                    label=f"measured ± σ ({_count(len(datasets), 'dataset')}, {_count(len(replicates), 'replicate')})")
        return True
    for group in groups:
        where = np.array(rows[group])
        label = ", ".join(["measured ± σ"] + [f"{what} {name}" for what, name in zip(("dataset", "replicate"), group)
                                               if name])
        named = group != ("", "")
        colour = datasets.index(group[0]) if len(datasets) > 1 else replicates.index(group[1])
        ax.errorbar(ds.time_measured.values[where], ds.measured.values[where], yerr=ds.sigma.values[where],
                    fmt=MARKERS[replicates.index(group[1]) % len(MARKERS)], ms=4.5 if named else 3.5,
                    color=COLOURS[colour % len(COLOURS)], mfc="none" if named else None, capsize=2, label=label)
    return groups != [("", "")]


def fit_figure(ds: xr.Dataset):
    """Measurements with error bars against the fitted model and its band, per observable and condition (and
    per dataset and replicate, `_measured`)."""
    pairs = list(dict.fromkeys(zip(ds.observable.values, ds.condition.values)))
    rows, columns = _grid(len(pairs))
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.3 * rows), squeeze=False)
    unit = ds.attrs.get("time_unit", "T*")
    for ax, (observable, condition) in zip(axes.flat, pairs):
        at = np.flatnonzero((ds.observable.values == observable) & (ds.condition.values == condition))
        at = at[np.argsort(ds.time_measured.values[at])]
        t = ds.time_measured.values[at]
        ax.fill_between(t, ds.band_lower.values[at], ds.band_upper.values[at], color="C1", alpha=0.3, lw=0,
                        label="95 % band of the fit")
        if "posterior_band_lower" in ds:
            ax.fill_between(t, ds.posterior_band_lower.values[at], ds.posterior_band_upper.values[at], color="C2",
                            alpha=0.3, lw=0, label="95 % posterior band")
        ax.plot(t, ds.fitted.values[at], "-", color="C1", label="fitted model")
        if _measured(ax, ds, at):
            ax.legend(fontsize=7)
        shown = units_text(str(ds.measurement_units.values[at[0]]))
        ax.set_xlabel(f"time ({unit})")
        ax.set_ylabel(f"{observable}" + (f" ({shown})" if shown else ""))
        ax.set_title(f"{observable}" + (f", condition {condition}" if condition else ""), fontsize=10)
    for ax in list(axes.flat)[len(pairs):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=8)
    fit = (f"-2 log L = {number(ds.attrs['chi2'], 3)}, σ estimated" if "objective" in ds.attrs else
           f"chi² = {number(ds.attrs['chi2'], 3)} for {ds.attrs['dof']} degrees of freedom")
    fig.suptitle(f"{ds.attrs.get('title', 'calibration')}: {fit}", fontsize=11)
    fig.tight_layout()
    return fig


def profiles_figure(ds: xr.Dataset):
    """chi² - its minimum along each parameter's profile, the 95 % threshold and interval."""
    k = ds.sizes["parameter"]
    rows, columns = _grid(k)
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.3 * rows), squeeze=False)
    minimum = float(ds.attrs["chi2_minimum"])
    for j, ax in enumerate(list(axes.flat)[:k]):
        value, chi2 = ds.profile_value.values[j], ds.profile_chi2.values[j]
        keep = np.isfinite(value) & np.isfinite(chi2)
        ax.plot(value[keep], chi2[keep] - minimum, "o-", ms=3.5, color="C0", label="profile")
        ax.axhline(THRESHOLD, color="0.4", ls="--", lw=1, label="95 % threshold (3.84)")
        ax.axvline(float(ds.estimate[j]), color="C1", lw=1, label="estimate")
        for end in (float(ds.lower[j]), float(ds.upper[j])):
            ax.axvline(end, color="C2", lw=1, ls=":")
        if str(ds.scale.values[j]) == "log":
            ax.set_xscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_ylim(bottom=-0.2)
        shown = units.shown(ds, j)
        ax.set_xlabel(f"{ds.parameter.values[j]}" + (f" ({shown})" if shown else ""))
        ax.set_ylabel(f"{ds.attrs.get('objective', 'chi²')} - minimum")
        verdict = "" if bool(ds.identifiable[j]) else " (not determined)"
        ax.set_title(f"{ds.parameter.values[j]}: [{number(ds.lower[j], 3)}, {number(ds.upper[j], 3)}]{verdict}",
                     fontsize=10)
    for ax in list(axes.flat)[k:]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def _axis_values(ds: xr.Dataset, j: int) -> tuple[np.ndarray, bool]:
    values = ds[f"posterior_{ds.parameter.values[j]}"].values
    log = str(ds.scale.values[j]) == "log"
    return (np.log10(values) if log else values), log


def corner_figure(ds: xr.Dataset):
    """The posterior samples: 1-D histograms on the diagonal, 2-D histograms of every pair below it (log10 axes
    for log parameters, said in the labels)."""
    k = ds.sizes["parameter"]
    fig, axes = plt.subplots(k, k, figsize=(2.8 * k + 0.6, 2.8 * k + 0.4), squeeze=False)
    columns = [_axis_values(ds, j) for j in range(k)]
    labels = []
    for j in range(k):
        shown = units.shown(ds, j)
        name = f"{ds.parameter.values[j]}" + (f" ({shown})" if shown else "")
        labels.append(f"log10 {name}" if columns[j][1] else name)

    def scaled(value: float, j: int) -> float:
        return math.log10(value) if columns[j][1] else value

    for i in range(k):
        for j in range(k):
            ax = axes[i, j]
            if j > i:
                ax.axis("off")
                continue
            if i == j:
                ax.hist(columns[j][0], bins=40, color="C0", alpha=0.8)
                for q, style in ((ds.posterior_median, "-"), (ds.posterior_lower, ":"), (ds.posterior_upper, ":")):
                    ax.axvline(scaled(float(q[j]), j), color="C1", ls=style, lw=1)
                ax.set_yticks([])
                ax.set_title(f"{ds.parameter.values[j]} = {number(ds.posterior_median[j], 3)} "
                             f"[{number(ds.posterior_lower[j], 3)}, {number(ds.posterior_upper[j], 3)}]", fontsize=9)
            else:
                ax.hist2d(columns[j][0], columns[i][0], bins=40, cmap="Blues")
                ax.plot(scaled(float(ds.estimate[j]), j), scaled(float(ds.estimate[i]), i), "x", color="C1",
                        label="least squares")
                if i == k - 1 and j == 0:
                    ax.legend(fontsize=7)
            if i == k - 1:
                ax.set_xlabel(labels[j], fontsize=9)
            if j == 0 and i > 0:
                ax.set_ylabel(labels[i], fontsize=9)
    fig.suptitle(f"posterior: {ds.attrs['posterior_samples']} samples, acceptance "
                 f"{number(ds.attrs['acceptance_fraction'], 2)}", fontsize=10)
    fig.tight_layout()
    return fig
