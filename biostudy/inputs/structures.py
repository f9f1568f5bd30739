"""Generated obstacle geometries of the paper's semi-2-D scenes (sections 4.4 and 4.5).

* `CircularMaze`: a seeded, reproducible circular ("theta") maze of concentric
  ring corridors split into sectors.  A random spanning tree of the sectors
  (depth-first from the entrance: long corridors and dead ends of every size)
  decides which walls are open; one opening leads into the central circle
  (where the scene holds the nutrient) and one through the outer wall (the
  entrance, centred on `entrance_angle`, where the biofilm starts).
* `grate`: a square lattice of square bars inside a box.

Both work on plain coordinate arrays (µm), so a 3-D grid gets the 2-D
pattern extruded along z.  A cell is wall when its centre lies within half
the wall thickness of a wall arc or radial wall segment.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


def _sector_counts(radii: np.ndarray, first: int) -> list[int]:
    """Sectors per ring: doubled whenever the arc at a ring's inner radius exceeds twice the ring width."""
    counts = [first]
    width = radii[1] - radii[0]
    for inner in radii[1:-1]:
        n = counts[-1]
        counts.append(2 * n if 2 * np.pi * inner / n > 2.0 * width else n)
    return counts


def _neighbours(ring: int, sector: int, counts: list[int]) -> list[tuple[int, int]]:
    n = counts[ring]
    out = [(ring, (sector - 1) % n), (ring, (sector + 1) % n)] if n > 1 else []
    if ring > 0:
        out.append((ring - 1, sector * counts[ring - 1] // n))
    if ring + 1 < len(counts):
        ratio = counts[ring + 1] // n
        out += [(ring + 1, sector * ratio + k) for k in range(ratio)]
    return out


def _spanning_tree(counts: list[int], rng: np.random.Generator, start: tuple[int, int]) -> dict:
    """Randomised depth-first spanning tree over all (ring, sector) cells of the maze."""
    tree = {(i, j): [] for i, n in enumerate(counts) for j in range(n)}
    seen, stack = {start}, [start]
    while stack:
        here = stack[-1]
        fresh = [c for c in _neighbours(*here, counts) if c not in seen]
        if not fresh:
            stack.pop()
            continue
        there = fresh[rng.integers(len(fresh))]
        tree[here].append(there)
        tree[there].append(here)
        seen.add(there)
        stack.append(there)
    return tree


@dataclass(frozen=True)
class CircularMaze:
    """A circular maze centred at `center` (x, y in µm), rings numbered from the inside out."""

    center: tuple[float, float]
    diameter: float
    wall: float
    rings: int
    core_radius: float  # radius of the open central circle (inner face of the innermost wall)
    seed: int
    entrance_angle: float = 0.0  # radians from +x, counter-clockwise
    first_sectors: int = 6

    @cached_property
    def radii(self) -> np.ndarray:
        """Centre lines of the circular walls, innermost first."""
        outer = 0.5 * self.diameter - 0.5 * self.wall
        return np.linspace(self.core_radius + 0.5 * self.wall, outer, self.rings + 1)

    @cached_property
    def counts(self) -> list[int]:
        return _sector_counts(self.radii, self.first_sectors)

    @cached_property
    def _layout(self) -> tuple[dict, int]:
        rng = np.random.default_rng(self.seed)
        tree = _spanning_tree(self.counts, rng, (self.rings - 1, 0))
        return tree, int(rng.integers(self.counts[0]))

    @property
    def tree(self) -> dict:
        """(ring, sector) -> the sectors it opens into."""
        return self._layout[0]

    @property
    def rotation(self) -> float:
        """Angle of sector boundary 0: outer sector 0 (the entrance) is centred on entrance_angle."""
        return self.entrance_angle - np.pi / self.counts[-1]

    @property
    def entrance(self) -> tuple[float, float]:
        """Middle of the gap in the outer wall, µm."""
        r = self.radii[-1]
        return (self.center[0] + r * np.cos(self.entrance_angle), self.center[1] + r * np.sin(self.entrance_angle))

    @property
    def corridor(self) -> float:
        """Clear width of a ring corridor between its walls, µm."""
        return float(self.radii[1] - self.radii[0] - self.wall)

    def path(self) -> list[tuple[int, int]]:
        """Sectors from the entrance to the one that opens into the central circle."""
        tree, goal = self._layout
        start, parents, queue = (self.rings - 1, 0), {(self.rings - 1, 0): None}, [(self.rings - 1, 0)]
        while queue:
            here = queue.pop(0)
            for there in tree[here]:
                if there not in parents:
                    parents[there] = here
                    queue.append(there)
        route, node = [], (0, goal)
        while node is not None:
            route.append(node)
            node = parents[node]
        assert route[-1] == start
        return route[::-1]

    def side_branches(self) -> list[tuple[tuple[int, int], list[tuple[int, int]]]]:
        """The dead ends the way in passes, from the tree: for every sector of `path()` and every sector it opens
        into off the way, (that sector of the way, the sectors of the branch behind the opening).  The way's
        last sector's branches are the rest of the maze around the core."""
        way, tree = self.path(), self.tree
        on_way, found = set(way), []
        for here in way:
            for first in (n for n in tree[here] if n not in on_way):
                branch, seen, stack = [], {here, first}, [first]
                while stack:
                    sector = stack.pop()
                    branch.append(sector)
                    for n in tree[sector]:
                        if n not in seen:
                            seen.add(n)
                            stack.append(n)
                found.append((here, sorted(branch)))
        return found

    def _polar(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dx, dy = x - self.center[0], y - self.center[1]
        return np.hypot(dx, dy), np.mod(np.arctan2(dy, dx) - self.rotation, 2 * np.pi)

    def sector(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Index into `sectors()` of the ring sector each point lies in; -1 inside the core or outside."""
        rho, theta = self._polar(x, y)
        ring = np.searchsorted(self.radii, rho) - 1
        inside = (ring >= 0) & (ring < self.rings)
        ring = np.clip(ring, 0, self.rings - 1)
        counts = np.asarray(self.counts)
        offsets = np.concatenate([[0], np.cumsum(counts)[:-1]])
        index = offsets[ring] + (theta * counts[ring] / (2 * np.pi)).astype(int) % counts[ring]
        return np.where(inside, index, -1)

    def sectors(self) -> list[tuple[int, int]]:
        return [(i, j) for i, n in enumerate(self.counts) for j in range(n)]

    def walls(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """True where a point lies in a wall or outside the maze's outer wall."""
        rho, theta = self._polar(x, y)
        half, counts, tree, radii = 0.5 * self.wall, self.counts, self.tree, self.radii
        solid = rho > radii[-1] + half

        def within(ring: int, sector: int, r: float) -> np.ndarray:
            step = 2 * np.pi / counts[ring]
            margin = half / max(r, 1e-9)
            return (theta >= sector * step + margin) & (theta <= (sector + 1) * step - margin)

        for i, r in enumerate(radii):  # circular walls, minus their openings
            band = np.abs(rho - r) <= half
            if not band.any():
                continue
            opening = np.zeros_like(band)
            if i == 0:
                opening |= within(0, self._layout[1], r)
            elif i == self.rings:
                opening |= within(self.rings - 1, 0, r)
            else:
                for j in range(counts[i]):  # ring i's sector j opens inward where the tree says so
                    if (i - 1, j * counts[i - 1] // counts[i]) in tree[(i, j)]:
                        opening |= within(i, j, r)
            solid |= band & ~opening
        for i in range(self.rings):  # radial walls between neighbouring sectors of ring i
            inside = (rho >= radii[i] - half) & (rho <= radii[i + 1] + half)
            n = counts[i]
            for j in range(n):
                if n > 1 and (i, (j + 1) % n) in tree[(i, j)]:
                    continue
                boundary = (j + 1) * 2 * np.pi / n
                arc = np.abs(np.angle(np.exp(1j * (theta - boundary)))) * rho
                solid |= inside & (arc <= half)
        return solid


def grate(x: np.ndarray, y: np.ndarray, lower: tuple[float, float], upper: tuple[float, float],
          bar: float, pitch: float) -> np.ndarray:
    """Square bars of side `bar` on a square lattice of `pitch` µm, as many as fit in the box
    lower..upper (x, y), the lattice centred in it."""
    inside = np.ones(np.broadcast(x, y).shape, bool)
    for q, low, high in ((x, lower[0], upper[0]), (y, lower[1], upper[1])):
        count = int(np.floor((high - low - bar) / pitch + 1e-9)) + 1
        first = 0.5 * (low + high) - 0.5 * (count - 1) * pitch  # centre of the first bar
        k = np.clip(np.rint((q - first) / pitch), 0, count - 1)
        inside &= np.abs(q - (first + k * pitch)) <= 0.5 * bar * (1 + 1e-9)
    return inside
