"""The dead ends off a 2-D run's route and the biofilm in each over time (paper 4.4, Table 7's "points of
interest"): where they are, how far the biofilm got into each and when, and whether it left again.

Left: the walls (grey), the route from the colony to the nutrient (blue line), the dead ends numbered in
the order the route passes their mouths (colours as in the right panel), the source (green) and the region
phi >= 0.5 at four times (outlines, light to dark).  Right: the area of phi >= 0.5 in each dead end over time,
labelled with its number and area; the dotted line is 40 % of the run, where the paper sees retraction.
"""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from ..quantities import dead_ends
from ..quantities.measures import THRESHOLD
from .style import OBSTACLE_GREY, SOURCE_GREEN, run_title, suptitle, time_axis

ROUTE_BLUE = "#1f77b4"


def figure(ds: xr.Dataset, indices: list[int]):
    found = dead_ends.of(ds)
    invaded = dead_ends.per_dead_end(ds)
    x, y = ds["x"].values, ds["y"].values
    h = float(x[1] - x[0])
    extent = (x[0] - h / 2, x[-1] + h / 2, y[0] - h / 2, y[-1] + h / 2)
    fig, (left, right) = plt.subplots(1, 2, figsize=(12.5, 5.6), layout="constrained", width_ratios=(1, 1.2))
    colours = plt.get_cmap("tab10" if found.area.size <= 10 else "tab20")
    image = np.ones((*found.label.shape, 4))
    image[ds["obstacle"].transpose("y", "x").values.astype(bool)] = (*_grey(), 1.0)
    for k in range(1, found.area.size + 1):
        image[found.label == k] = (*colours((k - 1) % colours.N)[:3], 0.35)
    image[ds["nutrient_source"].transpose("y", "x").values.astype(bool)] = (*_rgb(SOURCE_GREEN), 1.0)
    left.imshow(image, origin="lower", extent=extent, interpolation="nearest")
    phi = np.nan_to_num(ds["phi"].transpose("time", "y", "x").values)
    for shade, i in zip(np.linspace(0.75, 0.0, len(indices)), indices):
        left.contour(x, y, phi[i], levels=[THRESHOLD], colors=[str(shade)], linewidths=1.0)
    ry, rx = np.nonzero(found.route)
    left.plot(x[rx], y[ry], ",", color=ROUTE_BLUE)
    for k in range(1, found.area.size + 1):
        cy, cx = np.argwhere(found.label == k)[np.argmax(found.depth[found.label == k])]
        left.annotate(str(k), (x[cx], y[cy]), ha="center", va="center", fontsize=9, weight="bold",
                      color=colours((k - 1) % colours.N))
    left.set_xlabel("x (µm)")
    left.set_ylabel("y (µm)")
    left.set_title(f"dead ends off the route (blue), phi >= {THRESHOLD:g} at T* = "
                   + ", ".join(f"{ds['time'].values[i]:g}" for i in indices) + " (light to dark)", fontsize=8)
    time, time_label, on_axis = time_axis(ds)
    for k, series in enumerate(invaded, start=1):
        right.plot(time, series, "o-", ms=2.5, color=colours((k - 1) % colours.N),
                   label=f"{k}: {found.area[k - 1]:.0f} µm²")
    right.axvline(on_axis(0.4 * float(ds["time"].values[-1])), color="0.5", ls=":", lw=1)
    right.set_xlabel(time_label)
    right.set_ylabel("phi >= 0.5 in the dead end (µm²)")
    right.set_ylim(bottom=0)
    right.grid(alpha=0.3)
    right.legend(fontsize=7, title="dead end: its area", title_fontsize=7, ncol=2 if invaded.shape[0] > 8 else 1)
    suptitle(fig, run_title(ds))
    return fig


def _rgb(colour: str) -> tuple[float, float, float]:
    from matplotlib.colors import to_rgb

    return to_rgb(colour)


def _grey() -> tuple[float, float, float]:
    return _rgb(OBSTACLE_GREY)
