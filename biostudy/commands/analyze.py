"""`biostudy analyze DIR`: sensitivity of a study's observables, written beside its study.nc.

Writes DIR/analysis.nc, analysis.md and two pictures (the indices with their
intervals; the outputs against each parameter).  A sweep that is still
running, or was interrupted, has not written study.nc yet, and a study.nc
may be damaged: its cases are combined in memory (`current`), nothing is
written into the directory its sweep owns.
"""
from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Sequence

import numpy as np
import xarray as xr

from ..data import case_files, claims, combine, netcdf_io, reading, real_time, targets, writing
from ..errors import BadInput
from ..inputs.keys import key_parts
from ..inputs.resources import Preflight
from ..inputs.tomltext import literal
from ..plans.study import load_study
from ..plots.analysis import indices_figure, sample_figure, scatter_figure
from ..plots.style import save
from ..reports.cases import cases_of
from ..reports.sensitivity import analyze as indices
from ..reports.sensitivity import table_text, time_indices, variable

REPORTS = ("analysis.md", "analysis_indices.png", "analysis_scatter.png")


def current(source: Path) -> xr.Dataset:
    """study.nc's contents up to date with DIR/cases/.  Combined in memory from the study file it records
    (with the overrides study.nc records), when that file is still there and a case file is newer than
    study.nc, or study.nc is damaged or missing (then from the study file and the overrides a case file
    records); else study.nc as it is.  A damaged case file is `BadInput`.  Nothing is written: the directory
    belongs to its sweep (`ownership`)."""
    cases = sorted(source.parent.joinpath("cases").glob("*.nc"), key=lambda p: p.stat().st_mtime)
    if not cases or (source.is_file() and source.stat().st_mtime >= cases[-1].stat().st_mtime):
        try:
            return reading.open_dataset(source)
        except BadInput:
            if not cases:
                raise
    records = [source, *reversed(cases)] if source.is_file() else list(reversed(cases))
    record, attrs = next(((r, a) for r in records if (a := reading.attributes(r)) is not None), (None, {}))
    study_file = attrs.get("study_file")
    if not study_file or not os.path.isfile(study_file):
        return reading.open_dataset(source)
    plan = load_study(study_file, _common(attrs, record == source, study_file), Preflight())
    damaged = [BadInput("damaged: it cannot be read whole; run the sweep again to compute it again", path)
               for path in (case_files.case_file(source.parent, case.id) for case in plan.cases)
               if path.exists() and not netcdf_io.intact(path)]
    if damaged:
        raise BadInput.every(damaged)
    return combine.combine(plan, source.parent).load()


def _common(attrs: dict, study: bool, study_file: str) -> list[str]:
    """The overrides every case had, as --set arguments: study.nc's `overrides`, or a case file's without the
    keys the study varies."""
    given = tomllib.loads(str(attrs.get("overrides", "")))
    if not study:
        varied = {tuple(key_parts(key)) for key in load_study(study_file).keys}
        given = {key: value for key, value in given.items() if tuple(key_parts(key)) not in varied}
    return [f"{key}={literal(value)}" for key, value in given.items()]


def analyze(study: str | Path, *, outputs: list[str] | None = None,
            times: Sequence[float | str] | None = None) -> tuple[list[Path], str]:
    """Analyse a study (its study.nc, or its directory) and write analysis.nc, analysis.md and the pictures
    beside it (the options: `declared.ANALYZE`); returns the files written and the table.  Anything wrong with
    the request is `BadInput`."""
    source = Path(study)
    source = source / "study.nc" if source.is_dir() else source
    directory = source.parent
    _replaceable(directory)  # before anything is read or computed
    ds = current(source)
    try:
        asked = [real_time.t_star(ds, t) for t in times or ()]
        result = indices(ds, outputs or None, asked or None)
    except ValueError as error:
        raise BadInput(str(error), source, "--output" if "output" in str(error) else None) from None
    text = table_text(result)
    written = [writing.write_atomic(result, directory / "analysis.nc"),
               claims.write_report(directory / REPORTS[0], text), save(indices_figure(result), directory / REPORTS[1])]
    names = list(result.output.values)
    index = time_indices(ds, asked or None)[-1]
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
    written.append(save(figure, directory / REPORTS[2]))
    return written, text


def _replaceable(directory: Path) -> None:
    """`BadInput` (every one at once) unless analysis.nc and the reports may be replaced: absent, or biostudy's."""
    problems = claims.unproven([directory / name for name in REPORTS], "a report or picture")
    try:
        targets.replaceable(directory / "analysis.nc")
    except BadInput as error:
        problems.insert(0, error)
    if problems:
        raise BadInput.every(problems)
