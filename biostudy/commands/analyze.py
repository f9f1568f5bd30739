"""`biostudy analyze DIR`: sensitivity of a study's observables, written beside its study.nc.

Writes DIR/analysis.nc, analysis.md and two pictures (the indices with their
intervals; the outputs against each parameter).  A sweep that is still
running, or was interrupted, has not written study.nc yet: its cases are
combined in memory (`current`), nothing is written into the directory its
sweep owns.
"""
from __future__ import annotations

import contextlib
import os
import tomllib
from pathlib import Path

import netCDF4
import numpy as np
import xarray as xr

from ..data import combine, store
from ..errors import BadInput
from ..inputs.tomltext import literal
from ..plans.study import load_study
from ..plots.analysis import indices_figure, sample_figure, scatter_figure
from ..plots.style import save
from ..reports.cases import cases_of
from ..reports.sensitivity import analyze as indices
from ..reports.sensitivity import table_text, time_indices, variable


def current(source: Path) -> xr.Dataset:
    """study.nc's contents up to date with DIR/cases/.  Combined in memory from the study file it records
    (with the overrides study.nc records), when that file is still there and a case file is newer than
    study.nc; else study.nc as it is.  Nothing is written: the directory belongs to its sweep (`ownership`)."""
    cases = sorted(source.parent.joinpath("cases").glob("*.nc"), key=lambda p: p.stat().st_mtime)
    if not cases or (source.is_file() and source.stat().st_mtime >= cases[-1].stat().st_mtime):
        return store.open_dataset(source)
    record = source if source.is_file() else cases[-1]
    try:
        with netCDF4.Dataset(record) as nc:
            attrs = {name: nc.getncattr(name) for name in ("study_file", "overrides") if name in nc.ncattrs()}
    except OSError:
        return store.open_dataset(source)
    study_file = attrs.get("study_file")
    if not study_file or not os.path.isfile(study_file):
        return store.open_dataset(source)
    common = tomllib.loads(str(attrs.get("overrides", ""))) if record == source else {}
    plan = load_study(study_file, [f"{key}={literal(value)}" for key, value in common.items()])
    with contextlib.ExitStack() as opened:
        return combine.combine(plan, source.parent, opened).load()


def analyze(source: str | Path, *, outputs: list[str] | None = None,
            times: list[float] | None = None) -> tuple[list[Path], str]:
    """Analyse a study (its study.nc, or its directory) and write analysis.nc, analysis.md and the pictures
    beside it; returns the files written and the table.  Anything wrong with the request is `BadInput`."""
    source = Path(source)
    source = source / "study.nc" if source.is_dir() else source
    ds = current(source)
    directory = source.parent
    try:
        result = indices(ds, outputs or None, times or None)
    except ValueError as error:
        raise BadInput(str(error), source, "--output" if "output" in str(error) else None) from None
    text = table_text(result)
    written = [store.write_atomic(result, directory / "analysis.nc"), store.write_text(directory / "analysis.md", text),
               save(indices_figure(result), directory / "analysis_indices.png")]
    names = list(result.output.values)
    index = time_indices(ds, times or None)[-1]
    if "sample_method" in ds.attrs and all(n in ds for n in names):
        figure = sample_figure(ds, names, index)
    else:
        flat = cases_of(ds)
        values = {}
        for name in names:
            rows = flat.values(variable(ds, name))
            values[name] = np.asarray(rows[:, index] if rows.ndim == 2 else rows, dtype=float)
        units = {n: str(u) for n, u in zip(names, result["output_units"].values)}
        figure = scatter_figure(values, units, flat.parameters, flat.log, flat.status == "done",
                                "outputs against each parameter")
    written.append(save(figure, directory / "analysis_scatter.png"))
    return written, text
