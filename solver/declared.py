"""How the solver's settings are declared, once, with what a reader and the scene schema need.

A model parameter (`parameter`, on `problem.Parameters`) carries its default, units, meaning and range; an
option of the numerics or the mechanics (`option`, on `problem.Numerics` and `problem.MechanicsSetup`) its
default, meaning, units and range, its type being the field's annotation.  The study service derives its
scene schema, the dataset's attributes and its tables from these declarations, so a setting is declared here
once, where the solver uses it.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, get_type_hints


def parameter(default: float, units: str, long_name: str, **bounds: float):
    """A field of `Parameters`: default, units (the model's, e.g. um^2/T*; datasets write their udunits form,
    `solver.output.cf_units`), meaning and allowed range
    (bounds: gt, ge, lt, le).  The scene schema, the dataset's attributes and the tables of `show` and
    `stability` are all derived from these declarations, so a new parameter is declared here once."""
    return field(default=default, metadata={"units": units, "long_name": long_name, "bounds": _bounds(bounds)})


def _bounds(bounds: dict[str, float]) -> dict[str, float]:
    unknown = set(bounds) - {"gt", "ge", "lt", "le"}
    if unknown:
        raise TypeError(f"unknown bounds {sorted(unknown)}; use gt, ge, lt, le")
    return bounds


@dataclass(frozen=True)
class ParameterInfo:
    """One declared model parameter (see `parameter`)."""

    name: str
    default: float
    units: str
    long_name: str
    bounds: dict


def option(default: Any, help: str, units: str | None = None, result: bool = True, **bounds: float):
    """A field of `Numerics` or `MechanicsSetup` that a scene sets: default, what it does (the scene schema's
    description), units (numbers: "1" when dimensionless) and allowed range (bounds: gt, ge, lt, le).  Its type
    is the field's annotation (a Literal lists the choices; a tuple is a list in the scene).  The scene's
    ``[numerics]`` and ``[mechanics]`` tables are derived from these declarations (`option_infos`), as its
    ``[params]`` is from `parameter`: an option is declared here once.  A field declared without `option` is
    the solver's own, set from Python only.  `result=False` declares an option that changes how a run is
    computed but not what it computes (the threads): a finished case is the same case whatever its value
    (`changes_result`), and out of the settings' repr (which describes what is computed)."""
    return field(default=default, repr=result, metadata={"help": help, "units": units, "bounds": _bounds(bounds),
                                                         "result": result})


def changes_result(part) -> bool:
    """Whether a dataclass field (of the solver's settings) can change a run's result: every field but an
    option declared with ``result=False``."""
    return part.metadata.get("result", True)


@dataclass(frozen=True)
class OptionInfo:
    """One declared option (see `option`): its type is the field's annotation, resolved."""

    name: str
    kind: Any
    default: Any
    help: str
    units: str | None
    bounds: dict


def option_infos(settings: type) -> tuple[OptionInfo, ...]:
    """The options a dataclass declares with `option`, in order."""
    kinds = get_type_hints(settings)
    return tuple(OptionInfo(f.name, kinds[f.name], f.default, f.metadata["help"], f.metadata["units"],
                            dict(f.metadata["bounds"]))
                 for f in fields(settings) if "help" in f.metadata)


class OptionError(ValueError):
    """A rule of the solver's settings broken (between options, or between a problem's fields): `option` names
    the field it is told at ("slide", "output_times[1]"), `problem` says what is wrong, in the words the scene
    uses at its own key for the same rule."""

    def __init__(self, option: str, problem: str):
        self.option, self.problem = option, problem
        super().__init__(f"{option}: {problem}")
