"""Maps of the cell fields: one row per field (phi, c, p), one column per time.

The layout is the paper's Tables 3 and 5 turned on its side (a landscape page):
3-D runs are shown on a plane cut (by default the paper's diagonal cut, see
`cuts`), 2-D runs as they are, one square per cell.  Each row has one colour
scale for all its times, so growth and depletion read across the row.
Obstacles are grey; the nutrient source is outlined in green.  A time at which
the mechanics was not solved (p all NaN) says so instead of showing a grey
panel that would look like an obstacle.
"""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr
from matplotlib.ticker import FormatStrFormatter, NullFormatter

from .cuts import Plane, box, cell_axes, sample, sample_nearest
from .style import SOURCE_GREEN, axis_label, colour_scale, on_scale, run_title, suptitle, time_title

PANEL_WIDTH = 3.0  # inches
SAMPLES_PER_CELL = 4  # cut resolution: interpolated points per cell edge
LOG_TICKS = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0)
NOTES = {"c": " (log scale)", "p": ": compression < 0 < tension"}


def _source_on_plane(ds: xr.Dataset, points: np.ndarray) -> np.ndarray | None:
    if "nutrient_source" not in ds or not ds["nutrient_source"].values.any():
        return None
    mask = ds["nutrient_source"].transpose("z", "y", "x").values.astype(float)
    return sample_nearest(mask, cell_axes(ds), points)


def _upsampled(mask: np.ndarray, factor: int = SAMPLES_PER_CELL) -> np.ndarray:
    return np.kron(mask, np.ones((factor, factor)))


def _draw_rows(ds, names, indices, images, extent, limits, source, axis_labels, title, flip_up=False):
    """The panel grid; images[name] is a list of 2-D arrays (rows t, columns s), one per index.

    extent: outer edges of the image pixels (s0, s1, t0, t1); limits: the domain shown, same order.
    """
    (s0, s1, t0, t1), n_cols = limits, len(indices)
    height = PANEL_WIDTH * (t1 - t0) / (s1 - s0)
    fig, axes = plt.subplots(len(names), n_cols, squeeze=False, layout="constrained",
                             figsize=(PANEL_WIDTH * n_cols + 1.2, height * len(names) + 0.9),
                             sharex=True, sharey=True)
    for row, name in enumerate(names):
        cmap, norm = colour_scale(name, np.stack(images[name]))
        for col, (index, image) in enumerate(zip(indices, images[name])):
            ax = axes[row, col]
            shown = ax.imshow(on_scale(image, norm), origin="lower", extent=extent, cmap=cmap, norm=norm,
                              interpolation="nearest", aspect="equal")
            if source is not None:
                ax.contour(source, levels=[0.5], colors=SOURCE_GREEN, linewidths=1.0,
                           extent=extent, origin="lower")
            if name == "p" and not np.isfinite(image).any():
                ax.text(0.5, 0.5, "mechanics not\nsolved at this time", transform=ax.transAxes,
                        ha="center", va="center", fontsize=8)
            ax.set(xlim=(s0, s1), ylim=(t0, t1))
            if row == 0:
                ax.set_title(time_title(ds, index), fontsize=10)
            if row == len(names) - 1:
                ax.set_xlabel(axis_labels[0], fontsize=8)
            if col == 0:
                ax.set_ylabel(axis_labels[1], fontsize=8)
            ax.tick_params(labelsize=7)
        bar = fig.colorbar(shown, ax=axes[row, :], shrink=0.9, pad=0.01)
        bar.set_label(axis_label(ds[name]) + NOTES.get(name, ""), fontsize=9)
        if name == "c":  # plain numbers on the logarithmic scale
            low, high = bar.norm.vmin, bar.norm.vmax
            bar.set_ticks([v for v in LOG_TICKS if low <= v <= high * (1 + 1e-9)], labels=None, minor=False)
            bar.ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
            bar.ax.yaxis.set_minor_formatter(NullFormatter())
    if flip_up:
        axes[0, 0].invert_yaxis()  # shared: every panel
    suptitle(fig, title, run_title(ds))
    return fig


def cut_figure(ds: xr.Dataset, names: list[str], indices: list[int], plane: Plane):
    """3-D run: the fields on `plane` at the given output indices."""
    centres = cell_axes(ds)
    step = (centres[0][1] - centres[0][0] if centres[0].size > 1 else 1.0) / SAMPLES_PER_CELL
    s, t, points = plane.grid(step)  # one sampling of the plane for every field and time
    images = {}
    for name in names:
        field = ds[name].transpose("time", "z", "y", "x").values
        images[name] = [sample(field[i], centres, points) for i in indices]
    half_s, half_t = 0.5 * (s[1] - s[0]), 0.5 * (t[1] - t[0])  # samples are pixel centres
    extent = (s[0] - half_s, s[-1] + half_s, t[0] - half_t, t[-1] + half_t)
    return _draw_rows(ds, names, indices, images, extent, (s[0], s[-1], t[0], t[-1]), _source_on_plane(ds, points),
                      (plane.s_label, plane.t_label), plane.title, plane.flip_up)


def map_figure(ds: xr.Dataset, names: list[str], indices: list[int]):
    """2-D run: the fields as cell maps at the given output indices."""
    lower, upper = box(ds)
    images = {name: [ds[name].transpose("time", "y", "x").values[i] for i in indices] for name in names}
    source = None
    if "nutrient_source" in ds and ds["nutrient_source"].values.any():
        source = _upsampled(ds["nutrient_source"].transpose("y", "x").values.astype(float))
    extent = (lower[0], upper[0], lower[1], upper[1])
    return _draw_rows(ds, names, indices, images, extent, extent, source, ("x (µm)", "y (µm)"), "cell maps")
