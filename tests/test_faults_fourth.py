"""Nothing lost, fourth round (issue 39): a streamed run and a full disk, interrupts wherever they land.

Numbered as the issue's items: 4 a streamed run holds its outputs on disk twice while it writes its file (the
spool and the dataset's temporary): both are counted before anything is computed, and a disk that fills up
anyway is one line at each write; 5 an interrupt ends the command (130, 143) wherever it lands, finalisers
included.  Scenes are tiny (2-D 16², 20 steps); streaming is forced on them by lowering its threshold.
"""
from __future__ import annotations

import errno
import os
import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from conftest import TINY_SCENE
from test_faults_hostile import _full
from typer.testing import CliRunner

import solver
from biostudy.cli import app
from biostudy.data import netcdf_io
from biostudy.execution import worker
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


# ---- 5. interrupts wherever they land -----------------------------------------------------------------------------

INTERRUPTED = "interrupted: finished files are kept, nothing is left half-written"


@pytest.mark.parametrize("sent, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_an_interrupt_raised_inside_a_finaliser_still_ends_the_command(tiny_scene, tmp_path, monkeypatch, sent,
                                                                      status):
    """Issue 39.5: the signal's exception raised inside a finaliser (FiPy's `Solver.__del__` in the issue: its
    solvers are freed by the garbage collector, whenever it runs) was printed as "Exception ignored in" and lost:
    the run went on to its end, exit 0.  Here an object made and freed just before the simulation receives it."""
    class Freed:
        def __del__(self):
            signal.raise_signal(sent)

    simulate = solver.simulate

    def freed_first(*args, **kwargs):
        Freed()  # made and freed at once: its finaliser runs the signal's handler
        return simulate(*args, **kwargs)

    monkeypatch.setattr(solver, "simulate", freed_first)
    result = invoke("run", tiny_scene, "-o", tmp_path / "o.nc", "-q")
    assert result.exit_code == status, result.output
    assert result.stderr.strip() == INTERRUPTED and not (tmp_path / "o.nc").exists()


@pytest.mark.parametrize("sent, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_an_interrupt_while_a_finished_simulation_is_recorded_waits_for_its_case_file(tiny_study, tmp_path,
                                                                                     monkeypatch, sent, status):
    """An interruption between a simulation's end and its case file threw the simulation away: here it lands as
    the first case's simulation has ended and its dataset is about to be finished and written (by its worker, here
    the sweep's own process); the file is written, then the sweep ends (no other case)."""
    finished = worker.finished
    recorded = []

    def signalled(task, simulated):
        recorded.append(task.record.attrs["case_id"])
        if len(recorded) == 1:
            signal.raise_signal(sent)
        return finished(task, simulated)

    monkeypatch.setattr(worker, "finished", signalled)
    result = invoke("sweep", tiny_study, "-o", tmp_path / "out", "-q")
    assert result.exit_code == status, result.output
    assert result.stderr.strip() == INTERRUPTED
    assert len(recorded) == 1 and [p.stem for p in (tmp_path / "out" / "cases").glob("*.nc")] == recorded


# Interrupts at random moments of a calibration: each simulation that returns is logged before it is recorded;
# after the process ends every logged one must have its case file (benchmarks/interrupts.py: the many-trials form).
LOGGED = textwrap.dedent("""\
    import os, sys
    from biostudy.execution import backends

    finished = backends.Here.finished
    log = open("finished.txt", "a", buffering=1)

    def logged(self):
        done = finished(self)
        log.writelines(f"{case_id}\\n" for case_id, _ in done)
        return done

    backends.Here.finished = logged
    from biostudy.cli import app
    sys.argv = ["biostudy", "calibrate", "c.toml", "-o", "out", "-q"]
    app()
    """)


def test_interrupts_at_random_moments_end_a_calibration_and_keep_every_finished_simulation(tmp_path):
    from test_calibration_hostile import calibration, table

    calibration(tmp_path, table(*(("biomass", "", t, 2.0 + 2 * t, 0.1) for t in (0.02, 0.05, 0.08))),
                '[estimate]\ng = [1e7, 1e10, "log"]\nr = [20.0, 250.0, "log"]\n[method]\nstarts = 2\n'
                'profiles = false\n')
    (tmp_path / "logged.py").write_text(LOGGED)
    rng = random.Random(39)
    for trial, sent in enumerate((signal.SIGINT, signal.SIGTERM, signal.SIGINT)):
        process = subprocess.Popen([sys.executable, "logged.py"], cwd=tmp_path, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE, text=True)
        time.sleep(rng.uniform(2.0, 5.0))  # imports take ~2 s: from the first simulations on
        process.send_signal(sent)
        try:
            _, stderr = process.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            raise AssertionError(f"trial {trial}: still running 30 s after {sent.name}") from None
        finished = set((tmp_path / "finished.txt").read_text().split()) if (tmp_path / "finished.txt").exists() \
            else set()
        recorded = {p.stem for p in (tmp_path / "out" / "cases").glob("*.nc")}
        # 0: it had finished; -sent: it had, and the signal's default action ended its exit (a shell says 128 + sent)
        assert process.returncode in (128 + sent, 0, -sent), (trial, process.returncode, stderr)
        assert "Exception ignored" not in stderr and finished <= recorded, (trial, stderr, finished - recorded)


# ---- 10. calibrate --workers under a memory limit ------------------------------------------------------------------

def test_calibrate_on_more_workers_than_fit_is_refused_before_anything_runs(tmp_path, monkeypatch):
    """Issue 39.10: `calibrate --workers 4` under a memory limit ran two simulations (its first round), then
    refused ('4 runs at once need ~1.28 GB'), leaving a directory it owned and two cases; as `sweep`, it is
    refused before anything runs or is claimed."""
    from test_calibration_hostile import calibration, table

    from biostudy.execution import backends, pool

    path = calibration(tmp_path, table(("biomass", "", 0.05, 2.0, 0.1), ("biomass", "", 0.1, 2.2, 0.1)),
                       '[estimate]\nr = [50.0, 150.0]\n[method]\nstarts = 1\nprofiles = false\n')
    monkeypatch.setenv("BIOSTUDY_MEMORY", "700 MB")  # one simulation (~320 MB) fits, two do, four do not
    monkeypatch.setattr(pool, "warm_up", lambda: None)  # no fork server outlives this test
    monkeypatch.setattr(backends, "perform", _refuse)  # a case run here (its worker's whole work)
    monkeypatch.setattr(pool.LocalPool, "__init__", _refuse)
    line = one_line(invoke("calibrate", path, "-o", tmp_path / "out", "--workers", "4", "-q"), 2)
    assert "4 simulations at once (--workers 4) need ~" in line and "700 MB available (BIOSTUDY_MEMORY=700 MB); " \
        "use fewer workers" in line
    assert not (tmp_path / "out").exists()


# ---- 11. checks and reports linear in the table ---------------------------------------------------------------------

class _Passes(list):
    """A measurement table that counts the passes made over it."""

    passes = 0

    def __iter__(self):
        self.passes += 1
        return super().__iter__()


def test_named_sigmas_and_datasets_take_one_pass_over_the_table_whatever_their_number(monkeypatch):
    """Issue 39.11: validation scanned the whole table per σ name (64,000 rows of 32,000 names: 97 s) and
    calibration.md's and the fit picture's datasets scanned every measurement per dataset (16,000: 10.5 s); both
    grouped in one pass now (benchmarks/table_scaling.py measures the time).  The picture draws a panel of more
    datasets and replicates than anyone tells apart as one series (30 ms an error-bar series)."""
    import numpy as np
    import xarray as xr

    from biostudy.calibration import noise, petab, pictures
    from biostudy.calibration.measurements import Measurement
    from biostudy.calibration.methods import METHODS

    names = 300
    rows = _Passes(Measurement(2 + i, "biomass", 0.1 * (i % 4), 2.0 + i, float("nan"), noise=f"s{i // 2}")
                   for i in range(2 * names))
    found = noise.noise_parameters(rows)
    assert [p.rows for p in found[:2]] == [(0, 1), (2, 3)] and len(found) == names and rows.passes <= 2
    rows.passes = 0
    assert noise.noise_problems(rows, METHODS["least-squares"], [], Path("t.tsv"), Path("c.toml")) == []
    assert rows.passes <= 3, rows.passes

    n = 2 * names
    text = lambda values: ("measurement", np.array(values, dtype=object))  # noqa: E731
    ds = xr.Dataset({"dataset": text([f"d{i // 2}" for i in range(n)]), "replicate": text(["r"] * n),
                     "observable": text(["biomass"] * n), "condition": text([""] * n),
                     "residual": ("measurement", np.ones(n)), "time_measured": ("measurement", np.arange(n) / n),
                     "measured": ("measurement", np.ones(n)), "sigma": ("measurement", np.ones(n))})
    scans = []
    monkeypatch.setattr(petab, "enumerate", lambda items: scans.append(1) or enumerate(items), raising=False)
    lines = petab.datasets_text(ds)
    assert len(lines) == 5 + names and lines[-1] == f"| d{names - 1} | biomass | - | r | 2 | 2 |" and len(scans) <= 1

    class Axes:
        def __init__(self):
            self.series: list[str] = []

        def errorbar(self, t, y, yerr, label, **style):
            self.series.append(label)

    ax = Axes()
    assert pictures._measured(ax, ds, np.arange(n))
    assert ax.series == [f"measured ± σ ({names} datasets, 1 replicate)"]
    ax = Axes()
    assert pictures._measured(ax, ds, np.arange(6))  # three datasets: told apart
    assert ax.series == [f"measured ± σ, dataset d{k}, replicate r" for k in range(3)]


# ---- 13. ids as written or refused ---------------------------------------------------------------------------------

def test_ids_with_a_line_break_or_a_tab_are_refused_one_line_each_at_their_lines(tmp_path):
    """Issue 39.13: a quoted "new<line break>line" datasetId became `newline` in calibration.nc and
    simulation.tsv (csv joins a quoted cell's lines without the break), no longer the table's; a tab inside an
    id went raw into calibration.md.  Both are refused, one line each, and the rows after a cell that ran over
    two lines are blamed at their own lines."""
    from test_calibration_hostile import calibration

    from biostudy.calibration.measurements import read_measurements

    rows = ("observableId\ttime\tmeasurement\tnoiseParameters\tdatasetId\treplicateId\n"
            'biomass\t0.05\t2.0\t0.1\t"new\nline"\t\n'
            'biomass\t0.1\t2.2\t0.1\t"a\tb"\t\n'
            "biomass\t0.1\t2.2\t0.1\tkept | as written\tr\x0b1\n"
            "biomass\t0.1\tx\t0.1\tok\t\n")
    path = calibration(tmp_path, rows, "[estimate]\nr = [50.0, 150.0]\n")
    result = invoke("show", path)
    assert result.exit_code == 2 and "Traceback" not in result.output, result.output
    assert result.stderr.replace(f"{tmp_path}/", "").strip().splitlines() == [
        "error: t.tsv: line 2: a quoted cell runs on to line 3: a cell is one line (csv joins its lines without "
        "their line break, so the row would not be as written; close the quote on its line)",
        "error: t.tsv: line 4: datasetId: has a tab or control character (got 'a\\tb'): an id is printable text, "
        "as calibration.md, calibration.nc and simulation.tsv write it",
        "error: t.tsv: line 5: replicateId: has a tab or control character (got 'r\\x0b1'): an id is printable "
        "text, as calibration.md, calibration.nc and simulation.tsv write it",
        "error: t.tsv: line 6: measurement: not a number (got 'x')"]
    (tmp_path / "t.tsv").write_text(rows.split("\n", 1)[0] + "\nbiomass\t0.1\t2.2\t0.1\tkept | as  written\tr 1\n")
    assert [(m.dataset, m.replicate) for m in read_measurements(tmp_path / "t.tsv")] == [("kept | as  written", "r 1")]


def _scene(path: Path):
    from biostudy.inputs.scene import load_scene

    return load_scene(path)


def _refuse(*args, **kwargs):
    raise AssertionError("simulated although the run was refused")
