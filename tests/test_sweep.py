"""Sweeps: study.nc layout, resume, failures kept apart, local processes, a Dask cluster, interruptions."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from study_files import both_ways, same_files
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.commands.sweep import run_study
from biostudy.data import combine, study_arrays, writing
from biostudy.data.case_files import CASE_VARIABLES, recorded
from biostudy.execution import dask, worker
from biostudy.execution.jobs import Execution, fingerprint
from biostudy.inputs import bundled
from biostudy.inputs.scene import load_scene
from biostudy.plans.study import load_study

cli = CliRunner()

def sweep(plan, out, **execution):
    """A study's sweep into `out` as `biostudy sweep` runs it (`execution`: workers, retry_failed, ...)."""
    return run_study(plan, out, Execution(**execution))



def sweep_cli(*args):
    return cli.invoke(app, ["sweep", *(str(a) for a in args), "-q"])


def case_files(directory):
    return sorted(p.name for p in (directory / "cases").iterdir())


def same_results(a, b):
    """Two sweeps' study.nc and case files hold the same values bit for bit (but the wall times)."""
    for name in ["study.nc", *(f"cases/{n}" for n in case_files(a))]:
        x, y = xr.load_dataset(a / name), xr.load_dataset(b / name)
        assert set(x.variables) == set(y.variables), name
        for variable in set(x.variables) - {"wall_time", "elapsed"}:
            xr.testing.assert_identical(x[variable].drop_attrs(), y[variable].drop_attrs())


def test_grid_sweep_writes_cases_and_study_nc_with_one_dimension_per_key(tiny_study, tmp_path, monkeypatch):
    out = tmp_path / "out"
    result = sweep_cli(tiny_study, "-o", out)
    assert result.exit_code == 0, result.output
    assert case_files(out) == ["g=1e+08_r=100.nc", "g=1e+08_r=50.nc", "g=1e+09_r=100.nc", "g=1e+09_r=50.nc"]
    ds = xr.open_dataset(out / "study.nc")
    assert ds.phi_mean.dims == ("g", "r", "time") and ds.phi.dims == ("g", "r", "time", "y", "x")
    assert ds.g.values.tolist() == [1e8, 1e9] and ds.r.values.tolist() == [50.0, 100.0]
    assert ds.g.attrs["units"] == "1" and "consumption" in ds.g.attrs["long_name"] and "1/T*" in ds.g.attrs["long_name"]
    assert ds.r.attrs["units"] == "um" and "µm/T*" in ds.r.attrs["long_name"]
    assert (ds.status.values == "done").all() and ds.case_id.sel(g=1e9, r=50).item() == "g=1e+09_r=50"
    for name in list(ds.data_vars) + list(ds.coords):
        if name.endswith("_bounds"):  # CF 7.1: bounds carry their cell centre's units and long name
            continue
        assert "units" in ds[name].attrs and ds[name].attrs.get("long_name"), name
    # each entry is that case's own dataset, which has its place in the study as dimensions of length 1
    one = xr.open_dataset(out / "cases" / "g=1e+09_r=50.nc")
    assert one.phi_mean.dims == ("g", "r", "time") and one.g.values.tolist() == [1e9]
    np.testing.assert_array_equal(ds.phi_mean.sel(g=1e9, r=50).values, one.phi_mean.values[0, 0])
    assert one.attrs["status"] == "done" and one.attrs["case_id"] == "g=1e+09_r=50"
    assert one.attrs["g"] == 1e9 and one.attrs["overrides"] == "g = 1e+09\nr = 50.0"
    # swept parameters vary, so they are coordinates, not attributes, of study.nc
    assert "g" not in ds.attrs and ds.attrs["d"] == 1e10 and ds.attrs["cases_done"] == 4
    assert ds.attrs["sweep_mode"] == "grid" and "scene = \"tiny.toml\"" in ds.attrs["study"]
    shown = cli.invoke(app, ["show", str(out)])  # the sweep's directory: its study.nc
    assert shown.exit_code == 0 and "4 done, 0 failed" in shown.stdout and "g=1e+09_r=50" in shown.stdout
    # the cases in study-wide arrays, stacked variable by variable, are what xarray's combine_nested makes of them
    plan = load_study(tiny_study)
    arrays = combine.combine(plan, out).drop_attrs(deep=False)
    monkeypatch.setattr(study_arrays, "stacked", lambda *args: None)
    stacked = combine.combine(plan, out).drop_attrs(deep=False)
    monkeypatch.setattr(combine, "_stacked", lambda *args: None)
    nested = combine.combine(plan, out).drop_attrs(deep=False)
    for made in (arrays, stacked):
        xr.testing.assert_identical(made, nested)
        assert all(made[n].chunks == nested[n].chunks and made[n].encoding.keys() == nested[n].encoding.keys()
                   and all(repr(made[n].encoding[k]) == repr(e) for k, e in nested[n].encoding.items())  # NaN fills
                   for n in nested.variables)
    assert [stacked[n].chunks for n in stacked.data_vars] == [nested[n].chunks for n in nested.data_vars]


def test_resume_skips_finished_cases_and_cleans_temporaries(tiny_study, tmp_path, monkeypatch):
    out = tmp_path / "out"
    plan = load_study(tiny_study)
    first = sweep(plan, out)
    assert len(first.ran) == 4 and not first.skipped
    # as if a run had been killed: one case missing, a half-written temporary beside the others
    (out / "cases" / "g=1e+09_r=100.nc").unlink()
    dead = subprocess.Popen(["true"])  # the pid of a writer that is gone
    dead.wait()
    leftover = f".g=1e+09_r=100.nc.{dead.pid}.0123abcd.tmp"
    (out / "cases" / leftover).write_bytes(b"\x89HDF half")
    stamps = {p.name: p.stat().st_mtime_ns for p in (out / "cases").glob("*.nc")}
    combine.write_study(plan, out)  # study.nc of what is there: the lost case is "missing", NaN
    partial = xr.open_dataset(out / "study.nc")
    assert partial.status.sel(g=1e9, r=100).item() == "missing" and partial.attrs["cases_missing"] == 1
    assert np.isnan(partial.phi_mean.sel(g=1e9, r=100)).all() and partial.phi_mean.sel(g=1e9, r=50).notnull().all()
    with xr.open_dataset(out / "cases" / "g=1e+09_r=50.nc") as one:  # the fields, written case by case
        np.testing.assert_array_equal(partial.phi.sel(g=1e9, r=50).values, one.phi.values[0, 0])
    assert np.isnan(partial.phi.sel(g=1e9, r=100)).all()
    same_files(*both_ways(plan, out, monkeypatch))  # study-wide arrays make the file a dataset per case makes
    again = sweep(load_study(tiny_study), out)
    assert again.ran == ["g=1e+09_r=100"] and len(again.skipped) == 3
    assert [p.name for p in again.removed] == [leftover]
    assert case_files(out) == sorted([*stamps, "g=1e+09_r=100.nc"])
    assert all((out / "cases" / n).stat().st_mtime_ns == t for n, t in stamps.items())  # untouched
    assert (xr.open_dataset(out / "study.nc").status.values == "done").all()
    # a changed scene makes the recorded cases stale: they run again
    changed = sweep(load_study(tiny_study, ["time.steps=10"]), out)
    assert len(changed.ran) == 4


def test_fingerprint_follows_what_changes_the_result(tiny_scene):
    base = fingerprint(load_scene(tiny_scene).problem())
    assert base == fingerprint(load_scene(tiny_scene).problem())
    assert base == fingerprint(load_scene(tiny_scene, ["name=other", "description=x"]).problem())
    assert base != fingerprint(load_scene(tiny_scene, ["params.g=2e8"]).problem())
    assert base != fingerprint(load_scene(tiny_scene, ["biofilm.0.radius=2"]).problem())
    agar = bundled.resolve("agar-g1e8")  # the nutrient held on a face marks no cell: the face and value count too
    held = fingerprint(load_scene(agar).problem())
    assert held != fingerprint(load_scene(agar, ['nutrient.0.face="z+"']).problem())
    assert held != fingerprint(load_scene(agar, ["nutrient.0.value=0.5"]).problem())


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the overflow this case is built on
def test_a_failing_case_is_recorded_and_the_others_go_on(write_toml, tiny_scene, tmp_path, monkeypatch):
    study = write_toml("fail.toml", """\
        scene = "tiny.toml"
        [set]
        "numerics.max_substeps" = 40
        [sweep]
        mode = "zip"
        k_alpha = [1e-3, 1e100, 2e-3]
        """)
    out = tmp_path / "out"
    result = sweep_cli(study, "-o", out)
    assert result.exit_code == 1
    assert "1 of 3 cases failed" in result.stderr and "k_alpha=1e+100: t = " in result.stderr
    ds = xr.open_dataset(out / "study.nc")
    assert ds.phi_mean.dims == ("case", "time")
    assert ds.case.values.tolist() == ["k_alpha=0.001", "k_alpha=1e+100", "k_alpha=0.002"]
    assert ds.k_alpha.values.tolist() == [1e-3, 1e100, 2e-3]  # swept values as coordinates
    assert ds.status.values.tolist() == ["done", "failed", "done"]
    message = ds.message.sel(case="k_alpha=1e+100").item()
    assert message.startswith("t = ") and "below t_end/max_substeps" in message  # (k_alpha dt <= 1 needs 1e-100)
    assert np.isnan(ds.phi_mean.sel(case="k_alpha=1e+100")).all()
    assert np.isfinite(ds.phi_mean.sel(case="k_alpha=0.002")).all()
    assert ds.attrs["cases_failed"] == 1 and "k_alpha" not in ds.attrs  # swept: a coordinate, never an attribute
    record = xr.load_dataset(out / "cases" / "k_alpha=1e+100.nc")  # closed: the sweep below rewrites it
    assert record.attrs["status"] == "failed" and record.attrs["message"] == message
    assert set(record.data_vars) == set(CASE_VARIABLES)  # its place in the study, no fields
    assert record.status.dims == ("case",) and record.k_alpha.values.tolist() == [1e100]
    for new_defaults in (False, True):  # docs/results.md's recipe, under xarray's present and coming defaults
        with xr.set_options(use_new_combine_kwarg_defaults=new_defaults), xr.open_mfdataset(
                sorted((out / "cases").glob("*.nc")), data_vars="minimal", join="outer", compat="no_conflicts",
                combine_attrs="drop_conflicts") as cases:
            cases = cases.sel(case=ds.case).load()
        assert cases.status.values.tolist() == ds.status.values.tolist()
        np.testing.assert_array_equal(cases.phi_mean.values, ds.phi_mean.values)
    assert "failed" in cli.invoke(app, ["show", str(out / "cases" / "k_alpha=1e+100.nc")]).stdout
    plan = load_study(study)
    ds.close()
    same_files(*both_ways(plan, out, monkeypatch))  # zip, a failure: as a dataset per case
    # re-running keeps the recorded failure; --retry-failed runs it again
    assert sweep(plan, out).ran == []
    assert sweep(plan, out, retry_failed=True).ran == ["k_alpha=1e+100"]


def test_local_processes_give_the_serial_results(tiny_study, tmp_path, monkeypatch):
    """The same results, bit for bit; each of 2 workers takes half the processors (here 6, as BIOSTUDY_THREADS
    says), a serial sweep all of them; and the sweep's process neither finishes a case's dataset nor writes its file
    (issue 35: it only schedules; the workers are forked from a fork server, which the spies below do not reach)."""
    monkeypatch.setenv("BIOSTUDY_THREADS", "6")
    plan = load_study(tiny_study)
    serial = sweep(plan, tmp_path / "serial")
    environment = dict(os.environ)
    written, write_atomic = [], writing.write_atomic

    def refuse(*args, **kwargs):
        raise AssertionError("the sweep's process finished a case")

    monkeypatch.setattr(worker, "finished", refuse)
    monkeypatch.setattr(writing, "write_atomic", lambda ds, path, *a, **k: (written.append(Path(path).name),
                                                                              write_atomic(ds, path, *a, **k))[1])
    local = sweep(plan, tmp_path / "local", workers=2)
    assert written == ["study.nc"]
    assert dict(os.environ) == environment  # the workers' settings are theirs only
    assert sorted(local.ran) == sorted(serial.ran) and local.ok
    same_results(tmp_path / "serial", tmp_path / "local")  # bit for bit (array tasks: test_batch.py)
    case = xr.open_dataset(tmp_path / "local" / "cases" / "g=1e+08_r=50.nc")
    assert case.attrs["omp_num_threads"] == "1" and case.attrs["fipy_solvers"] == "scipy"
    assert case.attrs["threads"] == 3
    assert xr.open_dataset(tmp_path / "serial" / "cases" / "g=1e+08_r=50.nc").attrs["threads"] == 6


def test_sweep_on_a_dask_cluster_of_two_processes(tiny_study, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) \
            as cluster:
        result = sweep_cli(tiny_study, "-o", tmp_path / "out", "--scheduler", cluster.scheduler_address)
    assert result.exit_code == 0, result.output
    ds = xr.open_dataset(tmp_path / "out" / "study.nc")
    assert (ds.status.values == "done").all() and ds.phi_mean.sel(g=1e8, r=100).notnull().all()
    case = xr.open_dataset(tmp_path / "out" / "cases" / "g=1e+09_r=50.nc")
    assert case.attrs["omp_num_threads"] == "1"  # Dask's nanny sets it for its workers
    sweep(load_study(tiny_study), tmp_path / "serial")  # the files the workers made, as a serial sweep's
    same_results(tmp_path / "serial", tmp_path / "out")
    assert case.attrs["threads"] == 1  # a node's processors are shared by worker processes none of them sees


def test_sweep_on_a_dask_cluster_over_tls(tiny_study, tmp_path):
    """The secure recipe (docs/clusters.md, 'Local workers and a Dask cluster'): a scheduler that requires TLS,
    reached with Dask's TLS configuration (here set in-process; DASK_CONFIG for a real cluster); without it, one
    line and exit 2; a plain tcp:// client is refused by the scheduler.  A self-signed certificate for 127.0.0.1
    made with openssl."""
    import shutil

    import dask
    import distributed
    from distributed.security import Security

    if not shutil.which("openssl"):
        pytest.skip("no openssl to make a test certificate")
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out", str(cert),
                    "-days", "1", "-subj", "/CN=localhost", "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost"],
                   check=True, capture_output=True, timeout=600)
    pem = {f"tls_{role}_{part}": str(path) for role in ("scheduler", "worker", "client")
           for part, path in (("cert", cert), ("key", key))}
    security = Security(tls_ca_file=str(cert), require_encryption=True, **pem)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tls",
                                  security=security, dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tls://")
        refused = sweep_cli(tiny_study, "-o", tmp_path / "refused", "--scheduler", address)
        assert refused.exit_code == 2 and len(refused.stderr.splitlines()) == 1
        assert "needs a TLS configuration" in refused.stderr
        with dask.config.set({"distributed.comm.tls.ca-file": str(cert), "distributed.comm.tls.client.cert": str(cert),
                              "distributed.comm.tls.client.key": str(key)}):
            result = sweep_cli(tiny_study, "-o", tmp_path / "out", "--scheduler", address, "--set", "time.steps=4")
    assert result.exit_code == 0, result.output
    assert (xr.open_dataset(tmp_path / "out" / "study.nc").status.values == "done").all()


def test_unreachable_scheduler_is_bad_input(tiny_study, tmp_path, monkeypatch):
    monkeypatch.setattr(dask, "CONNECT_TIMEOUT", 1.0)
    result = sweep_cli(tiny_study, "-o", tmp_path / "out", "--scheduler", "tcp://127.0.0.1:9")
    assert result.exit_code == 2
    assert result.stderr.startswith("error: --scheduler: nothing listens at tcp://127.0.0.1:9")


def _wait_for(condition, timeout):
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError("timed out")
        time.sleep(0.05)


@pytest.mark.slow
def test_a_killed_sweep_leaves_only_complete_files_and_resumes(slow_study, tmp_path):
    study = slow_study(600)
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-m", "biostudy", "sweep", str(study), "-o", str(out), "-q"],
                               stderr=subprocess.PIPE)
    _wait_for(lambda: (out / "cases").is_dir() and any((out / "cases").glob("*.nc")), 300)
    process.kill()  # SIGKILL: no handler runs
    process.wait(timeout=60)
    finished = list((out / "cases").glob("*.nc"))
    assert 1 <= len(finished) < 4 and not (out / "study.nc").exists()
    for path in finished:
        assert recorded(path)["status"] == "done"  # complete, readable files only
    report = sweep(load_study(study), out)
    assert len(report.skipped) == len(finished) and len(report.ran) == 4 - len(finished)
    assert not list((out / "cases").glob(".*"))
    assert (xr.open_dataset(out / "study.nc").status.values == "done").all()


def test_sigterm_stops_local_workers_and_exits_143(slow_study, tmp_path):
    psutil = pytest.importorskip("psutil")
    study = slow_study(4000)
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-m", "biostudy", "sweep", str(study), "-o", str(out), "-q",
                                "--workers", "2"], stderr=subprocess.PIPE, text=True)
    parent = psutil.Process(process.pid)

    def simulating():  # worker processes (forked from the fork server, or spawned) that are computing
        try:
            helpers = [p for p in parent.children() if "forkserver" in " ".join(p.cmdline())]
            workers = [p for p in parent.children(recursive=True) if p not in helpers
                       and "resource_tracker" not in " ".join(p.cmdline())]
            return [p for p in workers if p.cpu_times().user > 0.2]
        except psutil.Error:  # a process came or went while we looked
            return []

    _wait_for(lambda: len(simulating()) >= 2, 300)  # both workers have started on a case
    workers = parent.children(recursive=True)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=600)
    assert process.returncode == 143, stderr
    assert "interrupted" in stderr and "Traceback" not in stderr
    _, alive = psutil.wait_procs(workers, timeout=60)
    assert not alive
    assert not [p for p in (out / "cases").iterdir() if p.suffix != ".nc"]  # no temporary left either


def test_cases_on_different_grids_keep_their_time_series_in_study_nc(write_toml, tiny_scene, tmp_path):
    study = write_toml("grids.toml", """\
        scene = "tiny.toml"
        [sweep]
        mode = "zip"
        "grid.shape" = [[16, 16], [20, 16]]
        """)
    assert sweep(load_study(study), tmp_path / "out").ok
    ds = xr.open_dataset(tmp_path / "out" / "study.nc")
    assert ds.grid_shape.values.tolist() == ["16x16", "20x16"]
    assert ds.phi_mean.dims == ("case", "time") and ds.phi_mean.notnull().all()
    assert "phi" not in ds and "phi" in ds.attrs["omitted_variables"]  # fields stay in cases/*.nc
    assert xr.open_dataset(tmp_path / "out" / "cases" / "grid_shape=20x16.nc").sizes["x"] == 20


def test_ctrl_c_cancels_the_cases_submitted_to_dask_and_keeps_the_finished(tiny_study, tmp_path):
    """Ctrl-C while cases run on a cluster (docs/clusters.md: Ctrl-C cancels the submitted cases): the
    KeyboardInterrupt unwinds through the submit loop, which cancels every case still submitted, so the scheduler
    is left with no task of this sweep; the case that finished before is on disk, and a re-run resumes after
    it."""
    distributed = pytest.importorskip("distributed")
    plan = load_study(tiny_study, ["time.steps=400"])  # long enough that cases are still queued at the interrupt

    def interrupt(event, case_id, message):
        if event == "done":
            raise KeyboardInterrupt

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) \
            as cluster:
        with pytest.raises(KeyboardInterrupt):
            run_study(plan, tmp_path / "out", Execution(scheduler=cluster.scheduler_address, notify=interrupt))
        scheduler = cluster.scheduler
        deadline = time.monotonic() + 60
        while any(key.startswith("biostudy-") for key in map(str, scheduler.tasks)) and time.monotonic() < deadline:
            time.sleep(0.05)
        left = [str(key) for key in scheduler.tasks if str(key).startswith("biostudy-")]
        computed = {str(key) for key, _, finish, *_ in scheduler.transition_log if finish == "memory"}
    assert left == []
    assert 1 <= len(computed) < len(plan.cases)  # the cases still queued at the interrupt never ran
    finished = sorted(p.name for p in (tmp_path / "out" / "cases").glob("*.nc"))
    assert len(finished) == 1, finished
    assert len(sweep(plan, tmp_path / "out").skipped) == 1
