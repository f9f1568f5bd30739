"""No report or picture replaces a file biostudy cannot prove it wrote, whatever the command (issue 25): a user's
calibration.md, analysis.md, simulation.tsv or picture in the output folder keeps its bytes, --force or not; what
biostudy wrote carries its mark (`data.claims`; simulation.tsv, which cannot, the sha256 calibration.nc records:
tests/test_petab_outputs.py) and is replaced by the next run."""
from __future__ import annotations

import hashlib

import matplotlib.pyplot as plt
import pytest
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.data import claims
from biostudy.errors import BadInput
from biostudy.plots.style import save

cli = CliRunner()

CALIBRATION = """\
scene = "tiny.toml"
[data]
measurements = "table.tsv"
[estimate]
r = [50.0, 150.0]
[method]
starts = 1
profiles = false
"""
TABLE = "observableId\ttime\tmeasurement\tnoiseParameters\nbiomass\t0.05\t4.0\t0.2\nbiomass\t0.1\t5.0\t0.2\n"
USERS = b"# my notes on the calibration\n\nnot biostudy's\n"
PNG = b"\x89PNG\r\n\x1a\n a user's picture"


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def refused_one_line(result, name: str) -> str:
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and name in lines[0] and "refusing to overwrite" in lines[0], result.output
    return lines[0]


@pytest.mark.parametrize("name, content", [("calibration.md", USERS), ("calibration_fit.png", PNG),
                                           ("simulation.tsv", b"observableId\tsimulation\nmine\t1\n")],
                         ids=["report", "picture", "PEtab simulation table"])
def test_calibrate_keeps_a_users_report_or_picture_force_or_not(tiny_scene, write_toml, tmp_path, name, content):
    (tmp_path / "table.tsv").write_text(TABLE)
    calibration = write_toml("cal.toml", CALIBRATION)
    out = tmp_path / "out"
    out.mkdir()
    (out / name).write_bytes(content)
    before = digest(out / name)
    refused_one_line(invoke("calibrate", calibration, "-o", out, "-q", "--force"), name)
    assert digest(out / name) == before
    assert not (out / "cases").exists() and not (out / "calibration.nc").exists()  # refused before anything ran


@pytest.mark.parametrize("name", ["convergence.md", "work_precision.png"])
def test_convergence_keeps_a_users_report_or_picture(tiny_scene, tmp_path, name):
    out = tmp_path / "out"
    out.mkdir()
    (out / name).write_bytes(USERS)
    result = invoke("convergence", tiny_scene, "-o", out, "--levels", "2", "--series", "time", "-q", "--force")
    refused_one_line(result, name)
    assert (out / name).read_bytes() == USERS and not (out / "cases").exists()


def test_analyze_keeps_a_users_report_and_replaces_its_own(tiny_study, tmp_path):
    out = tmp_path / "out"
    assert invoke("sweep", tiny_study, "-o", out, "-q", "--set", "time.steps=5").exit_code == 0
    first = invoke("analyze", out, "--output", "biofilm_volume")
    assert first.exit_code == 0, first.output
    report = (out / "analysis.md").read_text()
    assert report.rstrip().endswith(f"<!-- {claims.mark()} -->")  # invisible where Markdown is shown
    assert claims.marked(out / "analysis_scatter.png")
    again = invoke("analyze", out, "--output", "biofilm_volume")  # its own files: replaced
    assert again.exit_code == 0, again.output
    for name in ("analysis.md", "analysis_scatter.png"):
        (out / name).write_bytes(USERS if name.endswith(".md") else PNG)
        before = digest(out / name)
        refused_one_line(invoke("analyze", out, "--output", "biofilm_volume"), name)
        assert digest(out / name) == before
        (out / name).unlink()


def test_a_foreign_file_that_appears_while_a_job_computes_is_not_replaced(tmp_path):
    """The last guard: the writers of reports and pictures themselves refuse (a file put there after the
    job's check)."""
    (tmp_path / "notes.md").write_bytes(USERS)
    (tmp_path / "figure.png").write_bytes(PNG)
    with pytest.raises(BadInput, match="refusing to overwrite"):
        claims.write_report(tmp_path / "notes.md", "| a | b |\n")
    with pytest.raises(BadInput, match="refusing to overwrite"):
        save(plt.figure(), tmp_path / "figure.png")
    assert (tmp_path / "notes.md").read_bytes() == USERS and (tmp_path / "figure.png").read_bytes() == PNG
    claims.write_report(tmp_path / "ours.md", "| a | b |\n")
    claims.write_report(tmp_path / "ours.md", "| c | d |\n")  # its own: replaced
    assert (tmp_path / "ours.md").read_text().startswith("| c | d |\n")
