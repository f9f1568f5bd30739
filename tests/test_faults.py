"""Nothing lost, nothing hung (issue 10): every fault is injected, not assumed.

One test (or a few) per item of the issue, numbered as there: outputs that would overwrite an input or a
foreign file, temporaries of other writers, two sweeps and a foreign study in one directory, a case file
corrupted without changing its size, inf values, an unwritable output, a killed main process and killed
workers, an oversized grid, foreign datasets given to show/plot/export, mask paths and crafted .npy files,
errors blamed on the right file, the solver's convergence message, outdated cases.  Scenes are tiny (2-D 16²,
20 steps) unless a test needs a case that runs long enough to be killed; every process a test starts is
ended by the test, and every file stays in its temporary directory.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
import tomllib
import zlib
from pathlib import Path

import numpy as np
import psutil
import pytest
import xarray as xr
from test_sweep import _wait_for as wait_for
from typer.testing import CliRunner

import solver
from biostudy.cli import app
from biostudy.commands.sweep import run_study
from biostudy.data import case_files, netcdf_io, provenance, reading, writing
from biostudy.execution import jobs as runner
from biostudy.execution import ownership, pool, worker
from biostudy.execution.jobs import Execution
from biostudy.inputs import resources
from biostudy.plans.study import load_study

cli = CliRunner()

def sweep(plan, out, **execution):
    """A study's sweep into `out` as `biostudy sweep` runs it (`execution`: workers, retry_failed, ...)."""
    return run_study(plan, out, Execution(**execution))



def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def command(*args, **kw) -> subprocess.Popen:
    """`biostudy ARGS` in a process of its own (stderr as text); the test ends it."""
    return subprocess.Popen([sys.executable, "-m", "biostudy", *map(str, args)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, **kw)


def computing_workers(process: psutil.Process) -> list[psutil.Process]:
    """The sweep's worker processes that have started simulating (forked by its fork server)."""
    try:
        server = [p for p in process.children() if "forkserver" in " ".join(p.cmdline())]
        return [w for s in server for w in s.children() if w.cpu_times().user > 0.3]
    except psutil.Error:  # a process came or went while we looked
        return []


def ended(processes: list[psutil.Process], timeout: float) -> list[psutil.Process]:
    """Those of `processes` still alive after `timeout` s (zombies count as ended); the rest are killed."""
    _, alive = psutil.wait_procs(processes, timeout=timeout)
    alive = [p for p in alive if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
    for p in alive:
        p.kill()
    return alive


@pytest.fixture
def no_simulation(monkeypatch):
    """Fails the test if anything is simulated in this process: a refusal must come before computing."""
    def refuse(*args, **kwargs):
        raise AssertionError("simulated although the output was refused")

    monkeypatch.setattr(solver, "simulate", refuse)
    monkeypatch.setattr(worker, "solve", refuse)




def one_line_error(result) -> str:
    """The single line of a bad-input answer: exit 2, 'error: ...', no traceback, nothing on stdout."""
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.output and result.stdout == ""
    return lines[0]


# ---------------------------------------------------------------------------------------------
# 1. An output never overwrites an input or a file biostudy did not write


def test_run_refuses_to_overwrite_its_scene_a_mask_or_a_foreign_file(write_toml, tiny_scene, tmp_path, no_simulation):
    scene_text = tiny_scene.read_bytes()
    line = one_line_error(invoke("run", tiny_scene, "-o", tiny_scene))
    assert "is an input of this run" in line and tiny_scene.read_bytes() == scene_text
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes")
    line = one_line_error(invoke("run", tiny_scene, "-o", notes))
    assert "is not a dataset biostudy wrote" in line and notes.read_text() == "my notes"
    np.save(tmp_path / "m.npy", np.arange(256).reshape(16, 16) == 85)  # one cell, (5, 5)
    masked = write_toml("masked.toml", tiny_scene.read_text() + '[[obstacle]]\nshape = "mask"\npath = "m.npy"\n')
    line = one_line_error(invoke("run", masked, "-o", tmp_path / "m.npy"))
    assert "is an input of this run" in line and np.load(tmp_path / "m.npy").shape == (16, 16)


def test_run_replaces_an_earlier_result_of_the_same_scene_and_says_so(write_toml, tiny_scene, tmp_path):
    out = tmp_path / "out.nc"
    assert invoke("run", tiny_scene, "-o", out, "-q").exit_code == 0
    again = invoke("run", tiny_scene, "-o", out, "-q", "--set", "g=2e8")
    assert again.exit_code == 0 and "replaces the earlier result of the same scene" in again.stderr
    other = write_toml("other.toml", tiny_scene.read_text())
    line = one_line_error(invoke("run", other, "-o", out, "-q"))
    assert f"holds the result of another scene ({tiny_scene})" in line and "--force" in line
    assert xr.open_dataset(out).attrs["g"] == 2e8  # untouched
    forced = invoke("run", other, "-o", out, "-q", "--force")
    assert forced.exit_code == 0 and "(--force)" in forced.stderr


# ---------------------------------------------------------------------------------------------
# 2. A sweep removes only the temporaries of writers that are gone


def test_a_sweep_leaves_other_writers_temporaries_alone(tiny_study, tmp_path):
    out = tmp_path / "out"
    assert sweep(load_study(tiny_study), out).ok
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])  # a writer still running
    dead = subprocess.Popen(["true"])  # one that is gone
    dead.wait()
    try:
        kept = [out / ".draft.tmp", out / "cases" / ".notes.tmp",
                out / "cases" / f".g=1e+08_r=50.nc.{other.pid}.0123abcd.tmp"]
        for path in kept:
            path.write_text("someone's")
        gone = out / "cases" / f".g=1e+08_r=50.nc.{dead.pid}.0123abcd.tmp"
        gone.write_bytes(b"\x89HDF half")
        report = sweep(load_study(tiny_study), out)
        assert report.removed == [gone] and all(p.read_text() == "someone's" for p in kept)
    finally:
        other.kill()
        other.wait()


# ---------------------------------------------------------------------------------------------
# 3. A sweep directory belongs to one study; one run writes into it at a time


def test_another_study_is_refused_unless_forced(write_toml, tiny_study, tmp_path):
    out = tmp_path / "out"
    assert invoke("sweep", tiny_study, "-o", out, "-q").exit_code == 0
    before = {p.name: p.stat().st_mtime_ns for p in [out / "study.nc", *(out / "cases").iterdir()]}
    other = write_toml("other.toml", 'scene = "tiny.toml"\n[sweep]\ng = [1e8, 1e9]\n')
    line = one_line_error(invoke("sweep", other, "-o", out, "-q"))
    assert line.startswith(f"error: {out}: belongs to study 'tiny-sweep' of ") and "--force" in line
    assert {p.name: p.stat().st_mtime_ns for p in [out / "study.nc", *(out / "cases").iterdir()]} == before
    # the same study with other values resumes there; a folder of a user's files is refused too
    assert invoke("sweep", tiny_study, "-o", out, "-q", "--set", "time.steps=10").exit_code == 0
    folder = tmp_path / "papers"
    folder.mkdir()
    (folder / "draft.tex").write_text("mine")
    line = one_line_error(invoke("sweep", tiny_study, "-o", folder, "-q"))
    assert "holds files that no biostudy run recorded as its own (draft.tex)" in line
    assert sorted(os.listdir(folder)) == ["draft.tex"]  # refused: the folder as it was (issue 21, item 8)
    forced = invoke("sweep", other, "-o", out, "-q", "--force")
    assert forced.exit_code == 0 and xr.open_dataset(out / "study.nc").attrs["sweep_keys"] == "g"


def test_a_second_sweep_into_a_directory_in_use_is_refused_and_the_first_goes_on(slow_study, tmp_path):
    study = slow_study(300, (50.0, 60.0))
    out = tmp_path / "out"
    first = command("sweep", study, "-o", out, "-q")
    try:
        wait_for(lambda: f"pid {first.pid}" in (out / ownership.LOCK).read_text()
                 if (out / ownership.LOCK).exists() else False, 60)
        line = one_line_error(invoke("sweep", study, "-o", out, "-q"))
        assert f"another biostudy run is writing into this directory (pid {first.pid} on " in line
        _, stderr = first.communicate(timeout=600)  # a hang guard, not a speed bar
    finally:
        first.kill()
        first.wait()
    assert first.returncode == 0, stderr
    assert (xr.open_dataset(out / "study.nc").status.values == "done").all()
    with ownership.claimed(out, runner.plan_owner(load_study(study), "study")):  # held here: the same answer
        assert "another biostudy run is writing" in one_line_error(invoke("sweep", study, "-o", out, "-q"))


# ---------------------------------------------------------------------------------------------
# 4. Damage that keeps a file's size is found on resume (checksums) and the case computed again


def _stored_chunk(raw: bytes, snapshot: np.ndarray) -> tuple[int, int]:
    """Where a snapshot is stored in a netCDF4 file, as (offset, length): its chunk, deflated after the
    shuffle and the fletcher32 filters (`biostudy.data.netcdf.encoding`), found by inflating each zlib stream."""
    shuffled = np.ascontiguousarray(snapshot).view(np.uint8).reshape(-1, snapshot.itemsize).T.tobytes()
    for at in range(len(raw) - 1):
        if raw[at] != 0x78 or (raw[at] * 256 + raw[at + 1]) % 31:
            continue  # not a zlib header
        stream = zlib.decompressobj()
        try:
            if stream.decompress(raw[at:]).startswith(shuffled):
                return at, len(raw) - at - len(stream.unused_data)
        except zlib.error:
            continue
    raise AssertionError("snapshot not found in the file")


def test_a_case_file_corrupted_in_place_is_computed_again(tiny_study, tmp_path):
    out = tmp_path / "out"
    plan = load_study(tiny_study)
    sweep(plan, out)
    path = case_files.case_file(out, "g=1e+09_r=50")
    good = reading.open_dataset(path).phi.values
    raw = bytearray(path.read_bytes())
    at, length = _stored_chunk(bytes(raw), good[-1])  # the last snapshot of phi, as stored (compressed)
    assert at > 0 and length > 128
    damaged = min(1024, length - 64)
    raw[at + 64:at + 64 + damaged] = b"\x7f" * damaged  # garbage inside the chunk, the size unchanged
    path.write_bytes(raw)
    assert not netcdf_io.intact(path) and case_files.recorded(path)["status"] == "done"
    assert "damaged: it cannot be read whole" in one_line_error(invoke("show", path))
    study_nc = (out / "study.nc").read_bytes()
    (out / "study.nc").write_bytes(study_nc[:8] + b"\0" * (len(study_nc) - 8))  # beyond reading: replaced
    report = sweep(plan, out)
    assert report.damaged == report.ran == ["g=1e+09_r=50"] and len(report.skipped) == 3
    np.testing.assert_array_equal(reading.open_dataset(path).phi.values, good)
    study = xr.open_dataset(out / "study.nc")
    np.testing.assert_array_equal(study.phi.sel(g=1e9, r=50).values, good)
    assert float(study.alpha.max()) < 1


def test_resuming_while_this_process_holds_a_case_file_open(tiny_study, tmp_path):
    """Resume checks read numbers only: a variable-length string read through a second handle of a file held
    open here would crash HDF5 at a later open (netcdf_io.intact)."""
    out = tmp_path / "out"
    plan = load_study(tiny_study)
    sweep(plan, out)
    held = xr.open_dataset(case_files.case_file(out, "g=1e+09_r=50"))
    assert held.status.item() == "done"
    for _ in range(3):
        assert len(sweep(plan, out).skipped) == 4
    held.close()


# ---------------------------------------------------------------------------------------------
# 5. inf is bad input wherever NaN is


@pytest.mark.parametrize("override", ["time.t_end=inf", "params.g=inf", "params.mu=inf", "params.d=-inf",
                                      "params.beta=nan", "biofilm.0.radius=inf", "time.output_times=[0.1, inf]"])
def test_inf_and_nan_values_are_bad_input(tiny_scene, tmp_path, override):
    line = one_line_error(invoke("run", tiny_scene, "-o", tmp_path / "out.nc", "--set", override))
    assert line.startswith("error: --set: ") and "must be a finite number" in line
    assert not (tmp_path / "out.nc").exists()


def test_inf_in_a_study_names_the_case(write_toml, tiny_scene, tmp_path):
    study = write_toml("infinite.toml", 'scene = "tiny.toml"\n[sweep]\ng = [1e8, inf]\n')
    line = one_line_error(invoke("sweep", study, "-o", tmp_path / "out"))
    assert line == f"error: {study}: case g=inf: params.g: must be a finite number (got inf)"


# ---------------------------------------------------------------------------------------------
# 6. An output that cannot be written is refused before anything is computed


@pytest.mark.parametrize("target, expected", [
    ("/proc/o.nc", "cannot write here"),
    ("{dir}", "is a directory"),
    ("{dir}/tiny.toml/o.nc", "tiny.toml is a file, not a directory"),
    ("{dir}/" + "x" * 300 + ".nc", "File name too long"),
])
def test_an_unwritable_output_is_refused_before_computing(tiny_scene, tmp_path, no_simulation, target, expected):
    line = one_line_error(invoke("run", tiny_scene, "-o", target.replace("{dir}", str(tmp_path))))
    assert expected in line
    assert sorted(os.listdir(tmp_path)) == ["tiny.toml"]


def test_an_unwritable_sweep_directory_is_refused_before_computing(tiny_study, tmp_path, no_simulation):
    assert "cannot write here" in one_line_error(invoke("sweep", tiny_study, "-o", "/proc/sweep"))
    assert "is a file, not a directory" in one_line_error(invoke("sweep", tiny_study, "-o", tiny_study))


def test_a_long_case_id_gets_a_bounded_file_name_and_keeps_its_id(write_toml, tiny_scene, tmp_path):
    long = "x" * 300
    study = write_toml("long.toml", f'scene = "tiny.toml"\n[sweep]\ndescription = ["short", "{long}"]\n')
    out = tmp_path / "out"
    assert invoke("sweep", study, "-o", out, "-q").exit_code == 0
    names = sorted(p.name for p in (out / "cases").iterdir())
    assert names[0] == "description=short.nc" and len(names[1].encode()) <= case_files.CASE_NAME_BYTES + 3
    assert xr.open_dataset(out / "cases" / names[1]).attrs["case_id"] == f"description={long}"
    assert (xr.open_dataset(out / "study.nc").status.values == "done").all()


# ---------------------------------------------------------------------------------------------
# 7. Workers end with the sweep's process, however it ends


def test_no_process_of_a_sweep_survives_its_main_process_killed(slow_study, tmp_path):
    study = slow_study(4000, (50.0, 60.0, 70.0))
    sweep = command("sweep", study, "-o", tmp_path / "out", "-q", "--workers", "2")
    try:
        main = psutil.Process(sweep.pid)
        wait_for(lambda: len(computing_workers(main)) == 2, 300)
        family = main.children(recursive=True)  # fork server, resource tracker, workers
        assert len(family) >= 4
        sweep.kill()  # SIGKILL: no handler, no finally
        sweep.wait()
        assert ended(family, timeout=60) == []  # a hang guard: they end at once
    finally:
        sweep.kill()
        sweep.wait()


# ---------------------------------------------------------------------------------------------
# 8. A worker that dies takes only its own case; the sweep goes on, and resumes past it


def test_a_killed_worker_fails_its_case_and_the_others_finish(slow_study, tmp_path):
    study = slow_study(600, (50.0, 60.0, 70.0))
    out = tmp_path / "out"
    sweep = command("sweep", study, "-o", out, "-q", "--workers", "2")
    try:
        wait_for(lambda: len(computing_workers(psutil.Process(sweep.pid))) == 2, 300)
        victim = computing_workers(psutil.Process(sweep.pid))[0]
        victim.send_signal(signal.SIGKILL)
        _, stderr = sweep.communicate(timeout=600)  # a hang guard, not a speed bar
    finally:
        sweep.kill()
        sweep.wait()
    assert sweep.returncode == 1, stderr
    assert "1 of 3 cases failed" in stderr and "worker died: signal 9 (SIGKILL" in stderr
    assert "Traceback" not in stderr
    ds = xr.open_dataset(out / "study.nc")
    assert sorted(ds.status.values.tolist()) == ["done", "done", "failed"]
    assert "worker died: signal 9" in ds.message.where(ds.status == "failed", drop=True).item()


def deadly_serve(tasks, lifeline):
    """A worker whose case r = 60 kills it (as a case that runs out of memory would), every time."""
    import biostudy.execution.worker as worker

    solve = worker.solve

    def solve_or_die(problem):
        if problem.params.r == 60.0:
            os.kill(os.getpid(), signal.SIGKILL)
        return solve(problem)

    worker.solve = solve_or_die
    worker.serve(tasks, lifeline)


def _sweep_with_a_deadly_case(study, out, *options) -> subprocess.CompletedProcess:
    script = textwrap.dedent(f"""\
        import sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        import biostudy.execution.worker, test_faults
        biostudy.execution.worker.serve = test_faults.deadly_serve
        from biostudy.cli import app
        app(["sweep", {str(study)!r}, "-o", {str(out)!r}, "-q", "--workers", "2", *{list(options)!r}])
        """)
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)


def test_a_case_that_always_kills_its_worker_does_not_block_the_rest(slow_study, tmp_path):
    study = slow_study(20)
    out = tmp_path / "out"
    first = _sweep_with_a_deadly_case(study, out)
    assert first.returncode == 1 and "r=60 failed: worker died: signal 9" in first.stderr, first.stderr
    assert xr.open_dataset(out / "study.nc").status.values.tolist() == ["done", "failed", "done", "done"]
    assert sweep(load_study(study), out).ran == []  # the failure is recorded: resuming skips it
    retried = _sweep_with_a_deadly_case(study, out, "--retry-failed")  # it dies again; nothing else is lost
    assert "1 cases run, 3 skipped" in retried.stderr and "r=60 failed: worker died" in retried.stderr


def test_a_case_out_of_memory_is_recorded_as_such_and_the_others_go_on(tiny_study, tmp_path, monkeypatch):
    simulate = solver.simulate

    def greedy(problem, **kwargs):
        if problem.params.g == 1e9 and problem.params.r == 50:
            raise MemoryError("Unable to allocate 1.2 TiB for an array")
        return simulate(problem, **kwargs)

    monkeypatch.setattr(solver, "simulate", greedy)
    report = sweep(load_study(tiny_study), tmp_path / "out")
    assert list(report.failed) == ["g=1e+09_r=50"] and len(report.ran) == 4
    assert report.failed["g=1e+09_r=50"].startswith("out of memory (MemoryError: Unable to allocate 1.2 TiB")


# ---------------------------------------------------------------------------------------------
# 9. Memory and disk are estimated before anything is allocated; what cannot fit is refused with the estimate


@pytest.mark.parametrize("shape", ["[2000, 2000, 2000]", "[800, 800, 800]"])
def test_an_oversized_grid_is_refused_before_allocating(tiny_scene, tmp_path, monkeypatch, shape):
    import tracemalloc

    monkeypatch.setenv("BIOSTUDY_MEMORY", "16 GB")  # the same answer on any machine
    began = time.perf_counter()
    tracemalloc.start()
    try:
        result = invoke("run", tiny_scene, "-o", tmp_path / "o.nc", "--set", f"grid.shape={shape}")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    line = one_line_error(result)
    assert line.startswith("error: --set: grid.shape: ")
    assert "of memory, 16 GB available (BIOSTUDY_MEMORY=16 GB); running would need ~" in line
    assert peak < 50e6 and time.perf_counter() - began < 5  # refused before any array of the grid's size


def test_too_many_outputs_workers_or_bytes_are_refused_before_running(tiny_scene, tiny_study, tmp_path, monkeypatch,
                                                                     no_simulation):
    monkeypatch.setenv("BIOSTUDY_MEMORY", "500 MB")
    line = one_line_error(invoke("run", tiny_scene, "-o", tmp_path / "o.nc", "--set", "time.outputs=1000000"))
    assert line.startswith("error: --set: time.outputs: needs ~") and "of memory (tiny: " in line
    assert line.endswith(", 500 MB available (BIOSTUDY_MEMORY=500 MB)")
    assert "outputs ~" in line
    out = tmp_path / "out"
    monkeypatch.setattr(pool, "warm_up", lambda: None)  # no fork server outlives this test
    line = one_line_error(invoke("sweep", tiny_study, "-o", out, "--workers", "4"))
    assert "4 runs at once need ~" in line and "use fewer workers" in line and not list(out.rglob("*.nc"))
    monkeypatch.setattr(resources, "free_disk", lambda path: 1e3)
    line = one_line_error(invoke("run", tiny_scene, "-o", tmp_path / "o.nc"))
    assert "of disk for its datasets, 1 kB free" in line
    assert sorted(os.listdir(tmp_path)) == ["tiny-sweep.toml", "tiny.toml"]  # refused: no out/ (issue 21, item 8)


def test_show_tells_what_a_scene_or_a_study_needs(tiny_scene, tiny_study):
    scene = invoke("show", tiny_scene)
    assert scene.exit_code == 0 and "16 × 16 cells, 20 steps, 3 outputs" in scene.stdout
    assert "memory  ~" in scene.stdout and "; here ~" in scene.stdout and "for the dataset" in scene.stdout
    assert "of memory available (BIOSTUDY_MEMORY=16 GB)" in scene.stdout  # the binding limit and its source
    study = invoke("show", tiny_study)
    assert study.exit_code == 0 and "4 cases of tiny.toml" in study.stdout and "largest case" in study.stdout
    catalogue = invoke("show", Path(__file__).resolve().parents[1] / "studies" / "stability.toml")
    cases = len(tomllib.loads((Path(__file__).resolve().parents[1] / "studies" / "stability.toml").read_text())["case"])
    assert catalogue.exit_code == 0 and f"{cases} cases of directional.toml" in catalogue.stdout, catalogue.output


# ---------------------------------------------------------------------------------------------
# 10. show, plot and export answer a file they cannot use in one line, and leave nothing half-written


@pytest.fixture
def results(tiny_scene, tmp_path):
    """A run, a foreign netCDF file, a biostudy dataset with no variables and a failed case's record."""
    run = tmp_path / "run.nc"
    assert invoke("run", tiny_scene, "-o", run, "-q").exit_code == 0
    foreign = tmp_path / "foreign.nc"
    xr.Dataset({"temperature": ("t", [1.0, 2.0])}).to_netcdf(foreign)
    empty = writing.write_atomic(provenance.stamp(xr.Dataset(), "", tiny_scene, ""), tmp_path / "empty.nc")
    failed = writing.write_atomic(case_files.failure_record("t = 0.1: it broke", 1.0, "tiny", "", tiny_scene, ""),
                                  tmp_path / "failed.nc")
    return {"run": run, "foreign": foreign, "empty": empty, "failed": failed}


EXPECTED = {"foreign": "not a dataset biostudy wrote", "empty": "a dataset with no variables",
            "failed": "a failed case's record (t = 0.1: it broke)"}


@pytest.mark.parametrize("command, name", [(c, n) for c in ("show", "plot", "export") for n in EXPECTED
                                           if (c, n) != ("show", "failed")])  # show summarises a failed case
def test_a_file_a_command_cannot_use_is_one_line_and_leaves_nothing(results, tmp_path, command, name):
    expected = EXPECTED[name]
    before = sorted(os.listdir(tmp_path))
    args = {"show": [], "plot": ["-o", tmp_path / "fig.png"], "export": [tmp_path / "vtk"]}[command]
    line = one_line_error(invoke(command, results[name], *args))
    assert line.startswith(f"error: {results[name]}: {expected}")
    assert sorted(os.listdir(tmp_path)) == before


@pytest.mark.parametrize("format", ["vti", "vtu"])
def test_a_plot_or_export_that_fails_midway_leaves_no_file(results, tmp_path, monkeypatch, format):
    import meshio

    import biostudy.data.vtk_image as vtk_image
    import biostudy.plots.fields as fields

    def broken(*args, **kwargs):
        raise ValueError("broken on purpose")

    monkeypatch.setattr(fields, "map_figure", broken)  # the second figure of a 2-D run, after the series
    line = one_line_error(invoke("plot", results["run"], "-o", tmp_path / "fig.png"))
    assert "broken on purpose" in line and not list(tmp_path.glob("fig*"))
    calls = []
    module, name = (vtk_image, "write_vti") if format == "vti" else (meshio, "write")
    write = getattr(module, name)

    def second_fails(path, *args, **kwargs):
        calls.append(path)
        if len(calls) == 2:
            raise ValueError("disk trouble on purpose")
        return write(path, *args, **kwargs)

    monkeypatch.setattr(module, name, second_fails)
    assert "disk trouble" in one_line_error(invoke("export", results["run"], tmp_path / "vtk", "--format", format))
    assert len(calls) == 2 and not (tmp_path / "vtk").exists()
    assert not [p for p in tmp_path.rglob("*") if p.suffix in (".tmp", ".png", ".vti", ".vtu", ".pvd")]


# ---------------------------------------------------------------------------------------------
# 11. Mask files: confined to the scene's folder unless absolute; never unpickled; headers checked


def _mask_scene(write_toml, path: str):
    return write_toml("masked.toml", f'[grid]\nshape = [4, 4]\n[time]\nsteps = 2\n[[obstacle]]\nshape = "mask"\n'
                                     f'path = "{path}"\n')


def test_a_relative_mask_path_stays_in_the_scene_folder_an_absolute_one_is_taken_as_given(write_toml, tmp_path):
    from biostudy.inputs.scene import load_scene

    outside = tmp_path.parent / f"{tmp_path.name}-outside.npy"  # beside the test's folder: must not be read
    inside = tmp_path / "sub" / "mask.npy"
    inside.parent.mkdir()
    np.save(inside, np.eye(4, dtype=bool))
    line = one_line_error(invoke("run", _mask_scene(write_toml, f"../{outside.name}"), "-o", tmp_path / "o.nc"))
    assert "obstacle[0].path" in line and "outside the scene's folder" in line
    assert load_scene(_mask_scene(write_toml, "sub/mask.npy")).obstacle[0].path == str(inside)
    assert load_scene(_mask_scene(write_toml, "./sub/../sub/mask.npy")).obstacle[0].path == str(inside)
    assert load_scene(_mask_scene(write_toml, str(inside))).obstacle[0].path == str(inside)


def _npy_header(header: bytes) -> bytes:
    header = header + b" " * (118 - len(header)) + b"\n"
    return b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header


@pytest.mark.parametrize("content, expected", [
    (b"\x80\x04\x95\x09\x00\x00\x00\x00\x00\x00\x00]\x94(K\x01K\x02e.", "not a .npy file"),  # a pickle
    (b"hello", "not a .npy file"),
    (_npy_header(b"{'descr': '|O', 'fortran_order': False, 'shape': (4, 4), }") + b"\0" * 128,
     "holds Python objects"),
    (_npy_header(b"{'descr': '|b1', 'fortran_order': False, 'shape': (4, 4 }") + b"\0" * 16, "not a .npy file"),
    (_npy_header(b"{'descr': '<f8', 'fortran_order': False, 'shape': (100000, 100000, 100000), }") + b"\0" * 16,
     "header announces [100000, 100000, 100000] float64 values, but the file holds 16 bytes"),
])
def test_a_mask_that_is_not_a_npy_array_is_one_line(write_toml, tmp_path, content, expected):
    (tmp_path / "bad.npy").write_bytes(content)
    line = one_line_error(invoke("run", _mask_scene(write_toml, "bad.npy"), "-o", tmp_path / "o.nc"))
    assert "obstacle[0].path" in line and expected in line and "allow_pickle" not in line


# ---------------------------------------------------------------------------------------------
# 12. Errors name where the value came from: --set, the study's [set], the scene


def test_errors_name_the_override_that_gave_the_value(write_toml, tiny_scene, tmp_path):
    line = one_line_error(invoke("run", tiny_scene, "-o", tmp_path / "o.nc", "--set", "params.d=-1"))
    assert line == "error: --set: params.d: must be > 0 (got -1)"
    study = write_toml("study.toml", 'scene = "tiny.toml"\n[set]\n"params.gg" = 1.0\n[sweep]\nr = [1.0, 2.0]\n')
    line = one_line_error(invoke("sweep", study, "-o", tmp_path / "out"))
    assert line.startswith(f"error: {study}: set.params.gg: unknown key")
    study = write_toml("study.toml", 'scene = "tiny.toml"\n[sweep]\nr = [1.0, 2.0]\n')
    line = one_line_error(invoke("sweep", study, "-o", tmp_path / "out", "--set", "time.steps=0"))
    assert line == "error: --set: time.steps: must be >= 1 (got 0)"
    write_toml("tiny.toml", open(tiny_scene).read().replace("steps = 20", "steps = -3"))
    line = one_line_error(invoke("sweep", study, "-o", tmp_path / "out"))
    assert line == f"error: {tiny_scene}: time.steps: must be >= 1 (got -3)"  # the scene's own value
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------------------------
# 13. A linear solver's failure says what failed (the true-residual check), not "info 0"


def test_the_solver_says_which_check_failed(tiny_scene, tmp_path, monkeypatch):
    from solver import timeloop

    # the clock would split steps in which a front crosses thousands of cells; lifted, BiCGSTAB meets one it cannot
    # solve, and says why
    monkeypatch.setattr(timeloop, "LIMIT", float("inf"))
    result = invoke("run", tiny_scene, "-o", tmp_path / "o.nc", "-q", "--set", "params.r=1e7",
                    "--set", "numerics.max_substeps=50")
    assert result.exit_code == 1, result.output
    assert "BiCGSTAB did not converge: it stopped after" in result.stderr
    assert "on its own recursive residual, but the true residual |b - A x| = " in result.stderr
    assert "info 0" not in result.stderr
# ---------------------------------------------------------------------------------------------
# 14. Cases made by another software version are reused with a warning; --rerun-all runs them again


def test_cases_of_another_version_are_reported_and_rerun_on_request(tiny_study, tmp_path):
    import netCDF4
    import scipy

    out = tmp_path / "out"
    assert invoke("sweep", tiny_study, "-o", out, "-q").exit_code == 0
    with netCDF4.Dataset(case_files.case_file(out, "g=1e+08_r=50"), "a") as nc:
        nc.setncattr("biostudy_version", "0.0.1")
        nc.setncattr("version_scipy", "1.0.0")
    again = invoke("sweep", tiny_study, "-o", out, "-q")
    assert again.exit_code == 0 and "0 cases run, 4 skipped" in again.stderr
    assert (f"warning: 1 finished cases were computed by other software versions (biostudy 0.0.1 (now "
            f"{provenance.version()}), scipy 1.0.0 (now {scipy.__version__})) and were reused; --rerun-all computes "
            "every case again") in again.stderr
    rerun = invoke("sweep", tiny_study, "-o", out, "-q", "--rerun-all")
    assert rerun.exit_code == 0 and "4 cases run, 0 skipped" in rerun.stderr and "warning" not in rerun.stderr
    assert xr.open_dataset(case_files.case_file(out, "g=1e+08_r=50")).attrs["biostudy_version"] == provenance.version()


