"""Nothing lost, nothing hung, second round (issue 21): the faults a hostile user found, each injected.

Numbered as the issue's items: 1 damaged case headers and truncated case files, 2 two runs racing to one
output, 3 foreign files never replaced, 4 SIGTERM during a write and temporaries of killed runs, 5 hostile
input files and a grid too big to validate, 6 a silent, an empty and a lost Dask scheduler, 7 a full disk,
8 refused runs leave no claim behind, 9 misleading records, 10 the remaining tracebacks.  Scenes are tiny
(2-D 16², 20 steps); processes of their own only where a real signal, a race or a user's stderr is the
point, and every one is ended by its test.  Nothing here probes permissions (which prove nothing as root).
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import CUBE_SCENE, TINY_SCENE
from scipy import stats
from typer.testing import CliRunner

import solver
from biostudy.cli import app
from biostudy.commands.analyze import current
from biostudy.commands.sweep import run_study
from biostudy.data import case_files, combine, netcdf_io, reading
from biostudy.execution import dask, pool, worker
from biostudy.execution.jobs import Execution
from biostudy.inputs import files
from biostudy.plans.study import load_study
from biostudy.reports.sensitivity import analyze as indices

cli = CliRunner()
HERE = Path(__file__).resolve().parent
CASE = "g=1e+09_r=50"


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def one_line(result, status: int = 2) -> str:
    """The single line of an error: its exit status, 'error: ...', no traceback."""
    assert result.exit_code == status, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.output
    return lines[0]


def lines_of(result, status: int = 2) -> list[str]:
    assert result.exit_code == status, result.output
    lines = result.stderr.strip().splitlines()
    assert lines and all(line.startswith("error: ") for line in lines) and "Traceback" not in result.output
    return lines


@pytest.fixture
def hang_guard():
    """A test that would hang fails after 30 s instead (SIGALRM interrupts a blocking open or read)."""
    def expire(signum, frame):
        raise TimeoutError("hung")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(30)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished 2 x 2 sweep of the tiny scene, its study file, and two runs (5 and 3 outputs); tests work on
    copies of the sweep (`copied`)."""
    root = tmp_path_factory.mktemp("finished")
    (root / "tiny.toml").write_text(TINY_SCENE)
    study = root / "tiny-sweep.toml"
    study.write_text('scene = "tiny.toml"\n[sweep]\ng = [1e8, 1e9]\nr = [50.0, 100.0]\n')
    run_study(load_study(study), root / "sweep")
    for name, outputs in (("long", 5), ("short", 3)):
        assert invoke("run", root / "tiny.toml", "-o", root / f"{name}.nc", "-q", "--set",
                      f"time.outputs={outputs}").exit_code == 0
    return {"root": root, "study": study, "scene": root / "tiny.toml", "sweep": root / "sweep",
            "long": root / "long.nc", "short": root / "short.nc"}


def copied(finished, tmp_path) -> Path:
    out = tmp_path / "sweep"
    shutil.copytree(finished["sweep"], out)
    (out / ".biostudy.lock").unlink(missing_ok=True)
    return out


def slow_scene(directory: Path, name: str, steps: int) -> Path:
    path = directory / f"{name}.toml"
    path.write_text(TINY_SCENE.replace('name = "tiny"', f'name = "{name}"').replace("steps = 20", f"steps = {steps}"))
    return path


# ---------------------------------------------------------------------------------------------
# 1. A damaged case header does not block the study; truncated case files are named


def test_a_case_header_changed_in_place_is_damaged_to_every_command_and_computed_again(finished, tmp_path):
    out = copied(finished, tmp_path)
    path = case_files.case_file(out, CASE)
    good = reading.open_dataset(path).phi.values
    raw = bytearray(path.read_bytes())
    at = raw.index(b"radius = 3.0")  # 3 bytes inside the scene attribute: radius 3 -> 9, the size unchanged
    raw[at + 9:at + 12] = b"9.0"
    path.write_bytes(raw)
    assert not netcdf_io.intact(path)
    for args in (["show", path], ["plot", path, "-o", tmp_path / "fig.png"], ["export", path, tmp_path / "vtk"],
                 ["analyze", out]):
        line = one_line(invoke(*args))
        assert f"{path}: damaged" in line, args
    assert not list(tmp_path.glob("fig*")) and not (tmp_path / "vtk").exists()
    result = invoke("sweep", finished["study"], "-o", out, "-q", "--retry-failed")
    assert result.exit_code == 0, result.output
    assert f"warning: 1 case file was damaged (could not be read whole: header, attributes or data) and computed " \
           f"again: {CASE}" in result.stderr
    np.testing.assert_array_equal(reading.open_dataset(path).phi.values, good)
    assert netcdf_io.intact(out / "study.nc")


def test_truncated_case_files_are_named_and_computed_again(finished, tmp_path):
    out = copied(finished, tmp_path)
    plan = load_study(finished["study"])
    cut, emptied = case_files.case_file(out, "g=1e+08_r=50"), case_files.case_file(out, "g=1e+09_r=100")
    cut.write_bytes(cut.read_bytes()[:60_000])
    emptied.write_bytes(b"")
    report = run_study(plan, out)
    assert sorted(report.damaged) == sorted(report.ran) == ["g=1e+08_r=50", "g=1e+09_r=100"]
    assert "g=1e+08_r=50, g=1e+09_r=100" in report.warnings()[0]
    assert netcdf_io.intact(cut) and netcdf_io.intact(emptied)


def test_combine_names_the_truncated_and_the_damaged_case_files_it_cannot_read(finished, tmp_path):
    out = copied(finished, tmp_path)
    study_nc = (out / "study.nc").read_bytes()
    cut, damaged = case_files.case_file(out, "g=1e+08_r=50"), case_files.case_file(out, "g=1e+09_r=100")
    cut.write_bytes(cut.read_bytes()[:60_000])
    raw = bytearray(damaged.read_bytes())
    half = slice(len(raw) // 4, 3 * len(raw) // 4)
    raw[half] = bytes(b ^ 0xFF for b in raw[half])  # its data; the attributes still say "done"
    damaged.write_bytes(raw)
    lines = lines_of(invoke("sweep", finished["study"], "-o", out, "--combine"))
    assert len(lines) == 2 and all("damaged or truncated: it cannot be read whole" in line for line in lines)
    assert {line.split(": ")[1] for line in lines} == {str(cut), str(damaged)}
    assert (out / "study.nc").read_bytes() == study_nc  # nothing written over it


# ---------------------------------------------------------------------------------------------
# 2. Two runs into one output: the second is refused or told, never silently replaced


def test_two_runs_racing_to_one_output_one_is_refused_and_a_killed_ones_claim_is_cleaned_up(tmp_path):
    scenes = [slow_scene(tmp_path, name, 6000) for name in ("first", "second")]
    out = tmp_path / "same.nc"
    runs = [subprocess.Popen([sys.executable, "-m", "biostudy", "run", str(scene), "-o", str(out), "-q"],
                             stderr=subprocess.PIPE, text=True) for scene in scenes]
    try:
        deadline = time.monotonic() + 120
        while all(run.poll() is None for run in runs) and time.monotonic() < deadline:
            time.sleep(0.05)
        refused = next(i for i, run in enumerate(runs) if run.poll() is not None)
        winner = runs[1 - refused]
        stderr = runs[refused].communicate(timeout=30)[1]
        assert runs[refused].returncode == 2, stderr
        assert stderr.strip() == (f"error: {out}: another biostudy run (pid {winner.pid}) is computing this output; "
                                  "wait for it to end, or choose another output")
        assert winner.poll() is None  # still computing: kill -9 it
        claims = list(tmp_path.glob(f".same.nc.{winner.pid}.*.tmp"))
        assert len(claims) == 1
        winner.kill()
        winner.wait(timeout=30)
    finally:
        for run in runs:
            run.kill()
            run.wait()
    assert claims[0].exists() and not out.exists()  # SIGKILL: no handler, no finally
    done = invoke("run", scenes[refused], "-o", out, "-q", "--set", "time.steps=20")
    assert done.exit_code == 0, done.output
    assert not list(tmp_path.glob(".*.tmp"))  # the killed writer's temporary is gone
    assert xr.open_dataset(out).attrs["scene_file"] == str(scenes[refused])


def test_a_result_is_not_written_over_a_file_changed_while_it_ran(finished, tmp_path, monkeypatch):
    out = tmp_path / "out.nc"
    simulate = solver.simulate

    def meanwhile(*args, **kwargs):
        ds = simulate(*args, **kwargs)
        out.write_text("written by another program meanwhile")
        return ds

    monkeypatch.setattr(solver, "simulate", meanwhile)
    line = one_line(invoke("run", finished["scene"], "-o", out, "-q"), 1)
    kept = tmp_path / "out.1.nc"
    assert line == (f"error: {out} was changed by another program while this run computed; it is left as it is, "
                    f"and this run's result is kept in {kept}")
    assert out.read_text() == "written by another program meanwhile" and netcdf_io.intact(kept)
    assert not list(tmp_path.glob(".*.tmp"))


# ---------------------------------------------------------------------------------------------
# 3. A file biostudy cannot prove it wrote is never replaced, --force or not


def test_plot_and_export_never_replace_files_biostudy_did_not_write(finished, tmp_path):
    mine = tmp_path / "fig_series.png"
    mine.write_bytes(b"\x89PNG\r\n\x1a\n my own picture")
    line = one_line(invoke("plot", finished["short"], "-o", tmp_path / "fig.png"))
    assert line == (f"error: {mine}: exists and is not a picture biostudy wrote; refusing to overwrite it (choose "
                    "another output, or remove the file first)")
    assert mine.read_bytes().endswith(b"my own picture") and sorted(os.listdir(tmp_path)) == ["fig_series.png"]
    vtk = tmp_path / "vtk"
    vtk.mkdir()
    (vtk / "series.pvd").write_text("my collection")
    (vtk / "snapshot_0000.vti").write_text("my snapshot")
    errors = lines_of(invoke("export", finished["short"], vtk))
    assert [e.split(": ")[1] for e in errors] == [str(vtk / "snapshot_0000.vti"), str(vtk / "series.pvd")]
    assert sorted(os.listdir(vtk)) == ["series.pvd", "snapshot_0000.vti"]
    assert (vtk / "series.pvd").read_text() == "my collection"
    # biostudy's own files are replaced, and an earlier, longer export's extra snapshots go (a foreign one stays)
    ours = tmp_path / "ours"
    assert invoke("export", finished["long"], ours).exit_code == 0
    (ours / "snapshot_0009.vti").write_text("not biostudy's")
    assert invoke("export", finished["short"], ours).exit_code == 0
    assert sorted(os.listdir(ours)) == ["series.pvd", "snapshot_0000.vti", "snapshot_0001.vti", "snapshot_0002.vti",
                                        "snapshot_0009.vti"]
    assert (ours / "series.pvd").read_text().count("<DataSet ") == 3
    assert invoke("plot", finished["short"], "-o", tmp_path / "again.png").exit_code == 0
    assert invoke("plot", finished["short"], "-o", tmp_path / "again.png").exit_code == 0


def _foreign_netcdf(path: Path, truncated: bool) -> bytes:
    xr.Dataset({"temperature": ("t", np.arange(2000.0))}).to_netcdf(path, engine="netcdf4")
    if truncated:
        path.write_bytes(path.read_bytes()[:3000])
    return path.read_bytes()


def test_a_damaged_or_foreign_netcdf_is_never_replaced_force_or_not(finished, tmp_path):
    damaged = tmp_path / "theirs.nc"
    before = _foreign_netcdf(damaged, truncated=True)
    line = one_line(invoke("run", finished["scene"], "-o", damaged, "--force", "-q"))
    assert "exists and is a damaged or truncated netCDF file, so biostudy cannot tell whether it wrote it" in line
    assert damaged.read_bytes() == before
    folder = tmp_path / "folder"
    (folder / "cases").mkdir(parents=True)
    study_nc = _foreign_netcdf(folder / "study.nc", truncated=True)
    case = _foreign_netcdf(folder / "cases" / "g=1e+08_r=50.nc", truncated=False)
    errors = lines_of(invoke("sweep", finished["study"], "-o", folder, "--force", "-q"))
    assert [e.split(": ")[1] for e in errors] == [str(folder / "study.nc"), str(folder / "cases" / "g=1e+08_r=50.nc")]
    assert sorted(os.listdir(folder)) == ["cases", "study.nc"]  # no owner record, no lock: refused before both
    assert "holds files that no biostudy run recorded" in one_line(invoke("sweep", finished["study"], "-o", folder))
    assert (folder / "study.nc").read_bytes() == study_nc
    assert (folder / "cases" / "g=1e+08_r=50.nc").read_bytes() == case
    # in a sweep's own directory, a case file that is not biostudy's stops the sweep before anything runs
    out = copied(finished, tmp_path)
    planted = _foreign_netcdf(case_files.case_file(out, CASE), truncated=False)
    line = one_line(invoke("sweep", finished["study"], "-o", out, "-q", "--rerun-all"))
    assert line.startswith(f"error: {case_files.case_file(out, CASE)}: exists and is not a dataset biostudy wrote")
    assert case_files.case_file(out, CASE).read_bytes() == planted


# ---------------------------------------------------------------------------------------------
# 4. SIGTERM (or Ctrl-C) while a dataset is written ends the run at once; a killed run's temporary is cleaned up


def test_sigterm_at_many_points_of_a_write_ends_the_run_and_leaves_the_old_file_or_the_new_one(tmp_path):
    process = subprocess.run([sys.executable, str(HERE / "interrupted_writes.py"), str(tmp_path), "run:6", "study:2",
                              "run:4:INT"], capture_output=True, text=True, timeout=300)
    assert process.returncode == 0, process.stderr
    trials = [json.loads(line) for line in process.stdout.splitlines()]
    assert len(trials) == 12
    assert {t["signal"] for t in trials} == {"SIGTERM", "SIGINT"}
    for trial in trials:
        assert trial["ended"] is not None, trial  # not hung (the guard is 20 s; it ends in well under 1 s)
        interrupted = 143 if trial["signal"] == "SIGTERM" else 130
        assert trial["status"] in (0, interrupted, -signal.SIGTERM, -signal.SIGINT), (trial, process.stderr[-3000:])
        assert trial["temporaries"] == [], trial
        assert trial["whole"] == trial["output"], trial  # the old file or the new one, complete
    assert all(t["output"] for t in trials if t["kind"] == "study")  # study.nc was there before: never lost
    assert sum(t["status"] in (130, 143) for t in trials) >= 5  # signals landed while the commands ran


# ---------------------------------------------------------------------------------------------
# 5. Input files are regular files of bounded size; a run too big to fit is refused before it allocates


@pytest.mark.parametrize("kind", ["device", "fifo", "directory", "too big"])
def test_an_input_file_that_is_no_regular_file_or_too_big_is_one_line(kind, tmp_path, monkeypatch, hang_guard):
    path = tmp_path / "input.toml"
    if kind == "device":
        path = Path("/dev/zero")
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    else:
        monkeypatch.setattr(files, "TOML_BYTES", 1024, raising=False)
        path.write_text(TINY_SCENE + "#" * 1024)
    expected = {"device": "is a character device, not a TOML file", "fifo": "is a FIFO (named pipe), not a TOML file",
                "directory": "is a directory, not a TOML file",
                "too big": f"is {len(TINY_SCENE) / 1024 + 1:.3g} KiB; a TOML file may hold at most 1 KiB"}[kind]
    for command in ("run", "sweep"):
        assert one_line(invoke(command, path, "-o", tmp_path / "out")) == f"error: {path}: {expected}"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", ["directory", "fifo", "device"])
def test_a_mask_that_is_no_regular_file_is_one_line(kind, tmp_path, hang_guard):
    mask = {"directory": tmp_path / "mask", "fifo": tmp_path / "mask.npy", "device": Path("/dev/zero")}[kind]
    if kind == "directory":
        mask.mkdir()
    elif kind == "fifo":
        os.mkfifo(mask)
    scene = tmp_path / "masked.toml"
    scene.write_text(TINY_SCENE + f'[[obstacle]]\nshape = "mask"\npath = "{mask}"\n')
    what = {"directory": "a directory", "fifo": "a FIFO (named pipe)", "device": "a character device"}[kind]
    line = one_line(invoke("run", scene, "-o", tmp_path / "out.nc"))
    assert line == f"error: {scene}: obstacle[1].path: mask file '{mask}' is {what}, not a .npy mask file"


@pytest.mark.parametrize("command", ["run", "sweep"])
def test_a_run_or_sweep_too_big_for_this_machine_is_refused_before_its_arrays_are_built(command, tmp_path,
                                                                                         monkeypatch):
    monkeypatch.setenv("BIOSTUDY_MEMORY", "8 GB")
    scene = tmp_path / "cube.toml"
    scene.write_text(CUBE_SCENE)
    given = scene
    if command == "sweep":
        given = tmp_path / "study.toml"
        given.write_text('scene = "cube.toml"\n[sweep]\ng = [1e8, 1e9]\n')
    tracemalloc.start()
    try:
        result = invoke(command, given, "-o", tmp_path / "out", "--set", "grid.shape=[400, 400, 400]")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    line = one_line(result)
    assert line.startswith("error: --set: grid.shape: needs ~")
    assert "of memory (cube: transport ~" in line and line.endswith(", 8 GB available (BIOSTUDY_MEMORY=8 GB)")
    assert peak < 400 ** 3  # not even one boolean array of the grid (64 MB) was made
    assert sorted(os.listdir(tmp_path)) == sorted({"cube.toml", given.name})


# ---------------------------------------------------------------------------------------------
# 6. Dask: a silent address, a scheduler without workers, a scheduler lost mid-sweep


def test_an_address_that_accepts_and_never_answers_times_out_in_one_line(finished, tmp_path, monkeypatch, hang_guard):
    monkeypatch.setattr(dask, "CONNECT_TIMEOUT", 1.0)
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)
    held = []
    threading.Thread(target=lambda: held.append(listener.accept()), daemon=True).start()
    address = f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    try:
        line = one_line(invoke("sweep", finished["study"], "-o", tmp_path / "out", "--scheduler", address, "-q"))
    finally:
        listener.close()
    assert line == (f"error: --scheduler: cannot connect to a Dask scheduler at {address}: nothing answered within "
                    "1 s (a program that accepts the connection but is no Dask scheduler, or one that is stuck)")
    assert held and not (tmp_path / "out").exists()


def test_a_scheduler_without_workers_is_said_and_said_again(finished, tmp_path, monkeypatch, hang_guard):
    import distributed

    monkeypatch.setattr(dask, "NOTICE_EVERY", 0.2, raising=False)
    notes = []
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        address = cluster.scheduler_address

        def notify(event, case_id, message):
            if event == "note":
                notes.append(message)
                if len(notes) == 3:
                    cluster.scale(1)  # a worker comes after all: the sweep goes on

        report = run_study(load_study(finished["study"]), tmp_path / "out", Execution(scheduler=address, notify=notify))
    assert len(notes) >= 3
    assert all(note.startswith(f"waiting for workers on {address}: none is connected") for note in notes)
    assert len(report.ran) == 4 and not report.failed


def test_a_scheduler_lost_mid_sweep_says_what_was_kept_and_how_to_resume(tmp_path, capfd, hang_guard):
    import distributed

    (tmp_path / "tiny.toml").write_text(TINY_SCENE)
    study = tmp_path / "slow.toml"
    study.write_text('scene = "tiny.toml"\n[set]\n"time.t_end" = 1.0\n"time.steps" = 200\n[sweep]\n'
                     'r = [50.0, 60.0, 70.0, 80.0]\n')
    out = tmp_path / "out"
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None)
    address = cluster.scheduler_address

    def lose():  # the cluster goes down once the first case is recorded
        deadline = time.monotonic() + 120
        while not list((out / "cases").glob("*.nc")) and time.monotonic() < deadline:
            time.sleep(0.02)
        cluster.close()

    closer = threading.Thread(target=lose)
    closer.start()
    try:
        result = invoke("sweep", study, "-o", out, "-q", "--scheduler", address)
    finally:
        closer.join(timeout=120)
        cluster.close()
    recorded = sorted(p.stem for p in (out / "cases").glob("*.nc"))
    assert one_line(result, 1) == (
        f"error: lost the Dask scheduler at {address} (the connection to it broke); {len(recorded)} "
        f"case{'s' if len(recorded) > 1 else ''} recorded in {out / 'cases'} {'are' if len(recorded) > 1 else 'is'} "
        f"kept ({4 - len(recorded)} of 4 to run did not finish); run the same command again to resume")
    assert "Traceback" not in capfd.readouterr().err  # distributed's own log lines were held back
    report = run_study(load_study(study), out)  # resumed here: what was recorded is kept
    assert sorted(report.skipped) == recorded and len(report.ran) == 4 - len(recorded)


# ---------------------------------------------------------------------------------------------
# 7. A full disk: one line naming the disk and what was kept


def _full(disk: Path) -> str:
    return f"the disk is full (the file system at {disk}, 0 kB free)"


def test_a_disk_full_during_a_runs_write_is_one_line(finished, small_disk, monkeypatch):
    disk, fill = small_disk
    simulate = solver.simulate
    monkeypatch.setattr(solver, "simulate", lambda *args, **kwargs: (simulate(*args, **kwargs), fill())[0])
    line = one_line(invoke("run", finished["scene"], "-o", disk / "out.nc", "-q"), 1)
    assert line == (f"error: cannot write {disk / 'out.nc'}: {_full(disk)}; this run's result is lost (nothing was "
                    "written)")
    assert os.listdir(disk) == ["filler"]


def test_a_disk_full_during_a_case_or_study_nc_is_one_line_and_keeps_the_cases(finished, small_disk, monkeypatch):
    disk, fill = small_disk
    solve = worker.solve
    solved = []

    def second_fills(problem):
        solved.append(problem)
        return (solve(problem), fill() if len(solved) == 2 else None)[0]

    monkeypatch.setattr(worker, "solve", second_fills)
    line = one_line(invoke("sweep", finished["study"], "-o", disk / "a", "-q"), 1)
    second = case_files.case_file(disk / "a", "g=1e+08_r=100")
    assert line == (f"error: cannot write {second}: {_full(disk)}; the cases recorded before are kept, run the same "
                    "command again to resume once there is room")
    assert [p.name for p in (disk / "a" / "cases").iterdir()] == ["g=1e+08_r=50.nc"]
    assert netcdf_io.intact(disk / "a" / "cases" / "g=1e+08_r=50.nc")
    (disk / "filler").unlink()
    shutil.rmtree(disk / "a")
    monkeypatch.setattr(worker, "solve", solve)
    stack = combine._combined  # the study combined (its fields to come), then the disk fills
    monkeypatch.setattr(combine, "_combined", lambda *args: (stack(*args), fill())[0])
    line = one_line(invoke("sweep", finished["study"], "-o", disk / "b", "-q"), 1)
    assert line == (f"error: cannot write {disk / 'b' / 'study.nc'}: {_full(disk)}; the case files in "
                    f"{disk / 'b' / 'cases'} are kept: run the same command again to write study.nc (nothing is "
                    "computed again)")
    assert len(list((disk / "b" / "cases").glob("*.nc"))) == 4 and not list(disk.rglob("*.tmp"))


# ---------------------------------------------------------------------------------------------
# 8. A refused run leaves the folder as it found it


def test_refused_sweeps_leave_no_claim_behind(finished, tmp_path, monkeypatch):
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    monkeypatch.setattr(dask, "CONNECT_TIMEOUT", 1.0)
    monkeypatch.setattr(pool, "warm_up", lambda: None)  # no fork server outlives this test
    line = one_line(invoke("sweep", finished["study"], "-o", ".", "-q", "--scheduler", "tcp://127.0.0.1:9"))
    assert "nothing listens at tcp://127.0.0.1:9" in line and os.listdir(here) == []
    monkeypatch.setenv("BIOSTUDY_MEMORY", "450 MB")  # one run (~320 MB) fits, two do not
    for target in (".", "new/deeper"):
        line = one_line(invoke("sweep", finished["study"], "-o", target, "-q", "--workers", "2"))
        assert "use fewer workers" in line and os.listdir(here) == []
    (here / "notes.txt").write_text("mine")
    assert "holds files that no biostudy run recorded" in one_line(invoke("sweep", finished["study"], "-o", "."))
    assert os.listdir(here) == ["notes.txt"]


# ---------------------------------------------------------------------------------------------
# 9. Misleading records and messages


def test_an_override_of_a_swept_key_is_refused(finished, tmp_path):
    line = one_line(invoke("sweep", finished["study"], "-o", tmp_path / "out", "--set", "g=1e10"))
    assert line == ("error: --set: g: is varied by this study (sweep g), so every case would replace it; change the "
                    "study's values instead")
    study = tmp_path / "set.toml"
    study.write_text(f'scene = "{finished["scene"]}"\n[set]\n"params.r" = 3.0\n[sweep]\nr = [50.0, 100.0]\n')
    line = one_line(invoke("sweep", study, "-o", tmp_path / "out"))
    assert line.startswith(f"error: {study}: set.params.r: is varied by this study (sweep r)")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("mode, expected", [
    ("grid", "sweep.name: lists 'a/b' and 'a-b', which collide as file names: both are a-b in a case id"),
    ("zip", "sweep: cases {'name': 'a/b'} and {'name': 'a-b'} collide as file names: both are case name=a-b")])
def test_case_ids_that_collide_as_file_names_say_so(finished, tmp_path, mode, expected):
    study = tmp_path / "names.toml"
    study.write_text(f'scene = "{finished["scene"]}"\n[sweep]\nmode = "{mode}"\nname = ["a/b", "a-b"]\n')
    assert one_line(invoke("sweep", study, "-o", tmp_path / "out")).startswith(f"error: {study}: {expected}")


def test_every_bad_case_of_a_study_is_told(finished, tmp_path):
    study = tmp_path / "bad.toml"
    study.write_text(f'scene = "{finished["scene"]}"\n[sweep]\ng = [1e8, -1, nan, inf]\n')
    assert lines_of(invoke("sweep", study, "-o", tmp_path / "out")) == [
        f"error: {study}: case g=-1: params.g: must be >= 0 (got -1)",
        f"error: {study}: case g=nan: params.g: must be a finite number (got nan)",
        f"error: {study}: case g=inf: params.g: must be a finite number (got inf)"]


def test_a_study_sweeping_a_text_key_is_analysed_with_the_key_coded_in_its_order(finished, tmp_path):
    study = tmp_path / "laws.toml"
    study.write_text(f'scene = "{finished["scene"]}"\n[sweep]\n"model.consumption" = ["zero-order", "first-order"]\n'
                     'g = [1e8, 1e10]\n')
    run_study(load_study(study), tmp_path / "out")
    ds = reading.open_dataset(tmp_path / "out" / "study.nc")
    result = indices(ds, ["c_mean"])
    volume = ds.c_mean.isel(time=-1).transpose("model_consumption", "g").values.ravel()
    law = np.repeat([0.0, 1.0], 2)  # zero-order first, as the study lists them
    expected = stats.spearmanr(law, volume).statistic
    got = float(result.spearman.sel(output="c_mean", parameter="model_consumption"))
    assert got == pytest.approx(expected, abs=1e-12) and abs(expected) > 0
    assert "model_consumption is categorical (0 = zero-order, 1 = first-order" in result.attrs["notes"]


def test_analyze_rebuilds_a_damaged_study_nc_from_the_cases(finished, tmp_path):
    out = copied(finished, tmp_path)
    good = reading.open_dataset(out / "study.nc")
    raw = (out / "study.nc").read_bytes()
    (out / "study.nc").write_bytes(raw[:len(raw) // 2])  # truncated, and newer than every case
    rebuilt = current(out / "study.nc")
    for name in ("phi_mean", "c_mean", "biofilm_volume", "height", "status"):
        np.testing.assert_array_equal(rebuilt[name].values, good[name].values)
    assert rebuilt.attrs["overrides"] == good.attrs["overrides"]


# ---------------------------------------------------------------------------------------------
# 10. The remaining tracebacks, and usage errors in one line


def test_a_reference_of_another_dimension_is_one_line(finished, tmp_path):
    scene = tmp_path / "cube.toml"
    scene.write_text(CUBE_SCENE)
    line = one_line(invoke("convergence", scene, "--reference", finished["short"], "-o", tmp_path / "conv", "-q"))
    assert line == f"error: {finished['short']}: --reference: is a 2-D run; the scene is 3-D"
    assert not (tmp_path / "conv").exists()


def test_a_study_nc_without_its_case_variables_is_one_line(tmp_path):
    path = tmp_path / "study.nc"
    xr.Dataset({"phi_mean": ("g", [0.1, 0.2])}, coords={"g": [1e8, 1e9]},
               attrs={"biostudy_version": "0.1.0", "sweep_mode": "grid", "sweep_dimensions": "g"}).to_netcdf(path)
    line = one_line(invoke("show", path))
    assert line.startswith(f"error: {path}: a study.nc without case_id, status: not as biostudy writes one")


@pytest.mark.parametrize("args, expected", [
    (["run", "--bogus", "x.toml"], "error: biostudy run: No such option: --bogus"),  # click may name a close one
    (["run"], "error: biostudy run: Missing argument 'SCENE'. (see `biostudy run -h`)")])
def test_usage_errors_are_one_line(args, expected):
    line = one_line(invoke(*args))
    assert line.startswith(expected) and line.endswith(f"(see `biostudy {args[0]} -h`)"), line
    # a value an option's rule refuses is bad input, said as Python says it (`commands.options`)
    assert one_line(invoke("sweep", "x.toml", "--workers", "0")) == \
        "error: --workers: give a whole number of processes, 1 or more (got 0)"
