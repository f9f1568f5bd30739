"""Nothing lost, fourth round (issue 39): a streamed run and a full disk, interrupts wherever they land.

Numbered as the issue's items: 4 a streamed run holds its outputs on disk twice while it writes its file (the
spool and the dataset's temporary): both are counted before anything is computed, and a disk that fills up
anyway is one line at each write; 5 an interrupt ends the command (130, 143) wherever it lands, finalisers
included.  Scenes are tiny (2-D 16², 20 steps); streaming is forced on them by lowering its threshold.
"""
from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
from conftest import TINY_SCENE
from test_faults_hostile import _full
from typer.testing import CliRunner

import solver
from biostudy.cli import app
from biostudy.data import netcdf_io
from biostudy.inputs import resources

cli = CliRunner()


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def one_line(result, status: int) -> str:
    assert result.exit_code == status, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in result.output, result.stderr
    return lines[0]


STREAMED = TINY_SCENE.replace("outputs = 3", "outputs = 21")  # ~130 kB of fields


@pytest.fixture
def streamed(tmp_path, monkeypatch) -> Path:
    """The tiny scene with 21 outputs, streamed to a spool as a large run's are."""
    monkeypatch.setattr(resources, "STREAM_ABOVE", 0.0)
    scene = tmp_path / "tiny.toml"
    scene.write_text(STREAMED)
    return scene


@pytest.fixture(scope="module")
def earlier(tmp_path_factory) -> Path:
    """A streamed run's result, made once: the tests copy it."""
    folder = tmp_path_factory.mktemp("earlier")
    (folder / "tiny.toml").write_text(STREAMED)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(resources, "STREAM_ABOVE", 0.0)
        assert invoke("run", folder / "tiny.toml", "-o", folder / "out.nc", "-q").exit_code == 0
    return folder / "out.nc"


def test_a_streamed_run_counts_its_spool_beside_its_dataset_before_computing(streamed, tmp_path, monkeypatch):
    """Issue 39.4: the disk held the dataset (the check said so) but not the dataset's temporary beside the
    spool, and the run lost its result after computing it."""
    dataset = resources.estimate(_scene(streamed), streamed=True).disk
    monkeypatch.setattr(resources, "free_disk", lambda path: 1.5 * dataset)
    monkeypatch.setattr(solver, "simulate", _refuse)
    line = one_line(invoke("run", streamed, "-o", tmp_path / "out.nc"), 2)
    assert f"needs {resources.size(2 * dataset)} of disk for its dataset ({resources.size(dataset)}) and the spool " \
           "its outputs stream to until the dataset is written" in line
    assert sorted(os.listdir(tmp_path)) == ["tiny.toml"]
    shown = invoke("show", streamed).stdout
    assert f"{resources.size(2 * dataset)} while it is written (the outputs' spool beside it" in shown


def test_a_streamed_run_on_a_disk_that_holds_its_dataset_once_is_refused_before_computing(streamed, small_disk,
                                                                                         monkeypatch):
    disk, _ = small_disk  # 2 MB: 1.3 MB of fields fit once, not twice
    outputs = int(1.3e6 / resources.estimate(_scene(streamed)).disk * 21)
    streamed.write_text(TINY_SCENE.replace("outputs = 3", f"outputs = {outputs}").replace("steps = 20",
                                                                                          f"steps = {outputs}"))
    monkeypatch.setattr(solver, "simulate", _refuse)
    assert "of disk for its dataset" in one_line(invoke("run", streamed, "-o", disk / "out.nc"), 2)
    assert os.listdir(disk) == []


WRITES = ["the spool's first output", "the spool's tenth output", "the dataset", "the dataset's rename"]


@pytest.mark.parametrize("failing", WRITES)
def test_a_disk_full_at_any_write_of_a_streamed_run_is_one_line_and_leaves_nothing(streamed, tmp_path, monkeypatch,
                                                                                  earlier, failing):
    """ENOSPC injected at each of a streamed run's writes: one line naming the disk, nothing left behind (no spool,
    no temporary), an earlier result of the scene kept as it was."""
    before = earlier.read_bytes()
    earlier = tmp_path / "out.nc"
    earlier.write_bytes(before)
    full = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    if failing.startswith("the spool"):
        at = 1 if "first" in failing else 10 * 3  # three fields an output
        calls = []
        append = netcdf_io.Growing.append

        def failing_append(self, name, values):
            calls.append(name)
            if len(calls) == at:
                raise full
            return append(self, name, values)

        monkeypatch.setattr(netcdf_io.Growing, "append", failing_append)
    elif failing == "the dataset":
        monkeypatch.setattr(netcdf_io, "write", lambda *args: (_ for _ in ()).throw(full))
    else:
        monkeypatch.setattr(os, "replace", lambda *args: (_ for _ in ()).throw(full))
    line = one_line(invoke("run", streamed, "-o", earlier, "-q", "--force"), 1)  # another file's scene: --force
    assert line.startswith(f"error: cannot write {earlier}: the disk is full (the file system at ")
    assert "result is lost (the earlier file there is kept as it was)" in line
    assert sorted(os.listdir(tmp_path)) == ["out.nc", "tiny.toml"] and earlier.read_bytes() == before


def test_a_disk_filling_up_while_a_streamed_run_spools_is_one_line(streamed, small_disk, monkeypatch):
    """The same with a real file system filling up (2 MB tmpfs, filled after the first output is spooled)."""
    disk, fill = small_disk
    from biostudy.data import spool

    add = spool.Spool.add
    added = []

    def fills(self, snapshot):
        add(self, snapshot)
        added.append(1)
        if len(added) == 1:
            fill()

    monkeypatch.setattr(spool.Spool, "add", fills)
    line = one_line(invoke("run", streamed, "-o", disk / "out.nc", "-q"), 1)
    assert line.startswith(f"error: cannot write {disk / 'out.nc'}: {_full(disk)}") and "result is lost" in line
    assert os.listdir(disk) == ["filler"]


def _scene(path: Path):
    from biostudy.inputs.scene import load_scene

    return load_scene(path)


def _refuse(*args, **kwargs):
    raise AssertionError("simulated although the run was refused")
