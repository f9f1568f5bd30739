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

import enum
import os
from pathlib import Path
from typing import Annotated, List, Optional

import typer

from ..execution import worker
from . import logs, output, progress
from .guard import OneLineErrors, guarded
from .jobs import job_command
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
    Threads,
    Verbose,
    Workers,
    overrides,
)

app = typer.Typer(name="biostudy", cls=OneLineErrors, no_args_is_help=True, pretty_exceptions_enable=False,
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
    threads: Threads = None,
):
    """Run one simulation and write its dataset (netCDF)."""
    with guarded():
        from ..commands import run as command  # lazily (module docstring)

        loaded = command.load(scene, overrides=overrides, output=output, force=force, continue_from=continue_from,
                              threads=threads)
        try:
            with progress.simulation(loaded.scene.name, loaded.scene.time.t_end, quiet) as report:
                result = command.compute(loaded, progress=report)
        finally:  # interrupted before `compute` took the claim over: its temporary goes now, not at exit
            if loaded.claim is not None:
                loaded.claim.release()
        for warning in result.warnings():
            typer.echo(f"warning: {warning}", err=True)
        progress.err().print(result.message(), markup=False, highlight=False, soft_wrap=True)
        result.dataset.close()  # the file written, opened lazily (`commands.run.compute`)


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
    threads: Threads = None,
):
    """Run every case of a study; re-running skips finished cases."""
    def load():
        from ..commands import sweep as command  # lazily (module docstring)
        from ..execution.dask import runs_here  # lazily

        return command.load(study, output=output, overrides=overrides, cases=cases, task=task, tasks=tasks,
                            combine_only=combine_only, runs_here=runs_here(scheduler, scheduler_file))

    job_command(quiet, load, as_json, workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                 retry_failed=retry_failed, force=force, rerun_all=rerun_all, threads=threads)


@app.command()
def scenes(as_json: Json = False):
    """List the bundled scenes and studies with their descriptions."""
    from ..commands import scenes as command  # lazily (module docstring)

    listed = command.scenes()
    output.emit(listed) if as_json else progress.out().print(command.table(listed))


@app.command()
def show(paths: Annotated[List[Path], typer.Argument(metavar="FILE...", help="dataset written by run or sweep (a "
                                                                           "case file, study.nc, or a sweep's "
                                                                           "directory), or a scene or study file "
                                                                           "(TOML); several runs: side by side")],
         as_json: Json = False):
    """Print a readable summary: scene, parameters, run time, final averages; for a scene or study file what
    running it needs (memory, disk); for several runs, how they differ (scenes, parameters, observables at their
    common times, the largest field differences)."""
    with guarded():
        from ..commands import show as command  # lazily (module docstring)

        if as_json:
            output.emit(command.records(paths))
            return
        shown, _ = command.view(paths)
        typer.echo(shown) if isinstance(shown, str) else progress.out().print(shown)


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
    with guarded():
        from ..commands.plot import plot as command  # lazily (module docstring)

        for picture in command(path, output=output, variable=variable, time=time, cut=cut, warp=warp):
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
    with guarded():
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
    with guarded():
        from ..commands import export as command  # lazily (module docstring)

        written = command.export(path, directory, format=format.value)
        progress.out().print(command.said(written, directory, format.value))


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

    job_command(quiet, load, as_json, workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
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

    job_command(quiet, load, as_json, workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                 force=force, rerun_all=rerun_all)


@app.command()
def calibrate(
    calibration: Annotated[str, typer.Argument(metavar="FILE.toml", help="calibration file (TOML: a scene, the "
                                                                         "data, the keys to estimate, the method), "
                                                                         "or the name of a bundled one")],
    output: Annotated[Optional[Path], typer.Option("-o", "--output", metavar="DIR",
                                                   help="directory for cases/, calibration.nc, calibration.md, "
                                                        "the pictures and simulation.tsv (default: the "
                                                        "calibration's name)")] = None,
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

    job_command(quiet, load, as_json, workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                 force=force, rerun_all=rerun_all)
