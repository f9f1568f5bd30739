"""Time series of one run: mean c and mean phi (paper Figs. 4 and 7), and the biofilm volume.

Colours as in the paper: nutrient blue, biofilm red.  The volume (cells with
phi >= 0.5) gets its own panel because it has units and a scale of its own.
"""
from __future__ import annotations

import matplotlib.pyplot as plt
import xarray as xr

from .style import axis_label, run_title, suptitle

PHI_RED, C_BLUE = "#d62728", "#1f77b4"


def figure(ds: xr.Dataset, marks: list[float] = ()):
    """Two panels over T*: phi_mean and c_mean; biofilm_volume.  `marks`: times to flag (dotted)."""
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(6.4, 5.2), layout="constrained",
                                      height_ratios=(3, 2))
    time = ds["time"].values
    for name, colour in (("c_mean", C_BLUE), ("phi_mean", PHI_RED)):
        if name in ds:
            top.plot(time, ds[name].values, "o-", ms=3, color=colour,
                     label=ds[name].attrs.get("long_name", name))
    top.set_ylabel("mean over the open domain")
    top.set_ylim(bottom=0)
    top.legend(fontsize=8)
    top.grid(alpha=0.3)
    if "biofilm_volume" in ds:
        volume = ds["biofilm_volume"]
        bottom.plot(time, volume.values, "o-", ms=3, color="0.25")
        bottom.set_ylabel(axis_label(volume))
        bottom.set_title(volume.attrs.get("long_name", ""), fontsize=8)
        bottom.set_ylim(bottom=0)
    bottom.set_xlabel("normalised time T*")
    bottom.grid(alpha=0.3)
    for when in marks:
        for ax in (top, bottom):
            ax.axvline(when, color="0.5", ls=":", lw=1)
    suptitle(fig, run_title(ds))
    return fig
