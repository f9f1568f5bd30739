"""The phi >= 0.8 region in 3-D (paper Figs. 3 and 10): marching cubes, drawn with matplotlib.

The surface phi = 0.8 is found by marching cubes (scikit-image) on the
cell-centre values; beyond the walls the field is mirrored about the level so
that biofilm touching a wall shows a closed, solid body ending on the wall, as
in the paper.  The phi = 0.5 surface (the boundary counted by
`biofilm_volume`) is drawn see-through around it, for context when little or
nothing reaches 0.8.  Obstacles (grey, see-through) and the nutrient source
(green) are drawn as the surfaces of their cell masks so the growth direction
reads at a glance.  The view puts the source to the right, a little behind.
"""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr
from matplotlib.colors import LightSource
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection
from skimage import measure

from .cuts import box, cell_axes, diagonal_plane
from .style import OBSTACLE_GREY, SOURCE_GREEN, run_title, suptitle, time_title

LEVEL = 0.8
SHELL = 0.5  # the biofilm boundary of `biofilm_volume`, drawn see-through for context
BIOFILM_COLOUR = "#d95f02"
SHELL_COLOUR = "#fdae6b"


def isosurface(field: np.ndarray, level: float, centres: tuple[np.ndarray, ...]):
    """Triangulated surface field = level of a cell field (z, y, x), closed at the domain walls.

    centres: cell-centre coordinates x, y, z (uniform steps).  NaN counts as below the level.
    Returns vertices (n, 3) as (x, y, z) in µm and triangles (m, 3), or None if nothing reaches the level.
    """
    values = np.asarray(field, dtype=float)
    if not np.any(values >= level):
        return None
    low = min(float(np.nanmin(values)), level) - 1.0
    padded = np.pad(np.where(np.isfinite(values), values, low), 1, mode="edge")
    # the padding mirrors the wall cell about the level: a body touching a wall is closed on the wall
    border = np.ones(padded.shape, bool)
    border[1:-1, 1:-1, 1:-1] = False
    padded[border] = np.minimum(padded[border], 2 * level - padded[border])
    steps = [c[1] - c[0] if c.size > 1 else 1.0 for c in centres]
    verts, faces, _, _ = measure.marching_cubes(padded, level, spacing=(steps[2], steps[1], steps[0]))
    origin = np.array([centres[2][0] - steps[2], centres[1][0] - steps[1], centres[0][0] - steps[0]])
    return (verts + origin)[:, ::-1], faces


def _draw_mesh(ax, mesh, colour, alpha=1.0):
    if mesh is None:
        return
    verts, faces = mesh
    ax.add_collection3d(Poly3DCollection(verts[faces], facecolors=colour, linewidths=0, alpha=alpha,
                                         shade=True, lightsource=LightSource(azdeg=315, altdeg=45)))


def _draw_box(ax, lower, upper):
    corners = np.array([[x, y, z] for x in (lower[0], upper[0]) for y in (lower[1], upper[1])
                        for z in (lower[2], upper[2])])
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8)
             if np.count_nonzero(corners[a] != corners[b]) == 1]
    ax.add_collection3d(Line3DCollection([corners[[a, b]] for a, b in edges], colors="0.3", linewidths=0.6))


def view_azimuth(ds: xr.Dataset) -> float:
    """Azimuth (degrees) that puts the source direction to the right and a little away from the viewer.

    Away, because the opaque source is drawn first (behind the biofilm).
    """
    along = diagonal_plane(ds).along
    return float(np.degrees(np.arctan2(along[1], along[0])) - 120.0)


def figure(ds: xr.Dataset, indices: list[int]):
    """One 3-D view per output index of the phi >= 0.8 region, with obstacles and the source."""
    centres = cell_axes(ds)
    lower, upper = box(ds)
    phi = ds["phi"].transpose("time", "z", "y", "x").values
    masks = {}
    for name in ("obstacle", "nutrient_source"):
        if name in ds and ds[name].values.any():
            masks[name] = isosurface(ds[name].transpose("z", "y", "x").values.astype(float), 0.5, centres)
    azimuth = view_azimuth(ds)
    n = len(indices)
    fig = plt.figure(figsize=(3.6 * n + 0.4, 4.2), layout="constrained")
    for k, index in enumerate(indices):
        ax = fig.add_subplot(1, n, k + 1, projection="3d")
        mesh = isosurface(phi[index], LEVEL, centres)
        ax.computed_zorder = False  # nested surfaces: draw in this order, see-through ones last
        _draw_mesh(ax, masks.get("nutrient_source"), SOURCE_GREEN)
        _draw_mesh(ax, mesh, BIOFILM_COLOUR)
        _draw_mesh(ax, isosurface(phi[index], SHELL, centres), SHELL_COLOUR, alpha=0.18)
        _draw_mesh(ax, masks.get("obstacle"), OBSTACLE_GREY, alpha=0.35)
        _draw_box(ax, lower, upper)
        if mesh is None:
            ax.text2D(0.5, 0.02, f"nowhere φ ≥ {LEVEL}", transform=ax.transAxes, ha="center", fontsize=9)
        ax.set(xlim=(lower[0], upper[0]), ylim=(lower[1], upper[1]), zlim=(lower[2], upper[2]))
        for axis, name in zip((ax.xaxis, ax.yaxis, ax.zaxis), "xyz"):
            axis.set_major_locator(MaxNLocator(4))
            axis.set_label_text(f"{name} (µm)", fontsize=8)
            axis.labelpad = -2
        ax.set_box_aspect(upper - lower, zoom=0.85)
        ax.view_init(elev=22, azim=azimuth)
        ax.tick_params(labelsize=7, pad=-2)
        ax.set_title(time_title(ds, index), fontsize=10)
    suptitle(fig, f"φ ≥ {LEVEL} (orange), φ ≥ {SHELL} (see-through), nutrient source (green)"
             + (", obstacles (grey)" if "obstacle" in masks else ""), run_title(ds))
    return fig
