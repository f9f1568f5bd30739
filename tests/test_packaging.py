"""The package as people install it: a wheel built from the repository holds everything a run needs (the bundled
scenes, studies, catalogues and example data of `studies/`) and nothing of the development tree, finds its
scenes outside any checkout, and says its licence; CITATION.cff is valid Citation File Format 1.2.0."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("pyproject.toml", "setup.py", "README.md", "LICENSE", "biostudy", "solver", "studies")
SCHEMA = Path(__file__).parent / "data" / "cff-schema-1.2.0.json"  # from cffconvert 2.0.0's wheel (CC-BY-4.0)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built from a copy of the package's sources (the checkout is left as it was: no build/ there)."""
    source = tmp_path_factory.mktemp("source")
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        elif (ROOT / name).is_file():
            shutil.copy2(ROOT / name, source / name)
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
                    "-q", "-w", str(out), str(source)], check=True, capture_output=True, text=True)
    return next(out.glob("biostudy-*.whl"))


def test_the_wheel_holds_every_bundled_file_and_no_development_tree(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    bundled = sorted(path.name for path in (ROOT / "studies").iterdir() if path.is_file())
    assert {"directional.toml", "stability.toml", "calibrate-agar.tsv"} <= set(bundled)
    assert [name for name in bundled if f"biostudy/studies/{name}" not in names] == []
    code = sorted(path.relative_to(ROOT).as_posix() for package in ("biostudy", "solver")
                  for path in (ROOT / package).rglob("*.py"))
    assert [name for name in code if name not in names] == []
    assert [name for name in names if name.split("/")[0] in ("tests", "benchmarks", "scripts", "docs",
                                                             "studies")] == []
    info = next(name for name in names if name.endswith(".dist-info/METADATA"))
    metadata = zipfile.ZipFile(wheel).read(info).decode()
    assert "License-Expression: BSD-3-Clause" in metadata
    assert any(name.endswith(".dist-info/licenses/LICENSE") for name in names)


def test_an_unpacked_wheel_runs_its_bundled_scenes_from_any_directory(wheel, tmp_path):
    """Installed (here: unpacked onto the path, first), biostudy finds its scenes in itself, not in a checkout."""
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    found = subprocess.run(
        [sys.executable, "-c", "import json, biostudy; from biostudy.inputs import bundled; "
         "print(json.dumps([biostudy.__file__, str(bundled.resolve('directional')), "
         "str(bundled.resolve('calibrate-agar')), [e.kind for e in bundled.entries()]]))"],
        cwd=elsewhere, env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"}, capture_output=True, text=True)
    assert found.returncode == 0, found.stderr
    package, scene, calibration, kinds = json.loads(found.stdout.strip().splitlines()[-1])
    assert Path(package).is_relative_to(site) and Path(scene).is_relative_to(site / "biostudy" / "studies")
    assert Path(calibration).is_file() and (Path(calibration).parent / "calibrate-agar.tsv").is_file()
    assert {"scene", "study", "calibration", "stability"} <= set(kinds)


def citation_problems(citation: dict) -> list[str]:
    import jsonschema

    schema = json.loads(SCHEMA.read_text())
    validator = jsonschema.Draft7Validator(schema, format_checker=jsonschema.FormatChecker())
    return [error.message for error in validator.iter_errors(citation)]


def test_the_citation_file_is_valid_and_names_the_paper_and_this_version():
    import yaml

    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert citation_problems(citation) == []
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert str(citation["version"]) == project["version"] and citation["license"] == project["license"]
    paper = citation["references"][0]
    assert paper["doi"] == "10.1007/s10237-024-01883-x" and paper["year"] == 2024
    assert "CITATION.cff" in (ROOT / "README.md").read_text(encoding="utf-8")


def test_the_citation_check_finds_a_broken_file():
    import yaml

    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    del citation["authors"]
    citation["date-released"] = "2 December 2026"
    problems = citation_problems(citation)
    assert any("authors" in problem for problem in problems) and len(problems) >= 2
