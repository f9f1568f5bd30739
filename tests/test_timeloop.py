"""The time loop: output clock, bisection of failed steps, error-controlled steps."""
import numpy as np
import pytest

from solver import Grid, Numerics, Parameters, Problem, SimulationError, evolve, simulate
from solver.errors import StepFailure
from solver.timeloop import Clock
from solver.transport import State


def sphere_problem(n=10, t_end=0.2, steps=20, outputs=(0.0, 0.2), **kw):
    grid = Grid((n, n, n), 20.0 / n)
    x, y, z = grid.cell_coordinates()
    phi0 = ((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2 <= 25).astype(float)
    held = (x > 16) & (y > 16) & (z > 16)
    return Problem(grid=grid, phi0=phi0, nutrient_held=held, t_end=t_end, steps=steps,
                   output_times=np.asarray(outputs), **kw)


def test_evolve_is_a_generator_landing_exactly_on_output_times():
    """Output times need not be multiples of the step: steps are shortened to land on them."""
    outputs = [0.0, 0.033, 0.1, 0.2]
    run = evolve(sphere_problem(outputs=outputs))
    first = next(run)
    assert first.time == 0.0 and first.steps == 0
    rest = list(run)
    assert [s.time for s in rest] == outputs[1:]
    assert rest[-1].steps == 21  # 20 nominal steps, one of them split at t = 0.033
    assert all(b.steps > a.steps for a, b in zip(rest, rest[1:]))


class FlakyTransport:
    """Fails every step longer than `limit`; otherwise advances t (tests the clock alone)."""

    def __init__(self, problem, limit):
        self.problem, self.limit, self.attempts = problem, limit, []

    def step(self, state, dt, with_nutrient=True):
        self.attempts.append(dt)
        if dt > self.limit:
            raise StepFailure("linear solver did not converge", "cell (z, y, x) = (1, 2, 3)")
        return State(state.t + dt, state.phi, state.alpha, state.c)

    def velocity(self, state):
        return [], 0.0  # no front moves: no step is split for its Courant number

    def runaway(self, state):
        return None


def test_failed_steps_are_bisected_and_grow_back():
    problem = sphere_problem(t_end=1.0, steps=10)
    transport = FlakyTransport(problem, limit=0.03)
    clock = Clock(transport)
    state = clock.advance(State(0.0, None, None, None), 0.5)
    assert state.t == 0.5
    assert clock.bisections >= 2  # 0.1 -> 0.05 -> 0.025
    assert min(transport.attempts) == pytest.approx(0.025)
    assert clock.steps == 20  # 0.5 / 0.025: never back above the limit, never below


def test_persistent_failure_stops_with_time_cause_and_place():
    problem = sphere_problem(t_end=1.0, steps=10, numerics=Numerics(max_substeps=80))
    clock = Clock(FlakyTransport(problem, limit=0.0))
    with pytest.raises(SimulationError) as error:
        clock.advance(State(0.0, None, None, None), 1.0)
    message = str(error.value)
    assert message.startswith("t = 0: linear solver did not converge")
    assert "cell (z, y, x) = (1, 2, 3)" in message and "max_substeps" in message
    assert clock.bisections == 4  # 0.1 / 2^4 = 0.00625 < 1/80


def test_unreachable_solver_tolerance_fails_the_run_with_its_diagnosis():
    """A real failure through the whole loop: BiCGSTAB cannot reach 1e-30, bisection cannot help."""
    problem = sphere_problem(n=6, numerics=Numerics(biofilm_tolerance=1e-30, max_substeps=200))
    with pytest.raises(SimulationError, match="biofilm BiCGSTAB did not converge"):
        simulate(problem)


def test_error_control_meets_tolerance_and_spends_steps_where_needed():
    """Step doubling: final-time error against a fine fixed-step reference falls with the tolerance."""
    reference = simulate(sphere_problem(steps=800)).phi.values[-1]
    errors, steps = [], []
    for tolerance in (1e-2, 1e-3, 1e-4):
        ds = simulate(sphere_problem(steps=4, numerics=Numerics(time_tolerance=tolerance)))
        errors.append(np.nanmax(np.abs(ds.phi.values[-1] - reference)))
        steps.append(ds.attrs["steps_taken"])
        # the controller spends its tolerance: steps grow until their estimated error comes near it
        assert 0.1 * tolerance < ds.attrs["largest_step_error"] <= tolerance
    assert errors[0] > errors[1] > errors[2], errors
    assert steps[0] < steps[1] < steps[2], steps
    assert errors[-1] < 0.01


def test_progress_reports_every_accepted_step():
    seen = []
    simulate(sphere_problem(n=6), progress=seen.append)
    assert [p.steps for p in seen] == list(range(1, 21))
    assert seen[-1].time == pytest.approx(0.2) and seen[-1].t_end == 0.2


def test_progress_tells_the_mechanics_solves_done_and_to_come():
    """Solves at outputs 0, 3 and 4 (every 3rd and the last): each report says how many are done, how many come,
    their wall time so far and the outputs the run makes (a time-left estimate counts them apart from the
    steps)."""
    from solver.problem import MechanicsSetup

    seen = []
    simulate(sphere_problem(n=4, steps=8, outputs=(0.0, 0.05, 0.1, 0.15, 0.2), mechanics=MechanicsSetup(every=3)),
             progress=seen.append)
    told = [(p.mechanics_solves, p.mechanics_left) for p in seen]
    assert told[0] == (1, 2) and told[-1] == (2, 1)  # before the solves at T* = 0.15 and 0.2
    assert all(done + left == 3 for done, left in told)
    assert seen[0].mechanics_seconds > 0 and seen[-1].mechanics_seconds > seen[0].mechanics_seconds
    assert {p.outputs for p in seen} == {5}


def test_two_dimensional_scene_is_solved_in_two_dimensions():
    """A 2-D scene is the 3-D scene extruded along z with zero flux on the z faces: phi, c and alpha of the
    2-D run equal every layer of a 3-D run of three layers (volumes per µm of thickness aside)."""
    x2, y2 = Grid((12, 8), 1.0).cell_coordinates()
    phi0 = ((x2 - 6) ** 2 + (y2 - 4) ** 2 <= 4).astype(float)
    common = dict(t_end=0.1, steps=10, output_times=[0, 0.05, 0.1], params=Parameters(g=1e9))
    flat = simulate(Problem(grid=Grid((12, 8), 1.0), phi0=phi0, nutrient_held=x2 > 11, **common))
    assert flat.phi.dims == ("time", "y", "x") and "z" not in flat.dims and flat.phi.shape == (3, 8, 12)
    thick = simulate(Problem(grid=Grid((12, 8, 3), 1.0), phi0=np.stack([phi0] * 3),
                             nutrient_held=np.stack([x2 > 11] * 3), **common))
    for name in ("phi", "c", "alpha"):
        for layer in range(3):
            np.testing.assert_allclose(flat[name].values, thick[name].values[:, layer], rtol=0, atol=1e-9)
    assert float(flat.phi_mean[-1]) > float(flat.phi_mean[0])  # it grows


def test_the_nutrient_guess_is_exact_for_a_parabola_in_time():
    """The starting guess of the next nutrient solve (State.c_guess) is Newton's parabola through the last
    three c's: exact for c quadratic in t, also for unequal steps; after one step the line through two."""
    def c(t):
        return np.array([1.0 + 2.0 * t - 3.0 * t**2, 0.5 - t + 4.0 * t**2])

    times = [0.0, 0.1, 0.25, 0.27]  # steps 0.1, 0.15, 0.02
    state = State(times[0], None, None, c(times[0]))
    assert np.array_equal(state.c_guess(0.1), c(0.0))  # no history: c itself
    state = state.after(times[1] - times[0], None, None, c(times[1]))
    line = c(times[1]) + 0.15 * (c(times[1]) - c(times[0])) / 0.1
    assert np.allclose(state.c_guess(0.15), line, rtol=0, atol=1e-14)
    state = state.after(times[2] - times[1], None, None, c(times[2]))
    assert np.allclose(state.c_guess(times[3] - times[2]), c(times[3]), rtol=0, atol=1e-14)
    state = state.after(times[3] - times[2], None, None, c(times[3]))
    assert np.allclose(state.c_guess(0.5), c(times[3] + 0.5), rtol=0, atol=1e-13)


def test_the_transport_solves_on_one_blas_thread_from_its_first_step(monkeypatch):
    """OpenBLAS threads on busy cores made the coarsest multigrid level's pseudo-inverse (the whole operator of a
    small grid) 60 times slower; the first step's hierarchy is built under the one-thread limit too."""
    from threadpoolctl import threadpool_info, threadpool_limits

    pinv, threads = np.linalg.pinv, []

    def counted(matrix, *args, **kwargs):
        threads.append(max(pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"))
        return pinv(matrix, *args, **kwargs)

    monkeypatch.setattr(np.linalg, "pinv", counted)
    with threadpool_limits(limits=2, user_api="blas"):  # what a 2-core machine gives by default
        simulate(sphere_problem(n=8, steps=4, t_end=0.04, outputs=(0.0, 0.04)))
    assert threads and set(threads) == {1}, threads


def test_the_blas_libraries_are_looked_for_again_only_after_an_import(monkeypatch):
    """`blas_threads` keeps the libraries it found (a look costs milliseconds, at every output) until a module is
    imported, which is how a BLAS library comes to be loaded."""
    import sys

    from solver.parallel import blas

    first = blas._controller()
    assert blas._controller() is first
    monkeypatch.setitem(sys.modules, "biostudy_test_newly_imported", object())
    again = blas._controller()
    assert again is not first and blas._controller() is again


def test_a_process_forked_while_another_thread_looks_for_the_blas_libraries_can_look_too():
    """The look's lock, held by another thread at the fork, is not held in the child (no thread there releases it)."""
    import os
    import threading

    from solver.parallel import blas

    held = threading.Event()
    release = threading.Event()

    def looking():
        with blas._looking:
            held.set()
            release.wait(10)

    other = threading.Thread(target=looking)
    other.start()
    held.wait(10)
    pid = os.fork()
    if pid == 0:  # the child: one look, then out at once (a lock left held would block here; the parent kills it)
        try:
            with blas.blas_threads(1):
                pass
        finally:
            os._exit(0)
    release.set()
    other.join()
    for _ in range(200):
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        threading.Event().wait(0.05)
    else:
        os.kill(pid, 9)
        os.waitpid(pid, 0)
        raise AssertionError("the child waited for a lock its parent's thread held at the fork")
    assert os.waitstatus_to_exitcode(status) == 0
