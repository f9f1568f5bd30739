"""How the tables of a scene are declared: strict (no unknown key, no type coercion, inf and NaN bad input wherever a
number is expected), and every number with its units beside its meaning (the schema and `show` read them)."""
from __future__ import annotations

from pydantic import ConfigDict, Field

CONFIG = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)  # inf is bad input wherever NaN is


def unit_field(default, description: str, units: str = "1", **kw):
    return Field(default, description=description, json_schema_extra={"units": units}, **kw)
