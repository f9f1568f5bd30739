"""`--json`: the records of `reports.records` for what a command would print as a table, on stdout
(`show`'s and `scenes`' are made by their commands: `commands.show.records`, `commands.scenes.scenes`).

Only the JSON goes to stdout; progress, warnings and the summary line stay on
stderr, so `biostudy show --json run.nc | jq .observables` reads it as is.
"""
from __future__ import annotations

from pathlib import Path

import typer


def emit(record: dict | list) -> None:
    from ..reports.records import text  # lazily (app's docstring)

    typer.echo(text(record))


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
