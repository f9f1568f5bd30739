"""A calibration as a PEtab problem (PEtab v1 layout): the texts of ``DIR/petab/`` (docs/calibrate.md, "PEtab").

* ``problem.yaml``: PEtab v1's problem file.  Its model entry (``sbml_files``,
  the only model entry v1 has) names the scene file, which is biostudy's model
  and not SBML; what PEtab has no place for (the scene's [set], the unit of the
  times and t_ref, the method) is in a ``biostudy`` section, which PEtab's
  schema lets stand beside its own keys.
* ``measurements.tsv``: the measurement table's rows, every one with its
  ``simulationConditionId``; times in the table's own unit.
* ``conditions.tsv``: one row per condition (``conditionId``), one column per
  scene key a condition sets or estimates for itself, named by the key's PEtab
  id (`petab_id`: ``nutrient.0.value`` is ``nutrient__0__value``); a condition
  that leaves a key as the scene has it holds the scene's value, one that
  estimates it holds its parameter's id.
* ``observables.tsv``: one row per observable measured: ``observableFormula``
  the biostudy observable (the id itself), linear, normal noise of σ
  ``noiseParameter1_<id>`` (the measurement's ``noiseParameters``).
* ``parameters.tsv``: every estimated parameter (``parameterScale`` log10 for a
  log range, lin otherwise; the bounds; ``nominalValue`` the scene's value) and
  every noise parameter the table names (σ > 0, estimated; its bounds are
  PEtab's requirement, biostudy estimates σ in closed form: docs/calibrate.md).

PEtab ids are letters, digits and _, not starting with a digit; a calibration whose condition names, keys or
condition values PEtab cannot hold (a condition setting a list, a name with a '-') is `NotPetab`, said in words.
`problem_texts` returns the texts; `digests` and `write` put them into DIR/petab/ as calibrate puts
simulation.tsv: a TSV or YAML file carries no mark, so calibration.nc records each one's sha256
(`data.claims.digested`) and a file of these names is replaced only while its bytes are those.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable

from .measurements import NOISE_NAME, Measurement

if TYPE_CHECKING:
    from .problem import CalibrationPlan

PETAB_ID = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
SEPARATOR = "__"  # a dotted key's dots in its PEtab id
FILES = {"condition_files": "conditions.tsv", "measurement_files": "measurements.tsv",
         "observable_files": "observables.tsv"}
PARAMETERS = "parameters.tsv"
PROBLEM = "problem.yaml"
FOLDER = "petab"  # DIR/petab/ of a calibration
NAMES = (PROBLEM, *FILES.values(), PARAMETERS)
SCENE_ID = "scene"  # the condition of a calibration without [conditions] whose table names none
NOISE_BOUNDS = (1e-300, 1e300)  # σ > 0; biostudy does not bound it (it is estimated in closed form)


class NotPetab(ValueError):
    """A calibration PEtab's tables cannot hold; str() says what and why."""


def petab_id(key: str) -> str:
    """A dotted scene key as a PEtab id: 'g' -> 'g', 'nutrient.0.value' -> 'nutrient__0__value'."""
    found = key.replace(".", SEPARATOR)
    if not PETAB_ID.fullmatch(found) or SEPARATOR in key:
        raise NotPetab(f"the key {key!r} has no PEtab id (letters, digits and _, its dots as {SEPARATOR})")
    return found


def scene_key(identifier: str) -> str:
    """The dotted scene key of a PEtab id (`petab_id`'s inverse)."""
    return identifier.replace(SEPARATOR, ".")


def own_id(key: str, condition: str) -> str:
    """The PEtab id of a key one condition estimates for itself (biostudy's r[half]): 'r__half'."""
    return f"{petab_id(key)}{SEPARATOR}{condition}"


def number(value: Any) -> str:
    """A number as PEtab's tables hold it: the shortest text that reads back as the same double."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise NotPetab(f"{value!r} is not a number")
    return repr(float(value))


def _table(columns: list[str], rows: Iterable[list[str]]) -> str:
    return "".join("\t".join(row) + "\n" for row in [columns, *rows])


def condition_ids(conditions: dict[str, dict], measurements: list[Measurement], scene: str) -> list[str]:
    """The conditions' ids: the calibration's [conditions], or (without) the one id its table uses, or `scene`."""
    named = list(conditions) or sorted({m.condition for m in measurements if m.condition}) or [scene]
    for name in named:
        if not PETAB_ID.fullmatch(name):
            raise NotPetab(f"the condition {name!r} is not a PEtab id (letters, digits and _, not starting with a "
                           "digit)")
    return named


def measurements_table(measurements: list[Measurement], default_condition: str) -> str:
    """measurements.tsv: every row with its condition (`default_condition` where the table leaves it empty)."""
    optional = [c for c in ("datasetId", "replicateId", "datapointId") if any(
        getattr(m, c.removesuffix("Id")) for m in measurements)]
    columns = ["observableId", "simulationConditionId", "time", "measurement", "noiseParameters", *optional]
    rows = [[m.observable, m.condition or default_condition, number(m.time), number(m.value),
             m.noise or number(m.sigma), *(getattr(m, c.removesuffix("Id")) for c in optional)] for m in measurements]
    return _table(columns, rows)


def observables_table(names: list[str], long_names: dict[str, str]) -> str:
    """observables.tsv: each observable computed by biostudy under its own name, normal noise of σ from the
    measurement table."""
    columns = ["observableId", "observableName", "observableFormula", "observableTransformation", "noiseFormula",
               "noiseDistribution"]
    return _table(columns, [[name, long_names[name], name, "lin", f"noiseParameter1_{name}", "normal"]
                            for name in names])


def conditions_table(ids: list[str], sets: dict[str, dict[str, Any]], own: dict[str, dict[str, Any]],
                     shared: dict[str, str], nominal) -> str:
    """conditions.tsv: per condition the keys any condition sets (`sets`: id -> key -> value) or estimates for
    itself (`own`: id -> key -> range); elsewhere the scene's value (`nominal(key)`) or the shared parameter's id
    (`shared`: key -> id, for a key some conditions estimate for themselves and the others share)."""
    keys = list(dict.fromkeys([*(k for s in sets.values() for k in s), *(k for o in own.values() for k in o)]))
    columns = ["conditionId", "conditionName", *(petab_id(k) for k in keys)]
    rows = []
    for name in ids:
        row = [name, name]
        for key in keys:
            if key in own.get(name, {}):
                row.append(own_id(key, name))
            elif key in sets.get(name, {}):
                try:
                    row.append(number(sets[name][key]))
                except NotPetab:
                    raise NotPetab(f"the condition {name} sets {key} = {sets[name][key]!r}; PEtab's condition "
                                   "table holds numbers and parameter ids") from None
            else:
                row.append(shared[key] if key in shared else number(nominal(key)))
        rows.append(row)
    return _table(columns, rows)


def parameters_table(rows: list[tuple[str, str, Any, float]], noise: list[str]) -> str:
    """parameters.tsv: `rows` (PEtab id, biostudy's name, its range, the scene's value), then the noise parameters."""
    columns = ["parameterId", "parameterName", "parameterScale", "lowerBound", "upperBound", "nominalValue",
               "estimate"]
    found = [[identifier, name, "log10" if bounds.scale == "log" else "lin", number(bounds.low), number(bounds.high),
              number(value), "1"] for identifier, name, bounds, value in rows]
    for name in noise:
        if not NOISE_NAME.fullmatch(name):
            raise NotPetab(f"the noise parameter {name!r} is not a PEtab id")
        found.append([name, name, "lin", number(NOISE_BOUNDS[0]), number(NOISE_BOUNDS[1]), "1.0", "1"])
    return _table(columns, found)


def problem_yaml(scene: str, extension: dict[str, Any]) -> str:
    """problem.yaml: PEtab v1's layout, the scene as its model, biostudy's own settings in `extension`."""
    import yaml  # lazily: only where a PEtab problem is written or read

    document = {"format_version": 1, "parameter_file": PARAMETERS,
                "problems": [{"sbml_files": [scene], **{key: [name] for key, name in FILES.items()}}],
                "biostudy": extension}
    return yaml.safe_dump(document, sort_keys=False, allow_unicode=True)


def relative(path: Path, directory: Path) -> str:
    """`path` as problem.yaml names it: relative to the petab directory where it can be, else absolute."""
    import os

    try:
        return os.path.relpath(Path(path).resolve(), Path(directory).resolve())
    except ValueError:  # another drive
        return str(Path(path).resolve())


def _value(scene, key: str) -> Any:
    """A scene's value of a dotted key (its defaults filled in)."""
    from ..inputs.keys import key_parts

    node: Any = scene.model_dump(mode="json")
    for part in key_parts(key):
        node = node[int(part)] if isinstance(node, list) else node[part]
    return node


def problem_texts(plan: CalibrationPlan, directory: Path, given_set: dict[str, Any]) -> dict[str, str]:
    """Every file of ``DIR/petab/`` (module docstring) of a calibration plan, by name; `directory` is where they
    go (problem.yaml names the scene relative to it), `given_set` the overrides of every simulation ([set] and
    --set).  `NotPetab` when PEtab's tables cannot hold the calibration."""
    from ..quantities import observables

    spec = plan.spec
    ids = condition_ids({n: c.set for n, c in spec.conditions.items()}, plan.measurements, SCENE_ID)
    first = ids[0]
    own = {n: dict(c.estimate) for n, c in spec.conditions.items() if c.estimate}
    shared_keys = {key for o in own.values() for key in o}
    shared = {key: f"{petab_id(key)}{SEPARATOR}shared" for key in spec.estimate if key in shared_keys}
    rows = [(shared.get(key, petab_id(key)), key, bounds, _value(plan.scenes[first], key))
            for key, bounds in spec.estimate.items()]
    rows += [(own_id(key, name), f"{key}[{name}]", bounds, _value(plan.scenes[name], key))
             for name, table in own.items() for key, bounds in table.items()]
    names = list(dict.fromkeys(m.observable for m in plan.measurements))
    long_names = {n: f"{observables.get(n).long_name} [{observables.get(n).units}]" for n in names}
    noise = list(dict.fromkeys(m.noise for m in plan.measurements if m.noise))
    sets = {n: dict(c.set) for n, c in spec.conditions.items()}
    extension = {"scene": relative(plan.scene_file, directory), "set": given_set,
                 "time_unit": spec.data.time_unit, "t_ref": spec.data.t_ref,
                 "method": spec.method.model_dump(mode="json", exclude_unset=True) or None}
    return {
        PROBLEM: problem_yaml(relative(plan.scene_file, directory), {k: v for k, v in extension.items()
                                                                      if v is not None}),
        FILES["measurement_files"]: measurements_table(plan.measurements, first),
        FILES["condition_files"]: conditions_table(ids, sets, own, shared, lambda key: _value(plan.scenes[first],
                                                                                               key)),
        FILES["observable_files"]: observables_table(names, long_names),
        PARAMETERS: parameters_table(rows, noise),
    }


def digests(texts: dict[str, str], folder: Path, before: dict | None) -> dict[str, str]:
    """The attributes calibration.nc records of the files (`claims.digested`), each with the digest of the file
    it replaces where `before` (the calibration.nc it replaces) proves that file biostudy's."""
    from ..data import claims

    found: dict[str, str] = {}
    for name, text in texts.items():
        present = claims.sha256(folder / name)
        found.update(claims.digested(name, text, present if present in claims.recorded(before, name) else ""))
    return found


def write(texts: dict[str, str], folder: Path, before: dict | None) -> list[Path]:
    """Write the files into `folder` (made if absent), each refused where a file is whose sha256 `before` does not
    record (`claims.write_digested`)."""
    from ..data import claims

    folder.mkdir(exist_ok=True)
    return [claims.write_digested(folder / name, text, before, "calibration.nc") for name, text in texts.items()]
