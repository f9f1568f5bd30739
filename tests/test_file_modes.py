"""Every file and directory biostudy writes follows the umask, as a shared file system expects (issue 27): a
group reads a colleague's runs under 022 or 027.  Before, `run -o` files were 0600 whatever the umask (the
output's claimed temporary was made 0600 and netCDF wrote into it)."""
from __future__ import annotations

import os
import stat

import pytest
from typer.testing import CliRunner

from biostudy.cli import app

cli = CliRunner()


@pytest.fixture
def umask(request):
    previous = os.umask(request.param)
    yield request.param
    os.umask(previous)


@pytest.mark.parametrize("umask", [0o022, 0o027], indirect=True)
def test_every_output_follows_the_umask(umask, tiny_scene, write_toml, tmp_path):
    """A run, its pictures, its exports, a sweep of two cases: netCDF (through a claim and through temporaries),
    PNG, VTU/PVD, TIFF, the owner record and the lock; a report is written as the owner record is
    (`writing.write_text`)."""
    study = write_toml("two.toml", 'scene = "tiny.toml"\n[sweep]\nr = [50.0, 60.0]\n')
    given = {p.name for p in tmp_path.iterdir()}
    steps = ["--set", "time.steps=2"]
    for args in (["run", tiny_scene, "-o", tmp_path / "runs" / "run.nc", *steps],
                 ["plot", tmp_path / "runs" / "run.nc", "-o", tmp_path / "runs" / "run.png"],
                 ["export", tmp_path / "runs" / "run.nc", tmp_path / "vtu"],
                 ["export", tmp_path / "runs" / "run.nc", tmp_path / "tiff", "--format", "tiff"],
                 ["sweep", study, "-o", tmp_path / "sweep", *steps]):
        result = cli.invoke(app, [str(a) for a in (*args, "-q")] if args[0] in ("run", "sweep") else map(str, args))
        assert result.exit_code == 0, (args, result.output)
    modes = {}
    for root, directories, files in os.walk(tmp_path):
        for name in [*directories, *files]:
            path = os.path.join(root, name)
            if os.path.relpath(path, tmp_path) not in given:
                modes[os.path.relpath(path, tmp_path)] = stat.S_IMODE(os.stat(path).st_mode)
    expected = {name: (0o777 if os.path.isdir(tmp_path / name) else 0o666) & ~umask for name in modes}
    assert {"runs/run.nc", "runs/run_series.png", "vtu/series.pvd", "tiff/phi.tif", "sweep/study.nc",
            "sweep/.biostudy.lock", "sweep/.biostudy-owner.toml"} <= set(modes)
    assert {name: oct(mode) for name, mode in modes.items() if mode != expected[name]} == {}


def test_a_sweeps_lock_file_follows_the_umask(tmp_path):
    """Group-writable under umask 002, so that a colleague's array tasks can take the lock (it was 0644)."""
    from biostudy.execution.ownership import LOCK, Owner, claimed

    previous = os.umask(0o002)
    try:
        with claimed(tmp_path / "sweep", Owner("study", "s", "s.toml")):
            pass
    finally:
        os.umask(previous)
    assert stat.S_IMODE(os.stat(tmp_path / "sweep" / LOCK).st_mode) == 0o664
