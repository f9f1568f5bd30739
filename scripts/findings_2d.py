"""The paper's section-4 statements on its semi-2-D scenes (4.4 maze, and its mechanism in the dead-end corridor;
4.5 grate), measured with verdicts as in `findings.py` (which imports this module at its end).

Dead ends are those a run's own walls have off its route (`biostudy.quantities.dead_ends`); "settled" is the
plateau criterion `settled_from`: the first output from which biofilm volume, mean phi and mean c all stay
within 1 % of their values at the end, for at least the last fifth of the run.
"""
from __future__ import annotations

import numpy as np
from findings import DENSE, EXTENT, NOT, PARTLY, REPRODUCED, Finding, at, grade, series, solved, stresses
from scipy.stats import spearmanr

from biostudy.quantities import dead_ends, measures

PLATEAU = 0.01  # relative: within 1 % of the value at the end
LAST = 0.2  # for at least this fraction of the run


def settled_from(ds) -> float | None:
    """The first output time from which biofilm_volume, phi_mean and c_mean stay within PLATEAU of their values at
    the end (None if that is later than the run's last fifth begins)."""
    t = ds.time.values
    inside = np.ones(t.size, bool)
    for name in ("biofilm_volume", "phi_mean", "c_mean"):
        v = ds[name].values
        inside &= np.abs(v - v[-1]) <= PLATEAU * abs(v[-1])
    first = t.size - np.argmin(inside[::-1]) if not inside.all() else 0  # after the last output outside
    return float(t[first]) if first < t.size and t[first] <= (1 - LAST) * t[-1] else None


def _settling(ds) -> Finding:
    t, since = ds.time.values, settled_from(ds)
    values = "; ".join(f"{label} " + ", ".join(f"{ds[n].values[at(ds, s * t[-1])]:.4g}" for s in (0.6, 0.8, 1.0))
                       for n, label in (("biofilm_volume", "volume"), ("phi_mean", "phi_mean"), ("c_mean", "c_mean")))
    return Finding("4.4", "the biofilm arrives at a steady state by the end",
                   f"biofilm volume (µm²), phi_mean, c_mean at T* = {0.6 * t[-1]:g}, {0.8 * t[-1]:g}, {t[-1]:g}; "
                   "settled from", f"{values}; settled from {'T* = %g' % since if since is not None else 'never'}",
                   f"{grade(since is not None)} (criterion: all three within 1 % of their values at the end for at "
                   "least the run's last fifth)", "series")


def _invasion(ds, found, invaded: np.ndarray, paper: str) -> Finding:
    t = ds.time.values
    largest = invaded.max(axis=1)
    reached = int(np.count_nonzero(largest))
    value = "; ".join(f"{k}: {a:.0f} µm², at most {m:.0f} (T* = {t[np.argmax(s)]:g})"
                      for k, (a, m, s) in enumerate(zip(found.area, largest, invaded), start=1))
    rank = float(spearmanr(found.area, largest)[0]) if reached > 1 and np.ptp(largest) > 0 else np.nan
    verdict = REPRODUCED if reached >= 2 and rank > 0.5 else PARTLY if reached else NOT
    return Finding("4.4", paper, f"{found.area.size} dead ends off the way in (found in the walls, numbered from the "
                   "colony on): area; largest area of phi >= 0.5 in it (when); rank correlation of the two",
                   f"{value}; rank correlation {rank:.2f}",
                   f"{verdict} (criteria: two or more reached, rank correlation above 0.5)", "dead_ends")


def _retraction(ds, found, invaded: np.ndarray, paper: str, forty: bool = True) -> Finding:
    """'Once nutrients are depleted in the dead-end, the biofilm either stays at the level that was before, or it
    retracts': per dead end reached, its largest area and its area at the end, and the mean c in it at both;
    `forty`: also 'the retraction can be observed ... at 40 % of the simulation time when compared to the following
    images' (the maze's own timeline)."""
    t, c = ds.time.values, np.nan_to_num(ds.c.transpose("time", "y", "x").values)
    parts, retracted, after_40 = [], 0, 0
    then = at(ds, 0.4 * t[-1])
    for k, s in enumerate(invaded, start=1):
        if not s.max():
            continue
        peak = int(np.argmax(s))
        cells = found.label == k
        loss = 1 - s[-1] / s[peak]
        retracted += loss >= 0.1
        after_40 += s[then] > 0 and s[-1] <= 0.9 * s[then]
        parts.append(f"{k}: {s[peak]:.0f} → {s[-1]:.0f} µm² ({-loss:+.0%}; mean c {c[peak][cells].mean():.3f} → "
                     f"{c[-1][cells].mean():.3f})")
    verdict = grade(retracted > 0, after_40 > 0) if forty else grade(retracted > 0)
    why = f"{retracted} dead end(s) gave up 10 % or more of their largest" + (
        f", {after_40} held 10 % less at the end than at 40 % of the run (criteria: one of each)" if forty else
        " (criterion: one)")
    return Finding("4.4", paper, "per dead end reached: largest area of phi >= 0.5 → at the end, mean c in it then",
                   "; ".join(parts) or "none reached", f"{verdict}: {why}", "dead_ends")


def maze(ds, scene):
    layout = scene.obstacle[0].layout()
    x, y = scene.grid.solver_grid().cell_coordinates()
    radius = np.hypot(x - layout.center[0], y - layout.center[1])
    phi = np.nan_to_num(ds.phi.values)
    nearest = np.array([radius[p >= EXTENT].min() if (p >= EXTENT).any() else np.nan for p in phi])
    inside = nearest <= layout.core_radius
    found, invaded = dead_ends.of(ds), dead_ends.per_dead_end(ds)
    maximum = measures.phi_max(ds)
    return [
        Finding("4.4", "the biofilm reaches the middle of the maze",
                f"distance of the nearest phi >= 0.5 to the centre (µm); core radius {layout.core_radius:g} µm",
                series(nearest, ds.time.values, every=8, digits=3) + f"; inside the core from "
                f"{'T* = %g' % ds.time.values[np.argmax(inside)] if inside.any() else 'never'}",
                f"{grade(bool(inside.any()))} (criterion: inside the core)", "maps"),
        _settling(ds),
        _invasion(ds, found, invaded, "the biofilm grows into dead ends it passes, the bigger the dead end the more"),
        _retraction(ds, found, invaded, "once the nutrient in a dead end is depleted the biofilm stays or retracts, "
                                        "visible from 40 % of the run"),
        Finding("4.4", "dense biofilm", "max phi", series(maximum, ds.time.values, every=8),
                f"{grade(bool(np.all(maximum >= DENSE)))} (criterion: >= 0.8 at every output)"
                + ("" if np.all(maximum >= DENSE) else ": the pointwise velocity of the maze's wide beta = 10 fronts "
                   "thins the colony on its way in"), "maps"),
    ], {}


def dead_end(ds, scene):
    found, invaded = dead_ends.of(ds), dead_ends.per_dead_end(ds)
    largest = invaded.max(axis=1)
    wide, narrow = int(np.argmax(found.area)), int(np.argmin(found.area))
    return [
        _invasion(ds, found, invaded, "the front grows into the dead ends it passes, the bigger the more (the "
                                      "corridor: 32 and 16 µm wide)"),
        Finding("4.4", "the bigger the dead end, the more biofilm grows into it",
                "largest area of phi >= 0.5 in the wider / the narrower dead end (µm²)",
                f"{largest[wide]:.0f} / {largest[narrow]:.0f}",
                f"{grade(largest[wide] > largest[narrow] > 0)} (criterion: more in the wider)", "dead_ends"),
        _retraction(ds, found, invaded, "once the nutrient in a dead end is depleted the biofilm stays or retracts",
                    forty=False),
        _settling(ds),
    ], {}


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
    near, far = last[(ring > 0) & (ring < 1)].mean(), last[(ring > 3) & (ring < 5)].mean()
    p, p_verdict = stresses(ds)
    swelling, shown = "mechanics off", 0.0
    if "u" in ds:
        i = solved(ds)[-1]
        size = np.nanmax(np.sqrt((ds["u"].values[i] ** 2).sum(-1)))
        shown = 500 * size
        swelling = (f"largest |u| {size:.2g} µm at T* = {ds.time.values[i]:g}, alpha up to "
                    f"{np.nanmax(ds.alpha.values[-1]):.2g}: ×500 makes it {shown:.2g} µm")
    indent = REPRODUCED if near < 0.8 * far else PARTLY if near < far else NOT
    return [
        Finding("4.5", "splits at the bars and recombines", "most separate runs of phi >= 0.5 in an open row between "
                "bars", series(counts, ds.time.values, every=4, digits=2),
                f"{grade(counts.max() >= 3, counts[-1] == 1)} (criteria: three or more fingers, one at the end)",
                "maps"),
        Finding("4.5", "a half-circle indent at the source",
                "mean phi within 1 µm outside the source / 3–5 µm outside, at the end", f"{near:.2f} / {far:.2f}",
                f"{indent} (criterion: within 1 µm below 80 % of 3–5 µm; below it at all: partly, a shallow indent)",
                "maps"),
        Finding("4.5", "compression in the middle, tension where the biofilm meets boundaries", "p", p, p_verdict,
                "warped"),
        Finding("4.5", "swelling visible when magnified ×500", "displacement", swelling,
                f"{grade(shown >= 1.0)} (criterion: at least 1 µm at ×500)", "warped"),
    ], {}


FINDINGS_2D = {"maze": maze, "dead-end": dead_end, "grate": grate}
