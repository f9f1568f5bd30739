"""Many cases of one base scene: what studies, stability catalogues and calibrations share.

A file of this kind names a base scene (relative to the file), overrides for
every case (`[set]`, like `--set`) and its cases, each a set of overrides.
`load_plan` reads the file, the base scene and every case and validates each
case as a scene before anything runs, so a bad value in the fourth case stops
the whole at once (exit 2) instead of after hours.  The result is a `Plan`:
every case compiled to a `Scene`, nothing run yet.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ..errors import BadInput, from_validation_error
from ..inputs.bundled import studies_dir
from ..inputs.files import read_toml
from ..inputs.keys import Origins, apply_overrides, flatten, given_by, key_parts, parse_override, set_key
from ..inputs.resources import Preflight
from ..inputs.scene import Scene, read_scene_data, scene_from_data


class FlatSet(BaseModel):
    """A model with a `set` table of overrides, which may be written as nested tables: read as dotted keys."""

    @model_validator(mode="before")
    @classmethod
    def _flatten_set(cls, data: Any):
        if isinstance(data, dict) and isinstance(data.get("set"), dict):
            data = {**data, "set": flatten(data["set"])}
        return data


@dataclass(frozen=True)
class Case:
    """One simulation of a study or catalogue: its id, its overrides of the base scene, its position.

    attrs: what its case file records about it besides the id (a catalogue case: its name and why).
    """

    id: str
    values: dict[str, Any]
    index: tuple[int, ...]
    attrs: dict[str, Any] = field(default_factory=dict)

    def overrides(self) -> dict[str, Any]:
        return dict(self.values)


class OnScene(FlatSet):
    """A file of simulations of one base scene (a study, a catalogue, a calibration): its name, its one line for
    `biostudy scenes`, the base scene and the overrides of every simulation."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field("", description="short name (default: the file's name without .toml)")
    description: str = Field("", description="one line shown by `biostudy scenes`")
    scene: str = Field(description="base scene file, relative to this file, or a bundled scene's name (agar2d)")
    set: dict[str, Any] = Field({}, description="overrides applied to every case (dotted keys, like --set)")


class ManyCases(OnScene):
    """What study files and stability catalogues share: many cases of one base scene."""

    def varied_keys(self) -> list[str]:
        """The keys that vary from case to case."""
        return []

    def layout(self) -> str:
        return "list"

    def cases(self) -> list[Case]:
        """Every case, in the order they run and are recorded."""
        raise NotImplementedError

    def check(self, base_data: dict, scene_file: Path, path: Path) -> None:
        """Checks against the base scene that the schema alone cannot make (bad input: `BadInput`); they
        change nothing, so `cases()` gives the same cases whether or not they were made."""

    def case_noun(self) -> str:
        """What this file's cases are called in its errors: the key a repeated case id is blamed on."""
        return "case"


@dataclass
class Plan:
    """A validated study or catalogue: every case compiled to a `Scene`, nothing run yet."""

    file: Path
    spec: ManyCases  # the Study or Catalogue as read
    scene_file: Path
    base: Scene
    cases: list[Case]
    scenes: dict[str, Scene]
    common: dict[str, Any]  # [set] and --set overrides applied to every case

    @property
    def keys(self) -> list[str]:
        """The keys that vary from case to case (a study's swept or sampled keys)."""
        return self.spec.varied_keys()

    @property
    def mode(self) -> str:
        """How the cases are laid out: grid, zip, sample (a study) or list."""
        return self.spec.layout()


def base_scene(path: Path, scene: str, given_set: dict[str, Any], overrides=()) -> tuple[Path, dict, dict]:
    """The raw data of the base scene a study or catalogue file names, with its [set] and the --set
    overrides applied; returns (scene file, data, the overrides applied to every case)."""
    scene_file = scene_path(path, scene)
    data = read_scene_data(scene_file)
    for key, value in given_set.items():
        try:
            set_key(data, key, value)
        except BadInput as error:
            raise BadInput(error.problem, path, f"set.{key}") from None
    return scene_file, data, {**given_set, **dict(apply_overrides(data, overrides))}


def scene_path(path: Path, scene: str) -> Path:
    """The scene a study, catalogue or calibration file names: a file relative to it, or (a bare name, as the
    command line takes it: scene = "agar2d") a bundled scene; `BadInput` at its `scene` key otherwise."""
    scene_file = path.parent / scene
    if scene_file.is_file():
        return scene_file
    bare = len(Path(scene).parts) == 1 and Path(scene).suffix in ("", ".toml")
    if bare:
        for candidate in (studies_dir() / scene, studies_dir() / f"{scene}.toml"):
            if candidate.is_file():
                return candidate
    also = " nor a bundled scene of that name (`biostudy scenes` lists them)" if bare else ""
    raise BadInput(f"scene file {scene!r} not found (looked for {scene_file}){also}", path, "scene")


def case_scene(base_data: dict, values: dict[str, Any], scene_file: Path, path: Path, case_name: str,
               origins: Origins | None = None, preflight: Preflight | None = None) -> Scene:
    """One case's validated scene: the base data with the case's values; errors name the case, and the
    study file unless an override (`origins`: --set, the study's [set]) gave the value at fault (`preflight`:
    as for `scene_from_data`)."""
    data = copy.deepcopy(base_data)
    try:
        for key, value in values.items():
            set_key(data, key, value)
        return scene_from_data(data, scene_file, {**(origins or {}), **given_by(values, path)}, preflight)
    except BadInput as error:
        raise error.relocated(lambda file: path if file in (None, str(scene_file)) else file,
                              lambda key: ": ".join(filter(None, (f"case {case_name}", key)))) from None


M = TypeVar("M", bound=OnScene)


def read_spec(path: Path, model: type[M], wrong_kind: Callable[[dict], str] = lambda data: "",
              read: Callable[[Path], dict] = read_toml) -> M:
    """A study, catalogue or calibration file validated as `model`; `read` turns the file into its data (TOML; a
    calibration also reads a PEtab problem.yaml); wrong_kind(data) says why the file is not of this kind ("" if it
    is), before it is validated."""
    data = read(path)
    problem = wrong_kind(data)
    if problem:
        raise BadInput(problem, path)
    data.setdefault("name", path.stem)
    try:
        return model.model_validate(data)
    except ValidationError as error:
        raise from_validation_error(error, path, known_keys=model.model_fields) from None


def origins_of(given_set: dict[str, Any], path: Path, overrides) -> Origins:
    """Where each common override came from: the file's [set] or --set."""
    return {**given_by(given_set, path, "set."), **given_by(map(parse_override, overrides), "--set")}


def compile_cases(cases: list[Case], base_data: dict, scene_file: Path, path: Path, origins: Origins,
                  preflight: Preflight | None) -> dict[str, Scene]:
    """Every case's validated scene; every bad case told at once (as a scene tells every bad key)."""
    scenes, problems = {}, []
    for case in cases:
        try:
            scenes[case.id] = case_scene(base_data, case.values, scene_file, path,
                                         case.attrs.get("case_id", case.id), origins, preflight)
        except BadInput as error:
            problems.append(error)
    if problems:
        raise BadInput.every(problems)
    return scenes


@dataclass(frozen=True)
class Based:
    """A file of many cases of one scene, read and checked: its spec, its base scene (the file, its raw data with
    [set] and --set applied, validated), the overrides every case has and where each came from."""

    spec: Any
    scene_file: Path
    data: dict
    scene: Scene
    common: dict
    origins: Origins


def read_based(path: Path, model: type[M], overrides, wrong_kind: Callable[[dict], str], preflight: Preflight | None,
               varies: Callable[[Any], tuple[list[str], str]], read: Callable[[Path], dict] = read_toml) -> Based:
    """A study's, catalogue's or calibration's file and its base scene (`Based`), the spec's own checks against
    the base data done, and no override of a key its cases vary (varies(spec): those keys, and who varies them
    as `not_varied` says it; `read`: as for `read_spec`)."""
    spec = read_spec(path, model, wrong_kind, read)
    scene_file, data, common = base_scene(path, spec.scene, spec.set, overrides)
    origins = origins_of(spec.set, path, overrides)
    scene = scene_from_data(data, scene_file, origins, preflight)
    spec.check(data, scene_file, path)
    not_varied(*varies(spec), spec.set, path, overrides)
    return Based(spec, scene_file, data, scene, common, origins)


def load_plan(path: str | Path, model: type[ManyCases], overrides: list[str] | tuple[str, ...] = (),
              wrong_kind: Callable[[dict], str] = lambda data: "", preflight: Preflight | None = None) -> Plan:
    """Read a study or catalogue file, its base scene and every case; any bad input is a `BadInput`.

    wrong_kind(data) says why the file is not of this kind ("" if it is), before it is validated.
    preflight: the command's check that every case fits this machine (`resources.Preflight`: with `runs`, the
    cases run here, not on a Dask cluster), made before a case's masks are.
    """
    path = Path(path)
    based = read_based(path, model, overrides, wrong_kind, preflight, lambda spec: (
        spec.varied_keys(), f"varied by this study ({spec.case_noun()} {{key}}), so every case would replace it; "
                            "change the study's values instead"))
    spec, scene_file, base_data, base, common, origins = (based.spec, based.scene_file, based.data, based.scene,
                                                           based.common, based.origins)
    cases = spec.cases()
    ids = [case.id for case in cases]
    repeated = next((i for i in ids if ids.count(i) > 1), None)
    if repeated:
        twins = [case.values for case in cases if case.id == repeated]
        raise BadInput(f"case {repeated} comes twice" if all(t == twins[0] for t in twins) else
                       f"cases {' and '.join(map(str, twins[:2]))} collide as file names: both are case "
                       f"{repeated} (a case id keeps letters, digits and . + -; others become -)", path,
                       spec.case_noun())
    scenes = compile_cases(cases, base_data, scene_file, path, origins, preflight)
    return Plan(path, spec, scene_file, base, cases, scenes, common)


def not_varied(varied_keys: list[str], what: str, given_set: dict[str, Any], path: Path, overrides) -> None:
    """`BadInput` for an override ([set] or --set) of a key the cases vary: every case would replace it, while
    the record would say it was set.  `what` says who varies it and what to do ({key}: the varied key)."""
    varied = {tuple(key_parts(key)): key for key in varied_keys}
    problems = []
    for where, prefix, keys in ((str(path), "set.", list(given_set)),
                                ("--set", "", [parse_override(text)[0] for text in overrides])):
        for key in keys:
            parts = tuple(key_parts(key))
            swept = next((name for v, name in varied.items() if v[:len(parts)] == parts or parts[:len(v)] == v),
                         None)
            if swept is not None:
                problems.append(BadInput(f"is {what.format(key=swept)}", where, prefix + key))
    if problems:
        raise BadInput.every(problems)
