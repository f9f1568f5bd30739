"""`biostudy show A.nc B.nc`: runs side by side; and `show` of one run read at a glance (netCDF4 alone)."""
import re
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.formatting import number

cli = CliRunner()


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    """The tiny scene with g = 1e8 and g = 1e9 (the second with an extra output time)."""
    import textwrap

    from conftest import TINY_SCENE

    folder = tmp_path_factory.mktemp("compare")
    scene = folder / "tiny.toml"
    scene.write_text(textwrap.dedent(TINY_SCENE))
    a, b = folder / "a.nc", folder / "b.nc"
    for out, extra in ((a, []), (b, ["--set", "g=1e9", "--set", "time.output_times=[0.0, 0.05, 0.1, 0.2]"])):
        result = cli.invoke(app, ["run", str(scene), "-o", str(out), "-q", *extra])
        assert result.exit_code == 0, result.output
    return a, b


def test_two_known_runs_side_by_side(two_runs):
    a, b = two_runs
    result = cli.invoke(app, ["show", str(a), str(b)], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    text = result.stdout
    assert re.search(r"params\.g\s+│\s+1e8\s+│\s+1e9", text)  # the scene key that differs, from the files
    assert "time.output_times" in text and "grid.shape" not in text  # only what differs
    one, two = xr.open_dataset(a), xr.open_dataset(b).squeeze()
    common = [0.0, 0.1, 0.2]  # b's extra output 0.05 is not compared
    assert "T* = 0.05" not in text and all(f"T* = {t:g}" in text for t in common)
    row = next(line for line in text.splitlines() if line.strip().startswith("biofilm_volume"))
    expected = [number(run.biofilm_volume.sel(time=t).item()) for t in common for run in (one, two)]
    assert [cell.strip() for cell in row.split("│")] == ["biofilm_volume", "µm³", *expected]
    # the largest field difference, computed here independently, with where and when
    gap = np.abs(one.phi.sel(time=common) - two.phi.sel(time=common))
    where = gap.where(gap == gap.max(), drop=True)
    row = next(line for line in text.splitlines() if line.strip().startswith("phi "))
    assert number(float(gap.max()), exponent=True) in row
    assert "at T*" in text and number(float(where.time.values[0])) in row
    assert f"x = {number(float(where.x.values[0]))}, y = {number(float(where.y.values[0]))}" in row


def test_compare_refuses_what_is_not_a_run_and_says_when_grids_differ(two_runs, tiny_scene, tmp_path):
    a, _ = two_runs
    other = tmp_path / "other.nc"
    made = cli.invoke(app, ["run", str(tiny_scene), "-o", str(other), "-q", "--set", "grid.shape=[18,16]"])
    assert made.exit_code == 0
    shown = cli.invoke(app, ["show", str(a), str(other)], env={"COLUMNS": "200"})
    assert shown.exit_code == 0 and "run 2 has another grid than run 1: fields not compared" in shown.stdout
    result = cli.invoke(app, ["show", str(a), str(tiny_scene)])
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1


def test_show_of_a_run_reads_it_at_a_glance(two_runs):
    """show of a run's file imports neither xarray nor the solver (start-up, issue 19 item 6), and says the same
    as the full reader; a damaged file still goes to the reader that calls it damaged."""
    a, _ = two_runs
    probe = ("import sys\nfrom typer.testing import CliRunner\nfrom biostudy.cli import app\n"
             f"r = CliRunner().invoke(app, ['show', {str(a)!r}], env={{'COLUMNS': '200'}})\n"
             "print(r.exit_code, sorted(m for m in ('xarray', 'fipy', 'scipy', 'matplotlib') if m in sys.modules))\n"
             "print(r.stdout)")
    shown = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert shown.splitlines()[0] == "0 []", shown
    from rich.console import Console

    from biostudy.data.reading import open_result
    from biostudy.reports.show import run_summary

    console = Console(width=200, record=True)
    console.print(run_summary(open_result(a)))
    assert console.export_text().split() == "\n".join(shown.splitlines()[1:]).split()
