"""The Python API (`biostudy.run`, `sweep`, `calibrate`, `open`): the commands, called from a notebook.

Each function calls the same `biostudy.commands` function as the command
line, so a dataset made here is the one `biostudy run` writes (the scene, its
overrides, provenance, every observable), and bad input raises the same
`biostudy.errors.BadInput` (its message is the line the command prints).
Files written here record the call in their ``history`` (`netcdf.called`),
not the notebook kernel's command line.
"""
from __future__ import annotations

import logging
import numbers
import warnings
from pathlib import Path
from typing import Any, Mapping, Sequence

import xarray as xr

from .data import netcdf, reading
from .errors import BadInput
from .execution import worker
from .inputs.tomltext import literal

Overrides = Mapping[str, Any] | Sequence[str] | None
log = logging.getLogger("biostudy")  # what a call did, at INFO; silent unless logging is configured


def _overrides(given: Overrides) -> list[str]:
    """{'g': 1e9} or ['g=1e9'] -> ['g=1e9'] (values of a mapping written as TOML); anything else is `BadInput`."""
    if given is None:
        return []
    if isinstance(given, str):
        return [given]
    if isinstance(given, Mapping):
        return [f"{key}={literal(value)}" for key, value in given.items()]
    if not isinstance(given, Sequence):
        raise BadInput(f"give a dict {{'g': 1e9}} or a list ['g=1e9'] of overrides (got {given!r})", key="set")
    return [str(item) for item in given]


def _workers(workers: Any) -> int | None:
    """The number of local processes a call asked for: None or a whole number, 1 or more (`BadInput` else)."""
    if workers is None:
        return None
    if isinstance(workers, bool) or not isinstance(workers, numbers.Integral) or workers < 1:
        raise BadInput(f"give a whole number of processes, 1 or more, or None (got {workers!r})", key="workers")
    return int(workers)


def _call(name: str, *args, **kwargs) -> str:
    """The call as a user wrote it, for the files' history: biostudy.run('directional', set={'g': 1e9})."""
    def text(value) -> str:
        return repr(str(value)) if isinstance(value, Path) else repr(value)

    shown = [text(a) for a in args] + [f"{k}={text(v)}" for k, v in kwargs.items() if v not in (None, False, [], {})]
    return f"biostudy.{name}({', '.join(shown)})"


def run(scene: str | Path | Mapping, *, set: Overrides = None, output: str | Path | None = None,  # noqa: A002
        continue_from: str | Path | None = None, force: bool = False, progress=None) -> xr.Dataset:
    """Run one simulation and return its dataset, the one ``biostudy run`` writes.

    scene: a scene file, the name of a bundled scene ('directional'), or the scene's data as a dict (the
        tables of a scene file: {'grid': {'shape': [20, 20]}, 'time': {...}, 'biofilm': [...]}).
    set: overrides, {'g': 1e9, 'time.t_end': 0.5} or ['g=1e9', 'time.t_end=0.5'] (as ``--set``).
    output: also write the dataset there (atomically; as ``-o``: never over an input or a file biostudy
        did not write, another scene's result only with `force`).
    continue_from: a finished run of the same scene to go on from (as ``--continue``).
    progress: called with a `solver.Progress` after every step.

    Keys that `set` overrides are scalar coordinates of the dataset (in the file too: a run keeps its shape;
    runs with different values combine with ``xr.open_mfdataset(files, combine="nested", concat_dim=KEY)``).
    """
    from .commands import run as command  # lazily: `import biostudy` stays cheap (module docstring)

    overrides = _overrides(set)
    if progress is not None and not callable(progress):
        raise BadInput(f"give a function, called with each step's progress, or None (got {progress!r})",
                       key="progress")
    worker.pin_solvers()
    with netcdf.called(_call("run", scene if not isinstance(scene, Mapping) else dict(scene), set=set,
                             output=output, continue_from=continue_from)):
        loaded = command.load(dict(scene) if isinstance(scene, Mapping) else scene, overrides=overrides,
                              output=None if output is None else Path(output), force=force,
                              continue_from=continue_from, write=output is not None)
        result = command.compute(loaded, progress=progress)
    ds = result.dataset.load()  # a written run comes back from its file, read whole and closed as before
    ds.close()
    attrs = ds.attrs
    log.info("%s: %s steps, %s bisected, wall time %.3g s%s", loaded.scene.name, attrs["steps_taken"],
             attrs["steps_bisected"], attrs["wall_time"], f"; wrote {output}" if output is not None else "")
    for said in result.warnings():
        warnings.warn(said, stacklevel=2)
    return netcdf.as_run(ds)


def sweep(study: str | Path, directory: str | Path, *, workers: int | None = None, scheduler: str | None = None,
          scheduler_file: str | Path | None = None, set: Overrides = None, retry_failed: bool = False,  # noqa: A002
          rerun_all: bool = False, force: bool = False) -> xr.Dataset:
    """Run every case of a study into `directory` (as ``biostudy sweep STUDY -o DIR``) and return its study.nc.

    Here, one case after another; on `workers` local processes; or on a running Dask cluster, by its
    `scheduler` address or the `scheduler_file` its scheduler wrote.  Cases finished before are skipped.
    A case that fails is recorded (``status``, ``message``) and the others go on; a warning says which.
    """
    from .commands import sweep as command  # lazily, as in `run`
    from .execution.dask import check_choice, runs_here
    from .execution.jobs import Execution

    workers, overrides = _workers(workers), _overrides(set)
    worker.pin_solvers()
    check_choice(workers, scheduler, scheduler_file)
    with netcdf.called(_call("sweep", study, directory, workers=workers, scheduler=scheduler,
                             scheduler_file=scheduler_file, set=set)):
        job = command.load(study, output=Path(directory), overrides=overrides,
                           runs_here=runs_here(scheduler, scheduler_file))
        finished = job.run(Execution(workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                                     retry_failed=retry_failed, rerun_all=rerun_all, force=force))
    log.info(finished.summary)
    for said in finished.warnings:
        warnings.warn(said, stacklevel=2)
    if finished.failures:
        warnings.warn(finished.failure_line(), stacklevel=2)
    return reading.open_dataset(Path(directory) / "study.nc")


def calibrate(calibration: str | Path, directory: str | Path | None = None, *, workers: int | None = None,
              scheduler: str | None = None, scheduler_file: str | Path | None = None, set: Overrides = None,  # noqa: A002
              rerun_all: bool = False, force: bool = False) -> xr.Dataset:
    """Estimate scene parameters from measurements (as ``biostudy calibrate FILE.toml -o DIR``) and return its
    calibration.nc: estimates, standard errors, 95 % profile intervals, which parameters the data determine,
    the data beside the fitted observables.  Simulations finished before (in DIR/cases/) are reused; workers
    and a Dask cluster as for `sweep`.  Warnings say which simulations failed or lost their dense biofilm."""
    from .commands import calibrate as command  # lazily, as in `run`
    from .execution.dask import check_choice, runs_here
    from .execution.jobs import Execution

    workers, overrides = _workers(workers), _overrides(set)
    worker.pin_solvers()
    check_choice(workers, scheduler, scheduler_file)
    with netcdf.called(_call("calibrate", calibration, directory, workers=workers, scheduler=scheduler,
                             scheduler_file=scheduler_file, set=set)):
        job = command.load(calibration, output=None if directory is None else Path(directory),
                           overrides=overrides, runs_here=runs_here(scheduler, scheduler_file))
        finished = job.run(Execution(workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                                     rerun_all=rerun_all, force=force))
    log.info(finished.summary)
    for said in finished.warnings:
        warnings.warn(said, stacklevel=2)
    return reading.open_dataset(job.directory / "calibration.nc")


def open_result(path: str | Path) -> xr.Dataset:
    """A dataset biostudy wrote, loaded into memory: a run, a case file (as one run), a study's study.nc (or its
    directory), a convergence or stability summary.  `BadInput` for anything else."""
    path = Path(path)
    return reading.open_result(path / "study.nc" if path.is_dir() else path, ("run", "study", "failed", "summary"),
                             "biostudy.open reads runs, cases, studies and summaries")
