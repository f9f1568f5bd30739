"""What a new user meets first (issue 36.6): a study or calibration file naming a bundled scene as the command line
does (scene = "agar2d")."""
from __future__ import annotations

import pytest

from biostudy.calibration.problem import load_calibration
from biostudy.errors import BadInput
from biostudy.inputs.bundled import studies_dir
from biostudy.plans.study import load_study


def test_a_study_or_calibration_file_may_name_a_bundled_scene(tmp_path):
    (tmp_path / "s.toml").write_text('scene = "agar2d"\n[sweep]\ng = [1e8, 1e9]\n')
    plan = load_study(tmp_path / "s.toml")
    assert plan.scene_file == studies_dir() / "agar2d.toml" and len(plan.cases) == 2
    (tmp_path / "t.tsv").write_text("observableId\ttime\tmeasurement\tnoiseParameters\nbiomass\t0.1\t3.0\t0.2\n"
                                    "biomass\t0.2\t4.0\t0.2\n")
    (tmp_path / "c.toml").write_text('scene = "agar2d.toml"\n[data]\nmeasurements = "t.tsv"\n[estimate]\n'
                                     'g = [1e7, 1e10, "log"]\n')
    assert load_calibration(tmp_path / "c.toml").scene_file == studies_dir() / "agar2d.toml"


def test_a_scene_file_beside_the_study_wins_and_a_name_that_is_neither_is_one_line(tmp_path):
    (tmp_path / "agar2d.toml").write_text((studies_dir() / "agar2d.toml").read_text().replace(
        "[grid]", '[grid]\n# mine\n', 1))
    (tmp_path / "s.toml").write_text('scene = "agar2d"\n[sweep]\ng = [1e8]\n')
    (tmp_path / "agar2d").mkdir()  # a directory of that name is not a scene file
    assert load_study(tmp_path / "s.toml").scene_file == studies_dir() / "agar2d.toml"
    (tmp_path / "s.toml").write_text('scene = "agar2d.toml"\n[sweep]\ng = [1e8]\n')
    assert load_study(tmp_path / "s.toml").scene_file == tmp_path / "agar2d.toml"
    (tmp_path / "s.toml").write_text('scene = "agar2e"\n[sweep]\ng = [1e8]\n')
    with pytest.raises(BadInput, match=r"s.toml: scene: scene file 'agar2e' not found \(looked for .*agar2e\) nor a "
                                       r"bundled scene of that name"):
        load_study(tmp_path / "s.toml")


def blocks(section: str) -> list[str]:
    """The shell blocks of a README section."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    body = text.split(f"## {section}\n", 1)[1].split("\n## ", 1)[0]
    return [part.split("```", 1)[0] for part in body.split("```sh\n")[1:]]


def test_the_first_run_uses_the_biostudy_the_set_up_installed():
    """After the set-up's `python3 -m venv .venv && .venv/bin/pip install ...`, a bare `biostudy` is not on the
    PATH: "A first run" activates that venv before its first biostudy command (issue 36.6)."""
    set_up = blocks("Set up")[0]
    assert "python3 -m venv .venv" in set_up and ".venv/bin/pip install" in set_up
    lines = [line.split("#")[0].strip() for line in blocks("A first run")[0].splitlines() if line.strip()]
    assert lines[0] == ". .venv/bin/activate"
    assert all(line.startswith("biostudy ") for line in lines[1:])


def test_show_prints_what_the_readme_says(tiny_scene, tmp_path):
    """README: `show` gives every observable first and last, and --json at every output."""
    import json

    from test_cli import invoke

    comment = next(line for line in blocks("A first run")[0].splitlines() if line.startswith("biostudy show"))
    assert "every observable first and last (--json: at every output)" in comment
    assert invoke("run", tiny_scene, "-o", tmp_path / "r.nc", "-q").exit_code == 0
    shown = invoke("show", tmp_path / "r.nc").stdout
    header = next(line for line in shown.splitlines() if line.lstrip().startswith("observable"))
    assert header.count("T* = ") == 2 and "T* = 0 " in header and "T* = 0.2" in header  # 3 outputs: first, last
    record = json.loads(invoke("show", tmp_path / "r.nc", "--json").stdout)
    assert len(record["time"]) == 3 and len(record["observables"]["biofilm_volume"]["values"]) == 3


def test_a_table_naming_one_condition_needs_no_conditions_table(tmp_path):
    """PEtab gives every row a simulationConditionId; a calibration without [conditions] takes one name as the
    scene's own condition (it refused it unless an empty [conditions.agar] was added); two names still need
    [conditions], and a row left empty beside named ones is told."""
    rows = "observableId\tsimulationConditionId\ttime\tmeasurement\tnoiseParameters\n"
    (tmp_path / "c.toml").write_text('scene = "agar2d"\n[data]\nmeasurements = "t.tsv"\n[estimate]\n'
                                     'g = [1e7, 1e10, "log"]\n')
    (tmp_path / "t.tsv").write_text(rows + "biomass\tagar\t0.1\t3.0\t0.2\nbiomass\tagar\t0.2\t4.0\t0.2\n")
    plan = load_calibration(tmp_path / "c.toml")
    assert plan.conditions == ["agar"] and [p.conditions for p in plan.parameters] == [("agar",)]
    (tmp_path / "t.tsv").write_text(rows + "biomass\tagar\t0.1\t3.0\t0.2\nbiomass\t\t0.2\t4.0\t0.2\n")
    with pytest.raises(BadInput, match=r"line 3: simulationConditionId: empty; the calibration has conditions agar"):
        load_calibration(tmp_path / "c.toml")
    (tmp_path / "t.tsv").write_text(rows + "biomass\tagar\t0.1\t3.0\t0.2\nbiomass\thalf\t0.2\t4.0\t0.2\n")
    with pytest.raises(BadInput, match=r"unknown condition 'agar' \(the calibration has no \[conditions\]"):
        load_calibration(tmp_path / "c.toml")
