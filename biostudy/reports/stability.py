"""Stiff and extreme cases judged: each completed with its bounds held or stopped with a diagnosis.

Every case of a stability catalogue (`biostudy.plans.catalogue`) gets a verdict:

* completed: the dataset as written is read back (`examine`): no NaN in open
  cells; 0 <= c <= 1; alpha >= 0; phi and alpha within what the model allows
  them to reach from the first output's largest values and k_alpha alone
  (`solver.transport.bounds.model_bound`: P0 cosh(k_alpha t) + A0
  sinh(k_alpha t), t one step later, since the scheme's alpha may lead the
  model's by a step), not from the run's own alpha; p finite where the
  mechanics was solved;
* refused: the mechanics stopped the run with its diagnosis (det F <= 0,
  Newton not converged after its safeguards): acceptable, that is what the
  diagnosis is for;
* stopped: the expansion feedback ran away (`solver.errors.Runaway`: the
  fields outgrew what the solver resolves) and the run stopped with its
  diagnosis: acceptable, likewise;
* failed: anything else: a transport case that did not complete, a bound
  broken, a NaN, an exception that is not the solver's diagnosis.
`ok` is 1 for completed-within-bounds, refused and stopped, 0 for failed.

What the read-back can and cannot see: the solver itself checks c and phi
against their bounds after every step and projects round-off (within
`solver.transport.bounds.ROUNDOFF`) onto them, failing the step beyond that; so the
written c and phi lie within each step's bounds by construction, and the
read-back confirms the file, not the numerics.  It does check the fields
against the model's bounds independently of the solver's own steps, alpha,
p and NaN in what was written.  How close the raw solutions came to a bound is
recorded per run by the solver (`projected_c_count`, `projected_c_largest`,
`projected_phi_count`, `projected_phi_largest`) and reported here: a largest
correction close to ROUNDOFF means a case drifts toward a bound.  Each row
also says how many steps the clock shortened to the scheme's limit and the
largest Courant number it took (`steps_substepped`, `courant_max`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from solver.counters import MEANINGS
from solver.output import FIELDS, cf_attrs, on_output_times
from solver.problem import parameter_infos
from solver.transport.bounds import ROUNDOFF, model_bound

from ..data import case_files, reading
from ..execution.jobs import Job
from ..formatting import number


def examine(ds: xr.Dataset) -> dict:
    """Independent checks of a finished run: extremes, bounds, non-finite values."""
    ds = on_output_times(ds)
    open_cells = ~ds["obstacle"].values.astype(bool)
    fields = {name: ds[name].values[:, open_cells] for name in ("phi", "c", "alpha")}
    bound, alpha_bound = model_bounds(ds, fields["phi"][0], fields["alpha"][0])
    facts = {
        "nonfinite": int(sum(np.count_nonzero(~np.isfinite(v)) for v in fields.values())),
        "phi_min": float(np.nanmin(fields["phi"])), "phi_max": float(np.nanmax(fields["phi"])),
        "phi_bound": float(bound[-1]),
        "c_min": float(np.nanmin(fields["c"])), "c_max": float(np.nanmax(fields["c"])),
        "alpha_min": float(np.nanmin(fields["alpha"])),
        "newton_max": float(np.nanmax(ds["newton_iterations"].values)) if "newton_iterations" in ds else np.nan,
    }
    broken = []
    if facts["nonfinite"]:
        broken.append(f"{facts['nonfinite']} non-finite values")
    if facts["c_min"] < -ROUNDOFF or facts["c_max"] > 1 + ROUNDOFF:
        broken.append(f"c in [{facts['c_min']:.3g}, {facts['c_max']:.3g}]")
    if facts["alpha_min"] < -ROUNDOFF:
        broken.append(f"alpha min {facts['alpha_min']:.3g}")
    phi_max, alpha_max = np.nanmax(fields["phi"], axis=1), np.nanmax(fields["alpha"], axis=1)
    if facts["phi_min"] < -ROUNDOFF or np.any(phi_max > bound * (1 + ROUNDOFF) + ROUNDOFF):
        broken.append(f"phi in [{facts['phi_min']:.3g}, {facts['phi_max']:.6g}], bound {facts['phi_bound']:.6g}")
    if np.any(alpha_max > alpha_bound * (1 + ROUNDOFF) + ROUNDOFF):
        broken.append(f"alpha up to {float(np.nanmax(alpha_max)):.6g}, bound {float(alpha_bound[-1]):.6g}")
    if "p" in ds:
        solved = ds["newton_iterations"].values >= 0
        p = ds["p"].values[solved][:, open_cells]
        if not np.isfinite(p).all():
            broken.append("p not finite where the mechanics was solved")
    facts["broken"] = "; ".join(broken)
    return facts


def model_bounds(ds: xr.Dataset, phi0: np.ndarray, alpha0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per output, the largest phi and alpha the model allows from the first output's largest values and k_alpha
    (`model_bound`), one step later: the clock's nominal step, or with error-controlled steps the longest the
    scheme takes, 1/k_alpha (`solver.transport.courant`)."""
    times = ds["time"].values
    k_alpha = float(ds.attrs["k_alpha"])
    fixed = not float(ds.attrs.get("time_tolerance", 0.0))
    step = float(ds.attrs["t_end"]) / float(ds.attrs["steps_nominal"]) if fixed else 1.0 / max(k_alpha, 1e-300)
    lead = min(step, 1.0 / k_alpha) if k_alpha > 0 else 0.0
    start = (float(np.nanmax(phi0)), max(float(np.nanmax(alpha0)), 0.0))
    pairs = [model_bound(*start, k_alpha, t - times[0] + lead) for t in times]
    return np.array([p for p, _ in pairs]), np.array([a for _, a in pairs])


def verdicts(jobs: list[Job], out_dir: Path) -> xr.Dataset:
    """stability.nc: one entry per case with its verdict, counters, extremes and parameters."""
    rows = []
    for job in jobs:
        path = case_files.case_file(out_dir, job.id)
        record = case_files.recorded(path) or {}
        mechanics = job.scene.mechanics is not None and job.scene.mechanics.enabled
        row = {"name": job.attrs["case_id"], "why": job.attrs["case_why"], "mechanics": int(mechanics),
               "cells": int(np.prod(job.scene.grid.shape)), "steps_nominal": job.scene.time.steps,
               "consumption": job.scene.model.consumption, "advection": job.scene.numerics.advection,
               **{p.name: float(getattr(job.scene.params, p.name)) for p in parameter_infos()}}
        status = record.get("status", "missing")
        if status == "done":
            ds = reading.open_dataset(path)
            facts = examine(ds)
            row.update({k: v for k, v in facts.items() if k != "broken"})
            row.update(wall_time=float(ds.attrs["wall_time"]), steps_taken=int(ds.attrs["steps_taken"]),
                       steps_bisected=int(ds.attrs["steps_bisected"]), steps_rejected=int(ds.attrs["steps_rejected"]),
                       **{name: float(ds.attrs.get(name, np.nan)) for name in (*PROJECTED, *CLOCK)})
            if facts["broken"]:
                row.update(verdict="failed", ok=0, message=f"bounds broken: {facts['broken']}")
            else:
                row.update(verdict="completed", ok=1, message="bounds held")
        elif status == "failed":
            message, error = str(record.get("message", "")), str(record.get("error", ""))
            row.update(wall_time=float(record.get("wall_time", np.nan)))
            if mechanics and error == "MechanicsError":
                row.update(verdict="refused", ok=1, message=message)
            elif error == "Runaway":
                row.update(verdict="stopped", ok=1, message=message)
            else:
                row.update(verdict="failed", ok=0, message=f"{error or 'error'}: {message}")
        else:
            row.update(verdict="missing", ok=0, message="not run")
        rows.append(row)
    return _dataset(rows)


PROJECTED = ("projected_c_count", "projected_c_largest", "projected_phi_count", "projected_phi_largest")
CLOCK = ("steps_substepped", "courant_max")
NUMBERS = {"ok": ("1", "1 = completed within bounds, refused by the mechanics or stopped with a diagnosis"),
           "wall_time": ("s", "wall time"),
           **{name: ("1", MEANINGS[name]) for name in ("steps_taken", "steps_bisected", "steps_rejected", *CLOCK)},
           **{f"{field}_{end}": ("1", f"{word} {FIELDS[field][1]}") for field in ("phi", "c")
              for end, word in (("min", "smallest"), ("max", "largest"))},
           "phi_bound": ("1", "upper bound of phi the model allows by the last output (k_alpha, initial fields)"),
           "alpha_min": ("1", f"smallest {FIELDS['alpha'][1]}"),
           "nonfinite": ("1", "non-finite values in open cells"),
           "newton_max": ("1", "most Newton iterations of a mechanics solve"),
           **{name: ("1", MEANINGS[name]) for name in PROJECTED}}
LABELS = {"verdict": "completed, refused (mechanics diagnosis), stopped (runaway diagnosis) or failed",
          "message": "diagnosis or check result",
          "why": "what the case stresses"}
COORDS = {"cells": ("1", "grid cells"), "steps_nominal": ("1", "nominal steps"),
          "mechanics": ("1", "1 = the mechanics was solved")}


def _dataset(rows: list[dict]) -> xr.Dataset:
    data = {}
    for name, (units, long_name) in NUMBERS.items():
        data[name] = ("case", np.array([float(r.get(name, np.nan)) for r in rows]),
                      {"units": units, "long_name": long_name})
    for name, long_name in LABELS.items():
        data[name] = ("case", np.array([str(r.get(name, "")) for r in rows], dtype=object),
                      {"units": "1", "long_name": long_name})
    coords = {"case": ("case", np.array([r["name"] for r in rows], dtype=object), {"units": "1", "long_name": "case"})}
    for info in parameter_infos():
        coords[info.name] = ("case", np.array([r[info.name] for r in rows]), cf_attrs(info.units, info.long_name))
    for name, (units, long_name) in COORDS.items():
        coords[name] = ("case", np.array([r[name] for r in rows]), {"units": units, "long_name": long_name})
    for name in ("consumption", "advection"):
        coords[name] = ("case", np.array([r[name] for r in rows], dtype=object), {"units": "1", "long_name": name})
    return xr.Dataset(data, coords=coords)


def table_text(ds: xr.Dataset) -> str:
    """Markdown table: one row per case; "projected" is how many values of c and phi the solver moved onto
    a bound, and the largest such correction."""
    head = ["case", "what it stresses", "cells", "verdict", "steps", "bisected", "substepped", "Courant max", "wall s",
            "phi range", "c range", "projected c", "projected phi", "diagnosis"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for i in range(ds.sizes["case"]):
        row = ds.isel(case=i)
        lines.append("| " + " | ".join([
            str(row.case.values), str(row.why.values), f"{int(row.cells)}", str(row.verdict.values),
            number(row.steps_taken, 9), number(row.steps_bisected, 9), number(row.steps_substepped, 9),
            number(row.courant_max, 2), number(row.wall_time, 3),
            f"[{number(row.phi_min, 3)}, {number(row.phi_max, 4)}]",
            f"[{number(row.c_min, 3)}, {number(row.c_max, 3)}]",
            *(_projected(row, name) for name in ("c", "phi")),
            str(row.message.values).replace("|", "/"),
        ]) + " |")
    return "\n".join(lines) + "\n"


def _projected(row: xr.Dataset, name: str) -> str:
    count = float(row[f"projected_{name}_count"])
    if not np.isfinite(count):
        return "-"
    return f"{int(count)}, at most {number(row[f'projected_{name}_largest'], 2)}" if count else "0"
