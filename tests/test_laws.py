"""The model's laws (`[model]`, `solver.Laws`): Table 1's expansion and the transient nutrient, each against
something independent — the residual of the paper's Table 1 evaluated by hand on the solver's own steps, and the
exact profile of diffusion into a half-space held at c = 1 on its face, c = erfc(x / (2 sqrt(d t))) — and as keys
of scenes and studies."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import xarray as xr
from scipy.special import erfc

from biostudy.commands.sweep import run_study
from biostudy.execution.identity import fingerprint
from biostudy.execution.jobs import Execution
from biostudy.inputs.scene import load_scene
from biostudy.plans.study import load_study
from solver import Grid, Laws, Parameters, Problem, simulate
from solver.errors import StepFailure
from solver.transport import Transport
from solver.transport.expansion import table1


def test_table1_solves_its_residual_by_hand():
    """Table 1, step 3a, by hand: 1 + alpha' = (1 + alpha)/(1 - k_alpha (phi' - phi)).  From alpha = 0 with
    k_alpha = 0.1, phi 0 -> 0.5 -> 0.8 gives alpha = 0.05/0.95 = 1/19, then (1/19 + 0.03)/0.97; a step that leaves
    phi as it was leaves alpha; back down to 0 through 0.5, 1 + alpha = 1/(0.95 0.97 1.03 1.05), not 1 (the
    residual is exact per step, not a function of phi)."""
    alpha = table1(np.zeros(1), np.zeros(1), np.array([0.5]), 0.1)
    assert alpha[0] == pytest.approx(1 / 19, rel=1e-14)
    alpha = table1(alpha, np.array([0.5]), np.array([0.8]), 0.1)
    assert alpha[0] == pytest.approx((1 / 19 + 0.03) / 0.97, rel=1e-14)
    assert table1(alpha, np.array([0.8]), np.array([0.8]), 0.1)[0] == alpha[0]
    back = table1(table1(alpha, np.array([0.8]), np.array([0.5]), 0.1), np.array([0.5]), np.zeros(1), 0.1)
    assert back[0] == pytest.approx(1 / (0.95 * 0.97 * 1.03 * 1.05) - 1, rel=1e-12)
    with pytest.raises(StepFailure, match=r"no solution: k_alpha \(phi' - phi\) = 1.5 >= 1 at cell 0"):
        table1(np.zeros(1), np.zeros(1), np.ones(1), 1.5)


def small_problem(**laws) -> Problem:
    """A disc of biofilm fed from a corner box: 12 x 12 cells of 1 µm, k_alpha large enough that alpha's terms
    are far above round-off."""
    grid = Grid((12, 12), 1.0)
    x, y = grid.cell_coordinates()
    held = (x > 10) & (y > 10)
    return Problem(grid=grid, phi0=(np.hypot(x - 5, y - 5) < 3).astype(float), nutrient_held=held, t_end=0.02,
                   steps=2, output_times=[0.0, 0.02], params=Parameters(k_alpha=0.5, g=1e9),
                   laws=Laws(**laws))


@pytest.mark.parametrize("expansion, holds", [("table1", True), ("eq36", False)])
def test_the_solver_s_two_steps_make_table1_s_residual_vanish(expansion, holds):
    """R_alpha = (alpha' - alpha)/((1 + alpha') dt) - k_alpha (phi' - phi)/dt, evaluated on the transport's own
    two steps (dt = 0.01), is zero to round-off in every cell with expansion = "table1" and not with Eq. 36."""
    problem = small_problem(expansion=expansion)
    transport, dt, k_alpha = Transport(problem), problem.dt, problem.params.k_alpha
    states = [transport.initial()]
    for _ in range(2):
        states.append(transport.step(states[-1], dt))
    for before, after in zip(states, states[1:]):
        growth = k_alpha * (after.phi - before.phi) / dt
        residual = (after.alpha - before.alpha) / ((1 + after.alpha) * dt) - growth
        assert np.abs(growth).max() > 1e-3  # phi moves: the residual's terms are far from zero
        assert (np.abs(residual).max() <= 1e-12 * np.abs(growth).max()) == holds, np.abs(residual).max()


def test_table1_s_alpha_follows_phi_and_a_sink_keeps_phi_bounded():
    """With Table 1, alpha follows phi: it rises where the biofilm came and falls below zero where it left (Eq. 36's
    alpha >= 0 grows wherever there is biofilm); the sink k_alpha alpha < 0 it makes in Eq. 34 never takes phi below
    0."""
    problem = dataclasses.replace(small_problem(expansion="table1"), t_end=0.2, steps=20, output_times=[0, 0.1, 0.2])
    ds = simulate(problem)
    phi, alpha = ds.phi.values, ds.alpha.values
    came, left = phi[-1] > phi[0] + 0.2, phi[-1] < phi[0] - 0.2
    assert came.any() and left.any()
    assert np.all(alpha[-1][came] > 0) and np.all(alpha[-1][left] < 0)
    assert np.nanmin(phi) >= 0.0 and ds.attrs["steps_bisected"] == 0
    biofilm = Transport(problem).biofilm  # where alpha < 0 meets a cell the biofilm has left entirely
    empty, still = np.zeros(biofilm.fv.n), [np.zeros(f.lower.size) for f in biofilm.fv.faces]
    assert np.array_equal(biofilm.step(empty, np.full(biofilm.fv.n, -0.2), still, problem.dt), empty)


def erfc_error(cells: int, steps: int, d: float = 2.0, t_end: float = 0.5, length: float = 16.0) -> float:
    """Largest error at t_end of the transient nutrient against c = erfc(x / (2 sqrt(d t))): a strip of `cells`
    cells (2-D, one cell wide), c = 1 held on its face x- from t = 0, no biofilm; the far face (erfc(8) ~ 1e-29)
    does not matter."""
    grid = Grid((cells, 1), length / cells)
    problem = Problem(grid=grid, phi0=np.zeros(grid.cells_shape), nutrient_held=np.zeros(grid.cells_shape, bool),
                      t_end=t_end, steps=steps, output_times=[0.0, t_end], nutrient_faces=(("x-", 1.0),),
                      params=Parameters(d=d, g=0.0, r=0.0, k_alpha=0.0, beta=0.0), laws=Laws(nutrient="transient"))
    c = simulate(problem).c.values[-1, 0]
    return float(np.abs(c - erfc(grid.centres("x") / (2 * np.sqrt(d * t_end)))).max())


def test_the_transient_nutrient_converges_to_the_half_space_s_erfc_profile_at_its_orders():
    """Backward Euler is first order in the step, the finite volumes second order in h: with h fixed and fine
    the error halves with the step; with the step refined as h^2 it falls as h^2."""
    in_time = [erfc_error(512, steps) for steps in (8, 16, 32)]
    in_both = [erfc_error(cells, steps) for cells, steps in ((16, 4), (32, 16), (64, 64))]
    for errors, order in ((in_time, 1.0), (in_both, 2.0)):
        observed = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
        assert np.all(np.abs(observed - order) < 0.15), (errors, observed)
    assert in_both[-1] < 5e-3


def test_a_fast_transient_nutrient_is_the_quasi_steady_one():
    """With the diffusion time across the domain L^2/d far below the step (the paper's eta_c << eta_phi), one
    transient step from c = 0 lands on the quasi-steady nutrient of the same phi, to within L^2/(d dt)
    relatively; a transient run starts from c = 0 outside the sources."""
    quasi, transient = (Transport(small_problem(nutrient=law)) for law in ("quasi-steady", "transient"))
    start = transient.initial()
    assert start.c.max() == 1.0 and np.count_nonzero(start.c) == np.count_nonzero(small_problem().nutrient_held)
    dt = small_problem().dt
    stepped = transient.nutrient.solve(start.phi, None, start.c, dt)
    scale = 12.0**2 / (Parameters().d * dt)
    np.testing.assert_allclose(stepped, quasi.initial().c, rtol=10 * scale, atol=1e-9)
    assert np.abs(stepped - quasi.initial().c).max() > 1e-3 * scale  # the mass term is there


def test_the_laws_are_scene_keys_and_the_defaults_change_no_identity(tiny_scene):
    scene = load_scene(tiny_scene, ['model.expansion="table1"', 'model.nutrient="transient"'])
    assert scene.problem().laws == Laws("first-order", "table1", "transient")
    plain = load_scene(tiny_scene).problem()
    assert plain.laws == Laws()
    assert fingerprint(dataclasses.replace(plain, laws=Laws("first-order", "eq36", "quasi-steady"))) == \
        fingerprint(plain)
    assert len({fingerprint(dataclasses.replace(plain, laws=Laws(**law))) for law in (
        {}, {"expansion": "table1"}, {"nutrient": "transient"}, {"consumption": "zero-order"})}) == 4


def test_a_study_sweeps_the_laws(tiny_scene, write_toml, tmp_path):
    plan = load_study(write_toml("laws.toml", 'scene = "tiny.toml"\n[set]\n"time.steps" = 4\n"params.k_alpha" = 0.5\n'
                                              '[sweep]\n"model.expansion" = ["eq36", "table1"]\n'
                                              '"model.nutrient" = ["quasi-steady", "transient"]\n'))
    out = tmp_path / "out"
    assert len(run_study(plan, out, Execution()).ran) == 4
    with xr.open_dataset(out / "study.nc") as ds:
        assert set(ds.model_expansion.values) == {"eq36", "table1"}
        alpha = ds.alpha.isel(time=-1)
        assert float(alpha.sel(model_expansion="eq36").min()) >= 0 > float(alpha.sel(model_expansion="table1").min())
        c_start = ds.c.isel(time=0).mean(["x", "y"])
        assert float(c_start.sel(model_nutrient="transient").max()) < float(c_start.sel(model_nutrient="quasi-steady")
                                                                             .min())


def test_a_calibration_sets_the_laws_per_condition(tiny_scene, write_toml):
    """A calibration's [set] and its conditions choose the laws as any scene key: each simulation's problem has
    them (a full calibration with both, 32 simulations, is in the note of this change)."""
    from biostudy.calibration.problem import load_calibration

    write_toml("t.tsv", "observableId\tsimulationConditionId\ttime\tmeasurement\tnoiseParameters\n"
                        "biofilm_volume\tpaper\t0.1\t30\t1\nbiofilm_volume\tequations\t0.1\t30\t1\n")
    plan = load_calibration(write_toml("c.toml", """\
        scene = "tiny.toml"
        [set]
        "model.nutrient" = "transient"
        [data]
        measurements = "t.tsv"
        [estimate]
        r = [50.0, 150.0]
        [conditions.equations]
        [conditions.paper]
        "model.expansion" = "table1"
        """))
    laws = {name: plan.scene_at(name, plan.values(np.array([0.5]))).problem().laws for name in plan.conditions}
    assert laws == {"equations": Laws(nutrient="transient"), "paper": Laws(expansion="table1", nutrient="transient")}
