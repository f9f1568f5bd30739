"""How accurate is a scene's result, and what does accuracy cost (`biostudy convergence`).

Four refinement series from the scene as given (level 0):
  space     the grid refined by 2 per level (cells 2^ndim x), the time step kept;
  time      the nominal step halved per level, the grid kept;
  both      grid and step refined together;
  adaptive  error-controlled steps (step doubling) with the tolerance divided
            by 4 per level (local error ~ dt^2: halves the step), the grid kept.
The reference of each series is its own finest level (the adaptive series is
measured against the finest fixed-step level of `time`, same grid).  Errors
at the final output time: phi in L1 and L2 on the series' coarsest grid
(finer fields restricted by cell averaging), biofilm_volume (relative),
c_mean, front position (µm), and p in L2 when the mechanics is on.  The
observed order p is fitted to the differences between successive levels,
|q_l - q_(l+1)| ~ size^p (unbiased, unlike errors against a finite
reference); the error of the reference itself is then estimated by
Richardson, |q_L - q_(L-1)| / (2^p - 1).  Quantities a series reproduces to
round-off (below EXACT) get no order: they are reported as exact.
A level is one job: runs share `run_jobs` with sweeps (workers, a Dask
cluster, resume), identical runs (level 0 of three series) run once.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from . import measures, store
from .errors import BadInput
from .formatting import number
from .runner import Job, SweepReport, run_jobs
from .scene import Scene, overrides_text, scene_from_data, set_key

SERIES = ("space", "time", "both", "adaptive")
FIRST_TOLERANCE = 1e-2  # adaptive level 0: local error in phi per step
EXACT = 1e-9  # differences below this are round-off: no order to fit
QUANTITIES = ("phi_L1", "phi_L2", "biofilm_volume", "c_mean", "front_position", "p_L2")
UNITS = {"phi_L1": "1", "phi_L2": "1", "biofilm_volume": "1", "c_mean": "1", "front_position": "um", "p_L2": "Pa"}
LONG_NAMES = {
    "phi_L1": "mean |phi - phi_ref| over open cells (common grid)",
    "phi_L2": "root mean square of phi - phi_ref over open cells (common grid)",
    "biofilm_volume": "relative error of the biofilm volume (phi >= 0.5)",
    "c_mean": "error of the mean nutrient concentration",
    "front_position": "error of the front position toward the nutrient",
    "p_L2": "root mean square of p - p_ref over open cells (common grid)",
}


@dataclass(frozen=True)
class Refinement:
    """One level of one refinement series: how much finer than the scene as given (level 0) it is."""

    series: str
    index: int
    refine: int  # grid refinement factor against level 0
    steps: int
    tolerance: float | None

    @property
    def job_id(self) -> str:
        text = f"refine={self.refine}_steps={self.steps}"
        return text + (f"_tol={self.tolerance:.3g}" if self.tolerance is not None else "")


def chosen_series(text: str) -> tuple[str, ...]:
    """'space,time' -> ('space', 'time'); an unknown or empty choice is `BadInput`."""
    chosen = tuple(s.strip() for s in text.split(",") if s.strip())
    unknown = [s for s in chosen if s not in SERIES]
    if unknown or not chosen:
        raise BadInput(f"unknown series {', '.join(unknown) or '(none)'}; choose from {', '.join(SERIES)}",
                       None, "--series")
    return chosen


def plan(base: Scene, levels: int, series: tuple[str, ...] = SERIES, tolerance: float = FIRST_TOLERANCE) -> list[Refinement]:
    """The levels of every requested series (plus the fixed-step reference the adaptive series needs)."""
    steps = base.time.steps
    out = []
    for name in series:
        for i in range(levels):
            if name == "space":
                out.append(Refinement(name, i, 2**i, steps, None))
            elif name == "time":
                out.append(Refinement(name, i, 1, steps * 2**i, None))
            elif name == "both":
                out.append(Refinement(name, i, 2**i, steps * 2**i, None))
            else:
                out.append(Refinement(name, i, 1, steps, tolerance / 4**i))
    if "adaptive" in series and "time" not in series:
        out.append(Refinement("time", levels - 1, 1, steps * 2 ** (levels - 1), None))
    return out


def refined(data: dict, scene_file: Path, level: Refinement) -> Scene:
    """The base scene's data with the level's grid, steps and tolerance."""
    data = copy.deepcopy(data)
    grid = data["grid"]
    set_key(data, "grid.shape", [n * level.refine for n in grid["shape"]])
    set_key(data, "grid.spacing", float(grid.get("spacing", 1.0)) / level.refine)
    set_key(data, "time.steps", level.steps)
    if level.tolerance is not None:
        set_key(data, "numerics.time_tolerance", level.tolerance)
    return scene_from_data(data, scene_file)


def check_refinable(base: Scene, scene_file: Path) -> None:
    for kind in ("biofilm", "nutrient", "obstacle"):
        for i, region in enumerate(getattr(base, kind)):
            if getattr(region, "shape", None) == "mask":
                raise BadInput("a mask region has a fixed resolution and cannot be refined; describe it by "
                               "shapes to measure convergence", scene_file, f"{kind}[{i}]")


def run(data: dict, scene_file: Path, out_dir: Path, levels: int, series: tuple[str, ...] = SERIES,
        tolerance: float = FIRST_TOLERANCE, workers: int | None = None, scheduler: str | None = None,
        notify=None, fixed: dict | None = None) -> tuple[xr.Dataset, SweepReport]:
    """Run every level (skipping finished ones), measure, write DIR/convergence.nc; returns it and the report."""
    if levels < 2:
        raise BadInput("needs at least 2 levels (the finest is the reference)", None, "--levels")
    base = scene_from_data(copy.deepcopy(data), scene_file)
    check_refinable(base, scene_file)
    wanted = plan(base, levels, series, tolerance)
    scenes = {level.job_id: refined(data, scene_file, level) for level in wanted}
    text = overrides_text(fixed or {})
    jobs = [Job(job_id, scene, scene_file, text, {"case_id": job_id}) for job_id, scene in scenes.items()]
    report = run_jobs(jobs, out_dir, workers, scheduler, notify=notify)
    ds = measure(wanted, out_dir, levels, series, base)
    ds.attrs = store.with_provenance({**ds.attrs, "scene": base.to_toml(), "scene_file": str(scene_file.resolve()),
                                      "overrides": text})
    store.write_atomic(ds, out_dir / "convergence.nc")
    return ds, report


def _final(path: Path) -> dict | None:
    """What a level contributes: final fields and scalars, or None if it did not finish."""
    record = store.recorded(path)
    if not record or record.get("status") != "done":
        return None
    ds = store.open_dataset(path)
    last = ds.isel(time=-1)
    return {
        "phi": last["phi"].values, "p": last["p"].values if "p" in ds else None,
        "biofilm_volume": float(last["biofilm_volume"]), "c_mean": float(last["c_mean"]),
        "front_position": measures.front_position(ds), "wall_time": float(ds.attrs["wall_time"]),
        "steps": int(ds.attrs["steps_taken"]), "t_end": float(ds["time"].values[-1]),
    }


def _errors(result: dict, reference: dict, factor_result: int, factor_reference: int) -> dict:
    phi = measures.field_errors(measures.restrict(result["phi"], factor_result),
                                measures.restrict(reference["phi"], factor_reference))
    errors = {"phi_L1": phi[0], "phi_L2": phi[1],
              "biofilm_volume": abs(result["biofilm_volume"] - reference["biofilm_volume"])
              / max(abs(reference["biofilm_volume"]), 1e-300),
              "c_mean": abs(result["c_mean"] - reference["c_mean"]),
              "front_position": abs(result["front_position"] - reference["front_position"]),
              "p_L2": float("nan")}
    if result["p"] is not None and reference["p"] is not None:
        errors["p_L2"] = measures.field_errors(measures.restrict(result["p"], factor_result),
                                               measures.restrict(reference["p"], factor_reference))[1]
    return errors


def _successive(mine: list[Refinement], results: dict) -> list[dict]:
    """Errors of each level against the next finer one (on the series' coarsest grid)."""
    coarse = mine[0].refine
    out = []
    for level, finer in zip(mine, mine[1:]):
        a, b = results[level.job_id], results[finer.job_id]
        if a is None or b is None:
            out.append({q: float("nan") for q in QUANTITIES})
        else:
            out.append(_errors(a, b, level.refine // coarse, finer.refine // coarse))
    return out


def measure(wanted: list[Refinement], out_dir: Path, levels: int, series: tuple[str, ...], base: Scene) -> xr.Dataset:
    """convergence.nc from the finished levels: dimensions (series, level)."""
    results = {level.job_id: _final(store.case_file(out_dir, level.job_id)) for level in wanted}
    shape = (len(series), levels)
    table = {name: np.full(shape, np.nan) for name in ("cells", "h", "dt", "tolerance", "wall_time", "steps")}
    errors = {q: np.full(shape, np.nan) for q in QUANTITIES}
    attrs = {}
    h0, cells0 = float(base.grid.spacing), int(np.prod(base.grid.shape))
    for s, name in enumerate(series):
        mine = [lv for lv in wanted if lv.series == name]
        if name == "adaptive":
            reference_level = next(lv for lv in wanted if lv.series == "time" and lv.index == levels - 1)
        else:
            reference_level = mine[-1]
        reference = results[reference_level.job_id]
        for level in mine:
            result = results[level.job_id]
            i = level.index
            table["cells"][s, i] = cells0 * level.refine ** base.grid.solver_grid().ndim
            table["h"][s, i] = h0 / level.refine
            table["tolerance"][s, i] = level.tolerance if level.tolerance is not None else np.nan
            if result is None:
                continue
            table["wall_time"][s, i] = result["wall_time"]
            table["steps"][s, i] = result["steps"]
            table["dt"][s, i] = result["t_end"] / result["steps"]
            if reference is not None and level.job_id != reference_level.job_id:
                coarse = mine[0].refine
                for q, value in _errors(result, reference, level.refine // coarse,
                                        reference_level.refine // coarse).items():
                    errors[q][s, i] = value
        sizes = table["tolerance"][s] if name == "adaptive" else (table["dt"][s] if name == "time" else table["h"][s])
        steps = _successive(mine, results)
        for q in QUANTITIES:
            differences = np.array([d[q] for d in steps])
            if differences.size == 0 or np.all(np.isnan(differences)):
                continue  # not measured (p without mechanics)
            if np.nanmax(differences, initial=0.0) < EXACT:
                attrs[f"order_{name}_{q}"] = "exact"
                continue
            order = measures.observed_order(sizes[: differences.size], differences)
            attrs[f"order_{name}_{q}"] = order
            if name != "adaptive" and differences.size and math.isfinite(order) and order > 0:
                attrs[f"reference_error_{name}_{q}"] = float(differences[-1] / (2**order - 1))
    data = {
        "cells": (("series", "level"), table["cells"], {"units": "1", "long_name": "number of grid cells"}),
        "h": (("series", "level"), table["h"], {"units": "um", "long_name": "cell size"}),
        "dt": (("series", "level"), table["dt"], {"units": "1", "long_name": "mean time step (T*)"}),
        "tolerance": (("series", "level"), table["tolerance"],
                      {"units": "1", "long_name": "time_tolerance of the error-controlled steps"}),
        "wall_time": (("series", "level"), table["wall_time"], {"units": "s", "long_name": "wall time of the run"}),
        "steps": (("series", "level"), table["steps"], {"units": "1", "long_name": "accepted time steps"}),
        **{f"error_{q}": (("series", "level"), errors[q], {"units": UNITS[q], "long_name": LONG_NAMES[q]})
           for q in QUANTITIES},
    }
    coords = {"series": ("series", np.array(series, dtype=object), {"units": "1", "long_name": "refinement series"}),
              "level": ("level", np.arange(levels), {"units": "1", "long_name": "refinement level (0 = as given)"})}
    attrs.update({
        "Conventions": "CF-1.10", "title": f"convergence of {base.name}",
        "reference": "finest level of each series (adaptive: finest fixed-step level of the time series, same "
                     "grid); errors at the final output time; reference_error_* = Richardson estimate "
                     "|q_L - q_(L-1)| / (2^p - 1) of the reference's own error",
        "levels": levels, "series": ", ".join(series),
    })
    return xr.Dataset(data, coords=coords, attrs=store.legal_attrs(attrs))


def table_text(ds: xr.Dataset) -> str:
    """Markdown table of every level, then the observed orders."""
    present = [q for q in QUANTITIES if np.isfinite(ds[f"error_{q}"].values).any()]
    head = ["series", "level", "cells", "h µm", "dt", "tolerance", "steps", "wall s"] + [f"err {q}" for q in present]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name in ds.series.values:
        for level in ds.level.values:
            row = ds.sel(series=name, level=level)
            if not np.isfinite(float(row.cells)):
                continue
            cells = [str(name), str(int(level)), number(row.cells, 12), number(row.h), number(row.dt, 3),
                     number(row.tolerance, 1, exponent=True), number(row.steps, 9),
                     number(row.wall_time, 3) if np.isfinite(float(row.wall_time)) else "failed"]
            cells += [number(row[f"error_{q}"], 3, exponent=True) if np.isfinite(float(row[f"error_{q}"])) else "ref"
                      for q in present]
            lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append("observed orders (slope of log |q_l - q_(l+1)| against log h, dt or tolerance):")
    lines.append("")
    lines.append("| series | " + " | ".join(present) + " |")
    lines.append("|---|" + "---|" * len(present))
    for name in ds.series.values:
        values = [ds.attrs.get(f"order_{name}_{q}", float("nan")) for q in present]
        lines.append(f"| {name} | " + " | ".join(v if isinstance(v, str) else number(v, 3) for v in values) + " |")
    return "\n".join(lines) + "\n"
