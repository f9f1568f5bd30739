"""Work-precision pictures of a convergence study: error against each level's own cost, log-log.

The cost is the CPU time of the level's set-up and time loop (`cost`: the
operators it builds, its steps and mechanics solves, without the one-off first
step that loads compiled kernels), the same measure for every level; datasets
written before it was recorded fall back to the time loop alone, then to the
wall time.  The errors are those at the compared output time (the last, or
``--time``), against the study's one reference.

One line per refinement series (space, time, both, adaptive), one panel per
measured quantity that has errors; the observed order of each series is in
its legend entry.  Lower left is better: a method to the left of another
reaches the same error sooner.
"""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr
from matplotlib.ticker import NullFormatter

from ..formatting import number
from .style import save

MARKERS = {"space": "s", "time": "o", "both": "D", "adaptive": "^"}
PANELS = ("phi_L1", "biofilm_volume", "front_position", "p_L2")


def work_precision(ds: xr.Dataset, out: Path) -> Path:
    """Draw error against wall time for every series and quantity of `convergence.nc`."""
    panels = [q for q in PANELS if (ds[f"error_{q}"].values > 0).any()] or ["phi_L1"]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.8), layout="constrained", squeeze=False)
    label, cost = "wall time (s)", ds["wall_time"]
    for name, text in (("cpu_time_loop", "time loop CPU time (s)"), ("cost", "set-up and time loop CPU time (s)")):
        if name in ds and bool(np.isfinite(ds[name].values).any()):
            label, cost = text, ds[name]
    if "time" in ds.dims:
        times = ds["time"].values
        at = int(np.argmin(np.abs(times - float(ds.attrs.get("compared_time", times[-1])))))
        ds = ds.isel(time=at)
    for ax, quantity in zip(axes[0], panels):
        error = ds[f"error_{quantity}"]
        for name in ds.series.values:
            x, y = cost.sel(series=name).values, error.sel(series=name).values
            ok = np.isfinite(x) & np.isfinite(y) & (y > 0)
            if not ok.any():
                continue
            order = ds.attrs.get(f"order_{name}_{quantity}", float("nan"))
            if isinstance(order, str):
                suffix = f" ({order})"
            else:
                suffix = f" (order {number(order, 3)})" if math.isfinite(order) else ""
            ax.loglog(x[ok], y[ok], marker=MARKERS.get(str(name), "o"), label=f"{name}{suffix}")
        ax.set_xlabel(label)
        units = error.attrs.get("units", "1")
        ax.set_ylabel(f"error ({units})" if units not in ("1", "") else "error")
        ax.set_title(error.attrs.get("long_name", quantity), fontsize=8)
        ax.grid(alpha=0.3, which="both")
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_minor_formatter(NullFormatter())  # narrow ranges: minor labels pile up
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    fig.suptitle(f"work-precision: {ds.attrs.get('title', '')}", fontsize=10)
    return save(fig, Path(out))
