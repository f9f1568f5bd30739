"""The Python API: every command of the command line as a function, called from a notebook or a script.

`run`, `sweep`, `calibrate`, `convergence`, `stability`, `analyze`, `plot`,
`export`, `measure`, `show` and `scenes` are made from the same declarations as the
command line (`commands.declared`): the same options by the same names (``--set``
is ``set=``, ``-o`` of a job command its second argument ``directory``), the
same defaults, the same rules, and for the same mistake the same words.  They call
the same `biostudy.commands` functions, so a dataset made here is the one the
command writes (the scene, its overrides, provenance, every observable), and bad
input raises the same `biostudy.errors.BadInput` (its message is the line the
command prints).  They return what the command made (a dataset, the files
written, a summary) and print nothing: what they did goes to the ``biostudy``
logger, what a result warns about to `warnings`.  Files written here record the
call in their ``history`` (`netcdf.called`), not the notebook kernel's command
line.  `open` reads what any of them wrote.
"""
from __future__ import annotations

import inspect
import logging
import textwrap
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import xarray as xr

from .commands import declared
from .commands.options import REQUIRED, Command
from .data import netcdf, reading
from .execution import worker

if TYPE_CHECKING:
    from .commands.show import Shown

log = logging.getLogger("biostudy")  # what a call did, at INFO; silent unless logging is configured
Body = Callable[[dict[str, Any]], Any]


def _signature(command: Command, body: Body) -> inspect.Signature:
    """The Python function's signature: the files it reads and writes by position too, the rest by keyword."""
    params = []
    for option in command.on("python"):
        kind = (inspect.Parameter.VAR_POSITIONAL if option.variadic else inspect.Parameter.POSITIONAL_OR_KEYWORD
                if option.positional else inspect.Parameter.KEYWORD_ONLY)
        shown = option.kind.shown() + (" | None" if option.default is None else "")
        default = inspect.Parameter.empty if option.default is REQUIRED or option.variadic else option.default
        params.append(inspect.Parameter(option.name, kind, default=default, annotation=shown))
    return inspect.Signature(params, return_annotation=inspect.signature(body).return_annotation)


def _doc(command: Command) -> str:
    """The function's docstring: what it does, what it returns, and every option's help."""
    lines = [f"{command.help} (as ``biostudy {command.name}``)", "", f"Returns {command.returns}."]
    options = command.on("python")
    if options:
        lines.append("")
    for option in options:
        lines += textwrap.wrap(f"{option.name}: {option.described}", 110, subsequent_indent="    ",
                               break_on_hyphens=False)
    return "\n".join(lines)


def _call(command: Command, bound: inspect.BoundArguments) -> str:
    """The call as a user wrote it, for the files' history: biostudy.run('directional', set={'g': 1e9})."""
    def text(value) -> str:
        return repr(str(value)) if isinstance(value, Path) else repr(dict(value) if isinstance(value, Mapping)
                                                                     else value)

    shown = []
    for name, value in bound.arguments.items():
        kind = bound.signature.parameters[name].kind
        if kind is inspect.Parameter.VAR_POSITIONAL:
            shown += [text(v) for v in value]
        elif kind is inspect.Parameter.POSITIONAL_OR_KEYWORD:
            shown.append(text(value))
        elif not (value is None or value is False or callable(value) or
                  isinstance(value, (list, tuple, dict)) and not value):
            shown.append(f"{name}={text(value)}")
    return f"biostudy.{command.name}({', '.join(shown)})"


def _function(command: Command, body: Body) -> Callable[..., Any]:
    """The Python function of `command`: its arguments bound to the declared signature, read and checked by the
    options' kinds (`Command.values`: `BadInput` in the command line's words), handed to `body`."""
    signature = _signature(command, body)

    def function(*args: Any, **kwargs: Any) -> Any:
        try:
            bound = signature.bind(*args, **kwargs)
        except TypeError as error:
            raise TypeError(f"biostudy.{command.name}(): {error}") from None
        with netcdf.called(_call(command, bound)):
            return body(command.values(bound.arguments, "python"))

    function.__signature__ = signature  # type: ignore[attr-defined]
    function.__name__ = function.__qualname__ = command.name
    function.__doc__ = _doc(command)
    function.__module__ = __name__
    return function


def _run(values: dict[str, Any]) -> xr.Dataset:
    from .commands import run as command  # lazily: `import biostudy` stays cheap (module docstring)

    progress = values.pop("progress")
    worker.pin_solvers()
    with command.load(**values, write=values["output"] is not None) as loaded:
        result = command.compute(loaded, progress=progress)
    ds = result.dataset.load()  # a written run comes back from its file, read whole and closed as before
    ds.close()
    attrs = ds.attrs
    log.info("%s: %s steps, %s bisected, wall time %.3g s%s", loaded.scene.name, attrs["steps_taken"],
             attrs["steps_bisected"], attrs["wall_time"],
             f"; wrote {values['output']}" if values["output"] is not None else "")
    for said in result.warnings():
        warnings.warn(said, stacklevel=3)
    return netcdf.as_run(ds)


def _job(command: Command) -> Body:
    """The body of a job command's function: started as the command line starts it (`commands.jobs.started`),
    run here, on local processes or a Dask cluster; its summary logged, what it warns of and the jobs that
    failed warned of; its summary dataset (study.nc, convergence.nc, ...) returned."""
    def job(values: dict[str, Any]) -> xr.Dataset:
        from .commands.jobs import started  # lazily, as in `run`

        loaded, where = started(command, values)  # first: it starts the workers' fork server before the imports below
        from .execution.jobs import Execution

        finished = loaded.run(Execution(**where))
        log.info(finished.summary)
        for said in [*finished.warnings, *([finished.failure_line()] if finished.failures else [])]:
            warnings.warn(said, stacklevel=3)
        return reading.open_dataset(loaded.summary)

    return job


def _analyze(values: dict[str, Any]) -> xr.Dataset:
    from .commands.analyze import analyze as command  # lazily, as in `run`

    written, _ = command(**values)
    log.info("wrote %s", ", ".join(str(p) for p in written))
    found = reading.open_dataset(written[0])
    if found.attrs.get("warning"):  # Sobol' indices from too few samples
        warnings.warn(str(found.attrs["warning"]), stacklevel=3)
    return found


def _plot(values: dict[str, Any]) -> list[Path]:
    from .commands.plot import plot as command  # lazily, as in `run`

    written = command(**values)
    log.info("wrote %s", ", ".join(str(p) for p in written))
    return written


def _export(values: dict[str, Any]) -> list[Path]:
    from .commands import export as command  # lazily, as in `run`

    written = command.export(**values)
    log.info(command.said(written, values["directory"], values["format"]))
    return written


def _show(values: dict[str, Any]) -> Shown:
    from .commands.show import show as command  # lazily, as in `run`

    return command(values["paths"])


def _measure(values: dict[str, Any]) -> list[dict]:
    from .commands.measure import measure as command  # lazily, as in `run`

    found = command(**values)
    if found.written is not None:
        log.info("wrote %s", found.written)
    return found.records


def _scenes(values: dict[str, Any]) -> dict:
    from .commands.scenes import scenes as command  # lazily, as in `run`

    return command()


run = _function(declared.RUN, _run)
sweep = _function(declared.SWEEP, _job(declared.SWEEP))
calibrate = _function(declared.CALIBRATE, _job(declared.CALIBRATE))
convergence = _function(declared.CONVERGENCE, _job(declared.CONVERGENCE))
stability = _function(declared.STABILITY, _job(declared.STABILITY))
analyze = _function(declared.ANALYZE, _analyze)
plot = _function(declared.PLOT, _plot)
export = _function(declared.EXPORT, _export)
show = _function(declared.SHOW, _show)
measure = _function(declared.MEASURE, _measure)
scenes = _function(declared.SCENES, _scenes)


def open_result(path: str | Path) -> xr.Dataset:
    """A dataset biostudy wrote, loaded into memory: a run, a case file (as one run), a study's study.nc (or its
    directory), a convergence or stability summary.  `BadInput` for anything else."""
    path = Path(path)
    return reading.open_result(path / "study.nc" if path.is_dir() else path, ("run", "study", "failed", "summary"),
                               "biostudy.open reads runs, cases, studies and summaries")
