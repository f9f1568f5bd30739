"""The command line's own options, how it prints (declared once here): -q, -v and --json; every command's
options are declared for the command line and Python alike (`commands.declared`, `build`)."""
from __future__ import annotations

from typing import Annotated

import typer

from . import logs

FLAG = ""  # a flag takes nothing (typer would show <bool>)

Quiet = Annotated[bool, typer.Option("-q", "--quiet", metavar=FLAG, callback=logs.quiet,
                                     help="no progress bar or lines (as `biostudy -q COMMAND`)")]
Verbose = Annotated[bool, typer.Option("-v", "--verbose", metavar=FLAG, callback=logs.verbose,
                                       help="more detail on stderr: the scene's size, where the time went (as "
                                            "`biostudy -v COMMAND`)")]
Json = Annotated[bool, typer.Option("--json", metavar=FLAG,
                                    help="print the result as JSON on stdout instead of the table (the same numbers "
                                         "unrounded; NaN as null; docs/scripting.md)")]
