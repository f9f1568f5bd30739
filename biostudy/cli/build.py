"""Typer commands made from the declarations (`commands.declared`): one parameter per option of the command line.

Every option reaches typer as text (or a flag, or repeated text): its kind reads it when the command is called
(`Command.values`), so ``--levels 1`` is refused in the words ``levels=1`` is from Python, exit status 2, keyed
by the flag.  The command line's own options (-q, -v, --json: how it prints, `options`) are added per command.
"""
from __future__ import annotations

import inspect
from typing import Annotated, Any, Callable, List, Optional

import typer

from ..commands.options import REQUIRED, Command, Option
from ..errors import BadInput
from .guard import guarded
from .options import FLAG, Quiet, Verbose


def _complete(kinds: tuple[str, ...]):
    """Shell completion of a file argument: bundled names of those kinds, and TOML files."""
    def complete(incomplete: str) -> list[tuple[str, str]]:
        from ..inputs.bundled import completions  # lazily: only when the shell asks

        return completions(incomplete, kinds)

    return complete


def parameter(option: Option) -> inspect.Parameter:
    """The typer parameter of `option`: its type as text, its flags, metavar and help, its default."""
    given = option.kind.cli
    many = given is not str and given is not bool
    if many or option.variadic:
        kind: Any = List[str]
    elif given is bool:
        kind = bool
    else:
        kind = str if option.default is REQUIRED else Optional[str]
    if option.argument:
        info: Any = typer.Argument(metavar=option.metavar, help=option.described, show_default=False,
                                   autocompletion=_complete(option.complete) if option.complete else None)
    else:
        info = typer.Option(*option.flags, metavar=option.metavar or FLAG, help=option.described)
    default = inspect.Parameter.empty if option.default is REQUIRED else [] if many else option.default
    return inspect.Parameter(option.name, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=default,
                             annotation=Annotated[kind, info])


def flag(option: Option) -> str:
    """How the command line names an option in a message: its long flag, or an argument's metavar."""
    return option.flags[-1] if option.flags else option.metavar


def values(declared: Command, given: dict[str, Any]) -> dict[str, Any]:
    """The options' values from the command line's text, read by their kinds (`BadInput` keyed by the flag)."""
    named = {option.name: flag(option) for option in declared.options}
    try:
        return declared.values(given, "cli")
    except BadInput as error:
        raise error.relocated(lambda file: file, lambda key: named.get(key, key)) from None


def command(app: typer.Typer, declared: Command, *own: inspect.Parameter) -> Callable:
    """Register `declared` on `app`: the decorated function is called with the options' values (a dict, read
    and checked) and the command line's own options by name: -q and -v, which every command takes after it as
    before it (`EVERY`; their callbacks set them, `logs`), and `own` (--json), those its signature names."""
    def register(shows: Callable[..., None]) -> Callable[..., None]:
        mine = [*EVERY, *own]
        taken = inspect.signature(shows).parameters

        def called(**given: Any) -> None:
            extra = {p.name: given.pop(p.name) for p in mine}
            with guarded():
                checked = values(declared, given)
            shows(checked, **{name: value for name, value in extra.items() if name in taken})

        params = [parameter(option) for option in declared.on("cli")] + mine
        called.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
        called.__annotations__ = {p.name: p.annotation for p in params}
        called.__name__ = declared.name
        app.command(name=declared.name, help=declared.help)(called)
        return shows

    return register


def own(name: str, annotated: Any, default: Any = False) -> inspect.Parameter:
    """One of the command line's own options (`options.Quiet`, ...) as a parameter."""
    return inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=default, annotation=annotated)


EVERY = (own("quiet", Quiet), own("verbose", Verbose))  # every command takes -q and -v after it (README)
