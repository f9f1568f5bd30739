"""The Python API: every command of the command line as a function, called from a notebook or a script.

`run`, `sweep`, `calibrate`, `convergence`, `stability`, `analyze`, `plot`,
`export`, `show`, `scenes` and `open` call the same `biostudy.commands`
functions as the command line, with its options as keyword arguments, so a
dataset made here is the one the command writes (the scene, its overrides,
provenance, every observable), and bad input raises the same
`biostudy.errors.BadInput` (its message is the line the command prints).
They return what the command made (a dataset, the files written, a summary)
and print nothing: what they did goes to the ``biostudy`` logger, what a
result warns about to `warnings`.  Files written here record the call in
their ``history`` (`netcdf.called`), not the notebook kernel's command line.
"""
from __future__ import annotations

import logging
import numbers
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

import xarray as xr

from .data import netcdf, reading
from .errors import BadInput
from .execution import worker
from .inputs.tomltext import literal

if TYPE_CHECKING:
    from .commands.show import Shown

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


def _number(value: Any, key: str, whole: bool = False, least: float | None = None) -> Any:
    """`value` if it is a number (a whole one if `whole`), at least `least` if given; `BadInput` else."""
    kind = numbers.Integral if whole else numbers.Real
    if isinstance(value, bool) or not isinstance(value, kind) or (least is not None and not float(value) >= least):
        wanted = "a whole number" if whole else "a number"
        raise BadInput(f"give {wanted}{f', {least:g} or more' if least is not None else ''} (got {value!r})", key=key)
    return value


def _path(value: Any, key: str) -> Path:
    """A file or directory given as a str or a Path, as a Path; `BadInput` for anything else."""
    if isinstance(value, Path) or isinstance(value, str) and value:
        return Path(value)
    raise BadInput(f"give a file or directory as a str or a Path (got {value!r})", key=key)


def _optional_path(value: Any, key: str) -> Path | None:
    """`_path`, or None where it may be left out (the command's default)."""
    return None if value is None else _path(value, key)


def _strings(given: Any, key: str) -> list[str]:
    """'height' or ['height', 'coverage'] -> a list of names; `BadInput` for anything else."""
    if given is None:
        return []
    if isinstance(given, str):
        return [given]
    if not isinstance(given, Sequence) or not all(isinstance(g, str) for g in given):
        raise BadInput(f"give a name or a list of names (got {given!r})", key=key)
    return list(given)


def _call(name: str, *args, **kwargs) -> str:
    """The call as a user wrote it, for the files' history: biostudy.run('directional', set={'g': 1e9})."""
    def text(value) -> str:
        return repr(str(value)) if isinstance(value, Path) else repr(value)

    shown = [text(a) for a in args] + [f"{k}={text(v)}" for k, v in kwargs.items() if v not in (None, False, [], {})]
    return f"biostudy.{name}({', '.join(shown)})"


def run(scene: str | Path | Mapping, *, set: Overrides = None, output: str | Path | None = None,  # noqa: A002
        continue_from: str | Path | None = None, force: bool = False, progress=None,
        threads: int | None = None) -> xr.Dataset:
    """Run one simulation and return its dataset, the one ``biostudy run`` writes.

    scene: a scene file, the name of a bundled scene ('directional'), or the scene's data as a dict (the
        tables of a scene file: {'grid': {'shape': [20, 20]}, 'time': {...}, 'biofilm': [...]}).
    set: overrides, {'g': 1e9, 'time.t_end': 0.5} or ['g=1e9', 'time.t_end=0.5'] (as ``--set``).
    output: also write the dataset there (atomically; as ``-o``: never over an input or a file biostudy
        did not write, another scene's result only with `force`).
    continue_from: a finished run of the same scene to go on from (as ``--continue``).
    progress: called with a `solver.Progress` after every step.
    threads: the run's threads (as ``--threads``; default: the scene's, else the processors here); the results
        are the same for every count.

    Keys that `set` overrides are scalar coordinates of the dataset (in the file too: a run keeps its shape;
    runs with different values combine with ``xr.open_mfdataset(files, combine="nested", concat_dim=KEY)``).
    """
    from .commands import run as command  # lazily: `import biostudy` stays cheap (module docstring)

    overrides = _overrides(set)
    if progress is not None and not callable(progress):
        raise BadInput(f"give a function, called with each step's progress, or None (got {progress!r})",
                       key="progress")
    worker.pin_solvers()
    threads = None if threads is None else _number(threads, "threads", whole=True, least=1)
    with netcdf.called(_call("run", scene if not isinstance(scene, Mapping) else dict(scene), set=set,
                             output=output, continue_from=continue_from)):
        loaded = command.load(dict(scene) if isinstance(scene, Mapping) else scene, overrides=overrides,
                              output=None if output is None else Path(output), force=force,
                              continue_from=continue_from, write=output is not None, threads=threads)
        result = command.compute(loaded, progress=progress)
    ds = result.dataset.load()  # a written run comes back from its file, read whole and closed as before
    ds.close()
    attrs = ds.attrs
    log.info("%s: %s steps, %s bisected, wall time %.3g s%s", loaded.scene.name, attrs["steps_taken"],
             attrs["steps_bisected"], attrs["wall_time"], f"; wrote {output}" if output is not None else "")
    for said in result.warnings():
        warnings.warn(said, stacklevel=2)
    return netcdf.as_run(ds)


def _job(call: str, load: Callable[[], Any], where: dict[str, Any], **execution: Any) -> Any:
    """The one path of every job command (as `cli.jobs`): load (bad input before anything runs), run here, on
    local processes or on a Dask cluster (`where`: workers, scheduler, scheduler_file); log the summary, warn
    of what the result warns about and of the jobs that failed.  Returns the loaded job (its `directory`)."""
    from .execution.dask import check_choice
    from .execution.jobs import Execution

    where = {**where, "workers": _workers(where["workers"])}
    worker.pin_solvers()
    check_choice(where["workers"], where["scheduler"], where["scheduler_file"])
    with netcdf.called(call):
        job = load()
        finished = job.run(Execution(**where, **execution))
    log.info(finished.summary)
    for said in [*finished.warnings, *([finished.failure_line()] if finished.failures else [])]:
        warnings.warn(said, stacklevel=3)
    return job


def sweep(study: str | Path, directory: str | Path, *, workers: int | None = None, scheduler: str | None = None,
          scheduler_file: str | Path | None = None, set: Overrides = None, retry_failed: bool = False,  # noqa: A002
          rerun_all: bool = False, force: bool = False, threads: int | None = None) -> xr.Dataset:
    """Run every case of a study into `directory` (as ``biostudy sweep STUDY -o DIR``) and return its study.nc.

    Here, one case after another; on `workers` local processes; or on a running Dask cluster, by its
    `scheduler` address or the `scheduler_file` its scheduler wrote.  Cases finished before are skipped.
    A case that fails is recorded (``status``, ``message``) and the others go on; a warning says which.
    `threads`: each case's (as ``--threads``; default: the scene's, else the processors here shared among the
    workers).
    """
    from .commands import sweep as command  # lazily, as in `run`
    from .execution.dask import runs_here

    where, overrides = {"workers": workers, "scheduler": scheduler, "scheduler_file": scheduler_file}, _overrides(set)
    out = _path(directory, "directory")
    _job(_call("sweep", study, directory, **where, set=set),
         lambda: command.load(study, output=out, overrides=overrides,
                              runs_here=runs_here(scheduler, scheduler_file)),
         where, retry_failed=retry_failed, rerun_all=rerun_all, force=force,
         threads=None if threads is None else _number(threads, "threads", whole=True, least=1))
    return reading.open_dataset(out / "study.nc")


def calibrate(calibration: str | Path, directory: str | Path | None = None, *, workers: int | None = None,
              scheduler: str | None = None, scheduler_file: str | Path | None = None, set: Overrides = None,  # noqa: A002
              rerun_all: bool = False, force: bool = False) -> xr.Dataset:
    """Estimate scene parameters from measurements (as ``biostudy calibrate FILE.toml -o DIR``) and return its
    calibration.nc: estimates, standard errors, 95 % profile intervals, which parameters the data determine,
    the data beside the fitted observables.  Simulations finished before (in DIR/cases/) are reused; workers
    and a Dask cluster as for `sweep`.  Warnings say which simulations failed or lost their dense biofilm."""
    from .commands import calibrate as command  # lazily, as in `run`
    from .execution.dask import runs_here

    where, overrides = {"workers": workers, "scheduler": scheduler, "scheduler_file": scheduler_file}, _overrides(set)
    out = _optional_path(directory, "directory")
    job = _job(_call("calibrate", calibration, directory, **where, set=set),
               lambda: command.load(calibration, output=out, overrides=overrides,
                                    runs_here=runs_here(scheduler, scheduler_file)),
               where, rerun_all=rerun_all, force=force)
    return reading.open_dataset(job.directory / "calibration.nc")


def convergence(scene: str | Path, directory: str | Path | None = None, *, levels: int = 3,
                series: str | Sequence[str] = "space,time,both,adaptive", tolerance: float = 1e-2,
                workers: int | None = None, scheduler: str | None = None, scheduler_file: str | Path | None = None,
                set: Overrides = None, reference: str | Path | None = None, time: float | None = None,  # noqa: A002
                rerun_all: bool = False, force: bool = False) -> xr.Dataset:
    """Refine a scene in space, time, both and with error-controlled steps (as ``biostudy convergence SCENE -o
    DIR``) and return its convergence.nc: each level's error and cost, the observed orders.  `levels` per
    series, the finest the reference (or the run `reference`, compared at the output nearest T* = `time`);
    `tolerance`: the time_tolerance of the adaptive series' level 0; `set`: overrides of level 0 (and every
    level).  Levels finished before are reused; workers and a Dask cluster as for `sweep`."""
    from .commands import convergence as command  # lazily, as in `run`

    levels = _number(levels, "levels", whole=True, least=2)
    tolerance = _number(tolerance, "tolerance", least=0.0)
    time = None if time is None else _number(time, "time")
    chosen = series if isinstance(series, str) else tuple(series)
    where, overrides = {"workers": workers, "scheduler": scheduler, "scheduler_file": scheduler_file}, _overrides(set)
    out, reference = _optional_path(directory, "directory"), _optional_path(reference, "reference")
    job = _job(_call("convergence", scene, directory, levels=levels, series=series, tolerance=tolerance, **where,
                     set=set, reference=reference, time=time),
               lambda: command.load(scene, output=out, levels=levels, series=chosen, tolerance=tolerance,
                                    overrides=overrides, reference=reference, time=time),
               where, rerun_all=rerun_all, force=force)
    return reading.open_dataset(job.directory / "convergence.nc")


def stability(catalogue: str | Path, directory: str | Path | None = None, *, workers: int | None = None,
              scheduler: str | None = None, scheduler_file: str | Path | None = None, set: Overrides = None,  # noqa: A002
              rerun_all: bool = False, force: bool = False) -> xr.Dataset:
    """Run a catalogue of stiff and extreme cases (as ``biostudy stability CATALOGUE -o DIR``) and return its
    stability.nc: each case's verdict (completed within its bounds, or stopped with a diagnosis).  A case that
    did neither is warned of; workers and a Dask cluster as for `sweep`."""
    from .commands import stability as command  # lazily, as in `run`
    from .execution.dask import runs_here

    where, overrides = {"workers": workers, "scheduler": scheduler, "scheduler_file": scheduler_file}, _overrides(set)
    out = _optional_path(directory, "directory")
    job = _job(_call("stability", catalogue, directory, **where, set=set),
               lambda: command.load(catalogue, output=out, overrides=overrides,
                                    runs_here=runs_here(scheduler, scheduler_file)),
               where, rerun_all=rerun_all, force=force)
    return reading.open_dataset(job.directory / "stability.nc")


def analyze(study: str | Path, *, outputs: str | Sequence[str] | None = None,
            times: float | str | Sequence[float | str] | None = None) -> xr.Dataset:
    """Which parameter matters (as ``biostudy analyze DIR``): Sobol' or Morris indices of a sampled study, rank
    correlations of any study, for `outputs` (default: every observable it has) at the outputs nearest `times`
    (T*, or real times such as '12 h'; default: the last).  Writes analysis.nc, analysis.md and the pictures
    beside the study's study.nc and returns analysis.nc."""
    from .commands.analyze import analyze as command  # lazily, as in `run`

    names = _strings(outputs, "outputs")
    asked: list[float | str] = ([] if times is None else [times] if isinstance(times, (str, int, float))
                                else list(times))
    with netcdf.called(_call("analyze", study, outputs=outputs, times=times)):
        written, _ = command(_path(study, "study"), outputs=names, times=asked)
    log.info("wrote %s", ", ".join(str(p) for p in written))
    return reading.open_dataset(written[0])


def plot(result: str | Path, *, output: str | Path | None = None, variable: str | None = None,
         time: float | str | None = None, cut: str | None = None, warp: float | None = None) -> list[Path]:
    """Draw the pictures of a run or a study (as ``biostudy plot FILE.nc``) and return the files written:
    time series; a 3-D run's cut (`cut`: 'diagonal', 'xy-diagonal', 'x=10', ...) and isosurfaces, a 2-D run's
    maps; a study's outputs against its parameters.  `variable`: one field or output; `time`: the output
    nearest this T* (or real time, '12 h'); `warp`: also the body deformed by `warp` times u."""
    from .commands.plot import plot as command  # lazily, as in `run`

    warp = None if warp is None else _number(warp, "warp")
    out = _optional_path(output, "output")
    written = command(_path(result, "result"), output=out, variable=variable, time=time, cut=cut, warp=warp)
    log.info("wrote %s", ", ".join(str(p) for p in written))
    return written


def export(result: str | Path, directory: str | Path, *, format: str = "vtu") -> list[Path]:  # noqa: A002
    """Write one run's fields into `directory` (as ``biostudy export FILE.nc DIR``) and return the files
    written: 'vtu', one VTU per snapshot and series.pvd for ParaView; 'tiff', phi.tif and c.tif for Fiji."""
    from .commands import export as command  # lazily, as in `run`

    written = command.export(_path(result, "result"), _path(directory, "directory"), format=format)
    log.info(command.said(written, directory, format))
    return written


def show(*paths: str | Path) -> Shown:
    """What ``biostudy show FILE...`` prints, returned (`commands.show.Shown`): str() of it is the summary as
    text; `.record` the numbers of ``--json`` (a run's observables over time, a study's cases); for several
    runs `.comparison` (the scene keys that differ, the output times they share, the largest field
    differences).  A scene or study file (TOML): what running it needs, as text."""
    from .commands.show import show as command  # lazily, as in `run`

    given = list(paths[0]) if len(paths) == 1 and isinstance(paths[0], (list, tuple)) else list(paths)
    return command([_path(p, "paths") for p in given])


def scenes() -> dict:
    """The bundled scenes, studies, catalogues and calibrations (as ``biostudy scenes --json``): the directory
    they are in, and per file its name, kind and description; any of them runs by its name."""
    from .commands.scenes import scenes as command  # lazily, as in `run`

    return command()


def open_result(path: str | Path) -> xr.Dataset:
    """A dataset biostudy wrote, loaded into memory: a run, a case file (as one run), a study's study.nc (or its
    directory), a convergence or stability summary.  `BadInput` for anything else."""
    path = Path(path)
    return reading.open_result(path / "study.nc" if path.is_dir() else path, ("run", "study", "failed", "summary"),
                               "biostudy.open reads runs, cases, studies and summaries")
