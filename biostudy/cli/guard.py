"""How a command of the command line ends: one line per error, and an exit status that says why.

Usage errors (click's) are one line and exit 2 (`OneLineErrors`); inside a command (`guarded`) bad input is
exit 2 with one line per problem, a failure exit 1, Ctrl-C 130 and SIGTERM 143 (128 + the signal) wherever they
land, finalisers included (`execution.interrupts`), leaving nothing half-written; warnings are held and told after
the command, not after bad input.
"""
from __future__ import annotations

import contextlib
import sys

import typer

from ..errors import BadInput, Failed
from ..execution import interrupts
from .held import held_warnings

_USAGE_ERROR = typer.BadParameter.__mro__[1]  # click's UsageError, wherever this typer takes click from
_CLICK_ERROR = _USAGE_ERROR.__mro__[1]  # click's ClickException


class OneLineErrors(typer.core.TyperGroup):
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


def fail(message: str, status: int) -> typer.Exit:
    typer.echo(message, err=True)  # plain echo: rich would wrap a long message over several lines
    return typer.Exit(status)


def interrupted_status(error: BaseException | None) -> int:
    return interrupts.status(error)


def _unwinding(error: BaseException) -> KeyboardInterrupt | None:
    """The interruption `error` was raised while handling, if any: an error on the way out of an interrupted
    write (closing a file HDF5 was writing) is the interruption's, not a failure of its own."""
    seen: BaseException | None = error.__context__
    while seen is not None and not isinstance(seen, KeyboardInterrupt):
        seen = seen.__context__
    return seen


@contextlib.contextmanager
def guarded():
    """Bad input -> exit 2 with one line per problem; a failure -> exit 1 with its line; Ctrl-C -> exit 130,
    SIGTERM -> exit 143.  Warnings are held and told after the command, one line each, not after bad input."""
    held = []
    try:
        with interrupts.obeyed() as seen, held_warnings() as held:
            try:
                yield
            except Exception as error:
                interruption = _unwinding(error)
                if interruption is None:
                    raise
                raise interruption from None
            lost = seen.lost()
            if lost is not None:  # received, and swallowed by something on its way (`interrupts`)
                raise lost
    except BadInput as error:
        held.clear()  # a bad input prints only its own lines
        raise fail("\n".join(f"error: {line}" for line in error.lines()), 2) from None
    except Failed as error:
        raise fail(f"error: {error}", 1) from None
    except KeyboardInterrupt as error:
        raise fail("interrupted: finished files are kept, nothing is left half-written",
                    interrupted_status(error)) from None
    finally:
        for line in held:
            typer.echo(f"warning: {line}", err=True)
