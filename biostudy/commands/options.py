"""What a command's options are, declared once for the command line and for Python (`declared` holds them all).

An `Option` is a name (the Python keyword), a `Kind` (what it takes: the rule and its words), a default, a unit,
a help text, and the command line's spelling (flags, metavar).  `cli.declared` makes the typer command from a
`Command`, `biostudy.api` the Python function; both hand what they were given to `Command.values`, so a value
is read and checked by one rule, and a mistake is told in the same words from both (the key spelled as each
names it: ``--levels`` on the command line, ``levels`` in Python).  The command line reads text (`Kind.parse`),
Python takes values (`Kind.check`): ``--levels 1`` and ``levels=1`` are both "give a whole number, 2 or more
(got 1)".  Nothing here imports more than the standard library: the command line is built from these at start.
"""
from __future__ import annotations

import numbers
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import BadInput
from ..formatting import value_text
from ..inputs.tomltext import literal

_WHOLE = re.compile(r"\s*[+-]?[0-9]+\s*")
REQUIRED: Any = ...  # the default of an argument that must be given


class Kind:
    """What an option takes: `check` reads a Python value into the value the command uses, or raises `BadInput`
    in the words of `wanted`; `parse` reads the command line's text (or list of texts) into the same."""

    cli: Any = str  # what typer hands over: str, bool or list[str]

    def shown(self) -> str:
        """The Python type, as the function's signature shows it."""
        return "str"

    def wanted(self) -> str:
        return "a text"

    def refuse(self, given: Any, key: str) -> BadInput:
        """The words for a value this kind does not take (a number as the command line writes it: -1, not -1.0)."""
        number = isinstance(given, numbers.Real) and not isinstance(given, bool)
        return BadInput(f"give {self.wanted()} (got {value_text(given) if number else repr(given)})", None, key)

    def check(self, value: Any, key: str) -> Any:
        if not isinstance(value, str):
            raise self.refuse(value, key)
        return value

    def parse(self, text: Any, key: str) -> Any:
        return self.check(text, key)


@dataclass(frozen=True)
class Text(Kind):
    """A text: a name, a choice the command reads itself."""

    what: str = "a text"

    def wanted(self) -> str:
        return self.what


@dataclass(frozen=True)
class Whole(Kind):
    """A whole number, at least `least` if given; `of`: what it counts ('processes')."""

    least: int | None = None
    of: str = ""

    def shown(self) -> str:
        return "int"

    def wanted(self) -> str:
        counted = f"a whole number{f' of {self.of}' if self.of else ''}"
        return counted + (f", {self.least} or more" if self.least is not None else "")

    def check(self, value: Any, key: str) -> Any:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or \
                (self.least is not None and value < self.least):
            raise self.refuse(value, key)
        return int(value)

    def parse(self, text: Any, key: str) -> Any:
        return self.check(int(text) if isinstance(text, str) and _WHOLE.fullmatch(text) else text, key)


@dataclass(frozen=True)
class Real(Kind):
    """A real number, at least `least` if given."""

    least: float | None = None

    def shown(self) -> str:
        return "float"

    def wanted(self) -> str:
        return "a number" + (f", {self.least:g} or more" if self.least is not None else "")

    def check(self, value: Any, key: str) -> Any:
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or \
                (self.least is not None and not float(value) >= self.least):
            raise self.refuse(value, key)
        return value

    def parse(self, text: Any, key: str) -> Any:
        try:
            value = float(text) if isinstance(text, str) else text
        except ValueError:
            value = text
        return self.check(value, key)


class Flag(Kind):
    """On or off."""

    cli = bool

    def shown(self) -> str:
        return "bool"

    def wanted(self) -> str:
        return "True or False"

    def check(self, value: Any, key: str) -> Any:
        if not isinstance(value, bool):
            raise self.refuse(value, key)
        return value


class File(Kind):
    """A file or directory: a str or a Path."""

    def shown(self) -> str:
        return "str | Path"

    def wanted(self) -> str:
        return "a file or directory as a str or a Path"

    def check(self, value: Any, key: str) -> Any:
        if isinstance(value, Path) or isinstance(value, str) and value:
            return Path(value)
        raise self.refuse(value, key)


@dataclass(frozen=True)
class Source(Kind):
    """A TOML file or the name of a bundled one (kept as given: `inputs.bundled.resolve` reads it); with `data`,
    also the file's tables as a dict (Python's `run`)."""

    data: bool = False

    def shown(self) -> str:
        return "str | Path | Mapping" if self.data else "str | Path"

    def wanted(self) -> str:
        return "a file or a bundled name as a str or a Path" + (", or the file's tables as a dict" if self.data
                                                                else "")

    def check(self, value: Any, key: str) -> Any:
        if self.data and isinstance(value, Mapping):
            return dict(value)
        if isinstance(value, Path) or isinstance(value, str) and value:
            return value
        raise self.refuse(value, key)


class Overrides(Kind):
    """Scene overrides: ``--set``'s 'KEY=VALUE' strings, or from Python a dict {'g': 1e9} (values written as
    TOML) or a list of such strings."""

    cli = list[str]

    def shown(self) -> str:
        return "Mapping[str, Any] | Sequence[str]"

    def wanted(self) -> str:
        return "a dict {'g': 1e9} or a list ['g=1e9'] of overrides"

    def check(self, value: Any, key: str) -> Any:
        if isinstance(value, str):
            return [value]
        if isinstance(value, Mapping):
            return [f"{name}={literal(given)}" for name, given in value.items()]
        if not isinstance(value, Sequence):
            raise self.refuse(value, key)
        return [str(item) for item in value]


@dataclass(frozen=True)
class Many(Kind):
    """Any number of `each` (repeated on the command line): one value or a sequence of them, as a list; `what`:
    the words for them ('a name or a list of names')."""

    each: Kind = field(default_factory=Kind)
    what: str = ""
    cli = list[str]

    def shown(self) -> str:
        return f"{self.each.shown()} | Sequence[{self.each.shown()}]"

    def wanted(self) -> str:
        return self.what

    def check(self, value: Any, key: str) -> Any:
        given = [value] if isinstance(value, (str, Path, numbers.Number)) or not isinstance(value, Sequence) \
            else list(value)
        try:
            return [self.each.check(one, key) for one in given]
        except BadInput:
            raise self.refuse(value, key) from None

    def parse(self, text: Any, key: str) -> Any:
        return [self.each.parse(one, key) for one in text]


class Time(Kind):
    """A time: T* as a number, or a real time as text ('12 h', with the scene's t_ref)."""

    def shown(self) -> str:
        return "float | str"

    def wanted(self) -> str:
        return "a time: T* as a number, or a real time such as '12 h'"

    def check(self, value: Any, key: str) -> Any:
        if isinstance(value, bool) or not isinstance(value, (numbers.Real, str)):
            raise self.refuse(value, key)
        return value


@dataclass(frozen=True)
class Choice(Kind):
    """One of `values` (`many`: several, comma-separated or a sequence, as a tuple); `what` names them."""

    values: tuple[str, ...] = ()
    what: str = "choice"
    many: bool = False

    def shown(self) -> str:
        return "str | Sequence[str]" if self.many else "str"

    def check(self, value: Any, key: str) -> Any:
        if isinstance(value, str):
            chosen = tuple(s.strip() for s in value.split(",") if s.strip()) if self.many else (value,)
        elif self.many and isinstance(value, Sequence) and all(isinstance(s, str) for s in value):
            chosen = tuple(value)
        else:
            chosen = (value,)
        unknown = [str(s) if self.many else repr(s) for s in chosen if s not in self.values]
        if unknown or not chosen:
            listed = ", ".join(self.values)
            raise BadInput(f"unknown {self.what} {', '.join(unknown) or '(none)'}; "
                           f"{'choose from' if self.many else f'{self.what}s are'} {listed}", None, key)
        return chosen if self.many else chosen[0]


class Function(Kind):
    """A function (called back), or None."""

    def shown(self) -> str:
        return "Callable"

    def wanted(self) -> str:
        return "a function, called with each step's progress, or None"

    def check(self, value: Any, key: str) -> Any:
        if not callable(value):
            raise self.refuse(value, key)
        return value


@dataclass(frozen=True)
class Option:
    """One option of a command: its Python name, what it takes, its default (None: left out), its unit, its help
    text, and the command line's spelling (`flags`; none: an argument, `metavar` its name).  `side`: "cli" or
    "python" for an option of one of them only (then `why` says why), "" for both.  `positional`: a Python
    argument that may also be given by position (the file a command reads, where it writes)."""

    name: str
    kind: Kind
    default: Any
    help: str
    flags: tuple[str, ...] = ()
    metavar: str = ""
    unit: str = ""
    positional: bool = False
    side: str = ""
    why: str = ""
    variadic: bool = False  # any number of arguments (show's FILE...)
    complete: tuple[str, ...] = ()  # an argument's shell completion: the kinds of bundled files it names

    @property
    def argument(self) -> bool:
        return not self.flags

    @property
    def described(self) -> str:
        """The help text with its unit."""
        return f"{self.help} [{self.unit}]" if self.unit else self.help

    def value(self, given: Any, cli: bool) -> Any:
        """What the command uses of `given` (command-line text if `cli`, else a Python value); None where an
        option is left out ([] for one that takes many)."""
        if given is None:
            return [] if self.kind.cli is not str and self.kind.cli is not bool else None
        read = self.kind.parse if cli else self.kind.check
        if self.variadic:  # any number of arguments; from Python also one list of them
            given = given[0] if len(given) == 1 and isinstance(given[0], (list, tuple)) else given
            return [read(one, self.name) for one in given]
        return read(given, self.name)


@dataclass(frozen=True)
class Command:
    """One command, declared once: its name, what it does (the first line of its help and of its function's
    docstring), what its function returns, and its options in the order of the Python signature."""

    name: str
    help: str
    options: tuple[Option, ...]
    returns: str = ""
    more: str = ""  # the rest of the help, both sides

    def on(self, side: str) -> tuple[Option, ...]:
        """The options of the command line ("cli") or of Python ("python")."""
        return tuple(o for o in self.options if o.side in ("", side))

    def values(self, given: Mapping[str, Any], side: str) -> dict[str, Any]:
        """Every option's value from what `side` was given (`given`: by name; absent: its default), read and
        checked by its kind; every mistake at once (`BadInput`, keyed by the option's name)."""
        found, problems = {}, []
        for option in self.on(side):
            try:
                left = () if option.variadic else option.default  # left out: its default, or no arguments
                found[option.name] = option.value(given.get(option.name, left), side == "cli")
            except BadInput as error:
                problems.append(error)
        if problems:
            raise BadInput.every(problems)
        return found

    def option(self, name: str) -> Option:
        return next(o for o in self.options if o.name == name)

