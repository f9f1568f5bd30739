"""A PEtab problem as a calibration file (``biostudy calibrate problem.yaml``; docs/calibrate.md, "PEtab").

`calibration_data` reads PEtab v1's problem.yaml and its tables into the data a calibration file (TOML) holds,
which the calibration then validates as its own (`calibration.problem`):

* the scene: the ``biostudy`` section's ``scene``, else the problem's model entry (``sbml_files``), which must
  be a scene file (or a bundled scene's name): biostudy simulates scenes, not SBML;
* ``[data]``: the measurement table (read as any measurement table, `measurements`), ``time_unit`` and
  ``t_ref`` from the ``biostudy`` section (absent: the times are T*);
* ``[conditions]``: one per row of the condition table, setting the scene keys its columns name (PEtab ids:
  ``nutrient__0__value`` is ``nutrient.0.value``) to its numbers; a cell naming an estimated parameter makes
  that key estimated there: for that condition alone ([conditions.X.estimate]) or, named in every row (or, as
  biostudy writes it, with an id ending in ``__shared``), shared by the conditions naming it ([estimate]);
* ``[estimate]``: the estimated parameters (``estimate`` = 1) no condition names, each its key's, with its
  bounds (``parameterScale`` log10 or log: a log range); a parameter not estimated sets its key to its
  ``nominalValue`` ([set]); the noise parameters the measurement table names are estimated by the calibration
  itself (their bounds are not used);
* the observables: each must be a biostudy observable under its own name (``observableFormula`` = the id,
  linear, normal noise ``noiseParameter1_<id>``), as biostudy writes them;
* ``[set]`` and ``[method]``: from the ``biostudy`` section.

Each file is a regular file of bounded size, read as the measurement table is; a problem PEtab allows and
biostudy does not compute (several models or tables, another noise model, a formula) is one line naming the
file, the line and the column (`BadInput`).
"""
from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

from ..errors import BadInput
from ..inputs.files import TOML_BYTES, read_text
from .measurements import NOISE_NAME, TABLE_BYTES, read_measurements

SEPARATOR = "__"  # a dotted key's dots in its PEtab id
SHARED = "__shared"  # the id of a key's parameter shared by the conditions that do not estimate it for themselves
LISTS = ("condition_files", "measurement_files", "observable_files")


def _yaml(path: Path) -> dict:
    import yaml  # lazily: only for a PEtab problem

    try:
        data = yaml.safe_load(read_text(path, TOML_BYTES, "a PEtab problem file (YAML)"))
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f"line {mark.line + 1}: " if mark is not None else ""
        raise BadInput(f"{where}not YAML ({getattr(error, 'problem', None) or error})", path) from None
    if not isinstance(data, dict):
        raise BadInput("not a PEtab problem (a YAML mapping with format_version, parameter_file, problems)", path)
    return data


def _one(problem: dict, key: str, path: Path) -> str:
    files = problem.get(key)
    if not isinstance(files, list) or len(files) != 1 or not isinstance(files[0], str):
        raise BadInput(f"must list one file (biostudy reads one table of each kind; got {files!r})", path,
                       f"problems[0].{key}")
    return files[0]


def _rows(path: Path, required: tuple[str, ...]) -> list[tuple[int, dict[str, str]]]:
    """A PEtab table (TSV) as (line, row) pairs; a missing column is `BadInput`."""
    text = read_text(path, TABLE_BYTES, "a PEtab table", spreadsheet=True)
    reader = csv.DictReader(io.StringIO(text), delimiter="\t")
    missing = [c for c in required if c not in (reader.fieldnames or [])]
    if missing:
        raise BadInput(f"has no column {', '.join(missing)} (a PEtab table is tab-separated)", path)
    return [(line, {k: (v or "").strip() for k, v in row.items() if k is not None})
            for line, row in enumerate(reader, start=2)]


def _number(text: str, path: Path, where: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise BadInput(f"{text!r} is not a number", path, where) from None


def _parameters(path: Path) -> dict[str, dict[str, Any]]:
    """parameters.tsv: id -> {estimate, range [low, high(, "log")], nominal}."""
    found = {}
    for line, row in _rows(path, ("parameterId", "parameterScale", "lowerBound", "upperBound", "estimate")):
        name, scale = row["parameterId"], row["parameterScale"] or "lin"
        if scale not in ("lin", "log", "log10"):
            raise BadInput(f"{scale!r}: lin, log or log10", path, f"line {line}: parameterScale")
        estimate = row["estimate"] in ("1", "1.0", "true", "True")
        low, high = (_number(row[c], path, f"line {line}: {c}") for c in ("lowerBound", "upperBound"))
        nominal = row.get("nominalValue", "")
        if not estimate and not nominal:
            raise BadInput("a parameter not estimated needs its nominalValue", path, f"line {line}: nominalValue")
        found[name] = {"estimate": estimate, "range": [low, high, *(["log"] if scale != "lin" else [])],
                       "nominal": _number(nominal, path, f"line {line}: nominalValue") if nominal else None}
    return found


def _observables(path: Path) -> None:
    """Every observable biostudy's own: formula = id, linear, normal noise of the measurement's σ."""
    for line, row in _rows(path, ("observableId", "observableFormula")):
        name = row["observableId"]
        checks = (("observableFormula", row["observableFormula"] == name,
                   f"{row['observableFormula']!r}: biostudy computes its observables by name (give the observable "
                   f"itself, {name!r}: biomass, max_thickness, ...)"),
                  ("observableTransformation", row.get("observableTransformation", "") in ("", "lin"),
                   f"{row.get('observableTransformation')!r}: biostudy fits lin observables"),
                  ("noiseDistribution", row.get("noiseDistribution", "") in ("", "normal"),
                   f"{row.get('noiseDistribution')!r}: biostudy fits normal noise"),
                  ("noiseFormula", row.get("noiseFormula", "") in ("", f"noiseParameter1_{name}"),
                   f"{row.get('noiseFormula')!r}: σ is the measurement table's noiseParameters "
                   f"(noiseParameter1_{name})"))
        for column, fine, why in checks:
            if not fine:
                raise BadInput(why, path, f"line {line}: {column}")


def _conditions(path: Path, parameters: dict[str, dict]) -> tuple[dict[str, dict], dict[str, list]]:
    """conditions.tsv: {id: {key: value or {"estimate": range}}}, and the keys each estimated parameter sets:
    {parameter: [(condition, key)]}."""
    rows = _rows(path, ("conditionId",))
    conditions: dict[str, dict] = {}
    used: dict[str, list] = {}
    for line, row in rows:
        name = row["conditionId"]
        table: dict[str, Any] = {}
        for column, cell in row.items():
            if column in ("conditionId", "conditionName") or cell == "":
                continue
            key = column.replace(SEPARATOR, ".")
            if cell in parameters and parameters[cell]["estimate"]:
                used.setdefault(cell, []).append((name, key))
            elif cell in parameters:
                table[key] = parameters[cell]["nominal"]
            else:
                table[key] = _number(cell, path, f"line {line}: {column}")
        conditions[name] = table
    return conditions, used


def calibration_data(path: str | Path) -> dict[str, Any]:
    """A PEtab problem (problem.yaml) as a calibration file's data (module docstring); paths relative to it."""
    path = Path(path)
    document = _yaml(path)
    version = str(document.get("format_version", ""))
    if version.split(".")[0] != "1":
        raise BadInput(f"format_version {version or 'missing'}: biostudy reads PEtab v1 problems", path)
    problems = document.get("problems")
    if not isinstance(problems, list) or len(problems) != 1 or not isinstance(problems[0], dict):
        raise BadInput("problems must hold one problem (a scene, its conditions, measurements, observables)", path)
    extension = document.get("biostudy") or {}
    if not isinstance(extension, dict):
        raise BadInput("must be a mapping (scene, set, time_unit, t_ref, method)", path, "biostudy")
    scene = extension.get("scene") or _one(problems[0], "sbml_files", path)
    files = {key: path.parent / _one(problems[0], key, path) for key in LISTS}
    parameter_file = document.get("parameter_file")
    if not isinstance(parameter_file, str):
        raise BadInput(f"must name one file (got {parameter_file!r})", path, "parameter_file")
    parameters = _parameters(path.parent / parameter_file)
    _observables(files["observable_files"])
    conditions, used = _conditions(files["condition_files"], parameters)
    noise = {m.noise for m in read_measurements(files["measurement_files"]) if m.noise}
    folder = path.parent.parent if path.parent.name == "petab" else path.parent  # DIR/petab/problem.yaml: DIR's
    data: dict[str, Any] = {"name": folder.name if path.stem == "problem" else path.stem, "scene": scene,
                            "set": dict(extension.get("set") or {}), "estimate": {},
                            "data": {"measurements": str(files["measurement_files"].relative_to(path.parent))}}
    for key in ("time_unit", "t_ref"):
        if extension.get(key) is not None:
            data["data"][key] = extension[key]
    if extension.get("method") is not None:
        data["method"] = extension["method"]
    every = set(conditions)
    estimated = {}
    for name, found in parameters.items():
        if name in noise or not NOISE_NAME.fullmatch(name):
            continue
        if not found["estimate"]:
            if name not in used:
                data["set"][name.replace(SEPARATOR, ".")] = found["nominal"]
            continue
        places = used.get(name)
        keys = {k for _, k in places or ()}
        if not places:
            data["estimate"][name.replace(SEPARATOR, ".")] = found["range"]
        elif len(keys) == 1 and ({c for c, _ in places} == every or name.endswith(SHARED)):
            data["estimate"][places[0][1]] = found["range"]  # the key every condition not estimating its own shares
        elif len(places) == 1:
            estimated.setdefault(places[0][0], {})[places[0][1]] = found["range"]
        else:
            named = ", ".join(f"{k} in {c}" for c, k in places)
            raise BadInput(f"{name} sets {named}: a parameter sets one key, for one condition (its own) or as the "
                           f"value the others share (its id ending in {SHARED})", path.parent / parameter_file)
    data["conditions"] = {name: {**table, **({"estimate": estimated[name]} if name in estimated else {})}
                          for name, table in conditions.items()}
    return data
