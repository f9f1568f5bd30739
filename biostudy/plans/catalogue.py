"""A stability catalogue (`studies/stability.toml`): stiff and extreme cases of one base scene.

The catalogue names a base scene, overrides for every case (`[set]`, e.g. a
reduced grid) and a list of `[[case]]`s, each with its own overrides and a
line on what it stresses.  Each case runs like a sweep's (workers, a Dask
cluster, resume); `biostudy.reports.stability` judges it.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from pydantic import ConfigDict, Field, model_validator

from ..inputs.resources import Preflight
from .cases import Case, FlatSet, ManyCases, Plan, load_plan


class StabilityCase(FlatSet):
    """One stiff or extreme case: overrides of the base scene."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(description="short unique name, used as the case's file name")
    why: str = Field("", description="what the case stresses")
    set: dict[str, Any] = Field({}, description="overrides (dotted keys, like --set)")


class Catalogue(ManyCases):
    """A list of stiff and extreme cases of one base scene."""

    model_config = ConfigDict(extra="forbid")
    case: list[StabilityCase] = Field(description="the cases", min_length=1)

    @model_validator(mode="after")
    def _unique(self):
        names = [c.name for c in self.case]
        repeated = next((n for n in names if names.count(n) > 1), None)
        if repeated:
            raise ValueError(f"case name {repeated!r} comes twice")
        return self

    def cases(self) -> list[Case]:
        return [Case(job_id(c.name), dict(c.set), (i,), {"case_id": c.name, "case_why": c.why})
                for i, c in enumerate(self.case)]


def job_id(name: str) -> str:
    return re.sub(r"[^\w.+=-]", "_", name)


def load(path: Path, overrides: list[str] | tuple[str, ...] = (), preflight: Preflight | None = None) -> Plan:
    """Validate a catalogue and compile every case; bad input is `BadInput` naming file and case (`preflight`:
    as for `load_plan`)."""
    return load_plan(path, Catalogue, overrides,
                     lambda data: "" if "case" in data else "not a stability catalogue (it has no [[case]] list)",
                     preflight)
