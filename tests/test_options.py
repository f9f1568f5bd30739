"""The solver's options: declared once on `solver.Laws`, `solver.Numerics` and `solver.MechanicsSetup`
(`solver.declared.option`), they are the scene's [model], [numerics] and [mechanics] keys, with the same types,
defaults, meanings, units and ranges, and the rules between them are the solver's, told at the scene's key."""
import json
import subprocess
import sys
import textwrap

import pytest

import solver
from biostudy.errors import BadInput
from biostudy.execution.identity import fingerprint
from biostudy.inputs.scene import MechanicsSpec, Model, NumericsSpec, load_scene
from solver.declared import OptionError, option_infos


@pytest.mark.parametrize("settings, table, own", [(solver.Numerics, NumericsSpec, []), (solver.Laws, Model, []),
                                                  (solver.MechanicsSetup, MechanicsSpec, ["enabled"])])
def test_every_option_is_a_scene_key_as_declared(settings, table, own):
    infos = option_infos(settings)
    assert list(table.model_fields) == own + [info.name for info in infos]
    for info in infos:
        key = table.model_fields[info.name]
        default = list(info.default) if isinstance(info.default, tuple) else info.default
        assert key.default == default and key.description == info.help
        assert (key.json_schema_extra or {}).get("units") == info.units
    assert table().solver_settings() == settings()


def test_the_solver_options_own_rules_are_its_own():
    with pytest.raises(OptionError, match=r"^slide: x- already clamped$"):
        solver.MechanicsSetup(clamp=("x-",), slide=("y-", "x-"))
    with pytest.raises(OptionError, match=r"^clamp: lists 'y-' twice$"):
        solver.MechanicsSetup(clamp=("y-", "y-"))


# Run in a fresh interpreter: the solver's settings grow by one option each *before* biostudy is imported, as they
# would if the options had been written into solver/problem.py.
GROWN = textwrap.dedent("""\
    import dataclasses, json, sys
    import solver, solver.problem as problem

    @dataclasses.dataclass(frozen=True)
    class Numerics(problem.Numerics):
        smoothing: float = problem.option(0.25, "test smoothing of the growth velocity", "um", ge=0, lt=1)

    @dataclasses.dataclass(frozen=True)
    class MechanicsSetup(problem.MechanicsSetup):
        shell: tuple[problem.Face, ...] = problem.option((), "test faces of a shell")

    problem.Numerics = solver.Numerics = Numerics
    problem.MechanicsSetup = solver.MechanicsSetup = MechanicsSetup

    from biostudy.errors import BadInput
    from biostudy.execution.identity import fingerprint
    from biostudy.inputs.scene import Scene, key_info, load_scene

    scene = sys.argv[1]
    schema = Scene.model_json_schema()["$defs"]
    found = {"smoothing": schema["NumericsSpec"]["properties"]["smoothing"],
             "shell": schema["MechanicsSpec"]["properties"]["shell"],
             "key_info": key_info("numerics.smoothing"),
             "default": fingerprint(load_scene(scene, ["mechanics.clamp=['y-']"]).problem())}
    problem = load_scene(scene, ["numerics.smoothing=0.5", "mechanics.shell=['x+']"]).problem()
    found["set"] = [problem.numerics.smoothing, list(problem.mechanics.shell), fingerprint(problem)]
    found["bad"] = []
    for bad in ("numerics.smoothing=1.5", "numerics.smothing=0.5", "mechanics.shell=['q-']"):
        try:
            load_scene(scene, [bad])
        except BadInput as error:
            found["bad"].append(str(error))
    print(json.dumps(found))
    """)


def test_an_option_added_to_the_solver_reaches_the_scene(tiny_scene, tmp_path):
    done = subprocess.run([sys.executable, "-c", GROWN, str(tiny_scene)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout.splitlines()[-1])
    smoothing = found["smoothing"]
    assert smoothing["default"] == 0.25 and smoothing["minimum"] == 0 and smoothing["exclusiveMaximum"] == 1
    assert smoothing["description"] == "test smoothing of the growth velocity" and smoothing["units"] == "um"
    assert found["key_info"] == ["test smoothing of the growth velocity", "um"]
    assert found["shell"]["default"] == [] and found["shell"]["items"]["enum"] == list(solver.problem.FACES)
    assert found["set"][:2] == [0.5, ["x+"]]
    # at its default the new option leaves a finished case's identity as it was; set, it is another problem
    assert found["default"] == fingerprint(load_scene(tiny_scene, ["mechanics.clamp=['y-']"]).problem())
    assert found["set"][2] != found["default"]
    assert found["bad"] == ["--set: numerics.smoothing: must be < 1 (got 1.5)",
                            "--set: numerics.smothing: unknown key (did you mean 'smoothing'?)",
                            "--set: mechanics.shell[0]: must be 'x-', 'x+', 'y-', 'y+', 'z-' or 'z+' (got 'q-')"]


def test_a_rule_between_options_is_told_at_its_scene_key(tiny_scene):
    with pytest.raises(BadInput) as error:
        load_scene(tiny_scene, ["mechanics.clamp=['x-', 'y-']", "mechanics.slide=['y-']"])
    assert error.value.lines() == ["--set: mechanics.slide: y- already clamped"]
