"""Dead ends off the route: where the way from the colony to the nutrient passes openings that lead nowhere
(paper 4.4: "the biofilm grows into a dead-end ... once nutrients are depleted in the dead-end, ... it retracts").

Found in the geometry a run's dataset records — its obstacle mask, its held nutrient cells (`nutrient_source`)
and its biofilm (phi >= 0.5) at the first output, the colony — not in how a scene drew them, so that a generated
maze and a corridor built of boxes are measured alike:

1. the route: the shortest way through the open cells (8 neighbours, no corner cut between two walls) from the
   colony to the source, each step's length weighted by 1/w^2 (w: the distance to the nearest wall or the grid's
   edge), so that it runs along the middle of the corridors;
2. its corridor: the open cells within the local half-width (w where the route passes) plus one cell of it,
   by the distance through open cells;
3. the dead ends: the connected regions of the other open cells that open onto the corridor in one place (a
   region with two openings is another way, as between a grate's bars), reach deeper than half the corridor's
   width beyond it (shallower ones are the outer corners of the route's bends) and at least `DEEP` times as
   deep as their mouth is wide (open space beside a route, as in a box, is no dead end); numbered in the order
   the route passes their mouths from the colony on.  Each cell of a dead end has its depth, the distance through open
   cells beyond the corridor.

A scene without obstacles, without held nutrient cells (a nutrient face), without biofilm at its start, or in 3-D
has none (`applies`): its dead-end observables are left out.
"""
from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import xarray as xr
from scipy import ndimage
from scipy.sparse.csgraph import dijkstra

from .measures import THRESHOLD, spacing

EIGHT = np.ones((3, 3), bool)  # a cell's neighbours across faces and corners
DEEP = 0.5  # a dead end is at least half as deep as its mouth is wide (open space beside a route is not)


@dataclass(frozen=True)
class DeadEnds:
    """The dead ends of one geometry: `label` per cell (0: none, k: the k-th dead end), `depth` per cell (µm
    beyond the route's corridor; 0 outside dead ends), `route` (the route's cells) and `area` per dead end."""

    label: np.ndarray
    depth: np.ndarray
    route: np.ndarray
    area: np.ndarray  # µm² per dead end (2-D: per µm of thickness), index k - 1


def _graph(open_: np.ndarray, h: float, weight: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
    """(index of each open cell or -1, the symmetric graph of open cells to their 8 neighbours, each edge its
    length times the mean weight of its ends); a diagonal step needs both cells beside it open."""
    index = np.full(open_.shape, -1)
    index[open_] = np.arange(np.count_nonzero(open_))
    ny, nx = open_.shape
    rows, cols, lengths = [], [], []
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        here = (slice(0, ny - dy), slice(max(0, -dx), nx - max(0, dx)))
        there = (slice(dy, ny), slice(max(0, dx), nx + min(0, dx)))
        ok = (index[here] >= 0) & (index[there] >= 0)
        if dy and dx:  # the two cells beside a diagonal step: (y, x + dx) and (y + dy, x)
            ok &= open_[here[0], there[1]] & open_[there[0], here[1]]
        rows.append(index[here][ok])
        cols.append(index[there][ok])
        lengths.append(h * np.hypot(dy, dx) * 0.5 * (weight[here][ok] + weight[there][ok]))
    r, c, v = (np.concatenate(parts) for parts in (rows, cols, lengths))
    n = int(index.max()) + 1
    return index, sp.csr_matrix((np.r_[v, v], (np.r_[r, c], np.r_[c, r])), shape=(n, n))


def find(obstacle: np.ndarray, colony: np.ndarray, source: np.ndarray, h: float) -> DeadEnds:
    """The dead ends off the route from `colony` to `source` (boolean 2-D arrays alike) between `obstacle`s."""
    open_ = ~obstacle
    none = DeadEnds(np.zeros(open_.shape, int), np.zeros(open_.shape), np.zeros(open_.shape, bool), np.zeros(0))
    if obstacle.ndim != 2 or not obstacle.any() or not (colony & open_).any() or not (source & open_).any():
        return none
    wall = ndimage.distance_transform_edt(np.pad(open_, 1))[1:-1, 1:-1] * h  # to a wall or the grid's edge
    index, weighted = _graph(open_, h, 1.0 / np.maximum(wall, h) ** 2)
    starts, ends = index[colony & open_], index[source & open_]
    cost, previous, _ = dijkstra(weighted, indices=starts, min_only=True, return_predecessors=True)
    if not np.isfinite(cost[ends]).any():
        return none  # the source is walled off from the colony
    path = [int(ends[np.argmin(cost[ends])])]
    while previous[path[-1]] >= 0:
        path.append(int(previous[path[-1]]))
    _, plain = _graph(open_, h, np.ones(open_.shape))
    beyond, _, nearest = dijkstra(plain, indices=path, min_only=True, return_predecessors=True)
    half = wall[open_][nearest]  # the corridor's half-width where the route passes nearest
    depth = np.zeros(open_.shape)
    depth[open_] = np.where(np.isfinite(beyond), beyond - half - h, 0.0)
    side = np.zeros(open_.shape, bool)
    side[open_] = np.isfinite(beyond) & (beyond > half + h)
    along = np.zeros(open_.shape, int)  # how far along the route its cell nearest to each open cell lies
    along[open_] = np.argsort(path)[np.searchsorted(np.sort(path), nearest)]
    regions, count = ndimage.label(side)
    corridor = open_ & ~side
    kept = []  # (where along the route its mouth is, its cells)
    for k in range(1, count + 1):
        cells = regions == k
        mouth = ndimage.binary_dilation(cells, EIGHT) & corridor
        deep = depth[cells].max()
        if ndimage.label(mouth, EIGHT)[1] == 1 and deep > np.median(half[cells[open_]]) and \
                deep >= DEEP * np.count_nonzero(mouth) * h:
            kept.append((int(along[cells][np.argmin(depth[cells])]), cells))
    label, areas = np.zeros(open_.shape, int), []
    for _, cells in sorted(kept, key=lambda item: -item[0]):  # path runs source -> colony: mouths from the colony on
        areas.append(np.count_nonzero(cells) * h * h)
        label[cells] = len(areas)
    route = np.zeros(open_.shape, bool)
    route[tuple(np.argwhere(open_)[path].T)] = True
    return DeadEnds(label, np.where(label > 0, depth, 0.0), route, np.array(areas))


@functools.lru_cache(maxsize=4)
def _cached(key: bytes, obstacle: bytes, colony: bytes, source: bytes, shape: tuple[int, ...], h: float) -> DeadEnds:
    unpack = lambda raw: np.frombuffer(raw, bool).reshape(shape)  # noqa: E731
    return find(unpack(obstacle), unpack(colony), unpack(source), h)


def of(ds: xr.Dataset) -> DeadEnds:
    """The dead ends of a run's dataset (its obstacle, nutrient_source and phi at the first output), computed once
    per geometry."""
    obstacle, source = _cells(ds, "obstacle").astype(bool), _cells(ds, "nutrient_source").astype(bool)
    colony = np.nan_to_num(_cells(ds, "phi", time=0)) >= THRESHOLD
    parts = [np.ascontiguousarray(a).tobytes() for a in (obstacle, colony, source)]
    key = hashlib.sha256(b"".join(parts)).digest()
    return _cached(key, *parts, obstacle.shape, spacing(ds))


def _cells(ds: xr.Dataset, name: str, **where) -> np.ndarray:
    """One 2-D field of the dataset (a study's case dimensions: its first case), read in this thread: a lazily
    opened file is never read from dask's thread pool (HDF5 is not thread-safe; `observables.variables`)."""
    field = ds[name].isel(**where, **{d: 0 for d in ds[name].dims if d not in ("y", "x", *where)})
    return field.transpose("y", "x").load(scheduler="synchronous").values


def applies(ds: xr.Dataset) -> bool:
    """Whether the run has a route with dead ends to measure: 2-D, obstacles, held nutrient cells, a colony."""
    return "z" not in ds.dims and all(v in ds for v in ("obstacle", "nutrient_source", "phi")) and \
        bool(_cells(ds, "obstacle").any()) and bool(_cells(ds, "nutrient_source").any()) and of(ds).area.size > 0


def _fields(ds: xr.Dataset) -> np.ndarray:
    return np.nan_to_num(ds["phi"].transpose("time", "y", "x").load(scheduler="synchronous").values)


def biofilm(ds: xr.Dataset) -> np.ndarray:
    """µm² (per µm of thickness) of phi >= 0.5 in the dead ends, per output."""
    inside = of(ds).label > 0
    return np.array([np.count_nonzero((phi >= THRESHOLD) & inside) for phi in _fields(ds)]) * spacing(ds) ** 2


def reach(ds: xr.Dataset) -> np.ndarray:
    """How deep (µm beyond the route's corridor) phi >= 0.5 reaches into a dead end, per output (0: in none)."""
    depth = of(ds).depth
    return np.array([depth[phi >= THRESHOLD].max(initial=0.0) for phi in _fields(ds)])


def per_dead_end(ds: xr.Dataset) -> np.ndarray:
    """µm² of phi >= 0.5 in each dead end (rows) per output (columns)."""
    found, h = of(ds), spacing(ds)
    phi = _fields(ds) >= THRESHOLD
    return np.array([[np.count_nonzero(p & (found.label == k)) for p in phi] for k in range(1, found.area.size + 1)]) \
        * h * h
