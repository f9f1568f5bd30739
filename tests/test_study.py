"""Study files: sweep expansion (grid, zip), readable stable case ids, validation of every case up front."""
import os
import subprocess
import sys

import pytest

from biostudy.errors import BadInput
from biostudy.inputs.keys import dimension, id_text
from biostudy.plans.study import load_study


def test_grid_sweep_expands_every_combination_last_key_fastest(tiny_study):
    plan = load_study(tiny_study)
    assert plan.mode == "grid" and plan.keys == ["g", "r"]
    assert [c.id for c in plan.cases] == ["g=1e+08_r=50", "g=1e+08_r=100", "g=1e+09_r=50", "g=1e+09_r=100"]
    assert [c.index for c in plan.cases] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    scene = plan.scenes["g=1e+09_r=50"]
    assert scene.params.g == 1e9 and scene.params.r == 50 and scene.name == "tiny"
    assert plan.scenes["g=1e+08_r=100"].params.r == 100


def test_case_ids_do_not_depend_on_when_or_where_they_are_made(tiny_study, tmp_path):
    """Resume finds a case by its id: another process, with another hash seed and working directory, on
    another day, makes the same ids (nothing random, hashed per process or from the clock goes in)."""
    here = [c.id for c in load_study(tiny_study).cases]
    script = ("import sys; from biostudy.plans.study import load_study; "
              "print(' '.join(c.id for c in load_study(sys.argv[1]).cases))")
    for seed in ("1", "2"):
        there = subprocess.run([sys.executable, "-c", script, str(tiny_study)], cwd=tmp_path, check=True, text=True,
                               capture_output=True, env={**os.environ, "PYTHONHASHSEED": seed}).stdout.split()
        assert there == here
    assert here == ["g=1e+08_r=50", "g=1e+08_r=100", "g=1e+09_r=50", "g=1e+09_r=100"]


def test_zip_sweep_pairs_values_and_reaches_any_dotted_key(write_toml, tiny_scene):
    path = write_toml("z.toml", """\
        scene = "tiny.toml"
        [set]
        "time.steps" = 10
        [sweep]
        mode = "zip"
        "grid.shape" = [[16, 16], [20, 20]]
        numerics.advection = ["upwind", "tvd"]
        params.k_alpha = [0.001, 0.0025]
        """)
    plan = load_study(path)
    assert [c.id for c in plan.cases] == ["grid_shape=16x16_numerics_advection=upwind_k_alpha=0.001",
                                          "grid_shape=20x20_numerics_advection=tvd_k_alpha=0.0025"]
    second = plan.scenes[plan.cases[1].id]
    assert second.grid.shape == [20, 20] and second.numerics.advection == "tvd" and second.time.steps == 10
    assert plan.common == {"time.steps": 10}


def test_labels_and_dimension_names():
    assert [id_text(v) for v in (1e8, 50, 50.0, 0.0025, 1 / 3, True, [20, 20, 20], "zero-order", "a b/c")] == \
        ["1e+08", "50", "50", "0.0025", "0.3333333333333333", "true", "20x20x20", "zero-order", "a-b-c"]
    assert dimension("g") == dimension("params.g") == "g"
    assert dimension("grid.shape") == "grid_shape" and dimension("biofilm.0.radius") == "biofilm_0_radius"


def test_cli_overrides_apply_to_every_case(tiny_study):
    plan = load_study(tiny_study, ["time.steps=5"])
    assert all(s.time.steps == 5 for s in plan.scenes.values())


@pytest.mark.parametrize("text, where", [
    ('scene = "tiny.toml"\n[sweep]\ng = 1e8\n', "sweep.g: must be a non-empty list"),
    ('scene = "tiny.toml"\n[sweep]\ng = []\n', "sweep.g: must be a non-empty list"),
    ('scene = "tiny.toml"\n[sweep]\nmode = "zip"\ng = [1.0, 2.0]\nr = [1.0]\n', "sweep.r: has 1 values"),
    ('scene = "tiny.toml"\n[sweep]\nmode = "all"\ng = [1.0]\n', "sweep.mode: must be 'grid' or 'zip'"),
    ('scene = "tiny.toml"\n[sweep]\ng = [1.0, 1.0]\n', "sweep.g: lists 1 twice"),
    ('scene = "tiny.toml"\n[sweep]\ng = [1.0]\n"params.g" = [2.0]\n', "sweep.params.g: is the same key as g"),
    ('scene = "tiny.toml"\n[sweep]\n', "sweep: sweeps no key"),
    ('scene = "nope.toml"\n[sweep]\ng = [1.0]\n', "scene: scene file 'nope.toml' not found"),
    ('scene = "tiny.toml"\nsweeps = 1\n[sweep]\ng = [1.0]\n', "sweeps: unknown key (did you mean 'sweep'?)"),
    ('[sweep]\ng = [1.0]\n', "scene: required key is missing"),
    ('scene = "tiny.toml"\n[sweep]\ng = [1e8, -1.0]\n', "case g=-1: params.g: must be >= 0 (got -1)"),
    ('scene = "tiny.toml"\n[sweep]\ngg = [1.0]\n', "case gg=1: gg: unknown key"),
    ('scene = "tiny.toml"\n[set]\n"biofilm.3.radius" = 1.0\n[sweep]\ng = [1.0]\n', "set.biofilm.3.radius: there is no"),
    ('scene = "tiny.toml"\n[sweep]\n"grid.shape" = [[16, 16], [8, 8]]\n',
     "case grid_shape=8x8: nutrient[0].lower: x = 14 µm lies outside"),
])
def test_bad_studies_name_the_file_and_key(write_toml, tiny_scene, text, where):
    path = write_toml("bad.toml", text)
    with pytest.raises(BadInput) as error:
        load_study(path)
    assert str(error.value).startswith(f"{path}: {where}"), str(error.value)


def test_scene_and_study_files_are_told_apart(tiny_scene, tiny_study):
    with pytest.raises(BadInput, match="this is a scene file"):
        load_study(tiny_scene)
    from biostudy.inputs.scene import load_scene
    with pytest.raises(BadInput, match="this is a study file"):
        load_scene(tiny_study)


def test_a_designs_cases_are_the_same_before_and_after_its_checks(tiny_scene, write_toml):
    """No hidden state: the cases of a sampled study round integer keys (time.steps) whether or not the checks
    against the base scene ran first (they only validate)."""
    from biostudy.plans.study import Study

    ranges = {"time": {"steps": [10, 40]}, "g": [1e7, 1e9]}
    data = {"name": "s", "scene": str(tiny_scene), "sample": {"method": "lhs", "n": 6, "seed": 3, "ranges": ranges}}
    before = Study.model_validate(data).cases()
    checked = Study.model_validate(data)
    checked.check({"grid": {"shape": [16, 16]}}, tiny_scene, tiny_scene)
    after = checked.cases()
    assert [c.values for c in before] == [c.values for c in after]
    steps = [c.values["time.steps"] for c in before]
    assert all(isinstance(s, int) and 10 <= s <= 40 for s in steps) and len(set(steps)) > 1
