"""How a calibration's parameters are estimated: its [method] table (docs/calibrate.md), made from the methods'
declarations (`methods.METHODS`): `name` chooses one, `starts`, `profiles` and `seed` are every method's, and
each method's own keys (`Method.keys`) apply to it alone."""
from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, create_model, model_validator
from pydantic.fields import FieldInfo

from ..errors import InvalidAt
from .methods import METHODS, LeastSquares


class _Shared(BaseModel):
    """The method's name and the keys every method takes; `_keys_of_the_method` holds each method's own keys to
    it."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)
    name: Literal[tuple(METHODS)] = Field(LeastSquares.name, description="; ".join(
        f"{m.name}: {m.description}" for m in METHODS.values()))
    starts: int = Field(4, ge=1, le=64, description="starts of the optimiser, from a Latin hypercube in the bounds")
    profiles: bool = Field(True, description="a profile likelihood per parameter: its 95 % interval" + "".join(
        f" ({m.name}: false unless set)" for m in METHODS.values() if not m.profiles))
    seed: int = Field(0, ge=0, description="seed of the starts' design" + "".join(
        f" ({m.name}: of {m.seeds} too)" for m in METHODS.values() if m.seeds))

    @model_validator(mode="after")
    def _keys_of_the_method(self):
        chosen = METHODS[self.name]
        given = [key for m in METHODS.values() if m is not chosen for key in m.keys if key in self.model_fields_set]
        if given:
            owner = next(m for m in METHODS.values() if given[0] in m.keys)
            raise InvalidAt(given[0], f"applies to name = \"{owner.name}\" only (this method is {chosen.name!r})")
        if "profiles" not in self.model_fields_set:
            self.profiles = chosen.profiles
        return self


def _own_keys() -> dict[str, Any]:
    """Every method's own keys, their descriptions begun with the method's name."""
    found: dict[str, Any] = {}
    for method in METHODS.values():
        for key, (kind, info) in method.keys.items():
            found[key] = (kind, FieldInfo.merge_field_infos(info, description=f"{method.name}: {info.description}"))
    return found


MethodSpec = create_model("MethodSpec", __base__=_Shared, __doc__="How the parameters are estimated.", **_own_keys())
