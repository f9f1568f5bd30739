"""Every finding of the CF checker (compliance-checker, cf:1.10, every priority) on the files biostudy writes, for
comparing two versions: a 3-D and a 2-D run with mechanics, a grid study, one of its cases and its analysis.nc.

    .venv/bin/python scripts/cf_findings.py /tmp/new new.json                      # this checkout
    git archive main | tar -x -C /tmp/old
    PYTHONPATH=/tmp/old .venv/bin/python scripts/cf_findings.py /tmp/oldfiles old.json   # another version
    diff old.json new.json

Makes the files in the folder given (the tests' tiny scenes, tests/conftest.py), runs the checker on each and
writes {file: sorted findings} to the JSON file; prints each file's number of findings and its score.
"""
from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
warnings.simplefilter("ignore")

FILES = ["run3d.nc", "run2d.nc", "grid/study.nc", "grid/cases/g=1e+08_r=50.nc", "grid/analysis.nc"]


def make(root: Path) -> None:
    from conftest import CUBE_SCENE, TINY_SCENE
    from typer.testing import CliRunner

    from biostudy.cli import app

    root.mkdir(parents=True, exist_ok=True)
    (root / "tiny.toml").write_text(TINY_SCENE + "[mechanics]\nevery = 2\n")
    (root / "cube.toml").write_text(CUBE_SCENE + '[mechanics]\nclamp = ["z-"]\nevery = 2\n')
    (root / "grid.toml").write_text('scene = "tiny.toml"\n[sweep]\ng = [1e8, 1e9]\nr = [50.0, 100.0]\n')
    for args in (["run", root / "cube.toml", "-o", root / "run3d.nc", "-q"],
                 ["run", root / "tiny.toml", "-o", root / "run2d.nc", "-q"],
                 ["sweep", root / "grid.toml", "-o", root / "grid", "-q"],
                 ["analyze", root / "grid", "--output", "biofilm_volume"]):
        result = CliRunner().invoke(app, [str(a) for a in args])
        assert result.exit_code == 0, result.output


def findings(path: Path, report: Path) -> tuple[list[str], int, int]:
    from compliance_checker.runner import CheckSuite, ComplianceChecker

    CheckSuite.load_all_available_checkers()
    ComplianceChecker.run_checker(str(path), ["cf:1.10"], 0, "normal", output_filename=str(report),
                                  output_format="json")
    found = json.loads(report.read_text())["cf:1.10"]
    said = sorted({f"{level}: {check['name']}: {message}" for level in ("high_priorities", "medium_priorities",
                                                                         "low_priorities")
                   for check in found[level] for message in check["msgs"]})
    return said, found["scored_points"], found["possible_points"]


def main(root: Path, out: Path) -> None:
    make(root)
    result = {}
    for name in FILES:
        said, scored, possible = findings(root / name, root / (name.replace("/", "_") + ".json"))
        result[name] = said
        print(f"{name}: {len(said)} findings, {scored}/{possible}")
    out.write_text(json.dumps(result, indent=1, ensure_ascii=False))


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
