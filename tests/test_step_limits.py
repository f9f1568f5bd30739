"""The clock never steps beyond the scheme's limit (issue 33.2), and what the model lets phi and alpha reach bounds
every step (issue 33.3): a giant step gives the answer of many small ones, the expansion pair follows its exact
solution, a broken alpha is caught, and a runaway stops with its diagnosis and keeps what it computed."""
from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

import solver
from biostudy.cli import app
from biostudy.inputs.scene import load_scene
from solver import Grid, Problem
from solver.restart import start_state
from solver.transport import bounds, step

# the scene at 10³ cells of 2 µm: the directional sphere over T* = 5, mechanics off
GIANT = ["grid.shape=[10,10,10]", "grid.spacing=2.0", "time.t_end=5", "time.outputs=3", "mechanics.enabled=false"]


def directional(*overrides: str) -> xr.Dataset:
    return solver.simulate(load_scene("studies/directional.toml", [*GIANT, *overrides]).problem())


def test_one_giant_step_gives_the_answer_of_five_hundred():
    """Without the limit one step of 2.5 T* fills the box with biofilm (the issue: 8000 µm³ where 500 steps grow to
    1300 µm³ and then lose it all); split into substeps within it, both agree to 10 % at every output."""
    one, many = directional("time.steps=1"), directional("time.steps=500")
    assert many.attrs["steps_substepped"] == 0 and many.attrs["courant_max"] <= 1.0  # within the limit: as asked
    assert one.attrs["steps_substepped"] > 100 and 0.5 < one.attrs["courant_max"] <= 1.0
    assert one.attrs["steps_taken"] == one.attrs["steps_substepped"]
    np.testing.assert_allclose(one.biofilm_volume.values, many.biofilm_volume.values, rtol=0.10)
    assert many.biofilm_volume.values[1] > 2 * many.biofilm_volume.values[0] and many.biofilm_volume.values[2] == 0
    again = start_state(one)  # a continuation keeps to the step the limit needed
    assert again["step_limit"] == one.attrs["step_limit"] > 0


def exact_expansion(k_alpha: float, t: float) -> float:
    """A uniform phi = 1, alpha = 0 with nothing moving it: phi = cosh(k_alpha t) (Eqs. 34 and 36)."""
    return float(np.cosh(k_alpha * t))


def uniform(k_alpha: float, steps: int, t_end: float = 1.0) -> Problem:
    grid = Grid((4, 3), 1.0)
    return Problem(grid=grid, phi0=np.ones(grid.cells_shape), nutrient_held=np.zeros(grid.cells_shape, bool),
                   t_end=t_end, steps=steps, output_times=[0.0, t_end], params=solver.Parameters(k_alpha=k_alpha,
                                                                                                      r=0.0))


def test_the_expansion_pair_follows_cosh_and_stays_within_the_model_bound():
    """phi = cosh(k_alpha t) to first order in k_alpha dt; every step within the recursion's bound and the
    written fields within the model's (`model_bound` one step later), whatever the step."""
    for steps, tolerance in ((10, 0.05), (100, 0.005)):
        ds = solver.simulate(uniform(1.0, steps))
        phi = float(ds.phi.isel(time=-1).max())
        assert abs(phi - exact_expansion(1.0, 1.0)) <= tolerance * exact_expansion(1.0, 1.0), (steps, phi)
        allowed_phi, allowed_alpha = bounds.model_bound(1.0, 0.0, 1.0, 1.0 + 1.0 / steps)
        assert phi <= allowed_phi and float(ds.alpha.isel(time=-1).max()) <= allowed_alpha
    fast = solver.simulate(uniform(50.0, 1, t_end=0.2))  # k_alpha dt = 10 asked: split into e-folds at most
    assert fast.attrs["steps_substepped"] == fast.attrs["steps_taken"] == 10


def test_an_alpha_beyond_what_the_model_allows_fails_the_step(monkeypatch):
    """The bound comes from the parameters and the start, not from the run's own alpha: an alpha that grows twice
    as fast as Eq. 36 says is caught at once (bisected to the smallest step, then the run stops naming it)."""
    monkeypatch.setattr(step, "grow", lambda alpha, phi, k_alpha, dt: alpha + 2 * dt * k_alpha * phi)
    problem = uniform(1.0, 10)
    problem = Problem(**{**problem.__dict__, "numerics": solver.Numerics(max_substeps=100)})
    with pytest.raises(solver.SimulationError, match="expansion alpha = .* beyond .*what the model allows"):
        solver.simulate(problem)


def test_a_runaway_stops_with_its_diagnosis_and_keeps_what_it_computed(tmp_path):
    """The issue's scene with k_alpha = 1e3 (phi reached 6e55, the catalogue said "bounds held" and COMSTAT's
    marching cubes crashed): exit 1, one line naming time, cell, phi and alpha and the parameter; the outputs
    computed and the state where it stopped written, marked incomplete; `show` says so."""
    out = tmp_path / "runaway.nc"
    scene = ["--set", "grid.shape=[10,10,10]", "--set", "grid.spacing=2.0", "--set", "time.t_end=5", "--set",
             "time.outputs=3", "--set", "mechanics.enabled=false", "--set", "params.k_alpha=1e3", "--set",
             "time.steps=1", "--set", "substratum.face=\"z-\""]  # COMSTAT's observables on the huge fields too
    result = CliRunner().invoke(app, ["run", "directional", *scene, "-o", str(out), "-q"])
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 1 and len(lines) == 1 and "Traceback" not in result.output, result.output
    assert lines[0].startswith("error: simulation failed: ") and "t = 0.02" in lines[0]
    for said in ("expansion feedback runs away", "phi and alpha reach", "at cell (z, y, x)", "params.k_alpha",
                 "(marked incomplete)"):
        assert said in lines[0], said
    ds = xr.open_dataset(out)
    assert ds.time.values.tolist() == [0.0, pytest.approx(0.02)] and "stopped at T* = 0.02" in ds.attrs["incomplete"]
    assert np.isfinite(ds.phi.values).all() and float(ds.phi.max()) > 1e7 and np.isfinite(ds.biomass.values).all()
    shown = CliRunner().invoke(app, ["show", str(out)], env={"COLUMNS": "300"})
    assert shown.exit_code == 0 and "incomplete" in shown.stdout
    refused = CliRunner().invoke(app, ["run", "directional", *scene, "--continue", str(out), "--set", "time.t_end=6",
                                       "-o", str(tmp_path / "more.nc")])
    assert refused.exit_code == 2 and "unfinished run" in refused.stderr
