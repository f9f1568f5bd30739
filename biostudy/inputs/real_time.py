"""Real time: what T* = 1 is in the lab's clock (a scene's ``[time] t_ref``, a calibration's ``[data] t_ref``).

T* = t / t_ref.  `parse_time` reads any time pint reads ("48 h", "30 min",
"2 d"), one place for scenes and calibration tables, each problem one line
(`InvalidAt`).  pint parses its text as a Python expression: unbalanced text
ends in its tokenizer's TokenError or an AssertionError of its parser, and a
power such as '10**10**10' is computed exactly, for ever; so a time is at most
`TIME_TEXT` characters without powers.  Times of measurements outside a run are
told with as many digits as it takes not to read as the run's end (`apart`).
`RealTime` is a parsed t_ref: real times are shown in the unit t_ref was written
in (48 h -> hours, 30 min -> minutes), because that is the unit the lab chose
for its experiment; its CF spelling ("hours", "minutes") is a unit of time
udunits, cf-units and cf_xarray's pint registry read.
"""
from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass
from typing import Any, Mapping

from ..errors import InvalidAt, first_line
from ..formatting import number
from .tomltext import float_literal

T_REF = "t_ref"  # the attribute a dataset records its scene's t_ref in
TIME_TEXT = 100  # characters of a time_unit or t_ref ("48 h")


_MAKING = threading.Lock()


def registry():
    """pint's registry, made once and only when a real time is read (a second of start-up); under a lock, so that
    threads reading their first times at once share one (quantities of two registries do not compute together:
    "Cannot operate with Quantity and Quantity of different registries")."""
    with _MAKING:
        return _registry()


@functools.lru_cache(maxsize=1)
def _registry():
    import pint

    return pint.UnitRegistry()


def parse_time(text: str, key: str, positive: bool = False, unit: bool = False):
    """`text` as a pint quantity of time (`unit`: one of that unit); `InvalidAt(key)` if pint cannot read it
    or it is not a time (`positive`: nor a finite time > 0)."""
    what = "unit" if unit else "time"
    if len(text) > TIME_TEXT:
        raise InvalidAt(key, f"{text[:20]!r}... is {len(text):,} characters long: a {what} is a number and a unit, "
                             "such as '48 h'")
    if "**" in text or "^" in text:
        raise InvalidAt(key, f"{text!r}: powers (** or ^) are not read in a {what}, a number and a unit such as "
                             "'48 h'")
    import pint

    try:
        quantity = registry().Quantity(1.0, text) if unit else registry().Quantity(text)
        dimensionality = quantity.dimensionality
    except Exception as error:  # noqa: BLE001 - pint's parser raises anything, even AssertionError ("1 T*")
        reason = first_line(error) if isinstance(error, pint.errors.PintError) else "unbalanced or incomplete"
        raise InvalidAt(key, f"{text!r} is not a {what} pint reads ({reason})") from None
    if dimensionality != registry().second.dimensionality:
        raise InvalidAt(key, f"{text!r} is not a time (its dimension is {dimensionality})")
    if positive and not (math.isfinite(quantity.magnitude) and quantity.magnitude > 0):
        raise InvalidAt(key, f"must be a positive time (got {text!r})")
    return quantity


@dataclass(frozen=True)
class RealTime:
    """A t_ref: T* = 1 lasts `t_ref` `unit`s (unit: pint's symbol, "h", "min"; cf: "hours", "minutes")."""

    text: str
    t_ref: float
    unit: str
    cf: str

    def real(self, t_star):
        """T* -> real time in `unit`."""
        return t_star * self.t_ref

    def star(self, real):
        """Real time in `unit` -> T*."""
        return real / self.t_ref

    def rate_unit(self, units: str) -> str:
        """A model unit per T* in this clock's unit ('um/T*' -> 'um/h'); other units unchanged."""
        return units.replace("/T*", f"/{self.unit}")


def real_time(text: str, key: str = "t_ref") -> RealTime:
    """Parse a t_ref; the unit shown is the one it was written in, if it is one unit of time, else hours."""
    quantity = parse_time(text, key, positive=True)
    items = dict(quantity.unit_items())
    if len(items) == 1 and next(iter(items.values())) == 1:
        name = next(iter(items))
        return RealTime(text, float(quantity.magnitude), f"{quantity.units:~}", f"{name}s")
    return RealTime(text, float(quantity.to("hour").magnitude), "h", "hours")


def in_t_star(unit: str, t_ref: str) -> float:
    """T* per `unit` of time (a calibration table's `time_unit`): (1 unit) / t_ref; `InvalidAt` naming the key
    that is no time, or a `t_ref` that makes the ratio overflow to inf or 0."""
    one = parse_time(unit, "time_unit", unit=True)
    reference = parse_time(t_ref, "t_ref", positive=True)
    found = float((one / reference).to("dimensionless").magnitude)
    if not 0 < found < math.inf:  # '1e-320 h': T* per hour overflows, and a time 0 would be T* = 0 x inf = NaN
        raise InvalidAt("t_ref", f"{t_ref!r} makes one {unit} T* = {found:g}: not a time scale the table's "
                                 "times can be measured in")
    return found


def exact(value: float) -> str:
    """A time as the shortest text that reads back to it: 4.000001, not 4."""
    return float_literal(value).removesuffix(".0")


def apart(t: float, t_end: float) -> str:
    """`t` with four significant digits, or as many more as it takes not to read as `t_end`."""
    return next((text for text in (f"{t:.{digits}g}" for digits in range(4, 18)) if float(text) != t_end), repr(t))


def check_agree(given: str | None, scenes: str | None, where: str) -> None:
    """A calibration's ``[data] t_ref`` and its scene's ``[time] t_ref`` are one clock: the same time (48 h and
    2 d agree), or `InvalidAt("t_ref")` saying both."""
    if given is None or scenes is None:
        return
    mine, theirs = parse_time(given, "t_ref", positive=True), parse_time(scenes, "t_ref", positive=True)
    if not math.isclose(mine.to("s").magnitude, theirs.to("s").magnitude, rel_tol=1e-12):
        raise InvalidAt("t_ref", f"{given!r} is not the scene's time.t_ref = {scenes!r} ({where}): T* = 1 is one "
                                 "time; give the same in both")


def clock(ds: Any) -> RealTime | None:
    """A dataset's t_ref (its attributes, or a mapping of them), parsed; None for a dataset in T* alone
    (calibration.nc's "1 T*" among them)."""
    attrs: Mapping = ds.attrs if hasattr(ds, "attrs") else ds  # a Dataset is a Mapping too: of its variables
    text = attrs.get(T_REF)
    try:
        return real_time(str(text)) if text else None
    except InvalidAt:
        return None


def shown(ds: Any, t_star: float, digits: int = 4) -> str:
    """A time as a table, title or warning shows it: '12 h (T* = 0.25)' with t_ref, 'T* = 0.25' without."""
    found = clock(ds)
    if found is None:
        return f"T* = {number(t_star, digits)}"
    return f"{number(found.real(t_star), digits)} {found.unit} (T* = {number(t_star, digits)})"


def stated(ds: Any, t_star: float) -> str:
    """A time in a warning: 'T* = 0.25' as before without t_ref (3 digits), '12 h (T* = 0.25)' with it."""
    return shown(ds, t_star, 3) if clock(ds) is not None else f"T* = {t_star:.3g}"
