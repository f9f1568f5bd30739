"""Bad input, told in one line per problem: the file, the key, what is wrong; and failures, told in one line.

Everything a user can fix by editing a file or a command line ends up as a
`BadInput` (the CLI prints it and exits with status 2, no traceback).  The
schema's validators raise `InvalidAt` to say which key a cross-field problem
belongs to; `from_validation_error` and `from_toml_error` turn pydantic's and
tomllib's multi-line reports into such lines: every problem pydantic found,
so that an incomplete scene is fixed in one go.  A `Failed` is the other
kind of end: the input was good, the computation could not be done or kept
(exit status 1).
"""
from __future__ import annotations

import difflib
import tomllib
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Iterable, Mapping

from .formatting import value_text

if TYPE_CHECKING:
    from pydantic import ValidationError  # pydantic when a scene is validated, not when the CLI starts

# The tags of the tagged unions a model's lists hold, by the list's key ({"biofilm": ("box", "sphere", ...)}, as the
# schema declares them: `inputs.declared.union_tags`).  pydantic puts a tag into an error's location
# (biofilm, 0, "sphere", radius) where a user wrote biofilm[0].radius.
Tags = Mapping[str, tuple[str, ...]]
NO_TAGS: Tags = MappingProxyType({})


def first_line(error: BaseException) -> str:
    """The first line of an exception's message, or its type's name when the message is empty."""
    return (str(error).splitlines() or [type(error).__name__])[0]


class BadInput(Exception):
    """Input a user can fix.  str() is 'file: key: problem' (parts that are known); `more` holds the
    other problems found in the same input, `lines()` all of them."""

    def __init__(self, problem: str, file: str | Path | None = None, key: str | None = None,
                 more: tuple["BadInput", ...] = ()):
        self.problem = problem
        self.file = None if file is None else str(file)
        self.key = key
        self.more = tuple(more)
        super().__init__(problem)

    def __str__(self) -> str:
        return ": ".join(part for part in (self.file, self.key, self.problem) if part)

    def lines(self) -> list[str]:
        """Every problem, one line each."""
        return [str(self), *(str(other) for other in self.more)]

    @classmethod
    def every(cls, errors: list["BadInput"]) -> "BadInput":
        """One `BadInput` telling all the problems of `errors` (each with its own `more`), each once."""
        found = []
        for error in errors:
            for one in (error, *error.more):
                if str(one) not in map(str, found):
                    found.append(BadInput(one.problem, one.file, one.key))
        return BadInput(found[0].problem, found[0].file, found[0].key, tuple(found[1:]))

    def within(self, file: str | Path) -> "BadInput":
        """The same problem, attributed to `file` unless it already names one."""
        return self if self.file else BadInput(self.problem, file, self.key, self.more)

    def relocated(self, file, key) -> "BadInput":
        """Every problem attributed to file(old file or None), its key rewritten by key(old key or None)."""
        return BadInput(self.problem, file(self.file), key(self.key), tuple(o.relocated(file, key) for o in self.more))


class Failed(Exception):
    """A computation that could not be done or kept (a simulation that failed, a result that could not be
    written, a sweep whose workers are gone): exit status 1, the message says what happened and what was
    kept."""


class InvalidAt(ValueError):
    """Raised by a validator: `problem` belongs to `key`, relative to the model being validated."""

    def __init__(self, key: str, problem: str):
        self.key = key
        self.problem = problem
        super().__init__(problem)


def key_path(loc: Iterable, tags: Tags = NO_TAGS) -> str:
    """('biofilm', 0, 'sphere', 'radius') -> 'biofilm[0].radius' (the union's tag after an index left out)."""
    text, listed, previous = "", None, None
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
            listed = previous
        elif isinstance(previous, int) and part in tags.get(str(listed), ()):
            pass  # the union's tag, not a key the user wrote
        else:
            text += f".{part}" if text else str(part)
        previous = part
    return text


_BOUNDS = {"greater_than": ("gt", ">"), "greater_than_equal": ("ge", ">="),
           "less_than": ("lt", "<"), "less_than_equal": ("le", "<=")}


def _problem(error: dict, known_keys: Iterable[str], tags: Tags) -> tuple[str, str]:
    """(extra key path relative to the location, problem) for one pydantic error."""
    kind, ctx, given = error["type"], error.get("ctx") or {}, error.get("input")
    if kind == "value_error" and isinstance(ctx.get("error"), InvalidAt):
        return ctx["error"].key, ctx["error"].problem
    if kind in ("value_error", "assertion_error"):
        return "", str(ctx.get("error", error["msg"]))
    if kind == "extra_forbidden":
        name, known = str(error["loc"][-1]), set(known_keys)
        if name in known:  # right name, wrong table: offering it back would be no help
            return "", f"unknown key here ({name} is a key of another table)"
        close = difflib.get_close_matches(name, sorted(known), n=1)
        return "", "unknown key" + (f" (did you mean '{close[0]}'?)" if close else "")
    if kind == "missing":
        return "", "required key is missing"
    if kind in _BOUNDS:
        name, sign = _BOUNDS[kind]
        return "", f"must be {sign} {value_text(ctx[name])} (got {value_text(given)})"
    if kind == "union_tag_invalid":
        return "", f"unknown shape {value_text(ctx.get('tag'))}; shapes are {ctx.get('expected_tags')}"
    if kind in ("too_short", "too_long"):
        bound = ctx.get("min_length") if kind == "too_short" else ctx.get("max_length")
        least = "at least" if kind == "too_short" else "at most"
        return "", f"must have {least} {bound} entries (got {value_text(given)})"
    if kind == "union_tag_not_found":
        listed = error["loc"][-2] if len(error["loc"]) > 1 else ""
        choices = tags.get(str(listed), ())
        named = f" ({', '.join(choices[:-1])} or {choices[-1]})" if len(choices) > 1 else ""
        return "", f"needs a {ctx.get('discriminator', 'shape')} key{named}"
    message = error["msg"]
    for before, after in (("Input should be", "must be"), ("List should have", "must have"),
                          ("Value should have", "must have")):
        if message.startswith(before):
            message = after + message[len(before):]
    if not isinstance(given, dict):
        message += f" (got {value_text(given)})"
    return "", message


def from_validation_error(error: ValidationError, file: str | Path | None,
                          prefix: str = "", known_keys: Iterable[str] = (), tags: Tags = NO_TAGS) -> BadInput:
    """Every one of pydantic's errors as one line (the first, with the others in `more`); `tags`: the tags of the
    model's tagged unions (`Tags`)."""
    found = []
    for item in error.errors():
        extra, problem = _problem(item, known_keys, tags)
        key = ".".join(part for part in (prefix, key_path(item["loc"], tags), extra) if part)
        if (problem, key) not in [(f.problem, f.key or "") for f in found]:
            found.append(BadInput(problem, file, key or None))
    return BadInput(found[0].problem, file, found[0].key, tuple(found[1:]))


def from_toml_error(error: tomllib.TOMLDecodeError, file: str | Path) -> BadInput:
    """tomllib's message, e.g. 'Expected '=' after a key (at line 3, column 5)', as one line."""
    return BadInput(f"not valid TOML: {first_line(error)}", file)
