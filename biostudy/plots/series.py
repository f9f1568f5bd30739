"""Time series of one run: mean c and mean phi (paper Figs. 4 and 7), and the biofilm volume.

Colours as in the paper: nutrient blue, biofilm red.  The volume (cells with
phi >= 0.5) gets its own panel because it has units and a scale of its own; a
run that records its substratum gets a third, COMSTAT's biomass, mean and
maximum thickness (µm), as a confocal time-lapse would measure them.  A run
with error bars (``--error-estimate``) draws each series' band Q ± Q_error.
"""
from __future__ import annotations

import matplotlib.pyplot as plt
import xarray as xr

from ..quantities import observables
from .style import axis_label, run_title, suptitle, time_axis

ON_SUBSTRATUM = ("biomass", "mean_thickness", "max_thickness")

PHI_RED, C_BLUE = "#d62728", "#1f77b4"


def band(ax, ds: xr.Dataset, name: str, time, values, colour) -> None:
    """Q ± Q_error as a shaded band, where the run has error bars for `name` (nothing where they are NaN)."""
    if f"{name}_error" in ds:
        error = ds[f"{name}_error"].values
        label = "± estimated error"
        ax.fill_between(time, values - error, values + error, color=colour, alpha=0.2, lw=0,
                        label=None if label in ax.get_legend_handles_labels()[1] else label)


def figure(ds: xr.Dataset, marks: list[float] = ()):
    """Two panels over time (T*, or real time with t_ref): phi_mean and c_mean; biofilm_volume (and a third: the
    substratum's biomass and thicknesses, where the run records its substratum).  `marks`: times to flag (dotted)."""
    substratum = all(observables.available(ds, observables.get(n)) for n in ON_SUBSTRATUM)
    fig, axes = plt.subplots(3 if substratum else 2, 1, sharex=True, figsize=(6.4, 7.2 if substratum else 5.2),
                             layout="constrained", height_ratios=(3, 2, 2) if substratum else (3, 2))
    top, bottom = axes[0], axes[1]
    time, time_label, on_axis = time_axis(ds)
    for name, colour in (("c_mean", C_BLUE), ("phi_mean", PHI_RED)):
        if name in ds:
            top.plot(time, ds[name].values, "o-", ms=3, color=colour,
                     label=ds[name].attrs.get("long_name", name))
            band(top, ds, name, time, ds[name].values, colour)
    top.set_ylabel("mean over the open domain")
    top.set_ylim(bottom=0)
    top.legend(fontsize=8)
    top.grid(alpha=0.3)
    if "biofilm_volume" in ds:
        volume = ds["biofilm_volume"]
        bottom.plot(time, volume.values, "o-", ms=3, color="0.25")
        band(bottom, ds, "biofilm_volume", time, volume.values, "0.25")
        bottom.set_ylabel(axis_label(volume))
        bottom.set_title(volume.attrs.get("long_name", ""), fontsize=8)
        bottom.set_ylim(bottom=0)
    bottom.grid(alpha=0.3)
    if substratum:
        for name, style in zip(ON_SUBSTRATUM, ("o-", "s--", "^:")):
            values = observables.evaluate(ds, name).values
            line, = axes[2].plot(time, values, style, ms=3, label=name)
            band(axes[2], ds, name, time, values, line.get_color())
        axes[2].set_ylabel("on the substratum (µm)")
        axes[2].set_title(f"COMSTAT measures on the {ds.attrs['substratum_face']} face", fontsize=8)
        axes[2].set_ylim(bottom=0)
        axes[2].legend(fontsize=8)
        axes[2].grid(alpha=0.3)
    axes[-1].set_xlabel(time_label)
    for when in marks:
        for ax in (top, bottom):
            ax.axvline(on_axis(when), color="0.5", ls=":", lw=1)
    suptitle(fig, run_title(ds))
    return fig
