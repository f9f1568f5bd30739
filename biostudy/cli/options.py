"""The options several commands share, declared once (typer `Annotated` aliases), with one help text each."""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, List, Optional

import typer

from . import logs

SET = "KEY=VALUE"  # metavars: what an option takes
FLAG = ""  # a flag takes nothing (typer would show <bool>)
SET_HELP = "override a scene key, KEY=VALUE with the value as TOML (params.g=1e10, grid.shape=[40,40,40]); repeatable"


def overrides(applied: str = "") -> typer.models.OptionInfo:
    """--set, saying what it applies to (a run's scene, every case, level 0)."""
    return typer.Option("--set", metavar=SET, help=SET_HELP + (f"; applied to {applied}" if applied else ""))


Workers = Annotated[Optional[int], typer.Option("--workers", min=1, metavar="N",
                                                help="run the cases on N local processes")]
Threads = Annotated[Optional[int], typer.Option(
    "--threads", min=1, metavar="N", help="threads of each simulation (default: the scene's [numerics] threads, "
                                          "else the processors here, shared among the workers); the results are "
                                          "the same for every count")]
Scheduler = Annotated[Optional[str], typer.Option("--scheduler", metavar="ADDRESS",
                                                  help="address of a running Dask scheduler, e.g. "
                                                       "tcp://10.0.0.5:8786 or tls://... (README: 'Sweeps on a "
                                                       "Dask cluster')")]
SchedulerFile = Annotated[Optional[Path], typer.Option(
    "--scheduler-file", metavar="FILE", help="the file a Dask scheduler wrote (`dask scheduler --scheduler-file "
                                             "FILE`): how a batch job finds the cluster it started (README: "
                                             "'Batch clusters')")]
Force = Annotated[bool, typer.Option("--force", metavar=FLAG,
                                     help="use the output directory even if it belongs to another study or holds "
                                          "files no biostudy run recorded (cases of the same ids are replaced)")]
RerunAll = Annotated[bool, typer.Option("--rerun-all", metavar=FLAG,
                                        help="run every case again, also those finished before (e.g. after a "
                                             "software upgrade)")]
RetryFailed = Annotated[bool, typer.Option("--retry-failed", metavar=FLAG,
                                           help="run failed cases again (finished ones are skipped unless "
                                                "--rerun-all)")]
Quiet = Annotated[bool, typer.Option("-q", "--quiet", metavar=FLAG, callback=logs.quiet,
                                     help="no progress bar or lines (as `biostudy -q COMMAND`)")]
Verbose = Annotated[bool, typer.Option("-v", "--verbose", metavar=FLAG, callback=logs.verbose,
                                       help="more detail on stderr: the scene's size, where the time went (as "
                                            "`biostudy -v COMMAND`)")]
Directory = Annotated[Optional[Path], typer.Option("-o", "--output", metavar="DIR",
                                                   help="directory for cases/ and the results (default: from "
                                                        "the file's name)")]
def _complete(*kinds: str):
    """Shell completion of a scene or study argument: bundled names of those kinds, and TOML files."""
    def complete(incomplete: str) -> list[tuple[str, str]]:
        from ..inputs.bundled import completions  # lazily: only when the shell asks

        return completions(incomplete, kinds)

    return complete


SceneArgument = Annotated[str, typer.Argument(metavar="SCENE", help="scene file (TOML), or the name of a bundled "
                                                                     "scene", autocompletion=_complete("scene"))]
StudyArgument = Annotated[str, typer.Argument(metavar="STUDY", help="study file (TOML), or the name of a bundled "
                                                                     "study", autocompletion=_complete("study"))]
CatalogueArgument = Annotated[str, typer.Argument(metavar="CATALOGUE", help="stability catalogue (TOML), or the "
                                                                             "name of a bundled one",
                                                  autocompletion=_complete("stability"))]
Overrides = Annotated[List[str], overrides()]
CaseOverrides = Annotated[List[str], overrides("every case")]
Json = Annotated[bool, typer.Option("--json", metavar=FLAG,
                                    help="print the result as JSON on stdout instead of the table (the same numbers "
                                         "unrounded; NaN as null; docs/scripting.md)")]
