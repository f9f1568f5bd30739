"""Batch clusters: array tasks into one directory then combined, a Dask cluster by its scheduler file, runs that
combine along their overrides."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.commands import sweep as sweep_command
from biostudy.errors import BadInput
from biostudy.execution import ownership

cli = CliRunner()
FAST = ["--set", "time.steps=10"]
PER_CASE = ("wall_time", "elapsed")  # what differs between two computations of one case


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def same_study(a: xr.Dataset, b: xr.Dataset) -> None:
    assert set(a.data_vars) == set(b.data_vars) and set(a.coords) == set(b.coords)
    for name in a.data_vars:
        if name not in PER_CASE:
            xr.testing.assert_identical(a[name].drop_attrs(), b[name].drop_attrs())


def test_array_tasks_race_into_one_directory_then_combine_to_the_sweep(tiny_study, tmp_path):
    whole = invoke("sweep", tiny_study, "-o", tmp_path / "whole", "-q", *FAST)
    assert whole.exit_code == 0, whole.output
    out = tmp_path / "array"
    tasks = [[sys.executable, "-m", "biostudy", "sweep", str(tiny_study), "-o", str(out), "-q", *FAST, "--task",
              str(n), "--tasks", "2"] for n in range(2)]
    running = [subprocess.Popen(task, stderr=subprocess.PIPE, text=True) for task in tasks]  # at once
    for process in running:
        _, stderr = process.communicate(timeout=300)
        assert process.returncode == 0, stderr  # no lock conflict between them
    assert sorted(p.name for p in (out / "cases").iterdir()) == sorted(p.name for p in (tmp_path / "whole" / "cases")
                                                                      .iterdir())  # no file lost, none left over
    assert not (out / "study.nc").exists()  # the tasks leave study.nc to --combine
    combined = invoke("sweep", tiny_study, "-o", out, "--combine", *FAST)
    assert combined.exit_code == 0 and "combined 4 cases (4 done, 0 failed, 0 missing)" in combined.stderr
    assert "--array" not in combined.stderr  # nothing to submit again
    same_study(xr.open_dataset(out / "study.nc"), xr.open_dataset(tmp_path / "whole" / "study.nc"))
    again = invoke("sweep", tiny_study, "-o", out, "-q", *FAST)  # an ordinary run: nothing left to run
    assert again.exit_code == 0 and "0 cases run, 4 skipped" in again.stderr


def test_array_indices_are_case_numbers_so_resubmitting_some_runs_exactly_those(tiny_study, tmp_path):
    """`sbatch --array=1,3` (task N alone: case number N of the study's order) runs cases 1 and 3, and --combine
    names the others for `--array=0,2`; a share of a fixed M is the same cases whatever indices are submitted."""
    ids = [case.id for case in sweep_command.load(tiny_study).plan.cases]
    out = tmp_path / "out"
    for index in (3, 1):
        assert invoke("sweep", tiny_study, "-o", out, "-q", "--task", index, *FAST).exit_code == 0
    assert sorted(os.listdir(out / "cases")) == sorted(f"{ids[n]}.nc" for n in (1, 3))
    partial = invoke("sweep", tiny_study, "-o", out, "--combine", *FAST)
    assert "2 done, 0 failed, 2 missing" in partial.stderr and "`sbatch --array=0,2`" in partial.stderr
    shares = tmp_path / "shares"
    assert invoke("sweep", tiny_study, "-o", shares, "-q", "--task", 1, "--tasks", 2, *FAST).exit_code == 0
    assert sorted(os.listdir(shares / "cases")) == sorted(f"{ids[n]}.nc" for n in (1, 3))


def test_one_case_by_its_id_and_bad_choices(tiny_study, tmp_path):
    out = tmp_path / "out"
    one = invoke("sweep", tiny_study, "-o", out, "-q", "--case", "g=1e+09_r=50", *FAST)
    assert one.exit_code == 0 and os.listdir(out / "cases") == ["g=1e+09_r=50.nc"]
    partial = invoke("sweep", tiny_study, "-o", out, "--combine", *FAST)  # what is there: the others missing
    assert "1 done, 0 failed, 3 missing" in partial.stderr
    bad = {("--case", "g=1e7"): "--case: no case 'g=1e7' in this study (its 4 cases: g=1e+08_r=50,",
           ("--task", "3", "--tasks", "3"): "--task: must be in 0..2 for --tasks 3 (got 3)",
           ("--task", "4"): "--task: no case number 4 in this study (its 4 cases are numbered 0..3",
           ("--tasks", "2"): "--tasks: needs --task N",
           ("--combine", "--case", "g=1e+09_r=50"): "--combine: --combine runs no case",
           ("--scheduler-file", tmp_path / "none.json"): "--scheduler-file: no such file",
           ("--scheduler-file", tiny_study): "--scheduler-file: not a Dask scheduler file",
           ("--workers", "2", "--scheduler-file", tmp_path / "x.json"): "give --workers or --scheduler-file, not both"}
    for args, expected in bad.items():
        result = invoke("sweep", tiny_study, "-o", out, *args, *FAST)
        lines = result.stderr.strip().splitlines()
        assert result.exit_code == 2 and len(lines) == 1 and expected in lines[0], (args, result.output)


def test_array_tasks_share_the_lock_a_whole_sweep_does_not(tmp_path):
    owner = ownership.Owner("study", "s", "/x/scene.toml", ("g",))
    with ownership.claimed(tmp_path, owner, shared=True), ownership.claimed(tmp_path, owner, shared=True):
        with pytest.raises(BadInput, match="another biostudy run is writing into this directory"):
            with ownership.claimed(tmp_path, owner):
                pass
    with ownership.claimed(tmp_path, owner):
        with pytest.raises(BadInput, match="another biostudy run"):
            with ownership.claimed(tmp_path, owner, shared=True):
                pass


def test_sweep_on_a_cluster_found_by_its_scheduler_file(tiny_study, tmp_path):
    """As in a batch job, the sweep finds its cluster by the file the scheduler wrote (docs/clusters.md;
    the recipe's `dask scheduler --scheduler-file F` does the same as the scheduler here)."""
    distributed = pytest.importorskip("distributed")
    file = tmp_path / "scheduler.json"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None,
                                  scheduler_kwargs={"scheduler_file": str(file)}):
        assert json.loads(file.read_text())["address"].startswith(("tcp://", "inproc://"))
        result = invoke("sweep", tiny_study, "-o", tmp_path / "out", "-q", "--scheduler-file", file, *FAST)
        assert result.exit_code == 0, result.output
    here = invoke("sweep", tiny_study, "-o", tmp_path / "here", "-q", *FAST)
    assert here.exit_code == 0
    same_study(xr.open_dataset(tmp_path / "out" / "study.nc"), xr.open_dataset(tmp_path / "here" / "study.nc"))


def test_runs_with_other_set_values_combine_along_them(tiny_scene, tmp_path):
    files = []
    for g in ("1e8", "1e9", "1e10"):
        files.append(tmp_path / f"g{g}.nc")
        result = invoke("run", tiny_scene, "-o", files[-1], "-q", "--set", f"g={g}")
        assert result.exit_code == 0, result.output
    runs = [xr.open_dataset(f) for f in files]
    assert all(run.phi.dims == ("time", "y", "x") and run.g.dims == () for run in runs)  # each keeps its shape
    plain = xr.open_mfdataset(files, combine="nested", concat_dim="g", combine_attrs="drop_conflicts")
    assert plain.g.values.tolist() == [1e8, 1e9, 1e10] and plain.phi.dims == ("g", "time", "y", "x")
    for run in runs:
        np.testing.assert_array_equal(plain.phi.sel(g=run.g.item()).values, run.phi.values)
    assert plain.g.attrs["units"] == "1" and "consumption" in plain.g.attrs["long_name"]
