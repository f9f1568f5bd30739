"""How accurate is a scene's result, and what does accuracy cost: the measurements of `biostudy convergence`.

The levels are planned by `biostudy.plans.refinement`.  The reference of each
series is its own finest level (the adaptive series is measured against the
finest fixed-step level of `time`, same grid), or a given dataset
(`reference`): a refined run of the same scene, perhaps with another scheme,
e.g. the pointwise growth velocity on 1/16 µm cells as the yardstick of the
front velocity on 1 µm cells.  Errors at the final output time (or the output
nearest `time`): phi in L1 and L2 on the series' coarsest grid (finer fields
restricted by cell averaging), p in L2 when the mechanics is on, the
observables biofilm_volume and dense_volume (relative), phi_max, height,
c_mean, and the substratum's biomass and mean_thickness
(`biostudy.quantities.observables`, with their units), and the front position
(`measures.front_position`; the observable front_advance is its gain
since T* = 0, which starts elsewhere on every grid).  The observed order p is
fitted to the differences between successive levels, |q_l - q_(l+1)| ~ size^p
(unbiased, unlike errors against a finite reference); the error of the
reference itself is then estimated by Richardson, |q_L - q_(L-1)| / (2^p - 1).
Quantities a series reproduces to round-off (below EXACT) get no order: they
are reported as exact.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from solver.counters import MEANINGS
from solver.output import FIELDS, on_output_times

from ..data import case_files, provenance, reading
from ..errors import BadInput
from ..formatting import number
from ..inputs.scene import Scene
from ..plans.refinement import Refinement
from ..quantities import measures, observables

EXACT = 1e-9  # differences below this are round-off: no order to fit
# observables compared (biomass and mean_thickness: the COMSTAT ones a calibration fits, on the recorded substratum)
OBSERVED = ("biofilm_volume", "dense_volume", "phi_max", "height", "c_mean", "biomass", "mean_thickness")
RELATIVE = ("biofilm_volume", "dense_volume")  # compared relative to the reference's value


@dataclass(frozen=True)
class Compared:
    """One quantity whose error a convergence run reports, with the units and long name of its error."""

    name: str
    units: str
    long_name: str


def _compared() -> tuple[Compared, ...]:
    """The compared quantities, their units and long names from where each quantity is declared: the fields'
    in `solver.output.FIELDS`, the observables' in their registry."""
    fields = [Compared(f"{name}_{norm}", FIELDS[name][0], f"{what} of {name} - {name}_ref over open cells "
                       "(common grid)") for name, norm, what in (("phi", "L1", "mean |.|"),
                                                               ("phi", "L2", "root mean square"))]
    scalars = []
    for name in OBSERVED:
        observable = observables.get(name)
        relative = name in RELATIVE
        scalars.append(Compared(name, "1" if relative else observable.units,
                                f"{'relative ' if relative else ''}error of the {observable.long_name}"))
    scalars.append(Compared("front_position", "um", "error of the front position toward the nutrient"))
    return (*fields, *scalars, Compared("p_L2", FIELDS["p"][0], "root mean square of p - p_ref over open cells "
                                                                "(common grid)"))


COMPARED = _compared()
COSTS = ("cpu_time_loop", "cpu_time_first")  # a level's own cost, and its one-off start (`solver.timeloop.CpuTime`)
QUANTITIES = tuple(c.name for c in COMPARED)


def _final(path: Path, time: float | None = None) -> dict | None:
    """What a level contributes: fields and scalars at the last output (or the one nearest `time`), or None if
    it did not finish."""
    record = case_files.recorded(path)
    if not record or record.get("status") != "done":
        return None
    return final_state(reading.open_dataset(path), time)


def final_state(ds: xr.Dataset, time: float | None = None) -> dict:
    """A run's fields and measured quantities at its last output, or the output nearest `time`."""
    index = -1 if time is None else int(np.argmin(np.abs(ds["time"].values - time)))
    last = on_output_times(ds).isel(time=index)
    return {
        "phi": last["phi"].values, "p": last["p"].values if "p" in ds else None,
        **{q: observables.value(ds, q, index) if observables.available(ds, observables.get(q)) else float("nan")
           for q in OBSERVED},
        "front_position": measures.front_position(ds, index), "wall_time": float(ds.attrs["wall_time"]),
        **{name: float(ds.attrs.get(name, np.nan)) for name in COSTS},
        "steps_taken": int(ds.attrs["steps_taken"]), "t_end": float(ds["time"].values[-1]),
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
    for q in (*OBSERVED, "front_position"):
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
    ds = reading.open_dataset(path)
    if "phi" not in ds:
        raise BadInput("is not a run's dataset (no phi)", path, "--reference")
    dimensions = sum(axis in ds["phi"].dims for axis in ("x", "y", "z"))
    if dimensions != len(base.grid.shape):
        raise BadInput(f"is a {dimensions}-D run; the scene is {len(base.grid.shape)}-D", path, "--reference")
    found = final_state(ds, time)
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
    `final_state` that every level is measured against instead of its series' finest level."""
    results = {level.job_id: _final(case_files.case_file(out_dir, level.job_id), time) for level in wanted}
    shape = (len(series), levels)
    table = {name: np.full(shape, np.nan) for name in ("cells", "h", "dt", "tolerance", "wall_time", "steps_taken",
                                                      *COSTS)}
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
            table["steps_taken"][s, i] = result["steps_taken"]
            for cost in COSTS:
                table[cost][s, i] = result[cost]
            table["dt"][s, i] = result["t_end"] / result["steps_taken"]
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
        "steps_taken": (("series", "level"), table["steps_taken"],
                        {"units": "1", "long_name": MEANINGS["steps_taken"]}),
        "cell_steps": (("series", "level"), table["cells"] * table["steps_taken"],
                       {"units": "1", "long_name": "cells times accepted steps: the work, whatever the machine"}),
        **{name: (("series", "level"), table[name], {"units": "s", "long_name": MEANINGS[name]}) for name in COSTS},
        **{f"error_{c.name}": (("series", "level"), errors[c.name], {"units": c.units, "long_name": c.long_name})
           for c in COMPARED},
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
    return xr.Dataset(data, coords=coords, attrs=provenance.legal_attrs(attrs))


def table_text(ds: xr.Dataset) -> str:
    """Markdown table of every level, then the observed orders."""
    present = [q for q in QUANTITIES if np.isfinite(ds[f"error_{q}"].values).any()]
    head = (["series", "level", "cells", "h µm", "dt", "tolerance", "steps", "loop CPU s", "first step s", "wall s"]
            + [f"err {q}" for q in present])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name in ds.series.values:
        for level in ds.level.values:
            row = ds.sel(series=name, level=level)
            if not np.isfinite(float(row.cells)):
                continue
            cells = [str(name), str(int(level)), number(row.cells, 12), number(row.h), number(row.dt, 3),
                     number(row.tolerance, 1, exponent=True), number(row.steps_taken, 9),
                     *(number(row[name], 3) if np.isfinite(float(row[name])) else "-" for name in COSTS),
                     number(row.wall_time, 3) if np.isfinite(float(row.wall_time)) else "failed"]
            cells += [number(row[f"error_{q}"], 3, exponent=True) if np.isfinite(float(row[f"error_{q}"])) else "ref"
                      for q in present]
            lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append("loop CPU s: the level's own time loop (its steps and mechanics solves), CPU time of the thread that "
                 "ran it; first step s: its first step and mechanics solve, which load compiled kernels and build "
                 "the first hierarchies (one-off, like the process start and imports in wall s).")
    lines.append("")
    lines.append("observed orders (slope of log |q_l - q_(l+1)| against log h, dt or tolerance):")
    lines.append("")
    lines.append("| series | " + " | ".join(present) + " |")
    lines.append("|---|" + "---|" * len(present))
    for name in ds.series.values:
        values = [ds.attrs.get(f"order_{name}_{q}", float("nan")) for q in present]
        lines.append(f"| {name} | " + " | ".join(v if isinstance(v, str) else number(v, 3) for v in values) + " |")
    return "\n".join(lines) + "\n"
