"""What a new user meets first (issue 36.6): a study or calibration file naming a bundled scene as the command line
does (scene = "agar2d")."""
from __future__ import annotations

import pytest

from biostudy.errors import BadInput
from biostudy.inputs.bundled import studies_dir
from biostudy.plans.calibration import load_calibration
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
