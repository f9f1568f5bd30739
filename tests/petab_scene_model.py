"""A biostudy scene as a PEtab model (petab.v1.models.Model), for tests: with it, petab's own `lint_problem` makes
every check it makes on an SBML problem, the cross-table ones included (every parameter a table names is in the
parameter table, none is extraneous, condition columns are model entities, observable formulas use only known
symbols), which it skips when no model is given.  The scene's entities are its real-valued keys (dotted, list
indices included) as PEtab ids (`calibration.petab_out.petab_id`: nutrient.0.value is nutrient__0__value), and the
model parameters under their bare names too (g for params.g); symbols allowed in formulas are the observables."""
from __future__ import annotations

from typing import Any, Iterable

from petab.v1.models.model import Model

from biostudy.calibration.petab_out import SEPARATOR
from biostudy.inputs.keys import PARAMETER_NAMES
from biostudy.quantities import observables


def _flat(node: Any, prefix: str = "") -> dict[str, float]:
    if isinstance(node, dict):
        return {k: v for key, value in node.items() for k, v in _flat(value, f"{prefix}{key}.").items()}
    if isinstance(node, list):
        return {k: v for i, value in enumerate(node) for k, v in _flat(value, f"{prefix}{i}.").items()}
    if isinstance(node, (int, float)) and not isinstance(node, bool):
        return {prefix.rstrip(".").replace(".", SEPARATOR): float(node)}
    return {}


class SceneModel(Model):
    """A validated scene's real-valued keys as PEtab model parameters."""

    def __init__(self, scene):
        self.scene = scene
        self.values = _flat(scene.model_dump(mode="json"))
        self.values.update({name: self.values[f"params{SEPARATOR}{name}"] for name in PARAMETER_NAMES
                            if f"params{SEPARATOR}{name}" in self.values})

    @staticmethod
    def from_file(filepath_or_buffer, model_id: str):
        raise NotImplementedError

    def to_file(self, filename=None):
        raise NotImplementedError

    @classmethod
    def type_id(cls):
        return "biostudy-scene"

    @property
    def model_id(self):
        return self.scene.name

    def get_parameter_value(self, id_: str) -> float:
        return self.values[id_]

    def get_free_parameter_ids_with_values(self) -> Iterable[tuple[str, float]]:
        return self.values.items()

    def get_parameter_ids(self) -> Iterable[str]:
        return self.values.keys()

    def has_entity_with_id(self, entity_id) -> bool:
        return entity_id in self.values

    def get_valid_parameters_for_parameter_table(self) -> Iterable[str]:
        return self.values.keys()

    def get_valid_ids_for_condition_table(self) -> Iterable[str]:
        return self.values.keys()

    def symbol_allowed_in_observable_formula(self, id_: str) -> bool:
        return id_ in observables.REGISTRY or id_ in self.values

    def is_valid(self) -> bool:
        return True

    def is_state_variable(self, id_: str) -> bool:
        return False
