"""Error bars of a study's cases: each case's companions run as jobs beside it, and the case's file then carries
its ``Q_error`` (`biostudy sweep --error-estimate`).

A case's companions (`plans.companions`) are jobs like the cases (workers, a cluster, resume: a companion
finished before is not run again), recorded as DIR/cases/<case id>~<companion>.nc; study.nc is made of the cases
only.  Once they are done, each finished case's file is read, its error bars made from its companions' files
(`quantities.error_bars`), and written again in its place, atomically, every variable as it was (the error
variables laid out as the observables are: the study's dimensions and time).  A case whose file already has
error bars keeps them; a companion that failed or was not made is said in the case's ``error_estimate``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from ..data import case_files, netcdf, netcdf_io, reading, writing
from ..plans import companions
from ..quantities import error_bars
from .jobs import Job, SweepReport

SEPARATOR = "~"  # a companion's job id: <case id>~<companion>


def companion_jobs(jobs: list[Job]) -> tuple[list[Job], dict[str, dict[str, str]]]:
    """The companions' jobs of every case job, and per case what each of its companions runs (or why not)."""
    found, notes = [], {}
    for job in jobs:
        planned = companions.plan(job.scene, job.scene_file)
        notes[job.id] = {p.companion.name: p.describe() for p in planned}
        for p in planned:
            if p.scene is not None:
                name = f"{job.id}{SEPARATOR}{p.companion.name}"
                found.append(Job(name, p.scene, job.scene_file, job.overrides, {"case_id": name,
                                                                                 "companion_of": job.id}))
    return found, notes


def _done(path: Path) -> xr.Dataset | None:
    record = case_files.recorded(path)
    return reading.open_dataset(path) if record and record.get("status") == "done" else None


def add_error_bars(jobs: list[Job], notes: dict[str, dict[str, str]], out_dir: str | Path) -> int:
    """Give every finished case file of `jobs` without error bars its ``Q_error`` from its finished companions'
    files; returns how many were written."""
    written = 0
    for job in jobs:
        path = case_files.case_file(out_dir, job.id)
        run = _done(path)
        if run is None or error_bars.ATTRIBUTE in run.attrs:
            continue
        said = dict(notes[job.id])
        runs = {}
        for name in said:
            found = _done(case_files.case_file(out_dir, f"{job.id}{SEPARATOR}{name}"))
            if found is None and "not run" not in said[name]:
                said[name] = f"{said[name]}: did not finish"
            runs[name] = found
        scheme = job.scene.numerics.advection
        variables, attrs = error_bars.estimate(run, runs, said, scheme)
        seconds = sum(float(ds.attrs.get("wall_time", 0.0)) for ds in runs.values() if ds is not None)
        attrs = {**attrs, "error_estimate_wall_time": seconds,
                 "error_estimate_cost": seconds / float(run.attrs["wall_time"]) if run.attrs.get("wall_time")
                 else float("nan")}
        writing.write_atomic(_laid_out(path, variables, attrs), path)
        written += 1
    return written


def _laid_out(path: Path, variables: dict[str, xr.DataArray], attrs: dict) -> xr.Dataset:
    """The case file as written, read whole, with the error variables shaped as their observables are in it."""
    with netcdf_io.HDF5, xr.open_dataset(path) as opened:
        raw = netcdf.renamed(opened.load())
    for name, error in variables.items():
        observable = raw[name.removesuffix(error_bars.SUFFIX)]
        raw[name] = (observable.dims, np.asarray(error.values).reshape(observable.shape), error.attrs)
    raw.attrs.update(attrs)
    return raw


def cases_only(report: SweepReport) -> tuple[list[str], list[str]]:
    """`report` of a sweep's cases alone (its companions taken out of what ran, was skipped, failed or raised an
    alert: a companion's failure is its case's missing error bar, not a failed case); returns the companions'
    ids and a warning for those that failed."""
    companions = [i for i in (*report.ran, *report.skipped, *report.failed) if SEPARATOR in i]
    failed = {i: why for i, why in report.failed.items() if SEPARATOR in i}
    report.ran = [i for i in report.ran if SEPARATOR not in i]
    report.skipped = [i for i in report.skipped if SEPARATOR not in i]
    report.failed = {i: why for i, why in report.failed.items() if SEPARATOR not in i}
    report.alerts = {name: {i: s for i, s in said.items() if SEPARATOR not in i}
                     for name, said in report.alerts.items()}
    listed = "; ".join(f"{i}: {why}" for i, why in list(failed.items())[:3])
    return companions, ([f"{len(failed)} of {len(companions)} error-bar companions failed (their cases' "
                         f"error_estimate says which): {listed}"] if failed else [])
