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
from pathlib import Path

import numpy as np
import psutil
import pytest
import xarray as xr
from typer.testing import CliRunner

import solver
from biostudy import runner, store
from biostudy.cli import app
from biostudy.study import load_study

cli = CliRunner()


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def command(*args, **kw) -> subprocess.Popen:
    """`biostudy ARGS` in a process of its own (stderr as text); the test ends it."""
    return subprocess.Popen([sys.executable, "-m", "biostudy", *map(str, args)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, **kw)


def wait_for(condition, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


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
    monkeypatch.setattr(runner, "solve", refuse)


def slow_study(write_toml, steps: int, values=(50.0, 60.0, 70.0)):
    """A study of the tiny scene whose cases take a few seconds each (to be killed while they run)."""
    return write_toml("slow.toml", f"""\
        scene = "tiny.toml"
        [set]
        "time.t_end" = 1.0
        "time.steps" = {steps}
        [sweep]
        r = {list(values)}
        """)


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
    assert runner.sweep(load_study(tiny_study), out).ok
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
        report = runner.sweep(load_study(tiny_study), out)
        assert report.removed == [gone] and all(p.read_text() == "someone's" for p in kept)
    finally:
        other.kill()
        other.wait()


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
# 11. Mask files: confined to the scene's folder unless absolute; never unpickled; headers checked


def _mask_scene(write_toml, path: str):
    return write_toml("masked.toml", f'[grid]\nshape = [4, 4]\n[time]\nsteps = 2\n[[obstacle]]\nshape = "mask"\n'
                                     f'path = "{path}"\n')


def test_a_relative_mask_path_stays_in_the_scene_folder_an_absolute_one_is_taken_as_given(write_toml, tmp_path):
    from biostudy.scene import load_scene

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


def test_the_solver_says_which_check_failed(tiny_scene, tmp_path):
    result = invoke("run", tiny_scene, "-o", tmp_path / "o.nc", "-q", "--set", "params.r=1e7",
                    "--set", "numerics.max_substeps=50")
    assert result.exit_code == 1, result.output
    assert "BiCGSTAB did not converge: it stopped after" in result.stderr
    assert "on its own recursive residual, but the true residual |b - A x| = " in result.stderr
    assert "info 0" not in result.stderr
