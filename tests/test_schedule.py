"""The sweep's process only schedules (issue 35, item 1): a worker does all of its case's work and hands back a
small record; the case file is the worker's; a worker lost in the middle of writing costs its case only."""
from __future__ import annotations

import os
import pickle
import signal
from pathlib import Path

import numpy as np
import xarray as xr

from biostudy.commands.sweep import run_study
from biostudy.data import case_files, netcdf_io, writing
from biostudy.data.finish import Record, finish
from biostudy.execution import jobs, worker
from biostudy.execution.jobs import Execution
from biostudy.inputs.scene import load_scene
from biostudy.plans.study import load_study


def _task(scene_path: Path, path: Path | None, measure: tuple[str, ...] = ()) -> worker.Task:
    scene = load_scene(scene_path)
    return worker.Task(scene.problem(), Record.of(scene, scene_path, "", case_id="tiny"),
                       None if path is None else str(path), measure=measure)


def test_a_worker_hands_back_a_small_record_and_writes_its_case_file(tiny_scene, tmp_path):
    """The record holds what the sweep tells and a calibration needs, never the fields; the file holds the run
    finished as `biostudy run` finishes one."""
    outcome = worker.perform(_task(tiny_scene, tmp_path / "case.nc", measure=("biomass", "height_x")))
    assert (outcome.status, outcome.message, outcome.written, outcome.data) == ("done", "", True, None)
    assert sorted(outcome.series) == ["biomass", "height_x", "time"]
    assert len(pickle.dumps(outcome)) < 4000  # a few numbers; the fields of even this 16 x 16 run are 18 kB
    assert netcdf_io.intact(tmp_path / "case.nc") and not list(tmp_path.glob(".*.tmp"))
    written = xr.load_dataset(tmp_path / "case.nc")
    scene = load_scene(tiny_scene)
    simulated = worker.solve(scene.problem())
    alone = finish(simulated.dataset, Record.of(scene, tiny_scene, "", case_id="tiny"), status="done", message="")
    for name in ("phi", "c", "alpha", "biomass", "coverage", "front_advance"):
        np.testing.assert_array_equal(written[name].values, alone[name].values)
    np.testing.assert_array_equal(outcome.series["biomass"], alone["biomass"].values)
    np.testing.assert_array_equal(outcome.series["time"], alone["time"].values)
    assert written.attrs["observables"] == alone.attrs["observables"] and written.attrs["case_id"] == "tiny"


def test_a_worker_without_the_sweeps_directory_hands_back_the_files_bytes(tiny_scene, tmp_path):
    """As a Dask worker on another machine: the same file, as bytes, which the sweep's process writes unread."""
    outcome = worker.perform(_task(tiny_scene, None))
    assert outcome.status == "done" and not outcome.written and outcome.data[:4] == b"\x89HDF"
    (tmp_path / "case.nc").write_bytes(outcome.data)
    assert netcdf_io.intact(tmp_path / "case.nc")
    assert float(xr.load_dataset(tmp_path / "case.nc").phi.sum()) > 0


def test_a_failed_simulation_is_recorded_by_its_worker(write_toml, tiny_scene, tmp_path):
    bad = write_toml("bad.toml", (tmp_path / "tiny.toml").read_text().replace("g = 1e8", "g = 1e8\nk_alpha = 1e100"))
    outcome = worker.perform(_task(bad, tmp_path / "case.nc"))
    assert outcome.status == "failed" and outcome.written and outcome.message.startswith("t = 0: ")
    record = xr.load_dataset(tmp_path / "case.nc")
    assert record.attrs["status"] == "failed" and record.attrs["message"] == outcome.message
    assert not record.data_vars


def dies_writing(tasks, lifeline):
    """A worker that, for the case r = 100, starts writing its case file and is killed (out of memory, say)."""
    original = worker.perform

    def perform(task):
        if task.problem.params.r == 100.0:
            writing.temporary_name(Path(task.path)).write_bytes(b"\x89HDF half a file")
            os.kill(os.getpid(), signal.SIGKILL)
        return original(task)

    worker.perform = perform
    worker.serve(tasks, lifeline)


def test_a_worker_lost_while_it_writes_costs_its_case_and_leaves_no_temporary(tiny_study, tmp_path, monkeypatch):
    monkeypatch.setattr(worker, "serve", dies_writing)
    out = tmp_path / "out"
    report = run_study(load_study(tiny_study), out, Execution(workers=2))
    assert sorted(report.failed) == ["g=1e+08_r=100", "g=1e+09_r=100"]
    assert all(m.startswith("worker died: signal 9") for m in report.failed.values())
    assert not list((out / "cases").glob(".*")) and not list(out.glob(".*.tmp"))  # the half-written file is gone
    study = xr.load_dataset(out / "study.nc")
    assert sorted(study.status.values.ravel().tolist()) == ["done", "done", "failed", "failed"]
    assert case_files.recorded(case_files.case_file(out, "g=1e+09_r=100"))["status"] == "failed"
    monkeypatch.undo()
    again = run_study(load_study(tiny_study), out, Execution(retry_failed=True))  # here, and then they finish
    assert sorted(again.ran) == ["g=1e+08_r=100", "g=1e+09_r=100"] and again.ok


def test_a_case_file_a_worker_cannot_write_stops_the_sweep_in_one_line(tiny_study, tmp_path, monkeypatch):
    """A worker's failed write (here: the sweep's own process, running cases one after another) comes back in its
    record and stops the sweep with what was kept, as a write of the sweep's process would."""
    def full(ds, path, *args, **kwargs):
        raise writing.NotWritten(28, f"cannot write {path}: the disk is full")

    monkeypatch.setattr(writing, "write_atomic", full)
    try:
        run_study(load_study(tiny_study), tmp_path / "out")
    except jobs.SweepError as error:
        said = str(error)
    assert said.startswith("cannot write ") and "the disk is full; the cases recorded before are kept" in said
