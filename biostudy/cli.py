"""The `biostudy` command line (README, "Commands"): load, validate, call; nothing else.

Exit status: 0 done, 1 a simulation failed (the message says why), 2 bad
input (one line per problem: file, key, problem; no traceback), 130
interrupted (no file is left half-written).  Progress goes to stderr: a bar
on a terminal, plain lines (`_Lines`) when stderr is a file or a pipe.
"""
from __future__ import annotations

import contextlib
import os
import re
import signal
import sys
import time as clock
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, List, Optional

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from . import bundled, worker
from .errors import BadInput

app = typer.Typer(name="biostudy", no_args_is_help=True, pretty_exceptions_enable=False,
                  context_settings={"help_option_names": ["-h", "--help"]},
                  help="Parameter studies of biofilm growth: run scenes, sweep studies, inspect results.")
err = Console(stderr=True, soft_wrap=True)  # a long message stays one line in a log
out = Console()

SET_HELP = "override a scene key, KEY=VALUE with the value as TOML (params.g=1e10, grid.shape=[40,40,40]); repeatable"
SET = "KEY=VALUE"  # metavars: what an option takes
FLAG = ""  # a flag takes nothing (typer would show <bool>)
FORCE_HELP = ("use the output directory even if it belongs to another study or holds files no biostudy run "
              "recorded (cases of the same ids are replaced)")
RERUN_HELP = "run every case again, also those finished before (e.g. after a software upgrade)"


def _version(value: bool) -> None:
    if value:
        from .store import version

        typer.echo(f"biostudy {version()}")
        raise typer.Exit()


@app.callback()
def _process(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, metavar=FLAG,
                                          help="print the version and exit")) -> None:
    # Where a biostudy process starts, before FiPy or matplotlib is imported: FiPy's scipy solver suite,
    # and pictures drawn to files, never to a screen.
    worker.pin_solvers()
    os.environ["MPLBACKEND"] = "Agg"


def _fail(message: str, status: int) -> typer.Exit:
    typer.echo(message, err=True)  # plain echo: rich would wrap a long message over several lines
    return typer.Exit(status)


def _terminate(signum, frame):
    raise KeyboardInterrupt  # SIGTERM unwinds like Ctrl-C: temporary files are removed on the way out


@contextlib.contextmanager
def _guarded():
    """Bad input -> exit 2 with one line per problem; Ctrl-C / SIGTERM -> exit 130."""
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    except BadInput as error:
        raise _fail("\n".join(f"error: {line}" for line in error.lines()), 2) from None
    except KeyboardInterrupt:
        raise _fail("interrupted: finished files are kept, nothing is left half-written", 130) from None
    finally:
        signal.signal(signal.SIGTERM, previous)


@app.command()
def run(
    scene: str = typer.Argument(..., metavar="SCENE", help="scene file (TOML), or the name of a bundled scene"),
    output: Optional[Path] = typer.Option(None, "-o", "--output", metavar="OUT.nc",
                                          help="dataset to write (default: NAME.nc, the scene's name)"),
    overrides: List[str] = typer.Option([], "--set", metavar=SET, help=SET_HELP),
    force: bool = typer.Option(False, "--force", metavar=FLAG,
                               help="replace OUT.nc even if it holds the result of another scene or a sweep's file "
                                    "(never an input or a file biostudy did not write)"),
    quiet: bool = typer.Option(False, "-q", "--quiet", metavar=FLAG, help="no progress bar or lines"),
):
    """Run one simulation and write its dataset (netCDF)."""
    with _guarded():
        from solver import SimulationError, simulate

        from . import runner, store
        from .scene import load_scene, overrides_text, parse_override

        path = bundled.resolve(scene)
        loaded = load_scene(path, overrides)
        target = output or Path(re.sub(r"[^\w.+-]", "-", loaded.name) + ".nc")
        replacing = runner.check_run(loaded, path, target, force)  # before anything is computed
        problem = loaded.problem()
        try:
            with _simulation_progress(loaded.name, problem.t_end, quiet) as report:
                ds = simulate(problem, progress=report)
        except SimulationError as error:
            raise _fail(f"simulation failed: {path}: {error}", 1) from None
        text = overrides_text([parse_override(o) for o in overrides])
        try:
            store.write_atomic(store.stamp(ds, loaded.to_toml(), path, text, **worker.provenance()), target)
        except OSError as error:  # e.g. the disk filled up while it ran
            raise _fail(f"cannot write {target} ({error.strerror or error}); the result is lost", 1) from None
        err.print(f"wrote {target} (wall time {ds.attrs['wall_time']:.3g} s, {ds.attrs['steps_taken']} steps, "
                  f"{ds.attrs['steps_bisected']} bisected){replacing}", markup=False, highlight=False, soft_wrap=True)


@contextlib.contextmanager
def _simulation_progress(name: str, t_end: float, quiet: bool):
    """A rich progress bar of simulated time, steps and bisections (plain lines where stderr is not a
    terminal); yields the solver's callback."""
    if not quiet and not err.is_terminal:
        lines = _Lines(name, t_end)
        yield lambda p: lines.update(p.time, f"T* = {p.time:.4g} / {t_end:g}",
                                     f"steps {p.steps}, bisections {p.bisections}")
        return
    columns = (TextColumn("[bold]{task.description}"), BarColumn(),
               TextColumn("T* = {task.completed:.4g} / {task.total:g}"), TextColumn("steps {task.fields[steps]}"),
               TextColumn("bisections {task.fields[bisections]}"), TimeElapsedColumn())
    with Progress(*columns, console=err, disable=quiet) as progress:
        task = progress.add_task(name, total=t_end, steps=0, bisections=0)
        yield lambda p: progress.update(task, completed=p.time, steps=p.steps, bisections=p.bisections)


class _Lines:
    """Progress for a log (a batch job, a cluster log, `| tee`): one plain line each time another
    `EVERY` of the work is done or `SECONDS` have passed since the last line, no escape codes:
    what is done, the counts, the time elapsed and the time left at this pace."""

    EVERY = 0.1
    SECONDS = 30.0

    def __init__(self, title: str, total: float):
        self.title, self.total = title, total
        self.began = self.last_time = clock.monotonic()
        self.last_done = 0.0

    def update(self, done: float, position: str, counts: str, force: bool = False) -> None:
        now = clock.monotonic()
        fraction = done / self.total if self.total else 1.0
        if not (force or fraction - self.last_done >= self.EVERY - 1e-12 or now - self.last_time >= self.SECONDS
                or (fraction >= 1.0 > self.last_done)):
            return
        self.last_done, self.last_time = fraction, now
        elapsed = now - self.began
        left = f", left ~{_duration(elapsed * (1 - fraction) / fraction)}" if 0 < fraction < 1 else ""
        print(f"{self.title}: {position} ({fraction:.0%}), {counts}, elapsed {_duration(elapsed)}{left}",
              file=sys.stderr, flush=True)


def _duration(seconds: float) -> str:
    """12.3 s, 4 min 05 s, 2 h 03 min."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes = int(seconds // 60)
    if minutes < 60:
        return f"{minutes} min {int(seconds % 60):02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


@app.command()
def sweep(
    study: str = typer.Argument(..., metavar="STUDY", help="study file (TOML), or the name of a bundled study"),
    output: Optional[Path] = typer.Option(None, "-o", "--output", metavar="DIR",
                                          help="directory for cases/ and study.nc (default: the study's name)"),
    workers: Optional[int] = typer.Option(None, "--workers", min=1, metavar="N", help="run on N local processes"),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", metavar="ADDRESS",
                                            help="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                                                 "or tls://... (README: 'Sweeps on a Dask cluster')"),
    overrides: List[str] = typer.Option([], "--set", metavar=SET, help=SET_HELP + "; applied to every case"),
    retry_failed: bool = typer.Option(False, "--retry-failed", metavar=FLAG,
                                      help="run failed cases again (finished ones are skipped unless --rerun-all)"),
    force: bool = typer.Option(False, "--force", metavar=FLAG, help=FORCE_HELP),
    rerun_all: bool = typer.Option(False, "--rerun-all", metavar=FLAG, help=RERUN_HELP),
    quiet: bool = typer.Option(False, "-q", "--quiet", metavar=FLAG, help="no progress bar or lines"),
):
    """Run every case of a study; re-running skips finished cases."""

    def start():
        from . import runner
        from .study import load_study

        plan = load_study(bundled.resolve(study), overrides)
        directory = output or Path(plan.spec.name)

        def run(notify) -> _Finished:
            report = runner.sweep(plan, directory, workers=workers, scheduler=scheduler,
                                  retry_failed=retry_failed, notify=notify, force=force, rerun_all=rerun_all)
            return _Finished(f"{len(report.ran)} cases run, {len(report.skipped)} skipped (finished before), "
                             f"{len(report.failed)} failed; wrote {report.study}", report.failed, len(plan.cases),
                             warnings=report.warnings())

        return plan.spec.name, run

    _job_command("sweep", workers, scheduler, quiet, start)


@app.command()
def scenes():
    """List the bundled scenes and studies with their descriptions."""
    directory = bundled.studies_dir()
    table = Table(title=f"bundled scenes and studies in {directory}", show_edge=False)
    table.add_column("file", no_wrap=True)
    table.add_column("kind", no_wrap=True)
    table.add_column("description")
    for entry in bundled.entries(directory):
        table.add_row(entry.path.name, entry.kind, entry.description)
    out.print(table)


@app.command()
def show(path: Path = typer.Argument(..., metavar="FILE", help="dataset written by run or sweep (a case file, study.nc, "
                                                                 "or a sweep's directory), or a scene or study file (TOML)")):
    """Print a readable summary: scene, parameters, run time, final averages; for a scene or study file what
    running it needs (memory, disk)."""
    with _guarded():
        from .store import open_result
        from .summary import needs, summarize

        if path.suffix == ".toml" or (not path.exists() and not path.suffix):
            typer.echo(needs(bundled.resolve(path)))
            return
        summarize(open_result(path / "study.nc" if path.is_dir() else path, doing="show reads runs, cases and "
                              "study.nc"), out)


@app.command()
def plot(
    path: Path = typer.Argument(..., metavar="FILE.nc", help="dataset written by run or sweep (a sweep's directory means "
                                                              "its study.nc)"),
    output: Optional[Path] = typer.Option(None, "-o", "--output", metavar="FIG.png",
                                          help="picture (PNG); several figures get _series, _cut, ... suffixes "
                                               "(default: beside the dataset)"),
    variable: Optional[str] = typer.Option(None, "--variable", metavar="V", help="one field (phi, c, alpha, p) or, for a sweep, "
                                                                    "one output (phi_mean, c_mean, biofilm_volume)"),
    time: Optional[float] = typer.Option(None, "--time", metavar="T", help="draw the output nearest to this T*"),
    cut: Optional[str] = typer.Option(None, "--cut", metavar="C", help="3-D: 'diagonal' (toward the nutrient, default), "
                                                          "'xy-diagonal', or a plane such as 'x=10' or 'z=5.5' (µm)"),
    warp: Optional[float] = typer.Option(None, "--warp", metavar="FACTOR", help="also draw the deformed body with the displacement "
                                                             "magnified by this factor (e.g. 500, paper Fig. 13)"),
):
    """Draw the pictures of a run or a sweep: time series, cuts, isosurfaces, maps, sweep outputs."""
    with _guarded():
        from .plots import plot as draw
        from .store import open_result

        source = path / "study.nc" if path.is_dir() else path
        ds = open_result(source, ("run", "study"), "nothing to plot")
        try:
            written = draw(ds, output or source.with_suffix(".png"), variable=variable, time=time, cut=cut, warp=warp)
        except ValueError as error:
            raise BadInput(str(error), source) from None
        for picture in written:
            out.print(f"wrote {picture}")


@app.command()
def analyze(
    path: Path = typer.Argument(..., metavar="DIR", help="a study's directory (or its study.nc), written by sweep"),
    outputs: List[str] = typer.Option([], "--output", metavar="NAME", help="observable or study.nc variable to analyse; repeatable "
                                                           "(default: every observable the study has)"),
    times: List[float] = typer.Option([], "--time", metavar="T", help="analyse at the output nearest this T*; repeatable "
                                                         "(default: the last output)"),
):
    """Which parameter matters: Sobol' or Morris indices of a sampled study, rank correlations of any study."""
    with _guarded():
        from .analysis import write

        written, table = write(path / "study.nc" if path.is_dir() else path, outputs, times)
        typer.echo(table)
        err.print("wrote " + ", ".join(str(p) for p in written))


@app.command()
def export(
    path: Path = typer.Argument(..., metavar="FILE.nc", help="dataset written by run (or one case of a sweep)"),
    directory: Path = typer.Argument(..., metavar="DIR", help="directory for snapshot_NNNN.vtu files and series.pvd"),
):
    """Write files ParaView opens: one VTU per snapshot and a PVD listing them in time."""
    with _guarded():
        from .export import export as write
        from .store import open_result

        ds = open_result(path, ("run",), "export writes one run's fields")
        try:
            written = write(ds, directory)
        except ValueError as error:
            raise BadInput(str(error), path) from None
        out.print(f"wrote {len(written)} files to {directory} (open {directory / 'series.pvd'} in ParaView)")


@app.command()
def convergence(
    scene: str = typer.Argument(..., metavar="SCENE", help="scene file (TOML), or the name of a bundled scene"),
    output: Optional[Path] = typer.Option(None, "-o", "--output", metavar="DIR", help="directory for cases/, convergence.nc, "
                                                                     "convergence.md, work_precision.png"),
    levels: int = typer.Option(3, "--levels", min=2, metavar="N", help="levels per series; the finest is the reference"),
    series: str = typer.Option("space,time,both,adaptive", "--series", metavar="S",
                               help="comma-separated refinement series: space, time, both, adaptive"),
    tolerance: float = typer.Option(1e-2, "--tolerance", min=0.0, metavar="TOL",
                                    help="time_tolerance of adaptive level 0 (divided by 4 per level)"),
    workers: Optional[int] = typer.Option(None, "--workers", min=1, metavar="N", help="run levels on N local processes"),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", metavar="ADDRESS", help="address of a running Dask scheduler"),
    overrides: List[str] = typer.Option([], "--set", metavar=SET, help=SET_HELP + "; applied to level 0"),
    force: bool = typer.Option(False, "--force", metavar=FLAG, help=FORCE_HELP),
    rerun_all: bool = typer.Option(False, "--rerun-all", metavar=FLAG, help=RERUN_HELP),
    reference: Optional[Path] = typer.Option(None, "--reference", metavar="RUN.nc", help="measure every level against this run of "
                                                                       "the same scene (e.g. refined, another "
                                                                       "scheme) instead of the finest level"),
    time: Optional[float] = typer.Option(None, "--time", metavar="T", help="compare at the output nearest this T* "
                                                              "(default: the last)"),
    quiet: bool = typer.Option(False, "-q", "--quiet", metavar=FLAG, help="no progress bar or lines"),
):
    """Refine grid, time step and both; measure each level's error and cost (work-precision)."""

    def start():
        from . import convergence as refinement
        from . import store
        from .plots.accuracy import work_precision
        from .scene import apply_overrides, read_scene_data

        chosen = refinement.chosen_series(series)
        path = bundled.resolve(scene)
        data = read_scene_data(path)
        fixed = dict(apply_overrides(data, overrides))
        directory = output or Path(f"{path.stem}-convergence")

        def run(notify) -> _Finished:
            ds, report = refinement.run(data, path, directory, levels, chosen, tolerance, workers, scheduler,
                                        notify, fixed, reference, time, force, rerun_all)
            table = refinement.table_text(ds)
            store.write_text(directory / "convergence.md", table)
            work_precision(ds, directory / "work_precision.png")
            return _Finished(f"wrote {directory / 'convergence.nc'}, convergence.md, work_precision.png "
                             f"({len(report.ran)} runs, {len(report.skipped)} finished before)", report.failed,
                             len(report.ran) + len(report.skipped), table, "runs", report.warnings())

        return f"convergence {path.stem}", run

    _job_command("convergence", workers, scheduler, quiet, start)


def _one_pool(workers: int | None, scheduler: str | None) -> None:
    """Jobs run on local processes or on a Dask cluster, not both; a tls:// scheduler needs Dask's TLS
    configuration (certificates), which a plain Dask client would only miss with a traceback."""
    if workers and scheduler:
        raise BadInput("give --workers or --scheduler, not both", "--workers")
    if scheduler and scheduler.startswith("tls://"):
        from distributed.security import Security

        try:
            context = Security().get_connection_args("client").get("ssl_context")
        except (OSError, ValueError) as error:  # a configured certificate that cannot be read
            raise BadInput(f"Dask's TLS configuration cannot be used: {error}", "--scheduler") from None
        if context is None:
            raise BadInput(f"{scheduler} needs a TLS configuration: Dask's distributed.comm.tls.ca-file, "
                           ".client.cert and .client.key (a YAML file in DASK_CONFIG; README, 'Sweeps on a "
                           "Dask cluster')", "--scheduler")


@contextlib.contextmanager
def _job_progress(title: str, quiet: bool, noun: str = "cases"):
    """A progress bar over the jobs of a sweep, convergence or stability run (plain lines where stderr is not
    a terminal); yields run_jobs' notify.  A job that fails is told at once (also with --quiet): the others
    go on.  The bar shows from the first job on: input found bad before (an output directory in use, say) is
    told on its own line.  When every job had finished before, it says so instead of showing an empty bar."""
    counts = {"start": 0, "skip": 0, "failed before": 0, "finished": 0, "failed": 0}
    lines = None if quiet or err.is_terminal else _Lines(title, 0)
    progress = Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                        TextColumn("{task.fields[last]}"), TimeElapsedColumn(), console=err,
                        disable=quiet or lines is not None)
    task = progress.add_task(title, total=0, last="", visible=False)
    try:
        def notify(event: str, job_id: str, message: str):
            if not progress.live.is_started:
                progress.start()
            if event == "skip":
                counts["skip"] += 1
                counts["failed before"] += message == "failed"
            elif event == "start":
                counts["start"] += 1
                progress.update(task, total=counts["start"], visible=True)
            elif event in ("done", "failed"):
                counts["finished"] += 1
                counts["failed"] += event == "failed"
                progress.update(task, advance=1, last=f"{job_id} {event}")
                if event == "failed":
                    progress.console.print(f"{job_id} failed: {message}", markup=False, highlight=False)
                if lines is not None:
                    lines.total = counts["start"]
                    lines.update(counts["finished"], f"{counts['finished']}/{counts['start']} {noun}",
                                 f"{counts['failed']} failed, last {job_id} {event}", force=event == "failed")

        yield notify
    finally:
        if progress.live.is_started:
            progress.stop()
    if counts["start"] == 0 and counts["skip"]:
        again = (f", {counts['failed before']} of them failed (--retry-failed runs them again)"
                 if counts["failed before"] else "")
        err.print(f"nothing to run: all {counts['skip']} {noun} finished before{again}")


@dataclass
class _Finished:
    """What a job command has to say when its jobs are over."""

    summary: str  # one line on stderr: what ran, what was written
    failures: dict[str, str]  # job -> why it failed; any makes the exit status 1
    total: int  # jobs in all
    table: str = ""  # printed on stdout
    noun: str = "cases"
    warnings: list[str] = None  # printed on stderr, before the summary

    def __post_init__(self):
        self.warnings = self.warnings or []


def _job_command(command: str, workers: int | None, scheduler: str | None, quiet: bool,
                 start: Callable[[], tuple[str, Callable[..., _Finished]]]) -> None:
    """The one path of every job command (sweep, convergence, stability).

    start() loads and validates (bad input: exit 2 before anything runs) and returns the progress bar's
    title and run(notify), which runs the jobs on the chosen pool and says what came of them.  A job that
    failed, or a pool that broke down, is exit status 1.
    """
    with _guarded():
        _one_pool(workers, scheduler)
        if workers:
            from .pool import warm_up

            warm_up()  # the fork server imports the solver while this process imports it and validates
        from .runner import SweepError

        title, run = start()
        with _job_progress(title, quiet, "runs" if command == "convergence" else "cases") as notify:
            try:
                finished = run(notify)
            except SweepError as error:
                raise _fail(f"{command} stopped: {error}", 1) from None
        if finished.table:
            typer.echo(finished.table)
        for warning in finished.warnings:
            typer.echo(f"warning: {warning}", err=True)
        err.print(finished.summary)
        if finished.failures:
            raise _fail(f"{len(finished.failures)} of {finished.total} {finished.noun} failed: "
                        + "; ".join(f"{k}: {v}" for k, v in list(finished.failures.items())[:3]), 1)


@app.command()
def stability(
    catalogue: str = typer.Argument(..., metavar="CATALOGUE", help="stability catalogue (TOML), or the name of a bundled one"),
    output: Optional[Path] = typer.Option(None, "-o", "--output", metavar="DIR",
                                          help="directory for cases/, stability.nc, stability.md"),
    workers: Optional[int] = typer.Option(None, "--workers", min=1, metavar="N", help="run cases on N local processes"),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", metavar="ADDRESS", help="address of a running Dask scheduler"),
    overrides: List[str] = typer.Option([], "--set", metavar=SET, help=SET_HELP + "; applied to every case"),
    force: bool = typer.Option(False, "--force", metavar=FLAG, help=FORCE_HELP),
    rerun_all: bool = typer.Option(False, "--rerun-all", metavar=FLAG, help=RERUN_HELP),
    quiet: bool = typer.Option(False, "-q", "--quiet", metavar=FLAG, help="no progress bar or lines"),
):
    """Run stiff and extreme cases: each completes within its bounds or stops with a diagnosis."""

    def start():
        from . import stability as catalogue_run
        from . import store

        path = bundled.resolve(catalogue)
        plan = catalogue_run.load(path, overrides)
        directory = output or Path(f"{path.stem}-results")

        def run(notify) -> _Finished:
            ds, report = catalogue_run.run(plan, directory, workers, scheduler, notify, force, rerun_all)
            table = catalogue_run.table_text(ds)
            store.write_text(directory / "stability.md", table)
            failed = {str(c): str(m) for c, m, ok in zip(ds.case.values, ds.message.values, ds.ok.values) if not ok}
            return _Finished(f"wrote {directory / 'stability.nc'} and stability.md: {int(ds.ok.sum())} of "
                             f"{ds.sizes['case']} cases completed within bounds or stopped with a diagnosis",
                             failed, ds.sizes["case"], table, warnings=report.warnings())

        return f"stability {path.stem}", run

    _job_command("stability", workers, scheduler, quiet, start)
