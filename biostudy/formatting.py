"""Numbers, values and units as a person reads them: one spelling for tables, summaries, titles and messages.

* `number`: 1e+08 -> "1e8", 41.0 -> "41", NaN -> "-"; significant digits as asked,
  or a fixed mantissa (``exponent=True``: "2.6e-2") for columns of errors.
* `value_text`: a scene value as a user writes it in TOML, for error messages.
* `units_text`: datasets keep spellings udunits and plain pint both read
  (``um^2``, ``1`` for dimensionless); what is printed or drawn shows ``µm²``
  and leaves dimensionless units out.  `shown_units` gives a model parameter
  its model units back (``d``: ``µm²/T*``; a dataset writes ``um^2``, T* being
  dimensionless: `solver.output.cf_units`).  `current_units` reads the
  spelling of files written before (``um2``, ``um-1``) as today's.

Case ids are not formatted here: they must never change (`study.id_text`), and
scene text written back to files is exact (`tomltext`).
"""
from __future__ import annotations

import math
import re

UNCUT = 100_000  # the width of a table printed where no terminal is (a pipe, a file, a log): its content's, uncut
SHOWN_UNITS = {"1": "", "um": "µm", "um^2": "µm²", "um^3": "µm³", "um^-1": "µm⁻¹", "um^2/T*": "µm²/T*",
               "um/T*": "µm/T*"}
_EXPONENT = re.compile(r"e([+-])0*(\d)")
# a unit with its power glued on, as biostudy 0.4 and earlier wrote it ("um3", "um-1"): udunits reads it, pint not
_GLUED_POWER = re.compile(r"(?<![\w^.])([A-Za-z]+)(-?\d+)(?![\w.^])")


def number(value, digits: int = 4, exponent: bool = False) -> str:
    """A number for people: `digits` significant digits, exponents without '+' and leading zeros."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        return str(value)
    if math.isnan(x):
        return "-"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 0:
        return "0"
    if exponent:
        text = f"{x:.{max(digits - 1, 0)}e}"
    elif x == int(x) and abs(x) < 10**digits:
        text = str(int(x))
    else:
        text = f"{x:.{digits}g}"
    return _EXPONENT.sub(lambda m: "e" + ("-" if m.group(1) == "-" else "") + m.group(2), text)


def value_text(value) -> str:
    """A value as a user wrote it in TOML (short): 1e10 -> 1e10, 'a' -> 'a', [1, 2] -> [1, 2]."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else number(value, 6)
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(value_text(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{...}"
    return str(value)


def current_units(units: str) -> str:
    """A unit as biostudy spells it today: 'um3' -> 'um^3', 'um-1' -> 'um^-1', 'um2/T*' -> 'um^2/T*' (the
    spelling of older files, which pint cannot read); today's spellings unchanged."""
    return _GLUED_POWER.sub(r"\1^\2", str(units))


def units_text(units: str) -> str:
    """'um^2/T*' -> 'µm²/T*', 'um/h' -> 'µm/h', '1' -> '' (dimensionless); older files' 'um2' as 'um^2'."""
    units = current_units(units)
    head, per, tail = units.partition("/")
    if units in SHOWN_UNITS or not per:
        return SHOWN_UNITS.get(units, units)
    return f"{SHOWN_UNITS.get(head, head) or '1'}/{SHOWN_UNITS.get(tail, tail)}"


def shown_units(name: str, units: str) -> str:
    """The units of a dataset variable as people read them: a model parameter's own (per T*: 'r' -> 'µm/T*'),
    else `units_text`."""
    from solver.problem import parameter_infos  # lazily: the command line imports this module at start-up

    declared = {info.name: info.units for info in parameter_infos()}
    return units_text(declared.get(name, units))
