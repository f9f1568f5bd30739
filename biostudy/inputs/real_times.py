"""Times a user writes with a unit (a calibration's `time_unit` and `t_ref`, read with pint), and times told back.

pint parses its text as a Python expression: unbalanced text ends in its
tokenizer's TokenError or an AssertionError of its parser, and a power such
as '10**10**10' is computed exactly, for ever.  So a time is at most
`TIME_TEXT` characters without powers, and whatever pint cannot parse, or
parses to something that is no time, is one `InvalidAt` naming the key.
Times of measurements outside the run are told with as many digits as it
takes not to read as the run's end (`apart`).
"""
from __future__ import annotations

import functools
import math
from typing import Any, Callable

from ..errors import InvalidAt, first_line
from .tomltext import float_literal

TIME_TEXT = 100  # characters of a time_unit or t_ref ("48 h")


@functools.lru_cache(maxsize=1)
def _registry():
    import pint  # lazily: a second of start-up, only for calibrations with real times

    return pint.UnitRegistry()


def _time(text: str, key: str, parse: Callable[[str], Any]):
    """`text` read by pint as a time, or `InvalidAt(key)`."""
    if len(text) > TIME_TEXT:
        raise InvalidAt(key, f"{text[:20]!r}... is {len(text):,} characters long: a time is a number and a unit, "
                             "such as '48 h'")
    if "**" in text or "^" in text:
        raise InvalidAt(key, f"{text!r}: powers (** or ^) are not read in a time, a number and a unit such as "
                             "'48 h'")
    import pint

    try:
        quantity = parse(text)
        dimensionality = quantity.dimensionality
    except Exception as error:  # noqa: BLE001 - pint's parser fails in many ways on text it cannot read
        reason = first_line(error) if isinstance(error, pint.errors.PintError) else "unbalanced or incomplete"
        raise InvalidAt(key, f"{text!r} is not a time pint reads ({reason})") from None
    if dimensionality != _registry().second.dimensionality:
        raise InvalidAt(key, f"{text!r} is not a time (its dimension is {dimensionality})")
    return quantity


def factor(time_unit: str, t_ref: str) -> float:
    """T* per `time_unit` when T* = 1 is the real time `t_ref` ("h", "48 h": 1/48); `InvalidAt` naming the key
    that is no time, or a `t_ref` that is not positive and finite or makes the ratio overflow to inf or 0."""
    units = _registry()
    unit = _time(time_unit, "time_unit", lambda text: units.Quantity(1.0, text))
    reference = _time(t_ref, "t_ref", units.Quantity)
    if not reference.magnitude > 0 or not math.isfinite(reference.magnitude):
        raise InvalidAt("t_ref", f"must be a positive time (got {t_ref!r})")
    found = float((unit / reference).to("dimensionless").magnitude)
    if not 0 < found < math.inf:  # '1e-320 h': T* per hour overflows, and a time 0 would be T* = 0 x inf = NaN
        raise InvalidAt("t_ref", f"{t_ref!r} makes one {time_unit} T* = {found:g}: not a time scale the table's "
                                 "times can be measured in")
    return found


def exact(value: float) -> str:
    """A time as the shortest text that reads back to it: 4.000001, not 4."""
    return float_literal(value).removesuffix(".0")


def apart(t: float, t_end: float) -> str:
    """`t` with four significant digits, or as many more as it takes not to read as `t_end`."""
    return next((text for text in (f"{t:.{digits}g}" for digits in range(4, 18)) if float(text) != t_end), repr(t))
