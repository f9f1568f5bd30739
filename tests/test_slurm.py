"""The SLURM recipes of docs/batch, run for real where a SLURM cluster answers (e.g. Debian's slurm-wlm on one
node); skipped elsewhere.  Both must give the study a sweep gives here."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import xarray as xr
from typer.testing import CliRunner

from biostudy.cli import app

BATCH = Path(__file__).resolve().parents[1] / "docs" / "batch"


def _slurm_answers() -> bool:
    if not shutil.which("sbatch") or not shutil.which("sinfo"):
        return False
    try:
        states = subprocess.run(["sinfo", "-h", "-o", "%T"], capture_output=True, text=True, timeout=3).stdout
    except (OSError, subprocess.TimeoutExpired):
        return False
    return any(state.strip().rstrip("*") in ("idle", "mixed") for state in states.split())


pytestmark = [pytest.mark.skipif(not _slurm_answers(), reason="no SLURM cluster answers here (sinfo)"),
              pytest.mark.slow]


def sbatch(*args, cwd):
    """Submit and wait (`sbatch --wait`); the job's environment is this one, with this interpreter's scripts."""
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    done = subprocess.run(["sbatch", "--wait", "--parsable", *map(str, args)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip().split(";")[0]


def same_study(a: xr.Dataset, b: xr.Dataset) -> None:
    for name in a.data_vars:
        if name not in ("wall_time", "elapsed"):
            xr.testing.assert_identical(a[name].drop_attrs(), b[name].drop_attrs())


@pytest.fixture
def study(tiny_study, tmp_path):
    text = tiny_study.read_text().replace("[sweep]", '[set]\n"time.steps" = 10\n[sweep]')
    tiny_study.write_text(text)
    here = CliRunner().invoke(app, ["sweep", str(tiny_study), "-o", str(tmp_path / "here"), "-q"])
    assert here.exit_code == 0, here.output
    return tiny_study


def test_the_job_array_recipe_then_combine(study, tmp_path):
    sbatch("--array=0-3", BATCH / "sweep-array.sbatch", study, tmp_path / "array", cwd=tmp_path)  # waits for all
    combined = CliRunner().invoke(app, ["sweep", str(study), "-o", str(tmp_path / "array"), "--combine"])
    assert combined.exit_code == 0 and "(4 done, 0 failed, 0 missing)" in combined.stderr
    same_study(xr.open_dataset(tmp_path / "array" / "study.nc"), xr.open_dataset(tmp_path / "here" / "study.nc"))


def test_the_dask_in_an_allocation_recipe(study, tmp_path):
    job = sbatch("--ntasks=2", BATCH / "sweep-dask.sbatch", study, tmp_path / "dask", cwd=tmp_path)
    log = (tmp_path / f"slurm-{job}.out").read_text()
    assert "Start worker" in log and "4 cases run" in log
    same_study(xr.open_dataset(tmp_path / "dask" / "study.nc"), xr.open_dataset(tmp_path / "here" / "study.nc"))
