"""The deformed body, displacement magnified (paper Fig. 13: the grate's mesh, distortion x 500).

Growth strains are small (alpha ~ k_alpha t ~ 1e-3), so the deformation is
invisible at true scale; `factor` magnifies the displacement u.  A 2-D run is
drawn as its grid of cells moved to x + factor u (the cells' corners are the
nodes where u lives), its biofilm cells (phi >= 0.5) coloured by phi, cell
edges drawn; the void's cells are left out (soft: at x 500 they fold over
each other, a tangle that hides the biofilm), obstacles are grey at rest
(rigid).  Every panel has the same axes (all that any of them draws), so
the panels have one size and the deformation reads across them.  A 3-D run shows its phi >= 0.8
surface with every vertex moved by factor u (u interpolated trilinearly from
the nodes) inside the deformed outline of the domain.  Only outputs at which
the mechanics was solved (u finite) can be drawn.
"""
from __future__ import annotations

import matplotlib.colors as mcolors
import matplotlib.pyplot as plt
import numpy as np
import xarray as xr
from matplotlib.collections import PolyCollection
from scipy.ndimage import map_coordinates

from .cuts import box, cell_axes
from .isosurface import BIOFILM_COLOUR, LEVEL, _draw_mesh, isosurface, view_azimuth
from .style import OBSTACLE_GREY, axis_label, colour_scale, run_title, suptitle, time_title

BIOFILM = 0.5  # cells drawn deformed in 2-D: the biofilm, as its volume counts it (the void's soft cells fold)


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


def _signed_areas(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Signed area (µm²) of every displaced cell, corners (ny+1, nx+1); <= 0 where the cell folds over."""
    corners = [(x[:-1, :-1], y[:-1, :-1]), (x[:-1, 1:], y[:-1, 1:]), (x[1:, 1:], y[1:, 1:]), (x[1:, :-1], y[1:, :-1])]
    return 0.5 * sum(xa * yb - xb * ya for (xa, ya), (xb, yb) in zip(corners, corners[1:] + corners[:1]))


def _map_panel(ax, ds: xr.Dataset, index: int, factor: float, cmap, norm) -> tuple:
    """The biofilm's cells (phi >= 0.5) at node + factor u, coloured by phi, edges drawn; obstacles grey at rest;
    the domain's outline dashed.  Returns the mesh and how many drawn cells fold over."""
    x, y = displaced_nodes(ds, index, factor)
    phi = ds["phi"].isel(time=index).transpose("y", "x").values
    biofilm = np.nan_to_num(phi, nan=0.0) >= BIOFILM
    corners = [np.s_[:-1, :-1], np.s_[:-1, 1:], np.s_[1:, 1:], np.s_[1:, :-1]]  # counter-clockwise
    quads = np.stack([np.stack([x[c][biofilm], y[c][biofilm]], axis=-1) for c in corners], axis=1)
    mesh = PolyCollection(quads, array=phi[biofilm], cmap=cmap, norm=norm, edgecolors="0.25", linewidths=0.15)
    ax.add_collection(mesh)
    if "obstacle" in ds and ds["obstacle"].values.any():
        rest = np.meshgrid(ds["x_node"].values, ds["y_node"].values)
        solid = ds["obstacle"].transpose("y", "x").values.astype(bool)
        ax.pcolormesh(*rest, np.ma.masked_where(~solid, np.ones(solid.shape)), cmap=mcolors.ListedColormap(
            [OBSTACLE_GREY]), shading="flat")
    lower, upper = box(ds)
    ax.plot([lower[0], upper[0], upper[0], lower[0], lower[0]], [lower[1], lower[1], upper[1], upper[1], lower[1]],
            color="0.5", linestyle="--", linewidth=0.6)
    return mesh, int(np.count_nonzero(biofilm & (_signed_areas(x, y) <= 0)))


def _extent(ds: xr.Dataset, indices: list[int], factor: float) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corner of everything drawn at any of the outputs: the domain and the displaced biofilm."""
    lower, upper = box(ds)
    for index in indices:
        nodes = displaced_nodes(ds, index, factor)
        cells = [d for d in ("z", "y", "x") if d in ds.dims]
        phi = np.nan_to_num(ds["phi"].isel(time=index).transpose(*cells).values, nan=0.0) >= BIOFILM
        if not phi.any():
            continue
        used = np.zeros(nodes[0].shape, bool)
        for corner in np.ndindex(*(2,) * phi.ndim):  # every node of a biofilm cell
            used[tuple(slice(c, c + n) for c, n in zip(corner, phi.shape))] |= phi
        lower = np.minimum(lower, [c[used].min() for c in nodes])
        upper = np.maximum(upper, [c[used].max() for c in nodes])
    return lower, upper


def displaced_vertices(ds: xr.Dataset, index: int, verts: np.ndarray, factor: float) -> np.ndarray:
    u = np.nan_to_num(ds["u"].isel(time=index).transpose("z_node", "y_node", "x_node", "component").values, nan=0.0)
    nodes = [ds[f"{a}_node"].values for a in ("z", "y", "x")]
    index_coords = np.stack([(verts[:, 2 - k] - n[0]) / (n[1] - n[0]) for k, n in enumerate(nodes)])
    moved = verts.copy()
    for k in range(3):
        moved[:, k] += factor * map_coordinates(u[..., k], index_coords, order=1, mode="nearest")
    return moved


def figure(ds: xr.Dataset, wanted: list[int], factor: float):
    """The deformed body (displacement x factor) at the outputs nearest to `wanted` where u was solved: every
    panel the same size, on the same axes, so that the deformation reads from one to the next."""
    indices = solved_indices(ds, wanted)
    n = len(indices)
    lower, upper = _extent(ds, indices, factor)
    margin = 0.03 * (upper - lower)
    lower, upper = lower - margin, upper + margin
    u = np.abs(np.nan_to_num(ds["u"].isel(time=indices).values)).max(initial=0.0)
    if "z" not in ds.dims:
        aspect = (upper[0] - lower[0]) / (upper[1] - lower[1])
        width = float(np.clip(3.0 * aspect, 2.0, 9.0))
        columns = max(1, min(n, int(14 // width)))
        rows = -(-n // columns)
        fig, axes = plt.subplots(rows, columns, figsize=(width * columns + 1.4, 3.0 * rows + 1.1),
                                 layout="constrained", squeeze=False, sharex=True, sharey=True)
        cmap, norm = colour_scale("phi", ds["phi"].isel(time=indices).values)
        folded = 0
        for ax, index in zip(axes.flat, indices):
            mesh, folds = _map_panel(ax, ds, index, factor, cmap, norm)
            folded = max(folded, folds)
            ax.set_xlim(lower[0], upper[0])
            ax.set_ylim(lower[1], upper[1])
            ax.set_aspect("equal", adjustable="box")
            ax.set_title(time_title(ds, index), fontsize=10)
            ax.tick_params(labelsize=7)
        for ax in axes.flat[n:]:
            ax.remove()
        for ax in axes[-1, :]:
            ax.set_xlabel("x (µm)", fontsize=8)
        for ax in axes[:, 0]:
            ax.set_ylabel("y (µm)", fontsize=8)
        fig.colorbar(mesh, ax=list(axes.flat[:n]), shrink=0.9, pad=0.01).set_label(axis_label(ds["phi"]), fontsize=9)
        shown = f"cells with φ ≥ {BIOFILM:g} displaced by {factor:g} u (largest |u| {u:.3g} µm)"
        if folded:
            shown += (f"; up to {folded} cells fold over at this magnification ({factor:g} × {u:.3g} µm against "
                      f"cells of {float(ds.attrs.get('grid_spacing', 1.0)):g} µm): a smaller factor shows them")
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
            low, high = np.minimum(lower, [c.min() for c in nodes]), np.maximum(upper, [c.max() for c in nodes])
            ax.set_xlim(low[0], high[0])
            ax.set_ylim(low[1], high[1])
            ax.set_zlim(low[2], high[2])
            ax.set_box_aspect(tuple(high - low))
            ax.view_init(elev=22, azim=view_azimuth(ds))
            ax.set_title(time_title(ds, index), fontsize=10)
            ax.tick_params(labelsize=7, pad=-2)
        shown = f"φ ≥ {LEVEL} displaced by {factor:g} u (largest |u| {u:.3g} µm)"
    suptitle(fig, f"deformed body: {shown}", run_title(ds))
    return fig
