"""Scene schema: defaults, overrides, cross-field rules, compilation to solver.Problem, bundled files."""
import tomllib

import numpy as np
import pytest

import solver
from biostudy.calibration.problem import load_calibration
from biostudy.errors import BadInput
from biostudy.inputs import bundled
from biostudy.inputs.keys import parse_override
from biostudy.inputs.scene import Scene, key_info, load_scene
from biostudy.inputs.tomltext import dumps
from biostudy.plans import catalogue
from biostudy.plans.study import load_study


def test_defaults_are_the_solvers_and_the_papers(tiny_scene):
    scene = load_scene(tiny_scene)
    problem = scene.problem()
    assert problem.params == solver.Parameters(g=1e8)
    assert problem.numerics == solver.Numerics()
    assert problem.mechanics is None and problem.laws.consumption == "first-order"
    assert problem.name == "tiny"
    assert np.allclose(problem.output_times, [0, 0.1, 0.2])


def test_problem_has_the_scenes_masks_in_solver_order(tiny_scene):
    problem = load_scene(tiny_scene, ["biofilm.0.value=0.5", "nutrient.0.value=0.8"]).problem()
    grid = problem.grid
    assert grid.shape == (16, 16) and problem.phi0.shape == (16, 16)
    x, y = grid.cell_coordinates()
    disc = (x - 8) ** 2 + (y - 8) ** 2 <= 9
    assert np.array_equal(problem.phi0, np.where(disc, 0.5, 0.0))
    corner = (x > 14) & (y > 14)
    assert np.array_equal(problem.nutrient_held, corner)
    assert np.all(problem.nutrient_value[corner] == 0.8)
    # the obstacle box x in [0, 3], y in [12, 16]: 3 x 4 cells, the row index is y
    assert problem.obstacle.sum() == 12 and problem.obstacle[15, 0] and not problem.obstacle[0, 15]


def test_biofilm_inside_an_obstacle_is_removed(tiny_scene):
    problem = load_scene(tiny_scene, ["biofilm.0.center=[2.0, 14.0]"]).problem()
    assert problem.phi0.sum() > 0 and not problem.phi0[problem.obstacle].any()


def test_overrides_are_toml_values_on_dotted_keys(tiny_scene):
    scene = load_scene(tiny_scene, ["grid.shape=[16,18]", "params.g=1e10", "r=0", "mechanics.enabled=false",
                                    "model.consumption=zero-order", "time.output_times=[0, 0.05]",
                                    "numerics.advection='tvd'", "biofilm.0.radius=2"])
    assert scene.grid.shape == [16, 18] and scene.params.g == 1e10 and scene.params.r == 0
    assert scene.mechanics is not None and not scene.mechanics.enabled
    problem = scene.problem()
    assert problem.mechanics is None and problem.laws.consumption == "zero-order"
    assert problem.numerics.advection == "tvd"
    assert list(problem.output_times) == [0, 0.05, 0.2]  # t_end added


@pytest.mark.parametrize("text, expected", [
    ("params.g=1e10", ("params.g", 1e10)),
    ("grid.shape=[40, 40, 40]", ("grid.shape", [40, 40, 40])),
    ("mechanics.enabled=false", ("mechanics.enabled", False)),
    ("model.consumption=zero-order", ("model.consumption", "zero-order")),
    ("model.consumption=\"zero-order\"", ("model.consumption", "zero-order")),
    (" time.steps = 10 ", ("time.steps", 10)),
])
def test_parse_override(text, expected):
    assert parse_override(text) == expected


def test_mechanics_table_switches_it_on(tiny_scene):
    problem = load_scene(tiny_scene, ["mechanics.clamp=['y-']", "mechanics.every=2"]).problem()
    assert problem.mechanics == solver.MechanicsSetup(clamp=("y-",), every=2)


def test_scene_toml_text_reads_back_to_the_same_scene(tiny_scene, tmp_path):
    scene = load_scene(tiny_scene, ["params.k_alpha=2.5e-3", "time.output_times=[0, 0.05, 0.2]"])
    text = scene.to_toml()
    assert "k_alpha = 0.0025" in text and "g = 1e+08" in text
    again = tmp_path / "again.toml"
    again.write_text(text)
    assert load_scene(again) == scene


def test_toml_writer_round_trips():
    data = {"a": 1, "b": 1e-300, "c": [1.5, 2.0], "s": 'quote " and \\ and µ', "t": True,
            "nested": {"x": [[1, 2], [3, 4]], "deep": {"y": -0.0}}, "aot": [{"k": 1}, {"k": 2, "v": "w"}]}
    assert tomllib.loads(dumps(data)) == data


@pytest.mark.parametrize("override, key, problem", [
    ("params.d=-1", "params.d", "must be > 0 (got -1)"),
    ("params.nu=0.5", "params.nu", "must be < 0.5 (got 0.5)"),
    ("params.gg=1", "params.gg", "unknown key (did you mean 'g'?)"),
    ("time.steps=0", "time.steps", "must be >= 1"),
    ("time.output_times=[0, 0.3]", "time.output_times[1]", "outside [0, t_end = 0.2]"),
    ("time.output_times=[0.1, 0.05]", "time.output_times[1]", "does not come after"),
    ("grid.spacing=0", "grid.spacing", "must be > 0"),
    ("biofilm.0.center=[20.0, 8.0]", "biofilm[0].center", "outside the grid"),
    ("nutrient.0.lower=[0.0, 12.0]", "nutrient[0]", "lies inside obstacle[0]"),
    ("obstacle.0.upper=[3.0, 30.0]", "obstacle[0].upper", "y = 30 µm lies outside the grid [0, 16] µm"),
    ("numerics.max_substeps=10", "numerics.max_substeps", "must be >= time.steps = 20"),
    ("mechanics.clamp=['z-']", "mechanics.clamp", "'z-' is not a face of a 2-D grid (faces: x-, x+, y-, y+)"),
    ("mechanics.slide=['x-', 'x-']", "mechanics.slide", "lists 'x-' twice"),
    ("mechanics={clamp=['x-'], slide=['y-', 'x-']}", "mechanics.slide", "x- already clamped"),
    # a face source's face: at its key, not behind the union's tag (nutrient[0].face.face)
    ("nutrient.0={shape='face', face='q-'}", "nutrient[0].face", "must be 'x-', 'x+', 'y-', 'y+', 'z-' or 'z+' "
                                                                 "(got 'q-')"),
    ("nutrient.0={shape='face', face='z+'}", "nutrient[0].face", "'z+' is not a face of a 2-D grid"),
    ("nutrient.0={value=0.5}", "nutrient[0]", "needs a 'shape' key (box, sphere, cylinder, mask, image or face)"),
    ("biofilm.0.shape=cone", "biofilm[0]", "unknown shape 'cone'"),
])
def test_bad_values_name_the_key(tiny_scene, override, key, problem):
    with pytest.raises(BadInput) as error:
        load_scene(tiny_scene, [override])
    line = str(error.value)
    assert line.startswith(f"--set: {key}: "), line  # the override gave the value, not the scene file
    assert problem in line
    assert "\n" not in line


def test_obstacle_covering_everything_or_a_source_is_rejected(tiny_scene):
    with pytest.raises(BadInput, match=r"obstacle: covers every cell"):
        load_scene(tiny_scene, ["obstacle.0.lower=[0.0, 0.0]", "obstacle.0.upper=[16.0, 16.0]"])


def test_every_error_is_told(tiny_scene):
    """Every problem, one line each, each naming where its value was given (the scene file or --set)."""
    with pytest.raises(BadInput) as caught:
        load_scene(tiny_scene, ["params.d=-1", "params.k=0"])
    assert caught.value.lines() == ["--set: params.d: must be > 0 (got -1)",
                                    "--set: params.k: must be > 0 (got 0)"]
    tiny_scene.write_text(tiny_scene.read_text().replace("g = 1e8", "g = 1e8\nk = 0.0"))
    with pytest.raises(BadInput) as caught:
        load_scene(tiny_scene, ["params.d=-1"])
    assert caught.value.lines() == ["--set: params.d: must be > 0 (got -1)",
                                    f"{tiny_scene}: params.k: must be > 0 (got 0)"]


def test_mask_file_relative_to_the_scene(write_toml, tmp_path):
    array = np.zeros((16, 16), bool)
    array[:2, :] = True  # x < 2: a wall on the x- side
    np.save(tmp_path / "wall.npy", array)
    path = write_toml("m.toml", "[grid]\nshape = [16, 16]\n[[obstacle]]\nshape = \"mask\"\npath = \"wall.npy\"\n")
    problem = load_scene(path).problem()
    assert problem.obstacle.sum() == 32 and problem.obstacle[:, :2].all()
    with pytest.raises(BadInput, match=r"obstacle\[0\]\.path: mask file 'nope.npy' not found"):
        load_scene(path, ["obstacle.0.path=nope.npy"])
    with pytest.raises(BadInput, match=r"obstacle\[0\]\.path: array has shape \[16, 16\]"):
        load_scene(path, ["grid.shape=[16, 8]"])


def test_key_info_gives_units_for_sweep_coordinates():
    assert key_info("g") == ("consumption g (0: no consumption), 1/T*", "1/T*")
    assert key_info("params.d")[1] == "um^2/T*"
    assert key_info("biofilm.0.radius") == ("radius, µm", "um")
    assert key_info("grid.spacing")[1] == "um"


def test_json_schema_documents_units_and_meaning():
    schema = Scene.model_json_schema()
    params = schema["$defs"]["Params"]["properties"]
    assert params["d"]["units"] == "um^2/T*" and "diffusivity" in params["d"]["description"]
    assert params["d"]["exclusiveMinimum"] == 0


def test_every_bundled_file_validates():
    entries = bundled.entries()
    assert any(e.kind == "scene" for e in entries) and any(e.kind == "study" for e in entries)
    for entry in entries:
        assert entry.kind in ("scene", "study", "stability", "calibration"), entry
        assert entry.description, entry
        if entry.kind == "scene":
            load_scene(entry.path).problem()
        elif entry.kind == "study":
            assert load_study(entry.path).cases
        elif entry.kind == "calibration":
            assert load_calibration(entry.path).measurements
        else:
            plan = catalogue.load(entry.path)
            assert plan.cases
            for scene in plan.scenes.values():
                scene.problem()


def test_directional_scene_is_the_papers_4_1():
    problem = load_scene(bundled.resolve("directional")).problem()
    assert problem.grid.shape == (20, 20, 20) and problem.grid.spacing == 1.0
    assert problem.t_end == 1.0 and problem.steps == 1000 and len(problem.output_times) == 21
    x, y, z = problem.grid.cell_coordinates()
    assert np.array_equal(problem.phi0, ((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2 <= 25).astype(float))
    assert np.array_equal(problem.nutrient_held, (x > 19) & (y > 19) & (z > 19))  # the corner cell, as the paper
    assert problem.params == solver.Parameters()


def test_agar_scenes_hold_the_nutrient_on_the_bottom_face():
    """Paper 4.2: c = 1 on the bottom plane itself; the colony (5 µm across) stands on it, its cells free."""
    for name in ("agar-g1e8", "agar-g1e10"):
        problem = load_scene(bundled.resolve(name)).problem()
        assert problem.nutrient_faces == (("z-", 1.0),) and not problem.nutrient_held.any()
        x, y, z = problem.grid.cell_coordinates()
        colony = problem.phi0 == 1.0
        assert colony[0].any() and np.ptp(x[colony]) + 1 <= 5 and np.ptp(y[colony]) + 1 <= 5


def test_a_face_held_twice_is_refused_by_the_scene_and_by_the_solver(write_toml):
    """Two held values on one face would add its boundary flux twice (Nutrient sums the faces' 2/h² terms)."""
    path = write_toml("dup.toml", """\
        [grid]
        shape = [8, 8]
        spacing = 1.0
        [time]
        t_end = 0.01
        steps = 2
        [[biofilm]]
        shape = "box"
        lower = [2.0, 0.0]
        upper = [5.0, 2.0]
        [[nutrient]]
        shape = "face"
        face = "y-"
        [[nutrient]]
        shape = "face"
        face = "y-"
        value = 0.5
        """)
    with pytest.raises(BadInput, match=r"nutrient\[1\]\.face: 'y-' is held twice$"):
        load_scene(path)
    grid = solver.Grid((8, 8), 1.0)
    with pytest.raises(ValueError, match=r"nutrient_faces\[1\]: 'y-' is held twice$"):  # the same rule, the same words
        solver.Problem(grid=grid, phi0=np.zeros(grid.cells_shape), nutrient_held=np.zeros(grid.cells_shape, bool),
                       nutrient_faces=(("y-", 1.0), ("y-", 0.5)), t_end=0.01, steps=2, output_times=[0.0, 0.01])


def _first_cells(count: int, shape=(16, 16)) -> np.ndarray:
    """The first `count` cells of the tiny grid in the solver's order (the row y = 0 first)."""
    cells = np.zeros(shape[0] * shape[1], bool)
    cells[:count] = True
    return cells.reshape(shape)


@pytest.mark.parametrize("scene_override, scene_said, problem_change, problem_said", [
    ("time.output_times=[0.1, 0.05]", "time.output_times[1]: 0.05 does not come after 0.1",
     {"output_times": [0.1, 0.05]}, "output_times[1]: 0.05 does not come after 0.1"),
    ("time.output_times=[0.1, 0.3]", "time.output_times[1]: 0.3 lies outside [0, t_end = 0.2]",
     {"output_times": [0.1, 0.3]}, "output_times[1]: 0.3 lies outside [0, t_end = 0.2]"),
    ("nutrient.0.lower=[0.0, 12.0]", "nutrient[0]: lies inside obstacle[0] (12 cells in common)",
     {"obstacle": _first_cells(5), "nutrient_held": _first_cells(2)},
     "nutrient_held: lies inside an obstacle (2 cells in common)"),
    ("obstacle.0={shape='box', lower=[0.0, 0.0], upper=[16.0, 16.0]}", "obstacle: covers every cell of the grid",
     {"obstacle": _first_cells(256)}, "obstacle: covers every cell of the grid"),
])
def test_a_rule_between_keys_is_the_solvers_in_its_words(tiny_scene, scene_override, scene_said, problem_change,
                                                          problem_said):
    """The scene tells a broken rule at its key with the words the solver's `Problem` uses for it."""
    with pytest.raises(BadInput) as error:
        load_scene(tiny_scene, [scene_override])
    assert str(error.value) == f"--set: {scene_said}"
    problem = load_scene(tiny_scene).problem()
    given = {name: getattr(problem, name) for name in ("grid", "t_end", "steps", "output_times")}
    with pytest.raises(ValueError) as refused:
        solver.Problem(**{**given, "phi0": np.zeros((16, 16)), "nutrient_held": _first_cells(0), **problem_change})
    assert str(refused.value) == problem_said
