"""`--json`: the records of `reports.records` for what a command would print as a table, on stdout.

Only the JSON goes to stdout; progress, warnings and the summary line stay on
stderr, so `biostudy show --json run.nc | jq .observables` reads it as is.
"""
from __future__ import annotations

from pathlib import Path

import typer

from ..errors import BadInput
from ..inputs import bundled


def emit(record: dict | list) -> None:
    from ..reports.records import text  # lazily (app's docstring)

    typer.echo(text(record))


def shown(path: Path) -> dict:
    """The record of what `show PATH` prints: a run, a case, a failed case's record or a study."""
    if path.suffix == ".toml" or (not path.exists() and not path.suffix):
        raise BadInput("--json is for datasets (a run, a case, a study); a scene or study file's needs are "
                       "printed as text", path, "--json")
    from ..reports import glance, records  # lazily

    found = glance.read(path) if path.is_file() else None
    if found is not None:
        return records.run_record(*found)
    from ..data.reading import open_result  # lazily
    from ..reports.show import run_series  # lazily

    ds = open_result(path / "study.nc" if path.is_dir() else path, doing="show reads runs, cases and study.nc")
    return records.study_record(ds) if "sweep_mode" in ds.attrs else records.run_record(*run_series(ds))


def scenes(directory: Path) -> dict:
    """The bundled scenes and studies (`biostudy scenes`)."""
    return {"kind": "scenes", "directory": str(directory),
            "entries": [{"file": e.path.name, "kind": e.kind, "description": e.description}
                        for e in bundled.entries(directory)]}


def finished(job, result) -> dict:
    """What a job command made: its summary dataset (convergence, stability, calibration), or a sweep's
    study.nc; an array task writes no study.nc, so its record is the cases it ran, skipped and lost."""
    import xarray as xr  # lazily

    from ..reports import records  # lazily

    if isinstance(result, xr.Dataset):
        return records.dataset_record(result)
    study = result if isinstance(result, Path) else getattr(result, "study", None)
    if getattr(job, "share", None) is None and study is not None:
        from ..data.reading import open_dataset  # lazily

        return records.study_record(open_dataset(study))
    return {"kind": "cases", "ran": list(result.ran), "skipped": list(result.skipped), "failed": dict(result.failed)}


def written(summary: Path) -> dict:
    """A summary dataset a command wrote (analysis.nc): the numbers of its table."""
    from ..data.reading import open_dataset  # lazily
    from ..reports.records import dataset_record  # lazily

    return dataset_record(open_dataset(summary))
