"""The paper's section-4 statements measured on a run's dataset: what docs/paper.md sets beside the paper.

`FINDINGS[scene](ds, scene)` returns rows (statement, what is measured, value) for one bundled scene's
full-length run; `scripts/gallery.py` calls it for every scene it runs and writes docs/gallery/findings.md.
Quantities come from `biostudy.quantities.measures` (dense = phi >= 0.8, the paper's isosurface level; extent =
phi >= 0.5); stresses at the last output where the mechanics was solved.
"""
from __future__ import annotations

import numpy as np
import xarray as xr
from scipy import ndimage

from biostudy.quantities import measures

DENSE, EXTENT = measures.DENSE, measures.THRESHOLD


def at(ds: xr.Dataset, t: float) -> int:
    return int(np.argmin(np.abs(ds["time"].values - t)))


def when(ds: xr.Dataset, reached: np.ndarray) -> str:
    hits = np.flatnonzero(reached)
    return f"T* = {ds['time'].values[hits[0]]:g}" if hits.size else "never"


def series(values, times, every: int = 4, digits: int = 2) -> str:
    return ", ".join(f"{v:.{digits}g}" if np.isfinite(v) else "–" for v in np.asarray(values)[::every]) + \
        f" (T* = {times[0]:g}, {times[every]:g}, …)"


def stresses(ds: xr.Dataset) -> str:
    """Where p is negative (compression) and positive (tension), at the last solved output."""
    if "p" not in ds:
        return "mechanics off"
    solved = [i for i in range(ds.sizes["time"]) if np.isfinite(ds["p"].values[i]).any()]
    i = solved[-1]
    p, phi = ds["p"].values[i], ds["phi"].values[i]  # both NaN in obstacle cells: compared False below
    scale = np.nanmax(np.abs(p))
    inside, edge, outside = phi >= DENSE, (phi > 0.1) & (phi < DENSE), phi < 0.01
    parts = [f"T* = {ds['time'].values[i]:g}: |p| up to {scale:.2g} Pa",
             f"dense biofilm: mean p {np.nanmean(p[inside]):.2g} Pa, "
             f"{np.mean(p[inside] < 0):.0%} of its cells compressed"
             if inside.any() else "no dense biofilm",
             f"edge (0.1 < phi < 0.8): largest tension {np.nanmax(p[edge]):.2g} Pa" if edge.any() else "no edge",
             f"void (phi < 0.01): |p| <= {np.nanmax(np.abs(p[outside])) / scale:.1%} of the largest" if outside.any()
             else "no void"]
    return "; ".join(parts)


def advances(ds: xr.Dataset, centre, directions: dict, level: float) -> str:
    z, y, x = np.meshgrid(ds.z.values, ds.y.values, ds.x.values, indexing="ij")
    out = []
    for name, d in directions.items():
        d = np.asarray(d, float) / np.linalg.norm(d)
        along = (x - centre[0]) * d[0] + (y - centre[1]) * d[1] + (z - centre[2]) * d[2]
        reach = [along[phi >= level].max() if (phi >= level).any() else np.nan for phi in ds.phi.values]
        out.append(f"{name} {reach[-1] - reach[0]:+.1f}")
    return ", ".join(out) + " µm"


def directional(ds, scene):
    t, c, m = ds.time.values, ds.c_mean.values, ds.phi_mean.values
    dirs = {"toward": (1, 1, 1), "back": (-1, -1, -1), "side": (1, -1, 0)}
    return [
        ("mean c settles around 10 %", "c_mean at T* = 0.2, 0.5, 1",
         f"{c[at(ds, .2)]:.3f}, {c[at(ds, .5)]:.3f}, {c[-1]:.3f}"),
        ("phi still filling at T* = 1", "phi_mean at T* = 0.8, 0.9, 1",
         f"{m[at(ds, .8)]:.3f}, {m[at(ds, .9)]:.3f}, {m[-1]:.3f}"),
        ("the sphere's volume increases", "dense volume (µm³)", series(measures.volume(ds), t, digits=4)),
        ("egg-shaped toward the source, slightly backward, little to the sides",
         "advance by T* = 1 of phi >= 0.5 / phi >= 0.8 along the diagonal",
         advances(ds, (10, 10, 10), dirs, EXTENT) + " / " + advances(ds, (10, 10, 10), dirs, DENSE)),
        ("dense biofilm (the paper's phi >= 0.8 renders)", "max phi", series(measures.phi_max(ds), t)),
        ("compression inside, a ring of tension at the edge, zero outside", "p", stresses(ds)),
    ]


def agar(ds, scene):
    t = ds.time.values
    height = scene.grid.solver_grid().extent[2]
    top, top_dense = measures.height(ds, "z", EXTENT), measures.height(ds, "z", DENSE)
    rows = [
        ("height", "top of phi >= 0.5 / phi >= 0.8 (µm)", series(top, t) + " / " + series(top_dense, t)),
        ("fills the cube (g = 1e8: after 13 % of the time)", "phi >= 0.5 / phi >= 0.8 at the lid",
         f"{when(ds, top >= height - 0.5)} / {when(ds, top_dense >= height - 0.5)} (the front-speed bound r/2 "
         f"allows it from T* = {(height - top[0]) / (0.5 * scene.params.r):.2f})"),
        ("spreads into a bottom layer", "reach of phi >= 0.5 from the colony's axis (µm)",
         series(measures.reach(ds, "z", EXTENT), t)),
        ("dense biofilm", "max phi / dense volume (µm³) at T* = 1",
         f"{measures.phi_max(ds)[-1]:.2f} / {measures.volume(ds)[-1]:.0f}"),
        ("equilibrium: neither c nor phi changes at the end", "c_mean / phi_mean at T* = 0.8 and 1",
         f"{ds.c_mean.values[at(ds, .8)]:.3f} → {ds.c_mean.values[-1]:.3f} / "
         f"{ds.phi_mean.values[at(ds, .8)]:.3f} → {ds.phi_mean.values[-1]:.3f}"),
        ("mushroom, then droplet", "width of phi >= 0.5 (µm) near the top / at 1-3 µm above the agar, per time",
         _cap_and_stem(ds)),
        ("compression inside, tension toward bottom and top", "p", stresses(ds)),
    ]
    return rows


def _cap_and_stem(ds):
    out = []
    z = ds.z.values
    top = measures.height(ds, "z", EXTENT)
    for i in (at(ds, .2), at(ds, .3), at(ds, .5), at(ds, 1.0)):
        phi = ds.phi.values[i] >= EXTENT
        def width(sel, phi=phi):  # the disc of the largest layer
            return 2 * np.sqrt(phi[sel].sum(axis=(1, 2)).max() / np.pi)

        cap = (z > top[i] - 3) & (z <= top[i])
        stem = (z > 1) & (z < 3)
        out.append(f"T* = {ds.time.values[i]:g}: {width(cap):.1f} / {width(stem):.1f}")
    return "; ".join(out)


def obstacles(ds, scene):
    problem = scene.problem()
    x, y, z = problem.grid.cell_coordinates()
    behind = (x > 25.5) & (np.abs(y - 15) < 2.5)
    phi = np.nan_to_num(ds.phi.values)
    dense_behind = [(p[behind] >= DENSE).any() for p in phi]
    bodies, _ = ndimage.label(phi[-1] >= DENSE)
    one = len(set(bodies[behind & (phi[-1] >= DENSE)]) | {bodies[15, 15, 15]}) == 1
    return [
        ("no biofilm in the columns", "phi in obstacle cells", "NaN at every output" if np.isnan(
            ds.phi.values[:, problem.obstacle]).all() else "not NaN"),
        ("grows around the columns and reconnects behind them", "dense biofilm in the column's shadow",
         f"from {when(ds, np.array(dense_behind))}; at T* = 1 {'one body with the colony' if one else 'separate'}"),
        ("dense biofilm", "max phi / dense volume (µm³) at T* = 1",
         f"{measures.phi_max(ds)[-1]:.2f} / {measures.volume(ds)[-1]:.0f}"),
        ("pressure as in the other scenes", "p", stresses(ds)),
    ]


def maze(ds, scene):
    layout = scene.obstacle[0].layout()
    x, y = scene.grid.solver_grid().cell_coordinates()
    radius = np.hypot(x - layout.center[0], y - layout.center[1])
    phi = np.nan_to_num(ds.phi.values)
    t = ds.time.values
    nearest = [radius[p >= EXTENT].min() if (p >= EXTENT).any() else np.nan for p in phi]
    sector, names, way = layout.sector(x, y), layout.sectors(), layout.path()
    entrance = sector == names.index(way[0])
    area = scene.grid.spacing**2
    in_entrance = (phi[:, entrance] >= EXTENT).sum(axis=1) * area
    branches = _branches(layout)
    sizes, filled = [], []
    for cells in branches:
        mask = np.isin(sector, [names.index(s) for s in cells])
        sizes.append(mask.sum() * area)
        filled.append((phi[:, mask] >= EXTENT).sum(axis=1).max() * area)
    varied = len(sizes) > 2 and len(set(filled)) > 1  # no correlation of anything with a constant
    rank = np.corrcoef(np.argsort(np.argsort(sizes)), np.argsort(np.argsort(filled)))[0, 1] if varied else np.nan
    return [
        ("reaches the centre and settles", "distance of the nearest phi >= 0.5 to the centre (µm); core radius "
         f"{layout.core_radius:g} µm", series(nearest, t, every=8, digits=3)),
        ("dead ends invaded in proportion to their size", f"{len(sizes)} dead ends (corridors from a leaf back to "
         "a junction): rank correlation of their area with the largest area of phi >= 0.5 reached in them; "
         "how many were reached", f"{rank:.2f}; {sum(f > 0 for f in filled)} of {len(sizes)} reached "
         f"(areas {int(min(sizes))}-{int(max(sizes))} µm²)"),
        ("retraction visible from 40 %", "area of phi >= 0.5 in the entrance sector (µm²)",
         series(in_entrance, t, every=8, digits=3)),
        ("dense biofilm", "max phi", series(measures.phi_max(ds), t, every=8)),
    ]


def _branches(layout) -> list[list[tuple[int, int]]]:
    """The maze's dead ends: from every leaf of its tree off the way in, the corridor of sectors back to the
    nearest junction (a sector opening into three or more) or to the way; the way's last sector is no leaf."""
    way, tree = set(layout.path()), layout.tree
    out = []
    for leaf in (n for n, near in tree.items() if len(near) == 1 and n not in way):
        corridor, previous, here = [leaf], None, leaf
        while True:
            onward = [n for n in tree[here] if n != previous]
            if len(onward) != 1:
                break
            previous, here = here, onward[0]
            if here in way or len(tree[here]) > 2:
                break
            corridor.append(here)
        out.append(sorted(corridor))
    return out


def grate(ds, scene):
    bars = scene.obstacle[0]
    y = scene.grid.solver_grid().cell_coordinates()[1][:, 0]
    phi = ds.phi.values
    rows = np.flatnonzero(~np.isnan(phi[0]).any(axis=1) & (y > bars.lower[1]) & (y < bars.upper[1]))

    def runs(row):
        inside = row >= EXTENT
        return int(inside[0]) + int(np.count_nonzero(inside[1:] & ~inside[:-1]))

    counts = np.array([max(runs(phi[t, j]) for j in rows) for t in range(ds.sizes["time"])])
    source = scene.nutrient[0]
    x, yy = scene.grid.solver_grid().cell_coordinates()
    ring = np.hypot(x - source.center[0], yy - source.center[1]) - source.radius
    last = np.nan_to_num(phi[-1])
    swelling = ""
    if "u" in ds:
        solved = [i for i in range(ds.sizes["time"]) if np.isfinite(ds["u"].values[i]).any()]  # bars: no u inside
        size = np.nanmax(np.sqrt((ds["u"].values[solved[-1]] ** 2).sum(-1)))
        swelling = (f"largest |u| {size:.2g} µm at T* = {ds.time.values[solved[-1]]:g}, "
                    f"alpha up to {np.nanmax(ds.alpha.values[-1]):.2g}: ×500 makes it {500 * size:.2g} µm")
    return [
        ("splits at the bars and recombines", "most separate runs of phi >= 0.5 in an open row between bars, per time",
         series(counts, ds.time.values, every=4, digits=2)),
        ("a half-circle indent at the source", "mean phi within 1 µm outside the source / 3-5 µm outside, at the end",
         f"{last[(ring > 0) & (ring < 1)].mean():.2f} / {last[(ring > 3) & (ring < 5)].mean():.2f}"),
        ("compression in the middle, tension where the biofilm meets boundaries", "p", stresses(ds)),
        ("swelling visible when magnified ×500", "displacement", swelling or "mechanics off"),
    ]


FINDINGS = {"directional": directional, "agar-g1e8": agar, "agar-g1e10": agar, "obstacles": obstacles,
            "maze": maze, "grate": grate}
