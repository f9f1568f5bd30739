"""The `biostudy` command line (README's command table): load, validate, call; nothing else.

Every command is made from its declaration (`commands.declared`, by `build`: the
Python function of `biostudy.api` is made from the same) and calls one function of
`biostudy.commands` with the options' values.  Exit status: 0 done, 1 a computation failed (the message says why),
2 bad input (one line per problem: file, key, problem; no traceback), 130
interrupted by Ctrl-C (SIGINT), 143 by SIGTERM (no file is left half-written).  Progress goes to stderr
(`progress`), as much as -q/-v ask (`logs`); --json puts a table's numbers on
stdout instead of the table (`output`).  The commands' modules are imported inside the commands: `--version`
and `-h` do not pay for numpy, xarray and FiPy.
"""
from __future__ import annotations

import os
from typing import Annotated

import typer

from ..commands import declared
from ..errors import BadInput
from ..execution import worker
from . import logs, output, progress
from .build import command, flag, own
from .guard import OneLineErrors, guarded
from .jobs import job_command
from .options import FLAG, Json

app = typer.Typer(name="biostudy", cls=OneLineErrors, no_args_is_help=True, pretty_exceptions_enable=False,
                  context_settings={"help_option_names": ["-h", "--help"]},
                  help="Parameter studies of biofilm growth: run scenes, sweep studies, inspect results.")
JSON = own("as_json", Json)  # -q and -v: every command's (`build.EVERY`)


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


@command(app, declared.RUN)
def run(options: dict, quiet: bool = False, verbose: bool = False) -> None:
    with guarded():
        from ..commands import run as command  # lazily (module docstring)

        with command.load(**options, write=True) as loaded:
            with progress.simulation(loaded.scene.name, loaded.scene.time.t_end, quiet) as report:
                result = command.compute(loaded, progress=report)
        for warning in result.warnings():
            typer.echo(f"warning: {warning}", err=True)
        progress.err().print(result.message(), markup=False, highlight=False, soft_wrap=True)
        result.dataset.close()  # the file written, opened lazily (`commands.run.compute`)


@command(app, declared.SWEEP, JSON)
def sweep(options: dict, quiet: bool = False, verbose: bool = False, as_json: bool = False) -> None:
    job_command(declared.SWEEP, options, quiet, as_json)


@command(app, declared.SCENES, JSON)
def scenes(options: dict, as_json: bool = False) -> None:
    from ..commands import scenes as command  # lazily (module docstring)

    listed = command.scenes()
    output.emit(listed) if as_json else progress.out().print(command.table(listed))


@command(app, declared.SHOW, JSON)
def show(options: dict, as_json: bool = False) -> None:
    with guarded():
        from ..commands import show as command  # lazily (module docstring)

        if as_json:
            output.emit(command.records(options["paths"]))
            return
        shown, _ = command.view(options["paths"])
        typer.echo(shown) if isinstance(shown, str) else progress.out().print(shown)


@command(app, declared.PLOT)
def plot(options: dict) -> None:
    with guarded():
        from ..commands.plot import plot as command  # lazily (module docstring)

        for picture in command(**options):
            progress.out().print(f"wrote {picture}")


@command(app, declared.ANALYZE, JSON)
def analyze(options: dict, as_json: bool = False) -> None:
    with guarded():
        from ..commands.analyze import analyze as command  # lazily (module docstring)

        written, table = command(**options)
        output.emit(output.written(written[0])) if as_json else typer.echo(table)  # [0]: analysis.nc
        from ..data.reading import attributes

        said = (attributes(written[0]) or {}).get("warning")  # Sobol' indices from too few samples
        if said:
            typer.echo(f"warning: {said}", err=True)
        progress.err().print("wrote " + ", ".join(str(p) for p in written))


@command(app, declared.EXPORT)
def export(options: dict) -> None:
    with guarded():
        from ..commands import export as command  # lazily (module docstring)

        written = command.export(**options)
        progress.out().print(command.said(written, options["directory"], options["format"]))


@command(app, declared.MEASURE, JSON)
def measure(options: dict, as_json: bool = False) -> None:
    with guarded():
        from ..commands.measure import measure as command  # lazily (module docstring)

        flags = {option.name: flag(option) for option in declared.MEASURE.options}
        try:
            found = command(**options)
        except BadInput as error:  # the command's own checks name the options as Python does: here, their flags
            raise error.relocated(lambda file: file, lambda key: flags.get(key, key)) from None
        output.emit(found.records) if as_json else typer.echo(found.table)
        if found.written is not None:
            progress.err().print(f"wrote {found.written}", markup=False, highlight=False)


@command(app, declared.CONVERGENCE, JSON)
def convergence(options: dict, quiet: bool = False, verbose: bool = False, as_json: bool = False) -> None:
    job_command(declared.CONVERGENCE, options, quiet, as_json)


@command(app, declared.STABILITY, JSON)
def stability(options: dict, quiet: bool = False, verbose: bool = False, as_json: bool = False) -> None:
    job_command(declared.STABILITY, options, quiet, as_json)


@command(app, declared.CALIBRATE, JSON)
def calibrate(options: dict, quiet: bool = False, verbose: bool = False, as_json: bool = False) -> None:
    job_command(declared.CALIBRATE, options, quiet, as_json)
