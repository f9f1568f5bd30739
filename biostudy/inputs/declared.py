"""How the tables of a scene are declared: strict (no unknown key, no type coercion, inf and NaN bad input wherever a
number is expected), and every number with its units beside its meaning (the schema and `show` read them).

The tables that set the solver are derived from its declarations, never retyped: ``[params]`` from
`solver.Parameters` (`parameters_model`), ``[numerics]`` and ``[mechanics]`` from `solver.Numerics` and
`solver.MechanicsSetup` (`settings_model`): each field's type, default, meaning, units and range are the
solver's, and the rules between its fields are the solver's too (`SolverSettings`).
"""
from __future__ import annotations

from typing import Annotated, Any, ClassVar, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, Field, create_model, model_validator

from solver.declared import OptionError, option_infos
from solver.problem import parameter_infos

from ..errors import InvalidAt, Tags
from ..formatting import units_text

CONFIG = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)  # inf is bad input wherever NaN is


def unit_field(default, description: str, units: str = "1", **kw):
    return Field(default, description=description, json_schema_extra={"units": units}, **kw)


def parameters_model() -> type[BaseModel]:
    """The [params] table, derived from the declarations of `solver.Parameters`: each parameter's
    default, units, meaning and allowed range (`solver.problem.parameter`)."""
    fields: dict[str, Any] = {}
    for info in parameter_infos():
        shown = units_text(info.units)
        fields[info.name] = (float, unit_field(info.default, f"{info.long_name}{', ' + shown if shown else ''}",
                                               info.units, **info.bounds))
    return create_model("Params", __config__=CONFIG, __doc__="Model parameters (paper Table 2 by default; "
                        "docs/model.md); unspecified keys take their defaults.", **fields)


class SolverSettings(BaseModel):
    """A table of the scene that sets one of the solver's settings dataclasses (`settings`): validated by its
    fields' declarations, then by the dataclass itself, whose rules between fields (`solver.declared.OptionError`)
    are reported at the key they name."""

    model_config = CONFIG
    settings: ClassVar[type]

    def solver_settings(self) -> Any:
        """The solver's dataclass with this table's values (lists as the tuples it holds)."""
        values = {info.name: getattr(self, info.name) for info in option_infos(self.settings)}
        return self.settings(**{name: tuple(v) if isinstance(v, list) else v for name, v in values.items()})

    @model_validator(mode="after")
    def _solver_rules(self):
        try:
            self.solver_settings()
        except OptionError as error:
            raise InvalidAt(error.option, error.problem) from None
        return self


def _scene_type(kind: Any) -> Any:
    """A solver option's type as a scene file states it: a tuple is a TOML array (a list)."""
    return list[get_args(kind)[0]] if get_origin(kind) is tuple else kind  # type: ignore[misc]


def settings_model(settings: type, name: str, doc: str, **first: Any) -> type[SolverSettings]:
    """The scene table of `settings` (a dataclass whose fields are declared with `solver.declared.option`): one key
    per option, its type, default, description, units and bounds the declaration's; `first`: keys of the scene's
    own that come before them, as `create_model` takes them."""
    fields = dict(first)
    for info in option_infos(settings):
        default = list(info.default) if isinstance(info.default, tuple) else info.default
        units = {"json_schema_extra": {"units": info.units}} if info.units is not None else {}
        fields[info.name] = (_scene_type(info.kind), Field(default, description=info.help, **units, **info.bounds))
    model = create_model(name, __base__=SolverSettings, __doc__=doc, **fields)
    model.settings = settings
    return model


def union_tags(model: type[BaseModel]) -> Tags:
    """{key: tags} for every list of `model` whose items are a tagged union (``Annotated[Union[...],
    Field(discriminator=...)]``): the values each member declares for the tag (its ``Literal``), as pydantic puts
    them into error locations (`errors.key_path`)."""
    found = {}
    for key, info in model.model_fields.items():
        item = get_args(info.annotation)[0] if get_origin(info.annotation) is list else None
        if get_origin(item) is not Annotated:
            continue
        union, *marks = get_args(item)
        tag = next((mark.discriminator for mark in marks if getattr(mark, "discriminator", None)), None)
        if tag is not None and get_origin(union) is Union:
            found[key] = tuple(value for member in get_args(union)
                               for value in get_args(member.model_fields[tag].annotation))
    return found
