"""A calibration as a PEtab problem and back (issue 36.1): the tables biostudy writes are read by petab's own
library and pass its linter, table by table as `petablint -m -c -o -p` does (its same two calls) and, with the
scene as petab's model (`petab_scene_model`), with every cross-table check; problem.yaml passes petab's schema;
`load_calibration` of the problem.yaml is the calibration it came from.  Nothing is simulated (an 8 x 8 colony
is only validated)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_calibration_hostile import SCENE

from biostudy.calibration.petab_out import NotPetab, problem_texts
from biostudy.calibration.problem import load_calibration
from biostudy.errors import BadInput

petab = pytest.importorskip("petab.v1")

TABLE = """\
observableId\tsimulationConditionId\ttime\tmeasurement\tnoiseParameters\tdatasetId\treplicateId
biomass\tfull\t3\t0.52\t0.1\tday1\tA
biomass\tfull\t6\t0.81\tsigma_biomass\tday1\tA
biomass\thalf\t3\t0.47\tsigma_biomass\tday2\tB
max_thickness\thalf\t6\t1.6\t0.2\tday2\t
"""
CALIBRATION = """\
scene = "speck.toml"
[set]
"time.steps" = 8
[data]
measurements = "t.tsv"
time_unit = "min"
t_ref = "1 h"
[estimate]
g = [1e7, 1e10, "log"]
r = [20.0, 250.0]
[conditions.full]
[conditions.half]
"nutrient.0.value" = 0.5
[conditions.half.estimate]
r = [10.0, 300.0, "log"]
[method]
starts = 2
"""


@pytest.fixture
def calibration(tmp_path) -> Path:
    (tmp_path / "speck.toml").write_text(SCENE)
    (tmp_path / "t.tsv").write_text(TABLE)
    (tmp_path / "c.toml").write_text(CALIBRATION)
    return tmp_path / "c.toml"


def written(plan, directory: Path) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    for name, text in problem_texts(plan, directory, dict(plan.spec.set)).items():
        (directory / name).write_text(text)
    return directory


def test_petabs_library_reads_the_tables_and_its_linter_accepts_them(calibration, tmp_path):
    from petab.v1.lint import lint_problem
    from petab.v1.yaml import validate_yaml_syntax
    from petab_scene_model import SceneModel

    plan = load_calibration(calibration)
    folder = written(plan, tmp_path / "out" / "petab")
    tables = {"condition_file": "conditions.tsv", "measurement_file": "measurements.tsv",
              "parameter_file": "parameters.tsv", "observable_files": "observables.tsv"}
    with pytest.warns(DeprecationWarning):  # petab would rather read problem.yaml, whose model is not SBML here
        problem = petab.Problem.from_files(**{k: folder / v for k, v in tables.items()})
    assert not lint_problem(problem)  # False: no error; petablint -m -c -o -p makes these two calls
    problem.model = SceneModel(plan.base)
    assert not lint_problem(problem)  # and with every cross-table check
    validate_yaml_syntax(folder / "problem.yaml")
    assert list(problem.condition_df.index) == ["full", "half"]
    assert problem.condition_df.loc["half", "nutrient__0__value"] == 0.5
    assert problem.condition_df.loc["full", "nutrient__0__value"] == 1.0  # the scene's own value
    assert problem.condition_df.loc["half", "r"] == "r__half" and problem.condition_df.loc["full", "r"] == "r__shared"
    parameters = problem.parameter_df
    assert list(parameters.index) == ["g", "r__shared", "r__half", "sigma_biomass"]
    assert parameters.loc["g", "parameterScale"] == "log10" and parameters.loc["r__shared", "parameterScale"] == "lin"
    assert (parameters.loc["r__half", ["lowerBound", "upperBound", "nominalValue"]].tolist() == [10.0, 300.0, 100.0])
    assert list(problem.measurement_df["simulationConditionId"]) == ["full", "full", "half", "half"]
    assert list(problem.measurement_df["noiseParameters"].astype(str)) == ["0.1", "sigma_biomass", "sigma_biomass",
                                                                           "0.2"]
    assert set(problem.observable_df.index) == {"biomass", "max_thickness"}


def test_a_problem_yaml_is_read_as_the_calibration_it_came_from(calibration, tmp_path):
    plan = load_calibration(calibration)
    back = load_calibration(written(plan, tmp_path / "out" / "petab") / "problem.yaml")
    assert [(p.name, p.key, p.range, p.conditions) for p in back.parameters] == [
        (p.name, p.key, p.range, p.conditions) for p in plan.parameters]
    assert [(m.observable, m.condition, m.time, m.value, m.sigma, m.noise, m.dataset, m.replicate)
            for m in back.measurements] == [(m.observable, m.condition, m.time, m.value, m.sigma, m.noise, m.dataset,
                                             m.replicate) for m in plan.measurements]
    np.testing.assert_array_equal(back.times, plan.times)
    assert {n: s.to_toml() for n, s in back.scenes.items()} == {n: s.to_toml() for n, s in plan.scenes.items()}
    assert back.spec.method == plan.spec.method and back.spec.data.t_ref == "1 h"
    assert back.scene_file.resolve() == plan.scene_file.resolve() and back.spec.name == "out"
    from test_calibration_hostile import invoke

    shown = invoke("show", tmp_path / "out" / "petab" / "problem.yaml")  # what running it needs, as for its TOML
    assert shown.exit_code == 0 and shown.stdout.startswith("out: 3 parameters, 4 measurements, 2 conditions of "
                                                            "speck.toml"), shown.output


def test_a_calibration_petab_cannot_hold_is_said_in_words(tmp_path, calibration):
    (tmp_path / "c.toml").write_text(CALIBRATION.replace("[conditions.half]", "[conditions.half-strength]")
                                     .replace("[conditions.half.estimate]", "[conditions.half-strength.estimate]"))
    (tmp_path / "t.tsv").write_text(TABLE.replace("\thalf\t", "\thalf-strength\t"))
    with pytest.raises(NotPetab, match="the condition 'half-strength' is not a PEtab id"):
        problem_texts(load_calibration(tmp_path / "c.toml"), tmp_path, {})


def bad(folder: Path, name: str, old: str, new: str) -> str:
    path = folder / name
    path.write_text(path.read_text().replace(old, new))
    with pytest.raises(BadInput) as raised:
        load_calibration(folder / "problem.yaml")
    assert len(raised.value.lines()) == 1
    return str(raised.value)


@pytest.mark.parametrize("name, old, new, expected", [
    ("observables.tsv", "biomass\tlin", "2 * biomass\tlin", "observables.tsv: line 2: observableFormula: '2 * "
                                                            "biomass': biostudy computes its observables by name"),
    ("observables.tsv", "\tnormal\n", "\tlaplace\n", "line 2: noiseDistribution: 'laplace': biostudy fits normal"),
    ("parameters.tsv", "\tlog10\t", "\tlogit\t", "parameters.tsv: line 2: parameterScale: 'logit': lin, log or "
                                                 "log10"),
    ("problem.yaml", "format_version: 1", "format_version: 2", "problem.yaml: format_version 2: biostudy reads PEtab "
                                                               "v1 problems"),
    ("problem.yaml", "  - measurements.tsv", "  - measurements.tsv\n  - more.tsv",
     "problem.yaml: problems[0].measurement_files: must list one file"),
    ("problem.yaml", "parameter_file: parameters.tsv", "parameter_file: [", "problem.yaml: line 4: not YAML"),
    ("conditions.tsv", "\t0.5\t", "\tr__half\t", "parameters.tsv: r__half sets nutrient.0.value in half, r in half: a "
                                                 "parameter sets one key"),
])
def test_a_problem_biostudy_cannot_compute_is_one_line(calibration, tmp_path, name, old, new, expected):
    folder = written(load_calibration(calibration), tmp_path / "out" / "petab")
    assert expected in bad(folder, name, old, new)


def test_calibrate_writes_its_petab_problem_reads_it_back_and_keeps_a_users_edit(tmp_path):
    """`biostudy calibrate` writes DIR/petab/ (calibration.nc recording each file's sha256); `biostudy calibrate
    DIR/petab/problem.yaml` is the same calibration (the same estimate from the same table); an edited file of
    DIR/petab/ is the user's: refused, --force or not."""
    import hashlib

    import xarray as xr
    from test_calibration_hostile import calibration, invoke, one_line

    from biostudy.calibration.petab_out import NAMES

    rows = "observableId\ttime\tmeasurement\tnoiseParameters\nbiomass\t0.05\t3.1\t0.2\nbiomass\t0.1\t3.6\t0.2\n"
    path = calibration(tmp_path, rows, "[estimate]\nr = [50.0, 150.0]\n[method]\nstarts = 1\nprofiles = false\n")
    first = invoke("calibrate", path, "-o", tmp_path / "out", "-q")
    assert first.exit_code == 0, first.output
    folder = tmp_path / "out" / "petab"
    assert sorted(p.name for p in folder.iterdir()) == sorted(NAMES)
    with xr.open_dataset(tmp_path / "out" / "calibration.nc") as ds:
        for name in NAMES:
            assert ds.attrs[f"{name.replace('.', '_')}_sha256"] == hashlib.sha256((folder / name).read_bytes()
                                                                                  ).hexdigest(), name
        estimate = float(ds.estimate.values[0])
    again = invoke("calibrate", folder / "problem.yaml", "-o", tmp_path / "back", "-q")
    assert again.exit_code == 0, again.output
    with xr.open_dataset(tmp_path / "back" / "calibration.nc") as ds:
        assert float(ds.estimate.values[0]) == pytest.approx(estimate, rel=1e-9)
    with (folder / "parameters.tsv").open("a") as handle:
        handle.write("mine\tmine\tlin\t0\t1\t0.5\t0\n")
    for force in ([], ["--force"]):
        one_line(invoke("calibrate", path, "-o", tmp_path / "out", "-q", *force),
                 "parameters.tsv: exists and is not a file biostudy wrote")
