"""Option kinds of numbers given as a list or by name (`options.Kind`): ``--voxel 0.5,0.2,0.2``, ``--time 0,12,24``
(`Numbers`) and ``--noise biomass=0.2`` (`Named`), the same rule from the command line's text and from Python's
values (`biostudy measure`); a fraction strictly between 0 and 1 (`Fraction`: ``--target-error 0.02``)."""
from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .options import Kind, Real


@dataclass(frozen=True)
class Numbers(Kind):
    """Numbers: comma-separated on the command line ('0.5,0.2,0.2'), a sequence (or one number) from Python; as a
    list of floats, every one at least `least` (or above it, `positive`) if given; `what` names them."""

    what: str = "numbers"
    positive: bool = False

    def shown(self) -> str:
        return "Sequence[float] | float"

    def wanted(self) -> str:
        return f"{self.what}: numbers{' > 0' if self.positive else ''}, comma-separated on the command line"

    def check(self, value: Any, key: str) -> Any:
        given = [value] if isinstance(value, numbers.Real) else value
        if isinstance(given, (str, bytes)) or not isinstance(given, Sequence) or not given or any(
                isinstance(v, bool) or not isinstance(v, numbers.Real) or not float(v) == float(v) or
                (self.positive and not float(v) > 0) for v in given):
            raise self.refuse(value, key)
        return [float(v) for v in given]

    def parse(self, text: Any, key: str) -> Any:
        try:
            return self.check([float(part) for part in str(text).split(",")], key)
        except ValueError:
            raise self.refuse(text, key) from None


class Named(Kind):
    """Numbers by name: 'NAME=NUMBER', repeated on the command line (or a list of such texts), a dict from Python."""

    cli = list[str]

    def shown(self) -> str:
        return "Mapping[str, float] | Sequence[str]"

    def wanted(self) -> str:
        return "NAME=NUMBER texts, or a dict {NAME: NUMBER}"

    def check(self, value: Any, key: str) -> Any:
        if isinstance(value, Mapping):
            pairs = list(value.items())
        elif isinstance(value, Sequence) and not isinstance(value, str) and all(
                isinstance(v, str) and "=" in v for v in value):
            pairs = [tuple(part.strip() for part in v.split("=", 1)) for v in value]
        else:
            raise self.refuse(value, key)
        found = {}
        for name, number in pairs:
            try:
                found[str(name)] = float(number)
            except (TypeError, ValueError):
                raise self.refuse(value, key) from None
        return found


@dataclass(frozen=True)
class Fraction(Real):
    """A number strictly between 0 and 1 (a relative error); `what` names it."""

    what: str = "a fraction"

    def wanted(self) -> str:
        return f"{self.what} between 0 and 1 (0.02 for 2 %)"

    def check(self, value: Any, key: str) -> Any:
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not 0 < float(value) < 1:
            raise self.refuse(value, key)
        return float(value)
