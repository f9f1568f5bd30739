"""Threads change how fast a run goes, never what it computes (solver/parallel): each threaded kernel against
the serial numpy, scipy or pyamg form it replaces, bit for bit, and whole runs on 1, 2 and 3 threads.

The blocks of a team are made small here (`small_blocks`: 16 rows) so that reduced meshes are split as a
large one is."""
import dataclasses

import numpy as np
import pyamg
import pytest
import scipy.sparse as sp
from pyamg.amg_core import gauss_seidel

from biostudy.execution.identity import fingerprint
from solver import Grid, Laws, Numerics, Problem
from solver.mechanics.stencil import Stencil, offsets
from solver.parallel import Team, rows
from solver.parallel.rows import add_product, product, residual
from solver.parallel.sweeps import Sweeps, _relax, pipelined
from solver.problem import Parameters
from solver.timeloop import Simulation
from solver.transport.biofilm import Biofilm
from solver.transport.finite_volume import FiniteVolumeGrid
from solver.transport.krylov import jacobi_bicgstab, pcg
from solver.transport.linear import VCycle, coarse_places


@pytest.fixture
def small_blocks(monkeypatch):
    monkeypatch.setattr(rows, "MIN_ROWS", 16)


def grid_matrix(shape, seed=0):
    """The nutrient's kind of matrix, -lap + diag(d >= 0) on a grid with obstacles, and its rows' places."""
    rng = np.random.default_rng(seed)
    grid = Grid(shape, 0.7)
    fv = FiniteVolumeGrid(grid, rng.random(grid.cells_shape) < 0.1)
    matrix = sp.csr_matrix(-fv.laplacian + sp.diags(rng.random(fv.n)))
    return matrix, fv.places(np.arange(fv.n)), rng


def grid_levels(shape, seed):
    """The grid's matrix and its first two Ruge-Stueben coarse levels, each with its rows' places."""
    matrix, places, rng = grid_matrix(shape, seed=seed)
    hierarchy = pyamg.ruge_stuben_solver(matrix, max_coarse=20)
    levels = [(matrix, places)]
    for level in hierarchy.levels[:2]:
        places = coarse_places(level, places)
        levels.append((sp.csr_matrix(hierarchy.levels[len(levels)].A), places))
    return levels, rng


@pytest.mark.parametrize("size", [2, 3])
def test_products_are_scipys(small_blocks, size):
    matrix, _, rng = grid_matrix((9, 8, 7))
    team = Team(size)
    x, b = rng.normal(size=(2, matrix.shape[0]))
    assert np.array_equal(product(team, matrix, x), matrix @ x)
    assert np.array_equal(residual(team, matrix, x, b), b - matrix @ x)
    prolongation = sp.csr_matrix(sp.random(matrix.shape[0], 40, density=0.1, random_state=1))
    e, y = rng.normal(size=40), x.copy()
    add_product(team, prolongation, e, y)
    expected = x.copy()
    expected += prolongation @ e
    assert np.array_equal(y, expected)


@pytest.mark.parametrize("shape", [(9, 8, 7), (30, 26)])
@pytest.mark.parametrize("size", [2, 3])
def test_pipelined_sweeps_are_pyamgs(small_blocks, shape, size):
    """Forward and backward sweeps on several threads give pyamg's serial sweep bit for bit, on the grid's matrix
    (7- or 5-point, obstacles) and on its Ruge-Stueben coarse levels (denser, rows taking the places of their
    C-points)."""
    levels, rng = grid_levels(shape, seed=size)
    levels = [(operator, places) for operator, places in levels if operator.shape[0] >= size * rows.MIN_ROWS]
    assert len(levels) >= 2
    for operator, (layer, lane) in levels:
        sweeps = Sweeps(operator, layer, lane, Team(size), adaptive=False)
        assert sweeps.count == size  # the pipeline is used, not the serial fallback
        b, start = rng.normal(size=(2, operator.shape[0]))
        for forward, arguments in ((True, (0, operator.shape[0], 1)), (False, (operator.shape[0] - 1, -1, -1))):
            x, expected = start.copy(), start.copy()
            (sweeps.forward if forward else sweeps.backward)(operator, x, b)
            gauss_seidel(operator.indptr, operator.indices, operator.data, expected, b, *arguments)
            assert np.array_equal(x, expected)


@pytest.mark.parametrize("size", [1, 2, 3])
def test_a_forward_sweep_from_zero_leaves_out_the_later_rows_to_the_same_bits(small_blocks, size):
    """A forward sweep from x = 0 that leaves out the terms of the later rows (a_ij x_j = +-0 for j > i), pipelined
    or serial, gives pyamg's full sweep from 0 bit for bit on the grid's matrix and its coarse levels; from another
    x it would not (the test would see a sweep that left out nonzero terms)."""
    levels, rng = grid_levels((9, 8, 7), seed=size)
    for operator, (layer, lane) in levels:
        b = rng.normal(size=operator.shape[0])
        expected = np.zeros(operator.shape[0])
        gauss_seidel(operator.indptr, operator.indices, operator.data, expected, b, 0, operator.shape[0], 1)
        for adaptive in (False, True):  # the pipeline where the rows allow it, and the serial sweep
            sweeps = Sweeps(operator, layer, lane, Team(size), adaptive=adaptive)
            x = np.zeros(operator.shape[0])
            sweeps.forward(operator, x, b, zero=True)
            assert np.array_equal(x, expected)
        Sweeps._serial(operator, x, b, True, zero=True)  # again from a nonzero x: not the full sweep
        again = expected.copy()
        gauss_seidel(operator.indptr, operator.indices, operator.data, again, b, 0, operator.shape[0], 1)
        assert not np.array_equal(x, again)


def lanes_far_ahead(sweeps, matrix, x, b, forward):
    """A sweep with its blocks in the order the pipeline's waits allow that runs each lane as far ahead of the
    lanes after it as they let it (lane 0 first, as many layers as it may, then lane 1, ...): the order a thread
    schedule could take at worst, made here in one thread so that it is taken every time; backward: mirrored)."""
    count, layers, lag, starts, order = sweeps.count, sweeps.layers, sweeps.lag, sweeps.starts, sweeps.order
    done = [0] * count
    while min(done) < layers:
        for t in range(count) if forward else reversed(range(count)):
            while done[t] < layers and all(
                    done[s] >= (done[t] + 1 if (s < t) == forward else done[t] - lag + 1)
                    for s in range(count) if s != t):
                g = done[t] if forward else layers - 1 - done[t]
                block = t * layers + g
                arguments = (starts[block], starts[block + 1], 1) if forward else (starts[block + 1] - 1,
                                                                                    starts[block] - 1, -1)
                _relax(matrix.indptr, matrix.indices, matrix.data, x, b, order, *arguments)
                done[t] += 1


@pytest.mark.parametrize("shape", [(9, 8, 7), (30, 26)])
@pytest.mark.parametrize("size", [2, 3])
def test_a_lane_runs_ahead_only_as_far_as_the_couplings_allow(small_blocks, shape, size):
    """On the grid's matrix (couplings within a layer or a lane) a lane may run through every layer before the
    lanes after it start; on the Ruge-Stueben levels (couplings across both) only as far as the nearest such
    coupling.  Either way, the sweep in the order that runs lanes farthest ahead is pyamg's, bit for bit."""
    levels, rng = grid_levels(shape, seed=size)
    lags = []
    for operator, (layer, lane) in levels:
        sweeps = Sweeps(operator, layer, lane, Team(size), adaptive=False)
        if sweeps.count < 2:
            continue
        lags.append((sweeps.lag, sweeps.layers))
        b, start = rng.normal(size=(2, operator.shape[0]))
        for forward, arguments in ((True, (0, operator.shape[0], 1)), (False, (operator.shape[0] - 1, -1, -1))):
            x, expected = start.copy(), start.copy()
            lanes_far_ahead(sweeps, operator, x, b, forward)
            gauss_seidel(operator.indptr, operator.indices, operator.data, expected, b, *arguments)
            assert np.array_equal(x, expected)
    assert lags[0][0] == lags[0][1] and any(lag < layers for lag, layers in lags[1:])


def test_the_faster_way_of_sweeping_is_kept_and_the_other_timed_again(small_blocks, monkeypatch):
    """On a machine where the pipeline waits for threads that do not run, the serial sweep (the same numbers) is
    used instead: the faster by the running means of their times, the pipeline timed again after SAMPLE sweeps,
    then after twice as many each time it stays the slower."""
    from solver.parallel import sweeps as module

    matrix, (layer, lane), rng = grid_matrix((9, 8, 7))
    sweeps = Sweeps(matrix, layer, lane, Team(2))
    clock = iter(np.arange(0.0, 1e4, 1.0))
    monkeypatch.setattr(module.time, "perf_counter", lambda: next(clock))  # every sweep "takes" 1 s
    ways = []
    monkeypatch.setattr(sweeps, "_pipelined", lambda *args: ways.append("pipelined"))
    monkeypatch.setattr(sweeps, "_serial", lambda *args: ways.append("serial"))
    sweeps.seconds[False] = 0.5  # serial measured faster
    sweeps.seconds[True] = 2.0
    for _ in range(7 * module.SAMPLE):
        sweeps.forward(matrix, np.zeros(matrix.shape[0]), np.ones(matrix.shape[0]))
    tried = [i for i, way in enumerate(ways) if way == "pipelined"]
    assert tried == [0, module.SAMPLE, 3 * module.SAMPLE]  # later each time it stays the slower


def test_a_pipeline_timed_again_and_found_faster_is_used_from_then_on(small_blocks, monkeypatch):
    """The probe's time replaces the way's mean: a pipeline whose first sweep was slow (a cold start, 4 s here
    against 1 s serial) and that now takes 0.5 s is used from the sweep after its first probe on (blended into
    the old mean with weight 0.25 it stayed the "slower" through ever rarer probes)."""
    from solver.parallel import sweeps as module

    matrix, (layer, lane), rng = grid_matrix((9, 8, 7))
    sweeps = Sweeps(matrix, layer, lane, Team(2))
    now = [0.0]
    monkeypatch.setattr(module.time, "perf_counter", lambda: now[0])
    ways = []

    def way(name, seconds):
        def sweep(*args):
            ways.append(name)
            now[0] += seconds
        return sweep

    monkeypatch.setattr(sweeps, "_pipelined", way("pipelined", 0.5))
    monkeypatch.setattr(sweeps, "_serial", way("serial", 1.0))
    sweeps.seconds[True], sweeps.seconds[False] = 4.0, 1.0
    for _ in range(3 * module.SAMPLE):
        sweeps.forward(matrix, np.zeros(matrix.shape[0]), np.ones(matrix.shape[0]))
    # the first sweep is the pipeline's probe; from then on the pipeline, the serial sweep timed every SAMPLE-th
    assert ways == ["serial" if (i + 1) % module.SAMPLE == 0 else "pipelined" for i in range(len(ways))]


def test_a_pattern_against_the_grid_order_is_swept_serially(small_blocks):
    """A coupling from a row to an earlier row of a later layer would make the pipeline differ from the serial
    sweep: such a pattern is detected and swept by pyamg alone (same answer)."""
    matrix, (layer, lane), rng = grid_matrix((9, 8, 7))
    assert pipelined(matrix, layer, lane * 2 // (lane.max() + 1), 2)
    reversed_layers = layer.max() - layer  # the same rows, layers numbered against the rows' order
    assert not pipelined(matrix, reversed_layers, lane * 2 // (lane.max() + 1), 2)
    sweeps = Sweeps(matrix, reversed_layers, lane, Team(2))
    assert sweeps.count == 1
    b = rng.normal(size=matrix.shape[0])
    x, expected = np.zeros_like(b), np.zeros_like(b)
    sweeps.forward(matrix, x, b)
    gauss_seidel(matrix.indptr, matrix.indices, matrix.data, expected, b, 0, b.size, 1)
    assert np.array_equal(x, expected)


def numpy_pcg(matrix, rhs, x, precondition, target, max_iterations):
    """The nutrient's CG as whole-array numpy and scipy expressions (the form before threads)."""
    r = rhs - matrix @ x
    z = precondition(r)
    p = z.copy()
    rz = r @ z
    for iteration in range(1, max_iterations + 1):
        q = matrix @ p
        step = rz / (p @ q)
        x += step * p
        r -= step * q
        if np.linalg.norm(r) <= target:
            return x, iteration
        z = precondition(r)
        rz, previous = r @ z, rz
        p *= rz / previous
        p += z
    return x, max_iterations


def numpy_bicgstab(matrix, rhs, x, inverse, target):
    """The biofilm's BiCGSTAB as whole-array numpy (the form before threads)."""
    r = rhs - matrix @ x
    shadow = r.copy()
    rho = alpha = omega = 1.0
    v = p = np.zeros_like(r)
    for iteration in range(1, 100):
        rho, previous = shadow @ r, rho
        p = r + (rho / previous) * (alpha / omega) * (p - omega * v)
        p_hat = inverse * p
        v = matrix @ p_hat
        alpha = rho / (shadow @ v)
        s = r - alpha * v
        if np.linalg.norm(s) <= target:
            return x + alpha * p_hat, iteration
        s_hat = inverse * s
        t = matrix @ s_hat
        omega = (t @ s) / (t @ t)
        x = x + (alpha * p_hat + omega * s_hat)
        r = s - omega * t
        if np.linalg.norm(r) <= target:
            return x, iteration


@pytest.mark.parametrize("size", [1, 2, 3])
def test_krylov_loops_are_the_numpy_forms(small_blocks, size):
    """CG with the threaded V-cycle and BiCGSTAB on a team: the iterates of the whole-array numpy loops (with
    pyamg's serial V-cycle) bit for bit, iteration counts included."""
    matrix, places, rng = grid_matrix((9, 8, 7), seed=4)
    rhs = rng.random(matrix.shape[0])
    hierarchy = pyamg.ruge_stuben_solver(matrix, max_coarse=20)
    team, serial = Team(size), VCycle(hierarchy)
    threaded = VCycle(hierarchy, team=team, places=places)
    target = 1e-10 * np.linalg.norm(rhs)
    x, iterations, _, info = pcg(matrix, rhs, np.zeros_like(rhs), lambda r: threaded(matrix, r), target, 50, team)
    expected, expected_iterations = numpy_pcg(matrix, rhs, np.zeros_like(rhs), lambda r: serial(matrix, r), target, 50)
    assert info == 0 and iterations == expected_iterations and np.array_equal(x, expected)
    advection = sp.csr_matrix(sp.random(*matrix.shape, density=0.01, random_state=2) + 50 * sp.identity(rhs.size))
    nonsymmetric = sp.csr_matrix(matrix + advection)
    x, iterations = jacobi_bicgstab(nonsymmetric, rhs, np.zeros_like(rhs), 1e-12, nonsymmetric.diagonal(), team=team)
    expected, expected_iterations = numpy_bicgstab(nonsymmetric, rhs, np.zeros_like(rhs),
                                                   1.0 / nonsymmetric.diagonal(), 1e-12 * np.linalg.norm(rhs))
    assert iterations == expected_iterations and np.array_equal(x, expected)


def colony(shape, laws=Laws(), k_alpha=5.0, **numerics):
    """A colony growing toward a held corner past an obstacle, on a held face: every part of a transport step."""
    grid = Grid(shape, 20.0 / shape[0])
    centres = grid.cell_coordinates()
    phi0 = (sum((x - 10.0) ** 2 for x in centres) < 16.0).astype(float)
    held = np.logical_and.reduce([x > 17.0 for x in centres])
    obstacle = (np.abs(centres[0] - 4.0) < 1.5) & (centres[1] > 12.0)
    return Problem(grid=grid, phi0=phi0, nutrient_held=held, obstacle=obstacle, nutrient_faces=(("x-", 0.5),),
                   t_end=0.02, steps=20, output_times=[0.0, 0.01, 0.02], params=Parameters(k_alpha=k_alpha),
                   numerics=Numerics(**numerics), laws=laws)


TABLE1_TRANSIENT = Laws(expansion="table1", nutrient="transient")  # the paper's algorithm: alpha < 0 too
TABLE1_K_ALPHA = 0.5  # Table 1's expansion has a solution while k_alpha (phi' - phi) < 1


@pytest.mark.parametrize("shape, numerics, laws", [
    ((12, 12, 12), {"advection": "tvd", "growth_velocity": "front"}, Laws()),
    ((24, 20), {"advection": "upwind", "growth_velocity": "pointwise"}, Laws()),
    ((24, 20), {"advection": "tvd", "growth_velocity": "pointwise"}, TABLE1_TRANSIENT),
])
def test_runs_on_one_two_and_three_threads_are_identical(small_blocks, shape, numerics, laws):
    """phi, c and alpha at every output, and the solvers' iteration counts, equal for 1, 2 and 3 threads."""
    runs = []
    for threads in (1, 2, 3):
        problem = colony(shape, laws, TABLE1_K_ALPHA if laws.expansion == "table1" else 5.0, threads=threads,
                         **numerics)
        simulation = Simulation(problem)
        assert simulation.team.size == threads
        runs.append(([(s.phi, s.c, s.alpha) for s in simulation], simulation.report()))
    (first, report), others = runs[0], runs[1:]
    assert report["nutrient_cg_iterations"] > 0 and report["biofilm_iterations"] > 0
    for fields, other in others:
        for a, b in zip(first, fields):
            assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))
        assert all(other[k] == report[k] for k in ("nutrient_cg_iterations", "biofilm_iterations"))


@pytest.mark.parametrize("laws", [Laws(), TABLE1_TRANSIENT])
def test_the_first_hierarchy_built_ahead_changes_nothing(monkeypatch, laws):
    """`Nutrient.prepare` builds the first solve's hierarchy early (less memory held then): the run is the one
    whose first solve builds it, bit for bit (a transient nutrient's first solve has the mass on its diagonal:
    it is not prepared)."""
    from solver.transport.nutrient import Nutrient

    def run():
        simulation = Simulation(colony((24, 20), laws, TABLE1_K_ALPHA, advection="tvd"))
        return [(s.phi, s.c, s.alpha) for s in simulation], simulation.report()["nutrient_cg_iterations"]

    prepared, iterations = run()
    monkeypatch.setattr(Nutrient, "prepare", lambda self, phi: None)
    built, iterations_built = run()
    assert iterations == iterations_built
    for a, b in zip(prepared, built):
        assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))


def test_the_thread_count_is_no_part_of_a_cases_identity():
    problem = colony((8, 8))
    for threads in (1, 4):
        assert fingerprint(dataclasses.replace(problem, numerics=Numerics(threads=threads))) == fingerprint(problem)
    assert fingerprint(dataclasses.replace(problem, numerics=Numerics(advection="tvd"))) != fingerprint(problem)


def test_a_team_runs_every_part_at_once_and_reraises_a_failure():
    team = Team(3)
    seen = []

    def work(part):
        seen.append(part)
        if part == 2:
            raise ValueError("part 2")

    with pytest.raises(ValueError, match="part 2"):
        team.run(work)
    assert sorted(seen) == [0, 1, 2]
    team.run(lambda part: seen.append(part))  # still serving
    assert sorted(seen) == [0, 0, 1, 1, 2, 2]
    team.close()


@pytest.mark.parametrize("nodes_shape", [(7, 6, 5), (9, 8)])
@pytest.mark.parametrize("size", [2, 3])
def test_stencil_products_are_the_serial_pass(small_blocks, nodes_shape, size):
    """The mechanics' half-stencil product in layers on a team: the serial pass bit for bit (3x3 blocks in 3-D,
    2x2 in 2-D, nodes without unknowns among them)."""
    rng = np.random.default_rng(size)
    d = len(nodes_shape)
    node_of = np.where(rng.random(int(np.prod(nodes_shape))) < 0.15, -1, 0)
    nodes = np.flatnonzero(node_of == 0)
    node_of[nodes] = np.arange(nodes.size)
    blocks = rng.normal(size=(node_of.size, len(offsets(d)), d, d))
    x = rng.normal(size=nodes.size * d)
    serial = Stencil(blocks, nodes_shape, node_of, nodes) @ x
    assert np.array_equal(Stencil(blocks, nodes_shape, node_of, nodes, team=Team(size)) @ x, serial)


class Reversed(Team):
    """A team whose parts run one after another, last first: a schedule under which a block that wrote into
    another's rows, or read them before they were made, gives another answer (the row-wise kernels only: a
    pipelined sweep waits for the parts before it)."""

    def run(self, work):
        for part in reversed(range(self.size)):
            work(part)


@pytest.mark.parametrize("advection", ["upwind", "tvd"])
def test_the_biofilm_step_made_in_blocks_is_the_numpy_form(small_blocks, advection):
    """Matrix, right-hand side and bound of a phi step, made block by block in reverse order: whole-array numpy's
    (the advection data of tests/test_kernels.py's numpy form, diffusion added, 1/dt on the diagonal; a sink takes
    at most what is there)."""
    from test_kernels import numpy_advection, transport_on

    transport = transport_on((9, 8, 7), advection)
    blocked = Biofilm(transport.fv, transport.problem.params, transport.problem.numerics, team=Reversed(3))
    assert blocked.rows.size == 4
    rng = np.random.default_rng(11)
    w = [rng.normal(scale=30, size=f.lower.size) for f in transport.fv.faces]
    k_alpha = transport.problem.params.k_alpha
    phi = np.round(rng.random(transport.fv.n), 1)
    alpha = (rng.random(transport.fv.n) - 0.5) * 400.0 / k_alpha  # sinks too (Table 1's expansion), some > phi/dt
    rhs, diagonal, upper = blocked.assemble(phi, alpha, w, 0.01)
    laplacian, zero = transport.fv.laplacian, blocked.matrix.copy()
    zero.data[:] = 0.0
    beta = transport.problem.params.beta
    diffusion = sp.csr_matrix(zero + sp.csr_matrix((-beta * laplacian.data, laplacian.indices, laplacian.indptr)))
    assert np.array_equal(diffusion.indices, blocked.matrix.indices)  # -beta lap on the matrix's pattern
    data = diffusion.data + numpy_advection(blocked, w, phi)
    data[blocked.diagonal] += 1.0 / 0.01
    source = k_alpha * alpha
    assert np.array_equal(blocked.matrix.data, data)
    assert np.array_equal(diagonal, data[blocked.diagonal])
    assert np.any(phi / 0.01 + source < 0.0) and np.any(phi / 0.01 + source > 0.0)
    assert np.array_equal(rhs, np.maximum(phi / 0.01 + source, 0.0)) and upper == np.max(phi + 0.01 * source,
                                                                                          initial=0.0)


def test_a_team_runs_independent_parts_in_turn_while_that_has_been_faster(monkeypatch):
    """Parts run in the calling thread one after another while the team's running mean says threads have not
    paid (a busy machine), at once after PROBE times, then after twice as many each time; parts that wait for one
    another always run at once."""
    import threading

    from solver.parallel import team as module

    # the probes' own timings leave the mean as set (a part preempted on a loaded machine would otherwise measure)
    monkeypatch.setattr(module, "SHORT", float("inf"))
    team = Team(2)
    seen = []

    def where(part):
        seen.append(threading.current_thread() is threading.main_thread())

    team.ratios[module.kind(where)] = 3.0  # at once took 3 times as long as in turn would have
    for _ in range(7 * module.PROBE):
        team.run(where)
    probes = [i // 2 for i, here in enumerate(seen) if not here]  # the calls whose part 1 ran on the helper
    assert probes == [module.PROBE - 1, 2 * module.PROBE - 1, 4 * module.PROBE - 1]  # later each time
    team.ratios[module.kind(where)] = 3.0
    seen.clear()
    team.run(where, together=True)
    assert sorted(seen) == [False, True]
    team.close()


def test_each_kind_of_work_has_its_mean_and_a_trial_that_pays_brings_the_threads_back(monkeypatch):
    """A kind of work whose threads did not pay does not send another kind in turn; and once a trial at once
    pays, the parts run at once from the next call (the trial's ratio replaces the stale mean: blended into a
    mean of 3 with weight 0.1 it would have taken several ever rarer trials)."""
    import threading

    from solver.parallel import team as module

    team = Team(2)
    seen = []

    def slow(part):
        seen.append(("slow", threading.current_thread() is threading.main_thread()))

    def fast(part):
        seen.append(("fast", threading.current_thread() is threading.main_thread()))

    team.ratios[module.kind(slow)] = 3.0
    team.run(fast)
    team.run(slow)
    assert sorted(seen) == [("fast", False), ("fast", True), ("slow", True), ("slow", True)]
    assert module.kind(fast) not in team.ratios or team.ratios[module.kind(fast)] != 3.0
    clock = iter(np.arange(0.0, 1e4, 1.0))
    monkeypatch.setattr(module.time, "perf_counter", lambda: next(clock))  # a trial: own part 1 s, at once 2 s
    monkeypatch.setattr(module, "SHORT", 0.0)
    for _ in range(module.PROBE - 1):  # the calls up to the trial (it is the PROBE-th)
        team.run(slow)
    assert team.ratios[module.kind(slow)] == 1.0  # 2 s / (2 x 1 s): the trial's own ratio
    seen.clear()
    team.run(slow)  # not above 1: at once
    assert sorted(seen) == [("slow", False), ("slow", True)]
    team.close()
