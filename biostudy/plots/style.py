"""What every figure shares: names and units, colour scales, times, file names.

Colour scales are shared by all times of a figure so that growth and depletion
read across it: phi on [0, 1] (its physical range); c logarithmic from its
smallest shown value (at least 1e-3) to 1, because the nutrient is depleted to
~0.1-0.3 almost everywhere and a linear scale shows one flat colour; alpha
from 0 to its largest shown value; p on a diverging map centred at 0 (blue
compression, red tension, as the paper's stress pictures).  Obstacle cells
(NaN in the fields) are drawn grey.
"""
from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Callable

import matplotlib.colors as mcolors
import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from ..data import real_time
from ..data.claims import foreign, mark
from ..data.writing import atomic
from ..formatting import number, shown_units

OBSTACLE_GREY = "0.6"
SOURCE_GREEN = "#2ca02c"
FIELD_NAMES = ("phi", "c", "alpha", "p")
SERIES_NAMES = ("phi_mean", "c_mean", "biofilm_volume")
SYMBOLS = {"phi": "φ", "c": "c", "alpha": "α", "p": "p", "phi_mean": "mean φ", "c_mean": "mean c",
           "biofilm_volume": "biofilm volume"}
CMAPS = {"phi": "viridis", "c": "plasma", "alpha": "magma", "p": "RdBu_r"}
DPI = 110
C_FLOOR = 1e-3  # lowest nutrient concentration the log colour scale resolves


def units(var: xr.DataArray) -> str:
    """Display form of a variable's `units` attribute ('' for dimensionless)."""
    return shown_units(str(var.name), var.attrs.get("units", "1"))


def axis_label(var: xr.DataArray, name: str | None = None) -> str:
    """Short axis/colourbar label: symbol and units, e.g. 'p (Pa)', 'φ'."""
    name = name or str(var.name)
    text, unit = SYMBOLS.get(name, name), units(var)
    return f"{text} ({unit})" if unit else text


def colour_scale(name: str, values: np.ndarray) -> tuple[mcolors.Colormap, mcolors.Normalize]:
    """Colour map (obstacles grey) and normalisation of one field over all shown panels."""
    cmap = plt.get_cmap(CMAPS.get(name, "viridis")).with_extremes(bad=OBSTACLE_GREY)
    finite = values[np.isfinite(values)]
    if name == "phi":
        return cmap, mcolors.Normalize(0.0, 1.0)
    if name == "c":  # logarithmic: depletion (c ~ 0.1) and the gradient toward the source both show
        low = max(float(np.min(finite[finite > 0], initial=1.0)), C_FLOOR)
        top = max(float(np.max(finite, initial=1.0)), 1.0)
        return cmap, mcolors.LogNorm(min(low, 0.5 * top), top, clip=True)
    if name == "p":
        bound = float(np.max(np.abs(finite), initial=0.0)) or 1.0
        return cmap, mcolors.TwoSlopeNorm(0.0, -bound, bound)
    top = float(np.max(finite, initial=0.0))
    low = min(0.0, float(np.min(finite, initial=0.0)))
    return cmap, mcolors.Normalize(low, top if top > low else low + 1.0)


def on_scale(image: np.ndarray, norm: mcolors.Normalize) -> np.ndarray:
    """The image as drawn: NaN (obstacles) masked grey; on a log scale, c <= 0 (exhausted) at the bottom colour."""
    if isinstance(norm, mcolors.LogNorm):
        image = np.maximum(image, norm.vmin)  # NaN stays NaN
    return np.ma.masked_invalid(image)


def field_names(ds: xr.Dataset, variable: str | None) -> list[str]:
    """Cell fields to draw: the one asked for, or phi, c and p (where the run has p)."""
    present = [n for n in FIELD_NAMES if n in ds.data_vars]
    if variable is None:
        return [n for n in ("phi", "c", "p") if n in present]
    if variable not in present:
        raise ValueError(f"unknown variable {variable!r}; this dataset has {', '.join(present)}")
    return [variable]


def snapshot_indices(ds: xr.Dataset, time: float | None, count: int = 4) -> list[int]:
    """Output indices to draw: `count` spread over the run, or the output nearest to `time`.

    When the run has p but solved the mechanics only at some outputs (`[mechanics] every`), the
    spread is taken over those outputs, so that every drawn column has its p."""
    times = ds["time"].values
    if time is None:
        candidates = np.arange(times.size)
        if "p" in ds.data_vars:
            solved = np.flatnonzero(ds["p"].notnull().any([d for d in ds["p"].dims if d != "time"]).values)
            candidates = solved if solved.size >= min(count, times.size) else candidates
        picks = np.linspace(0, candidates.size - 1, min(count, candidates.size))
        return sorted({int(candidates[int(round(i))]) for i in picks})
    slack = 1e-9 * max(1.0, abs(times[-1]))
    if not times[0] - slack <= time <= times[-1] + slack:
        raise ValueError(f"time {time:g} is outside the run (T* from {times[0]:g} to {times[-1]:g})")
    return [int(np.argmin(np.abs(times - time)))]


def time_title(ds: xr.Dataset, index: int) -> str:
    """'T* = 0.25', or with t_ref '12 h (T* = 0.25)'."""
    t = float(ds["time"].values[index])
    return real_time.shown(ds, t, 3) if real_time.clock(ds) else f"T* = {t:.3g}"


def time_axis(ds: xr.Dataset) -> tuple[np.ndarray, str, Callable[[float], float]]:
    """The x axis of a time series: real time in t_ref's unit when the run has one, else T*; its label, and
    what turns a T* into a position on it."""
    found = real_time.clock(ds)
    if found is None:
        return ds["time"].values, "normalised time T*", lambda t: t
    return found.real(ds["time"].values), f"time ({found.unit}; T* = t / {found.text})", found.real


def run_title(ds: xr.Dataset) -> str:
    """One line naming the run, for figure titles."""
    title = str(ds.attrs.get("title", "biofilm growth"))
    keys = [k for k in ("g", "r", "k_alpha") if k in ds.attrs]
    params = ", ".join(f"{k} = {number(ds.attrs[k], 6)}" for k in keys)
    return f"{title}  ({params})" if params else title


def suptitle(fig, *lines: str):
    """Figure title, each line wrapped to the figure's width (narrow figures of one time included)."""
    width = max(30, int(fig.get_figwidth() * 13))
    fig.suptitle("\n".join(textwrap.fill(line, width) for line in lines), fontsize=9)


def output_paths(out: Path, tags: list[str]) -> list[Path]:
    """`out` itself for one figure; `stem_tag.suffix` beside it for several (PNG unless a suffix says else)."""
    out = Path(out)
    if out.is_dir():
        out = out / "biostudy.png"
    if not out.suffix:
        out = out.with_suffix(".png")
    if len(tags) == 1:
        return [out]
    return [out.with_name(f"{out.stem}_{tag}{out.suffix}") for tag in tags]


METADATA_KEY = {"png": "Software", "pdf": "Creator", "svg": "Creator", "ps": "Creator", "eps": "Creator"}


def save(fig, path: Path) -> Path:
    """Write the figure to `path` atomically (a temporary beside it, renamed): complete or absent.  PNG, PDF,
    SVG and PostScript files carry biostudy's mark in their metadata (`claims.mark`), so that a later plot may
    replace them; a file without it is never replaced (`claims.foreign`, checked by the commands before they
    compute, and here again)."""
    kind = path.suffix.lstrip(".").lower() or "png"
    metadata = {METADATA_KEY[kind]: mark()} if kind in METADATA_KEY else None
    try:
        foreign([path], "a picture")
        return atomic(path, lambda temporary: fig.savefig(temporary, dpi=DPI, format=kind, metadata=metadata))
    finally:
        plt.close(fig)
