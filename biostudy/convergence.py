"""How accurate is a scene's result, and what does accuracy cost (`biostudy convergence`).

Four refinement series from the scene as given (level 0):
  space     the grid refined by 2 per level (cells 2^ndim x), the time step kept;
  time      the nominal step halved per level, the grid kept;
  both      grid and step refined together;
  adaptive  error-controlled steps (step doubling) with the tolerance divided
            by 4 per level (local error ~ dt^2: halves the step), the grid kept.
The reference of each series is its own finest level (the adaptive series is
measured against the finest fixed-step level of `time`, same grid), or a
given dataset (`reference`): a refined run of the same scene, perhaps with
another scheme, e.g. the pointwise growth velocity on 1/16 µm cells as the
yardstick of the front velocity on 1 µm cells.  Errors at the final output
time (or the output nearest `time`): phi in L1 and L2 on the series' coarsest
grid (finer fields restricted by cell averaging), biofilm_volume and the
dense volume phi >= 0.8 (relative), max phi, the top of phi >= 0.5 along the
vertical axis (y in 2-D, z in 3-D; µm), c_mean, front position (µm), and p in
L2 when the mechanics is on.  The scalar ones are errors of the observables
(`biostudy.observables`; top is `height`, max_phi is `phi_max`), the front position
of `measures.front_position` (the observable front_advance is its gain since
T* = 0, which starts elsewhere on every grid).  The
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

from solver.output import on_output_times

from . import measures, observables, store
from .errors import BadInput
from .formatting import number
from .ownership import Owner
from .runner import Job, SweepReport, owned, run_jobs
from .scene import Scene, given_by, overrides_text, scene_from_data, set_key

SERIES = ("space", "time", "both", "adaptive")
FIRST_TOLERANCE = 1e-2  # adaptive level 0: local error in phi per step
EXACT = 1e-9  # differences below this are round-off: no order to fit
QUANTITIES = ("phi_L1", "phi_L2", "biofilm_volume", "dense_volume", "max_phi", "top", "c_mean", "front_position",
              "p_L2")
UNITS = {"phi_L1": "1", "phi_L2": "1", "biofilm_volume": "1", "dense_volume": "1", "max_phi": "1", "top": "um",
         "c_mean": "1", "front_position": "um", "p_L2": "Pa"}
RELATIVE = ("biofilm_volume", "dense_volume")
OBSERVED = {"max_phi": "phi_max", "top": "height"}  # quantities named apart from their observables
LONG_NAMES = {
    "dense_volume": "relative error of the dense volume (phi >= 0.8)",
    "max_phi": "error of the largest phi",
    "top": "error of the top of phi >= 0.5 along the vertical axis (y in 2-D, z in 3-D)",
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
        notify=None, fixed: dict | None = None, reference: Path | None = None,
        time: float | None = None, force: bool = False, rerun_all: bool = False) -> tuple[xr.Dataset, SweepReport]:
    """Run every level (skipping finished ones), measure, write DIR/convergence.nc; returns it and the report.
    DIR belongs to this scene's convergence runs (`runner.owned`; `force` takes over another's)."""
    if levels < 2:
        raise BadInput("needs at least 2 levels (the finest is the reference)", None, "--levels")
    base = scene_from_data(copy.deepcopy(data), scene_file, given_by(fixed or {}, "--set"))
    check_refinable(base, scene_file)
    given = None if reference is None else load_reference(reference, base, time)
    wanted = plan(base, levels, series, tolerance)
    scenes = {level.job_id: refined(data, scene_file, level) for level in wanted}
    text = overrides_text(fixed or {})
    jobs = [Job(job_id, scene, scene_file, text, {"case_id": job_id}) for job_id, scene in scenes.items()]
    owner = Owner("convergence", scene_file.stem, str(scene_file.resolve()))
    with owned(out_dir, owner, "convergence.nc", force):
        report = run_jobs(jobs, out_dir, workers, scheduler, notify=notify, rerun_all=rerun_all)
        ds = measure(wanted, out_dir, levels, series, base, given, time)
        if reference is not None:
            ds.attrs["reference"] = f"the run in {Path(reference).resolve()} (T* = {given['time']:g})"
        ds.attrs = store.with_provenance({**ds.attrs, "scene": base.to_toml(),
                                          "scene_file": str(scene_file.resolve()), "overrides": text})
        store.write_atomic(ds, out_dir / "convergence.nc")
    return ds, report


def _final(path: Path, time: float | None = None) -> dict | None:
    """What a level contributes: fields and scalars at the last output (or the one nearest `time`), or None if
    it did not finish."""
    record = store.recorded(path)
    if not record or record.get("status") != "done":
        return None
    return summary(store.open_dataset(path), time)


def summary(ds: xr.Dataset, time: float | None = None) -> dict:
    """A run's fields and measured quantities at its last output, or the output nearest `time`."""
    index = -1 if time is None else int(np.argmin(np.abs(ds["time"].values - time)))
    last = on_output_times(ds).isel(time=index)
    return {
        "phi": last["phi"].values, "p": last["p"].values if "p" in ds else None,
        **{q: observables.value(ds, OBSERVED.get(q, q), index) for q in ("biofilm_volume", "c_mean", "dense_volume",
                                                                        "max_phi", "top")},
        "front_position": measures.front_position(ds, index), "wall_time": float(ds.attrs["wall_time"]),
        "steps": int(ds.attrs["steps_taken"]), "t_end": float(ds["time"].values[-1]),
        "time": float(ds["time"].values[index]),
        "extent": tuple(float(ds[a].values[-1]) + 0.5 * measures.spacing(ds) for a in ("x", "y", "z") if a in ds.dims),
    }


def _errors(result: dict, reference: dict, factor_result: int, factor_reference: int) -> dict:
    """Errors of one level against a reference; factors: refinement of each against the common (coarsest) grid,
    None where the reference's grid is not a refinement of it (then no field errors)."""
    errors = {q: float("nan") for q in QUANTITIES}
    if factor_reference is not None:
        phi = measures.field_errors(measures.restrict(result["phi"], factor_result),
                                    measures.restrict(reference["phi"], factor_reference))
        errors.update(phi_L1=phi[0], phi_L2=phi[1])
        if result["p"] is not None and reference["p"] is not None:
            errors["p_L2"] = measures.field_errors(measures.restrict(result["p"], factor_result),
                                                   measures.restrict(reference["p"], factor_reference))[1]
    for q in ("biofilm_volume", "dense_volume", "max_phi", "top", "c_mean", "front_position"):
        difference = abs(result[q] - reference[q])
        if q in RELATIVE:  # a volume the reference does not have at all: infinitely wrong, unless absent too
            difference = difference / abs(reference[q]) if reference[q] else (np.inf if difference else 0.0)
        errors[q] = difference
    return errors


def _factor(reference: dict, coarse_h: float) -> int | None:
    """How many reference cells span a cell of the coarsest level along each axis, if a whole number."""
    h = reference["extent"][0] / reference["phi"].shape[-1]
    ratio = coarse_h / h
    return int(round(ratio)) if abs(ratio - round(ratio)) < 1e-6 and round(ratio) >= 1 else None


def load_reference(path: Path, base: Scene, time: float | None) -> dict:
    """A reference run for `measure`: the same domain as the scene, and an output at the compared time."""
    ds = store.open_dataset(path)
    if "phi" not in ds:
        raise BadInput("is not a run's dataset (no phi)", path, "--reference")
    found = summary(ds, time)
    extent = tuple(float(e) for e in base.grid.solver_grid().extent)
    if not np.allclose(found["extent"], extent, rtol=1e-9):
        raise BadInput(f"covers {found['extent']} µm; the scene covers {extent} µm", path, "--reference")
    wanted = base.time.t_end if time is None else time
    if abs(found["time"] - wanted) > 1e-9 * max(1.0, wanted):
        raise BadInput(f"has no output at T* = {wanted:g} (nearest {found['time']:g})", path, "--reference")
    return found


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


def measure(wanted: list[Refinement], out_dir: Path, levels: int, series: tuple[str, ...], base: Scene,
            given: dict | None = None, time: float | None = None) -> xr.Dataset:
    """convergence.nc from the finished levels: dimensions (series, level).  `given`: a reference run's
    `summary` that every level is measured against instead of its series' finest level."""
    results = {level.job_id: _final(store.case_file(out_dir, level.job_id), time) for level in wanted}
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
        reference = results[reference_level.job_id] if given is None else given
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
            if reference is not None and (given is not None or level.job_id != reference_level.job_id):
                coarse = mine[0].refine
                factor = reference_level.refine // coarse if given is None else _factor(given, h0 / coarse)
                for q, value in _errors(result, reference, level.refine // coarse, factor).items():
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
