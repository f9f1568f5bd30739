"""The deformed body, displacement magnified (paper Fig. 13: the grate's mesh, distortion x 500).

Growth strains are small (alpha ~ k_alpha t ~ 1e-3), so the deformation is
invisible at true scale; `factor` magnifies the displacement u.  A 2-D run is
drawn as its grid of cells moved to x + factor u (the cells' corners are the
nodes where u lives), coloured by phi, cell edges drawn; obstacle cells are
left out (rigid, u = 0 on their faces).  A 3-D run shows its phi >= 0.8
surface with every vertex moved by factor u (u interpolated trilinearly from
the nodes) inside the deformed outline of the domain.  Only outputs at which
the mechanics was solved (u finite) can be drawn.
"""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr
from scipy.ndimage import map_coordinates

from .cuts import box, cell_axes
from .isosurface import BIOFILM_COLOUR, LEVEL, _draw_mesh, isosurface, view_azimuth
from .style import axis_label, colour_scale, run_title, suptitle, time_title


def solved_indices(ds: xr.Dataset, wanted: list[int]) -> list[int]:
    """Of the wanted output indices, those where u was solved; else the solved outputs nearest to them."""
    if "u" not in ds:
        raise ValueError("--warp needs a run with mechanics (a displacement u); this dataset has none")
    dims = [d for d in ds["u"].dims if d != "time"]
    # solved where any node has u: nodes inside a rigid obstacle carry none (NaN) in every solved output
    solved = np.flatnonzero(np.isfinite(ds["u"].values).any(axis=tuple(range(1, len(dims) + 1))))
    if solved.size == 0:
        raise ValueError("--warp: the mechanics was not solved at any output of this run")
    times = ds["time"].values
    picked = [int(solved[np.argmin(np.abs(times[solved] - times[i]))]) for i in wanted]
    return sorted(set(picked))


def displaced_nodes(ds: xr.Dataset, index: int, factor: float) -> list[np.ndarray]:
    """Node coordinates moved by factor u at one output: one array per axis x, y[, z], shaped like the nodes
    (z_node, y_node, x_node).  Nodes inside obstacles (u NaN) do not move."""
    axes = [a for a in ("x", "y", "z") if f"{a}_node" in ds.dims]
    order = [f"{a}_node" for a in reversed(axes)]
    u = np.nan_to_num(ds["u"].isel(time=index).transpose(*order, "component").values, nan=0.0)
    grids = np.meshgrid(*(ds[name].values for name in order), indexing="ij")  # (z,) y, x
    return [g + factor * u[..., k] for k, g in zip(range(len(axes)), reversed(grids))]


def _map_panel(ax, ds: xr.Dataset, index: int, factor: float, cmap, norm):
    x, y = displaced_nodes(ds, index, factor)
    phi = ds["phi"].isel(time=index).transpose("y", "x").values
    mesh = ax.pcolormesh(x, y, np.ma.masked_invalid(phi), cmap=cmap, norm=norm, shading="flat",
                         edgecolors="0.25", linewidth=0.15)
    lower, upper = box(ds)
    ax.plot([lower[0], upper[0], upper[0], lower[0], lower[0]], [lower[1], lower[1], upper[1], upper[1], lower[1]],
            color="0.5", linestyle="--", linewidth=0.6)
    ax.set_aspect("equal")
    return mesh


def displaced_vertices(ds: xr.Dataset, index: int, verts: np.ndarray, factor: float) -> np.ndarray:
    u = np.nan_to_num(ds["u"].isel(time=index).transpose("z_node", "y_node", "x_node", "component").values, nan=0.0)
    nodes = [ds[f"{a}_node"].values for a in ("z", "y", "x")]
    index_coords = np.stack([(verts[:, 2 - k] - n[0]) / (n[1] - n[0]) for k, n in enumerate(nodes)])
    moved = verts.copy()
    for k in range(3):
        moved[:, k] += factor * map_coordinates(u[..., k], index_coords, order=1, mode="nearest")
    return moved


def figure(ds: xr.Dataset, wanted: list[int], factor: float):
    """The deformed body (displacement x factor) at the outputs nearest to `wanted` where u was solved."""
    indices = solved_indices(ds, wanted)
    n = len(indices)
    if "z" not in ds.dims:
        lower, upper = box(ds)
        width = 3.4 * (upper[0] - lower[0]) / (upper[1] - lower[1])
        fig, axes = plt.subplots(1, n, figsize=(width * n + 1.2, 3.8), layout="constrained", squeeze=False)
        cmap, norm = colour_scale("phi", ds["phi"].isel(time=indices).values)
        for ax, index in zip(axes[0], indices):
            mesh = _map_panel(ax, ds, index, factor, cmap, norm)
            ax.set_title(time_title(ds, index), fontsize=10)
            ax.set_xlabel("x (µm)", fontsize=8)
            ax.tick_params(labelsize=7)
        axes[0, 0].set_ylabel("y (µm)", fontsize=8)
        fig.colorbar(mesh, ax=axes[0, :], shrink=0.9, pad=0.01).set_label(axis_label(ds["phi"]), fontsize=9)
    else:
        centres = cell_axes(ds)
        phi = ds["phi"].transpose("time", "z", "y", "x").values
        fig = plt.figure(figsize=(3.6 * n + 0.4, 4.2), layout="constrained")
        for k, index in enumerate(indices):
            ax = fig.add_subplot(1, n, k + 1, projection="3d")
            surface = isosurface(phi[index], LEVEL, centres)
            if surface is not None:
                surface = (displaced_vertices(ds, index, surface[0], factor), surface[1])
            _draw_mesh(ax, surface, BIOFILM_COLOUR)
            nodes = displaced_nodes(ds, index, factor)
            outline = [(np.s_[:, :, 0], np.s_[:, :, -1]), (np.s_[:, 0, :], np.s_[:, -1, :]),
                       (np.s_[0, :, :], np.s_[-1, :, :])]
            for faces in outline:  # the deformed domain's edges, light
                for face in faces:
                    xs, ys, zs = (c[face] for c in nodes)
                    ax.plot_wireframe(xs, ys, zs, rstride=max(xs.shape[0] - 1, 1), cstride=max(xs.shape[1] - 1, 1),
                                      color="0.5", linewidth=0.4)
            ax.view_init(elev=22, azim=view_azimuth(ds))
            ax.set_title(time_title(ds, index), fontsize=10)
            ax.tick_params(labelsize=7, pad=-2)
    suptitle(fig, f"deformed body, displacement × {factor:g}"
             + ("" if "z" not in ds.dims else f" (φ ≥ {LEVEL})"), run_title(ds))
    return fig
