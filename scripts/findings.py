"""The paper's section-4 statements measured on a run's dataset, each with its verdict: what docs/paper.md sets
beside the paper.

`FINDINGS[run](ds, scene)` returns (rows, facts) for one bundled scene's full-length run (or a variant of one,
`scripts/gallery.py`'s REFINED runs): a row is a `Finding` — section, statement, what is measured, the value and
the verdict, decided by the criterion the verdict states (never by hand) — and `facts` the numbers a statement
about two runs needs (`ACROSS`: rows from the facts of several runs, e.g. the agar plateaus of g = 1e8 and 1e10).
`scripts/gallery.py` calls them for every run it makes and writes docs/gallery/findings.md (and the facts beside
it), which `scripts/docs_sync.py` renders into docs/paper.md.  Quantities come from `biostudy.quantities`
(dense = phi >= 0.8, the paper's isosurface level; extent = phi >= 0.5); stresses at the outputs where the mechanics
was solved.  The 2-D scenes' statements (maze, dead end, grate) are in `findings_2d.py`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr
from scipy import ndimage

from biostudy.quantities import measures

DENSE, EXTENT = measures.DENSE, measures.THRESHOLD
REPRODUCED, PARTLY, NOT = "**reproduced**", "**partly**", "**not reproduced**"
CONTRADICTS = "**contradicts the paper's own equations**"


@dataclass(frozen=True)
class Finding:
    section: str
    statement: str  # what the paper says
    measured: str  # what is measured
    value: str  # ours
    verdict: str  # REPRODUCED, PARTLY, ... and why, by the criterion it names
    pictures: str = ""  # the gallery's pictures that show it: the run's (by tag: "cut, series") or files ("x.png")


def at(ds: xr.Dataset, t: float) -> int:
    return int(np.argmin(np.abs(ds["time"].values - t)))


def when(ds: xr.Dataset, reached: np.ndarray) -> str:
    hits = np.flatnonzero(reached)
    return f"T* = {ds['time'].values[hits[0]]:g}" if hits.size else "never"


def series(values, times, every: int = 4, digits: int = 2) -> str:
    return ", ".join(f"{v:.{digits}g}" if np.isfinite(v) else "–" for v in np.asarray(values)[::every]) + \
        f" (T* = {times[0]:g}, {times[every]:g}, …)"


def grade(*met: bool) -> str:
    """All criteria met: reproduced; some: partly; none: not reproduced."""
    return REPRODUCED if all(met) else PARTLY if any(met) else NOT


def solved(ds: xr.Dataset) -> list[int]:
    return [i for i in range(ds.sizes["time"]) if "p" in ds and np.isfinite(ds["p"].values[i]).any()]


def stresses(ds: xr.Dataset, index: int | None = None) -> tuple[str, str]:
    """(where p is negative and positive at an output where the mechanics was solved (default the last), the
    verdict on "compression inside, tension at the edge, zero outside": at least 90 % of the dense cells
    compressed, some tension at the edge, |p| in the void below 1 % of the largest)."""
    if "p" not in ds:
        return "mechanics off", NOT
    i = solved(ds)[-1] if index is None else index
    p, phi = ds["p"].values[i], ds["phi"].values[i]  # both NaN in obstacle cells: compared False below
    scale = np.nanmax(np.abs(p))
    inside, edge, outside = phi >= DENSE, (phi > 0.1) & (phi < DENSE), phi < 0.01
    compressed = float(np.mean(p[inside] < 0)) if inside.any() else 0.0
    tension = float(np.nanmax(p[edge])) if edge.any() else 0.0
    void = float(np.nanmax(np.abs(p[outside])) / scale) if outside.any() else 0.0
    parts = [f"T* = {ds['time'].values[i]:g}: |p| up to {scale:.2g} Pa",
             f"dense biofilm: mean p {np.nanmean(p[inside]):.2g} Pa, {compressed:.0%} of its cells compressed"
             if inside.any() else "no dense biofilm",
             f"edge (0.1 < phi < 0.8): largest tension {tension:.2g} Pa" if edge.any() else "no edge",
             f"void (phi < 0.01): |p| <= {void:.1%} of the largest" if outside.any() else "no void"]
    verdict = grade(compressed >= 0.9, tension > 0, void < 0.01)
    return "; ".join(parts), f"{verdict} (criteria: >= 90 % of the dense cells compressed, tension at the edge, " \
                             "void |p| < 1 % of the largest)"


def advances(ds: xr.Dataset, centre, directions: dict, level: float) -> dict[str, float]:
    z, y, x = np.meshgrid(ds.z.values, ds.y.values, ds.x.values, indexing="ij")
    out = {}
    for name, d in directions.items():
        d = np.asarray(d, float) / np.linalg.norm(d)
        along = (x - centre[0]) * d[0] + (y - centre[1]) * d[1] + (z - centre[2]) * d[2]
        reach = [along[phi >= level].max() if (phi >= level).any() else np.nan for phi in ds.phi.values]
        out[name] = reach[-1] - reach[0]
    return out


def mean_c(ds: xr.Dataset, label: str) -> tuple[Finding, dict]:
    """4.1's "the nutrients tend to an equilibrium state at an average nutrients value of around 10 %", "being
    approached by the termination of the simulation": c_mean at T* = 1 within a factor 1.5 of 10 %, and settled
    (changing by at most 5 % over the last quarter of the run)."""
    c, t = ds.c_mean.values, ds.time.values
    end, change = float(c[-1]), float(c[-1] / c[at(ds, 0.75)] - 1)
    level, settled = 0.1 / 1.5 <= end <= 0.15, abs(change) <= 0.05
    value = (f"{', '.join(f'{c[at(ds, s)]:.3f}' for s in (0, 0.25, 0.5, 0.75, 1.0))}; last quarter {change:+.0%}; "
             f"10 % passed {when(ds, c <= 0.1)}")
    verdict = (f"{grade(level, settled)}: {end:.1%} at T* = 1 (criterion: 6.7–15 %), {change:+.0%} over the last "
               "quarter (settled: within 5 %)")
    return (Finding("4.1", "mean c settles around 10 % by the end (T* = 1)", f"c_mean at T* = 0, 0.25, 0.5, 0.75, 1 "
                    f"({label})", value, verdict, "series"),
            {"c_end": end, "c_start": float(c[0]), "t_10": float(t[np.argmax(c <= 0.1)]) if (c <= 0.1).any() else None})


def directional(ds, scene):
    m = ds.phi_mean.values
    dirs = {"toward": (1, 1, 1), "back": (-1, -1, -1), "side": (1, -1, 0)}
    extent, dense = advances(ds, (10, 10, 10), dirs, EXTENT), advances(ds, (10, 10, 10), dirs, DENSE)
    volume = measures.volume(ds)
    p, p_verdict = stresses(ds)
    c_row, facts = mean_c(ds, "h = 1 µm, the 1 µm corner cube held")
    rows = [
        c_row,
        Finding("4.1", "phi still filling at T* = 1", "phi_mean at T* = 0.8, 0.9, 1",
                f"{m[at(ds, .8)]:.3f}, {m[at(ds, .9)]:.3f}, {m[-1]:.3f}",
                f"{grade(m[-1] > m[at(ds, .9)])} (criterion: phi_mean still rises at the end)", "series"),
        Finding("4.1", "the sphere's volume increases", "dense volume (µm³)", series(volume, ds.time.values, digits=4),
                f"{grade(volume[-1] > volume[0])} (criterion: larger at the end; its largest is "
                f"{volume.max():.0f} µm³ at T* = {ds.time.values[np.argmax(volume)]:g})", "isosurface"),
        Finding("4.1", "egg-shaped toward the source, slightly backward, little to the sides",
                "advance of phi >= 0.5 / phi >= 0.8 along the diagonal by T* = 1 (µm)",
                ", ".join(f"{k} {extent[k]:+.1f} / {dense[k]:+.1f}" for k in dirs),
                f"{grade(extent['toward'] > extent['back'] > extent['side'] > 0)} (criterion: toward > back > side "
                "> 0)",
                "cut, isosurface"),
        Finding("4.1", "dense biofilm (the paper's phi >= 0.8 renders)", "max phi", series(measures.phi_max(ds),
                ds.time.values), f"{grade(bool(np.all(measures.phi_max(ds) >= DENSE)))} (criterion: >= 0.8 at every "
                "output)", "isosurface"),
        Finding("4.1", "compression inside, a ring of tension at the edge, zero outside", "p", p, p_verdict, "cut"),
    ]
    return rows, facts


def directional_variant(label: str):
    """The 4.1 mean-c row of a variant of the directional scene (refined, or another source)."""
    def measure(ds, scene):
        row, facts = mean_c(ds, label)
        return [row], facts
    return measure


def agar(ds, scene):
    t = ds.time.values
    height = scene.grid.solver_grid().extent[2]
    top, top_dense = measures.height(ds, "z", EXTENT), measures.height(ds, "z", DENSE)
    lid = top >= height - 0.5
    earliest = (height - top[0]) / (0.5 * scene.params.r)
    reach = measures.reach(ds, "z", EXTENT)
    c, m = ds.c_mean.values, ds.phi_mean.values
    changes = (c[-1] / c[at(ds, .8)] - 1, m[-1] / m[at(ds, .8)] - 1)
    p, p_verdict = stresses(ds)
    tall = scene.params.g < 1e9
    rows = [
        Finding("4.2", "g = 1e8: a dense colony grows tall and fills the cube" if tall else
                "g = 1e10: limited height, then a layer along the bottom",
                "top of phi >= 0.5 / 0.8 (µm); reach from the colony's axis (µm); max phi and dense volume at T* = 1",
                f"{series(top, t)} / {series(top_dense, t)}; reach {series(reach, t)}; "
                f"{measures.phi_max(ds)[-1]:.2f}, {measures.volume(ds)[-1]:.0f} µm³",
                (f"{grade(bool(lid.any()), measures.phi_max(ds)[-1] >= DENSE)} (criteria: phi >= 0.5 at the lid, "
                 "dense at the end)") if tall else
                (f"{grade(top[-1] < 0.5 * height, reach[-1] > top[-1] - top[0] + reach[0])} (criteria: below half "
                 "the box, spreading sideways more than it rose)"), "cut, isosurface"),
        *([Finding("4.2", "fills the cube after 13 % of the time", "when phi >= 0.5 / 0.8 reach the lid",
                   f"{when(ds, lid)} / {when(ds, top_dense >= height - 0.5)}",
                   f"{CONTRADICTS}: a front moves at most r c/(k + c) < r/2 = {scene.params.r / 2:g} µm/T*, so the "
                   f"{height - top[0]:.0f} µm from the colony's top to the lid take at least T* = {earliest:.2f}"
                   if earliest > 0.13 else f"{grade(bool(lid.any()) and float(t[np.argmax(lid)]) <= 0.13)}",
                   "series")] if tall else []),
        Finding("4.2", "equilibrium: neither c nor phi changes at the end", "c_mean / phi_mean at T* = 0.8 and 1",
                f"{c[at(ds, .8)]:.3f} → {c[-1]:.3f} / {m[at(ds, .8)]:.3f} → {m[-1]:.3f}",
                f"{grade(abs(changes[0]) <= 0.02, abs(changes[1]) <= 0.02)}: {changes[0]:+.1%} / {changes[1]:+.1%} "
                "(criterion: within 2 %)", "series"),
        *([_mushroom(ds)] if tall else []),
        Finding("4.2", "compression inside, tension at the edge", "p at the end", p, p_verdict, "warped"),
        _tension_where(ds, scene),
    ]
    return rows, {"c_end": float(c[-1])}


def _mushroom(ds) -> Finding:
    """'first a mushroom-shaped structure and then a droplet-like structure': a cap wider than the stem while the
    colony rises (before it reaches the lid)."""
    z, top = ds.z.values, measures.height(ds, "z", EXTENT)
    widths = []
    for i in (at(ds, .2), at(ds, .3), at(ds, .5), at(ds, 1.0)):
        phi = ds.phi.values[i] >= EXTENT

        def width(sel, phi=phi):  # the disc of the largest layer
            return 2 * np.sqrt(phi[sel].sum(axis=(1, 2)).max() / np.pi)

        widths.append((ds.time.values[i], width((z > top[i] - 3) & (z <= top[i])), width((z > 1) & (z < 3))))
    rising = [w for w in widths if w[0] < 0.45]
    capped = [w for w in widths if w[1] > w[2]]
    verdict = grade(any(cap > stem for _, cap, stem in rising))
    if verdict == NOT and capped:
        verdict = f"{PARTLY}: a cap wider than its base only at T* = {capped[0][0]:g}, under the lid"
    return Finding("4.2", "mushroom, then droplet", "width of phi >= 0.5 (µm) near the top / 1–3 µm above the agar",
                   "; ".join(f"T* = {t:g}: {cap:.1f} / {stem:.1f}" for t, cap, stem in widths),
                   f"{verdict} (criterion: a cap wider than the base while the colony rises)", "cut")


def _tension_where(ds, scene) -> Finding:
    """Fig. 8a, 'at the very start of the simulation': tension where the biofilm grows toward the bottom and at the
    top, pressure inside.  Measured at the first solved output after T* = 0."""
    i = next((k for k in solved(ds) if ds.time.values[k] > 0), None)
    if i is None:
        return Finding("4.2", "tension toward the bottom and at the top early on", "p", "mechanics off", NOT)
    p, phi = ds["p"].values[i], ds["phi"].values[i]
    z = ds.z.values[:, None, None] * np.ones_like(phi)
    colony = phi >= EXTENT
    top = z[colony].max()
    base, cap = colony & (z < 2), colony & (z > top - 2)
    where = z[colony][np.argmax(p[colony])]
    value = (f"T* = {ds.time.values[i]:g}: mean p in the colony's bottom 2 µm {np.mean(p[base]):.2g} Pa, its top 2 µm "
             f"{np.mean(p[cap]):.2g} Pa; largest tension {np.max(p[colony]):.2g} Pa at z = {where:g} µm")
    bottom_tension, top_tension = where < z[colony].min() + 2, np.mean(p[cap]) > 0
    verdict = grade(bottom_tension, top_tension)
    return Finding("4.2", "early on, tension where the biofilm grows toward the bottom and at its top; pressure inside",
                   "p by height in the colony (phi >= 0.5)", value,
                   f"{verdict} (criteria: the largest tension in the colony's bottom 2 µm, its top 2 µm in tension)"
                   + ("" if bottom_tension else ": the boundary condition — on the clamped agar the base is the most "
                      "compressed; on a sliding one the largest tension is at the foot, as in the paper "
                      "(docs/paper.md, 'Where the colony on agar is in tension')"), "warped, agar_tension.png")


def obstacles(ds, scene):
    problem = scene.problem()
    x, y, z = problem.grid.cell_coordinates()
    behind = (x > 25.5) & (np.abs(y - 15) < 2.5)
    phi = np.nan_to_num(ds.phi.values)
    dense_behind = np.array([(p[behind] >= DENSE).any() for p in phi])
    bodies, _ = ndimage.label(phi[-1] >= DENSE)
    one = len(set(bodies[behind & (phi[-1] >= DENSE)]) | {bodies[15, 15, 15]}) == 1
    empty = bool(np.isnan(ds.phi.values[:, problem.obstacle]).all())
    p, p_verdict = stresses(ds)
    return [
        Finding("4.3", "no biofilm in the columns", "phi in obstacle cells", "NaN at every output" if empty else
                "not NaN", f"{grade(empty)}", "isosurface"),
        Finding("4.3", "grows around the columns and reconnects behind them", "dense biofilm in the column's shadow",
                f"from {when(ds, dense_behind)}; at T* = 1 {'one body with the colony' if one else 'separate'}",
                f"{grade(bool(dense_behind.any()), one)} (criteria: dense biofilm behind the column, one body with "
                "the colony)", "isosurface, cut"),
        Finding("4.3", "dense biofilm", "max phi / dense volume (µm³) at T* = 1",
                f"{measures.phi_max(ds)[-1]:.2f} / {measures.volume(ds)[-1]:.0f}",
                f"{grade(measures.phi_max(ds)[-1] >= DENSE)}", "cut"),
        Finding("4.3", "pressure as in the other scenes", "p", p, p_verdict, "cut"),
    ], {}


def agar_plateaus(facts: dict) -> list[Finding]:
    """4.2: 'the nutrient concentration's equilibrium [of g = 1e8] is significantly higher than ... [of g = 1e10]':
    at least twice."""
    high, low = facts["agar-g1e8"]["c_end"], facts["agar-g1e10"]["c_end"]
    return [Finding("4.2", "the c plateau of g = 1e8 far above that of g = 1e10", "c_mean at T* = 1",
                    f"{high:.3f} against {low:.3f}", f"{grade(high >= 2 * low)} (criterion: at least twice)", "series")]


def mean_c_dependence(facts: dict) -> list[Finding]:
    """4.1's mean c against the source's size and the cell size: the level is the source's, not the model's."""
    base, fine, wide = (facts[k]["c_end"] for k in ("directional", "directional-h0.5", "directional-source3"))
    return [Finding("4.1", "mean c around 10 %: how it depends on the source and the grid",
                    "c_mean at T* = 1: the 1 µm corner cube held at h = 1 and 1/2 µm; a 3 µm corner cube at h = 1 µm",
                    f"{base:.3f}, {fine:.3f} ({fine / base - 1:+.0%} at h/2); {wide:.3f}",
                    f"the paper's 10 % lies {'between' if min(base, fine) < 0.1 < wide else 'outside'} the levels of "
                    "a 1 µm and a 3 µm source: the level measures the source the paper held (its corner node), which "
                    "its text does not size", "series")]


FINDINGS = {"directional": directional, "agar-g1e8": agar, "agar-g1e10": agar, "obstacles": obstacles,
            "directional-h0.5": directional_variant("h = 1/2 µm, the same 1 µm corner cube"),
            "directional-source3": directional_variant("h = 1 µm, a 3 µm corner cube held")}
ACROSS = {"agar-plateaus": (("agar-g1e8", "agar-g1e10"), agar_plateaus),
          "mean-c": (("directional", "directional-h0.5", "directional-source3"), mean_c_dependence)}

from findings_2d import FINDINGS_2D  # noqa: E402  (it imports Finding and the helpers above)

FINDINGS.update(FINDINGS_2D)
