"""The `biostudy` command line (README's command table): load, validate, call; nothing else.

Every command calls one function of `biostudy.commands` with keyword-only
options.  Exit status: 0 done, 1 a computation failed (the message says why),
2 bad input (one line per problem: file, key, problem; no traceback), 130
interrupted by Ctrl-C (SIGINT), 143 by SIGTERM (no file is left half-written).  Progress goes to stderr
(`progress`), as much as -q/-v ask (`logs`); --json puts a table's numbers on
stdout instead of the table (`output`).  The commands' modules are imported inside the commands: `--version`
and `-h` do not pay for numpy, xarray and FiPy.
"""
from __future__ import annotations

import contextlib
import enum
import os
import signal
import sys
from pathlib import Path
from typing import Annotated, Callable, List, Optional

import typer

from ..errors import BadInput, Failed
from ..execution import worker
from ..inputs import bundled
from . import logs, output, progress
from .held import held_warnings
from .options import (
    FLAG,
    CaseOverrides,
    CatalogueArgument,
    Directory,
    Force,
    Json,
    Overrides,
    Quiet,
    RerunAll,
    RetryFailed,
    SceneArgument,
    Scheduler,
    SchedulerFile,
    StudyArgument,
    Verbose,
    Workers,
    overrides,
)

_USAGE_ERROR = typer.BadParameter.__mro__[1]  # click's UsageError, wherever this typer takes click from
_CLICK_ERROR = _USAGE_ERROR.__mro__[1]  # click's ClickException


class _OneLineErrors(typer.core.TyperGroup):
    """Usage errors (an unknown option, a missing argument, a value out of range) told in one line, exit status
    2, as every other error: "error: biostudy run: No such option: --bogus (biostudy run -h lists them)"."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        try:
            status = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except _USAGE_ERROR as error:
            if type(error).__name__ == "NoArgsIsHelpError":  # `biostudy` alone: the help, as typer shows it
                error.show()
                sys.exit(error.exit_code)
            command = error.ctx.command_path if error.ctx else "biostudy"
            message = " ".join(error.format_message().split())
            typer.echo(f"error: {command}: {message} (see `{command} -h`)", err=True)
            sys.exit(2)
        except _CLICK_ERROR as error:
            typer.echo(f"error: {' '.join(error.format_message().split())}", err=True)
            sys.exit(error.exit_code)
        except typer.Abort as abort:  # click's for a KeyboardInterrupt, and for an EOFError, which is none
            if isinstance(abort.__cause__, EOFError):
                raise abort.__cause__ from None
            typer.echo("interrupted", err=True)
            sys.exit(interrupted_status(abort.__cause__))
        except KeyboardInterrupt as late:  # while click ended the command (Ctrl-C just as it returned)
            typer.echo("interrupted", err=True)
            sys.exit(interrupted_status(late))
        sys.exit(status if isinstance(status, int) else 0)


app = typer.Typer(name="biostudy", cls=_OneLineErrors, no_args_is_help=True, pretty_exceptions_enable=False,
                  context_settings={"help_option_names": ["-h", "--help"]},
                  help="Parameter studies of biofilm growth: run scenes, sweep studies, inspect results.")


def _version(value: bool) -> None:
    if value:
        import importlib.metadata

        try:
            typer.echo(f"biostudy {importlib.metadata.version('biostudy')}")
        except importlib.metadata.PackageNotFoundError:
            typer.echo("biostudy unknown")
        raise typer.Exit()


@app.callback()
def _process(ctx: typer.Context,
             version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, metavar=FLAG,
                                                   help="print the version and exit")] = False,
             quiet: Annotated[bool, typer.Option("-q", "--quiet", metavar=FLAG,
                                                 help="no progress bar or lines, for every command")] = False,
             verbose: Annotated[bool, typer.Option("-v", "--verbose", metavar=FLAG,
                                                   help="more detail on stderr, for every command")] = False) -> None:
    logs.start(quiet, verbose)  # the library's logger to stderr while this command line runs
    ctx.call_on_close(logs.stop)
    # Where a biostudy process starts, before FiPy or matplotlib is imported: FiPy's scipy solver suite,
    # and pictures drawn to files, never to a screen.
    worker.pin_solvers()
    os.environ["MPLBACKEND"] = "Agg"


def _fail(message: str, status: int) -> typer.Exit:
    typer.echo(message, err=True)  # plain echo: rich would wrap a long message over several lines
    return typer.Exit(status)


class Terminated(KeyboardInterrupt):
    """SIGTERM, unwinding as Ctrl-C does (temporary files are removed on the way out), told apart by its exit
    status: 143 (128 + 15), where Ctrl-C's is 130 (128 + 2)."""


def interrupted_status(error: BaseException | None) -> int:
    return 128 + (signal.SIGTERM if isinstance(error, Terminated) else signal.SIGINT)


def _terminate(signum, frame):
    raise Terminated


def _unwinding(error: BaseException) -> KeyboardInterrupt | None:
    """The interruption `error` was raised while handling, if any: an error on the way out of an interrupted
    write (closing a file HDF5 was writing) is the interruption's, not a failure of its own."""
    seen: BaseException | None = error.__context__
    while seen is not None and not isinstance(seen, KeyboardInterrupt):
        seen = seen.__context__
    return seen


@contextlib.contextmanager
def _guarded():
    """Bad input -> exit 2 with one line per problem; a failure -> exit 1 with its line; Ctrl-C -> exit 130,
    SIGTERM -> exit 143.  Warnings are held and told after the command, one line each, not after bad input."""
    previous = signal.signal(signal.SIGTERM, _terminate)
    held = []
    try:
        with held_warnings() as held:
            try:
                yield
            except Exception as error:
                interruption = _unwinding(error)
                if interruption is None:
                    raise
                raise interruption from None
    except BadInput as error:
        held.clear()  # a bad input prints only its own lines
        raise _fail("\n".join(f"error: {line}" for line in error.lines()), 2) from None
    except Failed as error:
        raise _fail(f"error: {error}", 1) from None
    except KeyboardInterrupt as error:
        raise _fail("interrupted: finished files are kept, nothing is left half-written",
                    interrupted_status(error)) from None
    finally:
        signal.signal(signal.SIGTERM, previous)
        for line in held:
            typer.echo(f"warning: {line}", err=True)


@app.command()
def run(
    scene: SceneArgument,
    output: Annotated[Optional[Path], typer.Option(
        "-o", "--output", metavar="OUT.nc", help="dataset to write (default: NAME.nc, the scene's name)")] = None,
    overrides: Overrides = [],
    force: Annotated[bool, typer.Option("--force", metavar=FLAG,
                                        help="replace OUT.nc even if it holds the result of another scene or a "
                                             "sweep's file (never an input or a file biostudy did not write)")] = False,
    quiet: Quiet = False,
    verbose: Verbose = False,
    continue_from: Annotated[Optional[Path], typer.Option(
        "--continue", metavar="RUN.nc", help="go on from the last state of this finished run of the same scene "
                                              "(give a later --set time.t_end=...); writes the whole history "
                                              "(default: RUN-tT_END.nc beside it)")] = None,
):
    """Run one simulation and write its dataset (netCDF)."""
    with _guarded():
        from ..commands import run as command  # lazily (module docstring)

        loaded = command.load(scene, overrides=overrides, output=output, force=force, continue_from=continue_from)
        with progress.simulation(loaded.scene.name, loaded.scene.time.t_end, quiet) as report:
            result = command.compute(loaded, progress=report)
        for warning in result.warnings():
            typer.echo(f"warning: {warning}", err=True)
        progress.err().print(result.message(), markup=False, highlight=False, soft_wrap=True)
        result.dataset.close()  # the file written, opened lazily (`commands.run.compute`)


def _job_command(quiet: bool, load: Callable, as_json: bool = False, **execution) -> None:
    """The one path of every job command (sweep, convergence, stability).

    load() reads and validates (bad input: exit 2 before anything runs) and returns a `commands.JobCommand`,
    which runs the jobs on the chosen pool and says what came of them (`commands.finished.Finished`).  A job
    that failed, or a pool that broke down, is exit status 1.  `as_json`: the result as JSON on stdout
    instead of the table (`output.finished`).
    """
    with _guarded():
        from ..execution.dask import check_choice  # lazily (module docstring)
        from ..execution.jobs import Execution  # lazily

        check_choice(execution.get("workers"), execution.get("scheduler"), execution.get("scheduler_file"))
        if execution.get("workers"):
            from ..execution.pool import warm_up  # lazily

            warm_up()  # the fork server imports the solver while this process imports it and validates
        job = load()
        with progress.jobs(job.title, quiet, job.noun) as notify:
            finished = job.run(Execution(notify=notify, **execution))
        if as_json:
            output.emit(output.finished(job, finished.result))
        elif finished.table:
            typer.echo(finished.table)
        for warning in finished.warnings:
            typer.echo(f"warning: {warning}", err=True)
        progress.err().print(finished.summary)
        if finished.failures:
            raise _fail(finished.failure_line(), 1)


@app.command()
def sweep(
    study: StudyArgument,
    output: Directory = None,
    workers: Workers = None,
    scheduler: Scheduler = None,
    scheduler_file: SchedulerFile = None,
    overrides: CaseOverrides = [],
    retry_failed: RetryFailed = False,
    force: Force = False,
    rerun_all: RerunAll = False,
    quiet: Quiet = False,
    verbose: Verbose = False,
    cases: Annotated[List[str], typer.Option(
        "--case", metavar="ID", help="run only this case (an array task; repeatable): its file goes into DIR "
                                     "beside those of other such tasks; study.nc is left to --combine")] = [],
    task: Annotated[Optional[int], typer.Option(
        "--task", metavar="N", help="an array task: run case number N (the study's order from 0), or with "
                                    "--tasks M share N (0..M-1): cases N, N+M, ...")] = None,
    tasks: Annotated[Optional[int], typer.Option("--tasks", metavar="M", help="how many shares --task numbers "
                                                                             "(fixed, not the array's size)")] = None,
    combine_only: Annotated[bool, typer.Option(
        "--combine", metavar=FLAG, help="run nothing: write DIR/study.nc from the case files there (after array "
                                        "tasks)")] = False,
    as_json: Json = False,
):
    """Run every case of a study; re-running skips finished cases."""
    def load():
        from ..commands import sweep as command  # lazily (module docstring)
        from ..execution.dask import runs_here  # lazily

        return command.load(study, output=output, overrides=overrides, cases=cases, task=task, tasks=tasks,
                            combine_only=combine_only, runs_here=runs_here(scheduler, scheduler_file))

    _job_command(quiet, load, as_json, workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                 retry_failed=retry_failed, force=force, rerun_all=rerun_all)


@app.command()
def scenes(as_json: Json = False):
    """List the bundled scenes and studies with their descriptions."""
    from rich.table import Table

    directory = bundled.studies_dir()
    if as_json:
        output.emit(output.scenes(directory))
        return
    table = Table(title=f"bundled scenes and studies in {directory}", show_edge=False)
    table.add_column("file", no_wrap=True)
    table.add_column("kind", no_wrap=True)
    table.add_column("description")
    for entry in bundled.entries(directory):
        table.add_row(entry.path.name, entry.kind, entry.description)
    progress.out().print(table)


@app.command()
def show(paths: Annotated[List[Path], typer.Argument(metavar="FILE...", help="dataset written by run or sweep (a "
                                                                           "case file, study.nc, or a sweep's "
                                                                           "directory), or a scene or study file "
                                                                           "(TOML); several runs: side by side")],
         as_json: Json = False):
    """Print a readable summary: scene, parameters, run time, final averages; for a scene or study file what
    running it needs (memory, disk); for several runs, how they differ (scenes, parameters, observables at their
    common times, the largest field differences)."""
    if as_json:
        with _guarded():
            records = [output.shown(p) for p in paths]
            output.emit(records[0] if len(paths) == 1 else records)
        return
    if len(paths) > 1:
        with _guarded():
            from ..data.store import open_result  # lazily (module docstring)
            from ..reports.compare import show_compared  # lazily (module docstring)

            runs = [open_result(p, ("run",), "show of several files sets runs side by side") for p in paths]
            show_compared(runs, paths, progress.out())
        return
    path = paths[0]
    with _guarded():
        if path.suffix == ".toml" or (not path.exists() and not path.suffix):
            from ..reports.needs import needs  # lazily (module docstring)

            typer.echo(needs(bundled.resolve(path)))
            return
        from ..reports.glance import glance  # lazily (module docstring)

        at_a_glance = glance(path) if path.is_file() else None  # a run's file: netCDF4 alone, no xarray
        if at_a_glance is not None:
            progress.out().print(at_a_glance)
            return
        from ..data.store import open_result  # lazily (module docstring)
        from ..reports.show import summarize  # lazily

        summarize(open_result(path / "study.nc" if path.is_dir() else path, doing="show reads runs, cases and "
                              "study.nc"), progress.out())


@app.command()
def plot(
    path: Annotated[Path, typer.Argument(metavar="FILE.nc", help="dataset written by run or sweep (a sweep's "
                                                                 "directory means its study.nc)")],
    output: Annotated[Optional[Path], typer.Option("-o", "--output", metavar="FIG.png",
                                                   help="picture (PNG); several figures get _series, _cut, ... "
                                                        "suffixes (default: beside the dataset)")] = None,
    variable: Annotated[Optional[str], typer.Option("--variable", metavar="V",
                                                    help="one field (phi, c, alpha, p) or, for a sweep, one output "
                                                         "(phi_mean, c_mean, biofilm_volume)")] = None,
    time: Annotated[Optional[str], typer.Option("--time", metavar="T",
                                                help="draw the output nearest to this T* (or real time: "
                                                     "'12 h', with the scene's t_ref)")] = None,
    cut: Annotated[Optional[str], typer.Option("--cut", metavar="C",
                                               help="3-D: 'diagonal' (toward the nutrient, default), 'xy-diagonal', "
                                                    "or a plane such as 'x=10' or 'z=5.5' (µm)")] = None,
    warp: Annotated[Optional[float], typer.Option("--warp", metavar="FACTOR",
                                                  help="also draw the deformed body with the displacement magnified "
                                                       "by this factor (e.g. 500, paper Fig. 13)")] = None,
):
    """Draw the pictures of a run or a sweep: time series, cuts, isosurfaces, maps, sweep outputs."""
    with _guarded():
        from ..data.real_time import t_star  # lazily (module docstring)
        from ..data.store import open_result
        from ..plots import plot as draw

        source = path / "study.nc" if path.is_dir() else path
        ds = open_result(source, ("run", "study"), "nothing to plot")
        try:
            at = None if time is None else t_star(ds, time)
            written = draw(ds, output or source.with_suffix(".png"), variable=variable, time=at, cut=cut, warp=warp)
        except ValueError as error:
            raise BadInput(str(error), source) from None
        for picture in written:
            progress.out().print(f"wrote {picture}")


@app.command()
def analyze(
    path: Annotated[Path, typer.Argument(metavar="DIR", help="a study's directory (or its study.nc), written by "
                                                             "sweep")],
    outputs: Annotated[List[str], typer.Option("--output", metavar="NAME",
                                               help="observable or study.nc variable to analyse; repeatable "
                                                    "(default: every observable the study has)")] = [],
    times: Annotated[List[str], typer.Option("--time", metavar="T",
                                             help="analyse at the output nearest this T* (or real time: '12 h', "
                                                  "with the scene's t_ref); repeatable (default: the last "
                                                  "output)")] = [],
    as_json: Json = False,
):
    """Which parameter matters: Sobol' or Morris indices of a sampled study, rank correlations of any study."""
    with _guarded():
        from ..commands.analyze import analyze as command  # lazily (module docstring)

        written, table = command(path, outputs=outputs, times=times)
        output.emit(output.written(written[0])) if as_json else typer.echo(table)  # [0]: analysis.nc
        progress.err().print("wrote " + ", ".join(str(p) for p in written))


class ExportFormat(str, enum.Enum):
    vtu = "vtu"
    tiff = "tiff"


@app.command()
def export(
    path: Annotated[Path, typer.Argument(metavar="FILE.nc", help="dataset written by run (or one case of a sweep)")],
    directory: Annotated[Path, typer.Argument(metavar="DIR", help="directory for snapshot_NNNN.vtu files and "
                                                                  "series.pvd (tiff: phi.tif, c.tif)")],
    format: Annotated[ExportFormat, typer.Option(
        "--format", metavar="F", help="vtu: ParaView (default); tiff: ImageJ hyperstacks of phi and c at scale (µm) "
                                      "with the time axis, for Fiji, BiofilmQ, COMSTAT")] = ExportFormat.vtu,
):
    """Write files ParaView opens (one VTU per snapshot and a PVD listing them in time), or TIFF stacks for Fiji."""
    with _guarded():
        from ..data.store import open_result  # lazily (module docstring)

        ds = open_result(path, ("run",), "export writes one run's fields")
        try:
            if format is ExportFormat.tiff:
                from ..data.tiff import export_tiff  # lazily (module docstring)

                written = export_tiff(ds, directory, str(path))
            else:
                from ..data.export import export as write  # lazily (module docstring)

                written = write(ds, directory)
        except ValueError as error:
            raise BadInput(str(error), path) from None
        opened = "in Fiji (File > Open: at scale, in µm)" if format is ExportFormat.tiff else \
            f"{directory / 'series.pvd'} in ParaView"
        progress.out().print(f"wrote {len(written)} files to {directory} (open {opened})")


@app.command()
def convergence(
    scene: SceneArgument,
    output: Annotated[Optional[Path], typer.Option("-o", "--output", metavar="DIR",
                                                   help="directory for cases/, convergence.nc, convergence.md, "
                                                        "work_precision.png")] = None,
    levels: Annotated[int, typer.Option("--levels", min=2, metavar="N",
                                        help="levels per series; the finest is the reference")] = 3,
    series: Annotated[str, typer.Option("--series", metavar="S",
                                        help="comma-separated refinement series: space, time, both, "
                                             "adaptive")] = "space,time,both,adaptive",
    tolerance: Annotated[float, typer.Option("--tolerance", min=0.0, metavar="TOL",
                                             help="time_tolerance of adaptive level 0 (divided by 4 per "
                                                  "level)")] = 1e-2,
    workers: Workers = None,
    scheduler: Scheduler = None,
    scheduler_file: SchedulerFile = None,
    overrides: Annotated[List[str], overrides("level 0")] = [],
    force: Force = False,
    rerun_all: RerunAll = False,
    reference: Annotated[Optional[Path], typer.Option("--reference", metavar="RUN.nc",
                                                      help="measure every level against this run of the same scene "
                                                           "(e.g. refined, another scheme) instead of the finest "
                                                           "level")] = None,
    time: Annotated[Optional[float], typer.Option("--time", metavar="T",
                                                  help="compare at the output nearest this T* (default: the "
                                                       "last)")] = None,
    quiet: Quiet = False,
    verbose: Verbose = False,
    as_json: Json = False,
):
    """Refine grid, time step and both; measure each level's error and cost (work-precision)."""
    def load():
        from ..commands import convergence as command  # lazily (module docstring)

        return command.load(scene, output=output, levels=levels, series=series, tolerance=tolerance,
                            overrides=overrides, reference=reference, time=time)

    _job_command(quiet, load, as_json, workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                 force=force, rerun_all=rerun_all)


@app.command()
def stability(
    catalogue: CatalogueArgument,
    output: Annotated[Optional[Path], typer.Option("-o", "--output", metavar="DIR",
                                                   help="directory for cases/, stability.nc, stability.md")] = None,
    workers: Workers = None,
    scheduler: Scheduler = None,
    scheduler_file: SchedulerFile = None,
    overrides: CaseOverrides = [],
    force: Force = False,
    rerun_all: RerunAll = False,
    quiet: Quiet = False,
    verbose: Verbose = False,
    as_json: Json = False,
):
    """Run stiff and extreme cases: each completes within its bounds or stops with a diagnosis."""
    def load():
        from ..commands import stability as command  # lazily (module docstring)
        from ..execution.dask import runs_here  # lazily

        return command.load(catalogue, output=output, overrides=overrides,
                            runs_here=runs_here(scheduler, scheduler_file))

    _job_command(quiet, load, as_json, workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                 force=force, rerun_all=rerun_all)


@app.command()
def calibrate(
    calibration: Annotated[str, typer.Argument(metavar="FILE.toml", help="calibration file (TOML: a scene, the "
                                                                         "data, the keys to estimate, the method), "
                                                                         "or the name of a bundled one")],
    output: Annotated[Optional[Path], typer.Option("-o", "--output", metavar="DIR",
                                                   help="directory for cases/, calibration.nc, calibration.md and "
                                                        "the pictures (default: the calibration's name)")] = None,
    workers: Workers = None,
    scheduler: Scheduler = None,
    scheduler_file: SchedulerFile = None,
    overrides: Annotated[List[str], overrides("the scene of every simulation")] = [],
    force: Force = False,
    rerun_all: RerunAll = False,
    quiet: Quiet = False,
    verbose: Verbose = False,
    as_json: Json = False,
):
    """Estimate scene parameters from measurements: least squares, profile likelihoods, 95 % intervals."""
    def load():
        from ..commands import calibrate as command  # lazily (module docstring)
        from ..execution.dask import runs_here  # lazily

        return command.load(calibration, output=output, overrides=overrides,
                            runs_here=runs_here(scheduler, scheduler_file))

    _job_command(quiet, load, as_json, workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                 force=force, rerun_all=rerun_all)
