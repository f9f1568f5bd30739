"""Continuing a run (`run --continue`): from its last state, equal to the run straight to the later end."""
import dataclasses

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.data import case_files, reading, writing
from biostudy.inputs.scene import load_scene
from solver import simulate
from solver.restart import joined, start_state

cli = CliRunner()

# The linear solves stop at relative residuals of 1e-10 (nutrient) and 1e-12 (phi); a continuation builds the
# nutrient's AMG hierarchy afresh where the straight run reuses an older one, so the two agree to those
# tolerances, amplified over a few steps: 1e-8 is far above that and far below any change of state (alpha grows
# by k_alpha phi dt = 1e-2 a step here).
AGREE = 1e-8

SCENE = """\
name = "grow"
[grid]
shape = [12, 12]
[params]
k_alpha = 0.1
[time]
t_end = 0.2
steps = 20
outputs = 3
[[biofilm]]
shape = "sphere"
center = [6.0, 6.0]
radius = 2.5
[[nutrient]]
shape = "box"
lower = [11.0, 11.0]
upper = [12.0, 12.0]
[[obstacle]]
shape = "box"
lower = [0.0, 9.0]
upper = [2.0, 12.0]
[mechanics]
every = 2
"""
LATER = ["time.t_end=0.4", "time.steps=40", "time.outputs=5"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The scene run to 0.2, and straight to 0.4 with the same steps (mechanics at every other output)."""
    folder = tmp_path_factory.mktemp("continue")
    path = folder / "grow.toml"
    path.write_text(SCENE)
    first = simulate(load_scene(path).problem())
    straight = simulate(load_scene(path, LATER).problem())
    return path, first, straight


def test_a_continued_run_equals_the_run_straight_to_its_end(runs):
    path, first, straight = runs
    problem = dataclasses.replace(load_scene(path, LATER).problem(), **start_state(first))
    whole = joined(first, simulate(problem))
    np.testing.assert_array_equal(whole.time.values, straight.time.values)
    np.testing.assert_array_equal(whole.time_mechanics.values, straight.time_mechanics.values)  # 0, 0.2, 0.4
    for name in ("phi", "c", "alpha"):
        assert float(np.nanmax(np.abs(whole[name] - straight[name]))) < AGREE, name
    assert float(np.nanmax(straight.alpha.isel(time=-1))) > 100 * AGREE  # alpha went on growing: not trivially 0
    # the mechanics starts from the last converged u; Newton stops at 1e-6 of the growth load
    scale = float(np.nanmax(np.abs(straight.u)))
    assert float(np.nanmax(np.abs(whole.u - straight.u))) < 1e-6 * scale
    np.testing.assert_array_equal(whole.steps_taken.values, straight.steps_taken.values)
    assert whole.attrs["steps_taken"] == straight.attrs["steps_taken"] == 40


def _run(*args):
    return cli.invoke(app, ["run", *(str(a) for a in args), "-q"])


def test_run_continue_writes_the_whole_history_and_says_so(runs, tmp_path):
    path, _, straight = runs
    scene = tmp_path / "grow.toml"
    scene.write_text(SCENE.replace("every = 2", "enabled = false"))
    assert _run(scene, "-o", tmp_path / "grow.nc").exit_code == 0
    result = _run(scene, "--continue", tmp_path / "grow.nc", *(a for s in LATER for a in ("--set", s)))
    assert result.exit_code == 0, result.output
    written = tmp_path / "grow-t0.4.nc"  # the default: beside the run, never over it
    ds = reading.open_dataset(written)
    np.testing.assert_allclose(ds.time.values, [0, 0.1, 0.2, 0.3, 0.4])
    off = simulate(load_scene(scene, LATER).problem())
    assert float(np.nanmax(np.abs(ds.phi - off.phi))) < AGREE
    assert ds.attrs["continued_from"].startswith(str((tmp_path / "grow.nc").resolve()))
    assert "whole history" in ds.attrs["continuation"]
    lines = ds.attrs["history"].splitlines()  # CF: the run's own line, then this one's
    assert len(lines) == 2 and lines[0] == xr.open_dataset(tmp_path / "grow.nc").attrs["history"]
    assert ds.steps_taken.values.tolist() == [0, 10, 20, 30, 40] and ds.attrs["steps_taken"] == 40
    # the observables are those of the whole history: front_advance from the first output of the first run
    assert "front_advance" in ds and float(ds.front_advance[0]) == 0.0


def test_the_run_continued_is_read_an_output_at_a_time_and_counted(runs, tmp_path, monkeypatch):
    """Issue 39.6: `run --continue` read the whole history into memory, uncounted (from a streamed run of 101
    outputs of 32³: peak 531 MB where the scene run fresh peaks at 365 MB, estimate ~386 MB).  The run continued
    stays open, its fields read an output at a time as the history is written again (and the run's estimate
    counts it); closed when the run ends, whatever ended it; the API's result read whole before that."""
    from biostudy.commands import run as command
    from biostudy.inputs import resources

    path, _, _ = runs
    scene = tmp_path / "grow.toml"
    scene.write_text(SCENE.replace("every = 2", "enabled = false"))
    assert _run(scene, "-o", tmp_path / "grow.nc").exit_code == 0
    estimated = []
    monkeypatch.setattr(resources, "run_problem", lambda found, *args, **kw: estimated.extend(found.values()) or "")
    loaded = command.load(scene, set=LATER, output=tmp_path / "later.nc", continue_from=tmp_path / "grow.nc")
    assert loaded.previous is not None and loaded.previous["phi"].chunks == ((1, 1, 1), (12,), (12,))  # lazily
    assert estimated[-1].continuing == resources.CONTINUATION + 3 * resources.CONTINUATION_PER_OUTPUT
    command.compute(loaded)
    with pytest.raises(RuntimeError, match="Not a valid ID"):  # closed with the run: its file is held no longer
        loaded.previous["phi"].load()
    kept = command.compute(command.load(scene, set=LATER, write=False, continue_from=tmp_path / "grow.nc"))
    assert kept.dataset.sizes["time"] == 5 and np.isfinite(kept.dataset.phi.values).any()  # read before closing


def test_continue_refuses_what_it_cannot_go_on_from(runs, tmp_path, write_toml):
    path, first, _ = runs
    scene = tmp_path / "grow.toml"
    scene.write_text(SCENE.replace("every = 2", "enabled = false"))
    run = tmp_path / "grow.nc"
    assert _run(scene, "-o", run).exit_code == 0
    cut = reading.open_dataset(run).isel(time=slice(0, 2))  # as if it had stopped at T* = 0.1 of its 0.2
    writing.write_atomic(cut, tmp_path / "cut.nc")
    writing.write_atomic(case_files.failure_record("worker died", 1.0, "grow", "", scene, ""), tmp_path / "failed.nc")
    cases = {
        "another scene": (["--continue", run, "--set", "g=1e9", "--set", "time.t_end=1"],
                          "a run of another scene (1 key differs besides [time]: params.g: 1e9 here, 1e8 in the run)"),
        "unfinished": (["--continue", tmp_path / "cut.nc", "--set", "time.t_end=1"], "an unfinished run"),
        "failed case": (["--continue", tmp_path / "failed.nc", "--set", "time.t_end=1"], "a failed case's record"),
        "not later": (["--continue", run], "time.t_end: must be after the last output"),
        "over its input": (["--continue", run, "--set", "time.t_end=1", "-o", run], "is an input of this run"),
        "no file": (["--continue", tmp_path / "none.nc", "--set", "time.t_end=1"], "no such file"),
    }
    for label, (args, expected) in cases.items():
        result = _run(scene, *args)
        lines = result.stderr.strip().splitlines()
        assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), (label, result.output)
        assert expected in lines[0], (label, lines[0])
    assert xr.open_dataset(run).time.size == 3  # untouched


def test_the_fingerprint_counts_a_start_state_and_not_its_absence(runs):
    from biostudy.execution.identity import ADDED_LATER, fingerprint

    path, first, _ = runs
    fresh = load_scene(path, LATER).problem()
    continued = dataclasses.replace(fresh, **start_state(first))
    assert fingerprint(continued) != fingerprint(fresh)
    assert fingerprint(dataclasses.replace(continued, alpha0=continued.alpha0 * 2)) != fingerprint(continued)
    assert all(getattr(fresh, name) == default for name, default in ADDED_LATER.items())  # left out: old prints


def test_run_continue_goes_on_from_a_sweeps_case_file(tmp_path, monkeypatch):
    scene = tmp_path / "grow.toml"
    scene.write_text(SCENE.replace("every = 2", "enabled = false"))
    study = tmp_path / "one.toml"
    study.write_text('scene = "grow.toml"\n[sweep]\ng = [1e8]\n')
    assert cli.invoke(app, ["sweep", str(study), "-o", str(tmp_path / "out"), "-q"]).exit_code == 0
    case = tmp_path / "out" / "cases" / "g=1e+08.nc"
    later = [a for s in ["g=1e8", *LATER] for a in ("--set", s)]
    result = _run(scene, "--continue", case, *later, "-o", tmp_path / "on.nc")
    assert result.exit_code == 0, result.output
    ds = reading.open_dataset(tmp_path / "on.nc")
    off = simulate(load_scene(scene, ["g=1e8", *LATER]).problem())
    np.testing.assert_allclose(ds.time.values, off.time.values)
    assert float(np.nanmax(np.abs(ds.phi - off.phi))) < AGREE
    # a case file keeps only the total of its steps: the counts before its last output are not made up
    assert np.isnan(ds.steps_taken.values[:2]).all() and ds.steps_taken.values[2:].tolist() == [20, 30, 40]
    assert ds.attrs["steps_taken"] == 40

    # what the continuation could not join is refused before anything is computed
    edited = reading.open_dataset(case).drop_vars("c_mean")
    writing.write_atomic(edited, tmp_path / "edited.nc")

    def simulate_refused(*args, **kwargs):
        raise AssertionError("simulated before the run continued was checked")

    monkeypatch.setattr("solver.simulate", simulate_refused)
    result = _run(scene, "--continue", tmp_path / "edited.nc", *later)
    assert result.exit_code == 2 and "c_mean" in result.stderr and "Traceback" not in result.output, result.output
