"""Biofilm step (paper Eq. 34) and expansion (Eq. 36) against independent answers."""
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.integrate import solve_ivp

from solver import Grid, Numerics, Parameters, Problem, evolve, simulate, timeloop
from solver.errors import StepFailure
from solver.timeloop import Clock
from solver.transport import Transport
from solver.transport.finite_volume import fipy_mesh


def problem_on(grid, phi0, held=None, value=None, obstacle=None, t_end=1.0, steps=100, outputs=None, **kw):
    held = np.zeros(grid.cells_shape, bool) if held is None else held
    outputs = np.linspace(0, t_end, 2) if outputs is None else outputs
    return Problem(grid=grid, phi0=phi0, nutrient_held=held, nutrient_value=value, obstacle=obstacle,
                   t_end=t_end, steps=steps, output_times=outputs, **kw)


def advection_matrix(transport, w, phi):
    b = transport.biofilm
    return sp.csr_matrix((b.advection(w, phi), b.matrix.indices, b.matrix.indptr),
                         shape=(transport.fv.n,) * 2)


def fipy_advection(grid, transport, w, phi):
    """FiPy's UpwindConvectionTerm(v) - ImplicitSourceTerm(div v) applied to phi (per unit volume)."""
    import fipy
    from fipy.solvers import DummySolver

    mesh = fipy_mesh(grid)
    ids = np.ma.filled(mesh.faceCellIDs, -1)
    lookup = {(int(a), int(b)): k for k, (a, b) in enumerate(zip(*ids)) if b >= 0}
    values = np.zeros((grid.ndim, mesh.numberOfFaces))
    for faces, wf in zip(transport.fv.faces, w):
        cells = transport.fv.cells
        for a, b, v in zip(cells[faces.lower], cells[faces.upper], wf):
            values[faces.axis, lookup.get((a, b), lookup.get((b, a)))] = v
    var = fipy.CellVariable(mesh=mesh, value=phi)
    term = fipy.UpwindConvectionTerm(coeff=fipy.FaceVariable(mesh=mesh, rank=1, value=values)) \
        - fipy.ImplicitSourceTerm(coeff=fipy.FaceVariable(mesh=mesh, rank=1, value=values).divergence)
    term.cacheMatrix()
    term.cacheRHSvector()
    term.solve(var=var, solver=DummySolver())
    return (sp.csr_matrix(term.matrix.matrix) @ phi - np.asarray(term.RHSvector)) / grid.cell_volume


@pytest.mark.parametrize("shape", [(5, 4, 3), (7, 6)])
def test_upwind_operator_equals_fipy_terms(shape):
    """Our in-place upwind matrix is FiPy's UpwindConvectionTerm - ImplicitSourceTerm(div v), to round-off."""
    grid = Grid(shape, 0.7)
    transport = Transport(problem_on(grid, np.zeros(grid.cells_shape)))
    rng = np.random.default_rng(1)
    w = [rng.normal(scale=10, size=f.lower.size) for f in transport.fv.faces]
    phi = rng.random(transport.fv.n)
    ours = advection_matrix(transport, w, phi) @ phi
    assert np.abs(ours - fipy_advection(grid, transport, w, phi)).max() < 1e-12 * np.abs(ours).max()


@pytest.mark.parametrize("advection", ["upwind", "tvd"])
def test_advection_matrix_is_an_m_matrix_with_zero_row_sums(advection):
    """Positive-coefficient form: off-diagonals <= 0, rows sum to 0, for any velocity and phi."""
    grid = Grid((6, 5, 4), 1.0)
    transport = Transport(problem_on(grid, np.zeros(grid.cells_shape), numerics=Numerics(advection=advection)))
    rng = np.random.default_rng(2)
    w = [rng.normal(scale=50, size=f.lower.size) for f in transport.fv.faces]
    a = advection_matrix(transport, w, rng.random(transport.fv.n)).tocoo()
    off = a.row != a.col
    assert a.data[off].max() <= 0.0
    assert np.abs(np.asarray(a.sum(axis=1))).max() < 1e-12 * np.abs(a.data).max()


def van_leer_face(up_up, up, down):
    """Textbook MUSCL face value with the van Leer limiter."""
    if down == up:
        return up
    r = (up - up_up) / (down - up)
    psi = (r + abs(r)) / (1 + abs(r))
    return up + 0.5 * psi * (down - up)


def test_tvd_operator_is_van_leer_muscl_in_one_dimension():
    """Interior cells: v.grad(phi) = w (phi_{i+1/2} - phi_{i-1/2}) / h with van Leer face values."""
    n, h, w = 12, 0.5, 3.0
    grid = Grid((n, 1), h)
    transport = Transport(problem_on(grid, np.zeros(grid.cells_shape), numerics=Numerics(advection="tvd")))
    rng = np.random.default_rng(3)
    phi = np.cumsum(rng.random(n)) ** 1.5
    phi[7] -= 2.0  # a local extremum so the limiter acts
    ours = advection_matrix(transport, [np.full(n - 1, w), np.zeros(0)], phi) @ phi
    for i in range(2, n - 1):
        east = van_leer_face(phi[i - 1], phi[i], phi[i + 1])
        west = van_leer_face(phi[i - 2], phi[i - 1], phi[i])
        assert ours[i] == pytest.approx(w * (east - west) / h, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("advection, order", [("upwind", 1.0), ("tvd", 2.0)])
def test_advection_operator_consistency_order(advection, order):
    """|v.grad(phi) - w phi'| on a smooth profile falls as h^order (interior cells)."""
    errors, sizes = [], []
    for n in (20, 40, 80, 160):
        h = 10.0 / n
        grid = Grid((n, 1), h)
        transport = Transport(problem_on(grid, np.zeros(grid.cells_shape), numerics=Numerics(advection=advection)))
        x = grid.centres("x")
        phi = 0.5 * (1 - np.tanh(x - 5.0))
        ours = advection_matrix(transport, [np.full(n - 1, 2.0), np.zeros(0)], phi) @ phi
        exact = 2.0 * -0.5 / np.cosh(x - 5.0) ** 2
        inner = (x > 2) & (x < 8)
        errors.append(np.abs(ours - exact)[inner].max())
        sizes.append(h)
    observed = np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert observed > order - 0.25, (observed, errors)


def front_position(x, phi):
    """Where phi falls through 0.5, interpolated between cell centres."""
    i = np.flatnonzero((phi[:-1] >= 0.5) & (phi[1:] < 0.5))[-1]
    return x[i] + (phi[i] - 0.5) / (phi[i] - phi[i + 1]) * (x[i + 1] - x[i])


@pytest.mark.parametrize("advection", ["upwind", "tvd"])
@pytest.mark.parametrize("beta", [0.0, 2.0])
def test_flat_front_travels_at_monod_speed(advection, beta):
    """In a linear nutrient field the front obeys dX/dt = r c(X)/(k + c(X)) (within one cell)."""
    n, h, r, k = 60, 1.0, 100.0, 1.0
    grid = Grid((n, 1), h)
    x = grid.centres("x")
    held = np.zeros(grid.cells_shape, bool)
    held[0, 0] = held[0, -1] = True
    value = np.zeros(grid.cells_shape)
    value[0, -1] = 1.0
    phi0 = (x < 10.0).astype(float)[None, :]
    times = np.linspace(0, 1.0, 6)
    problem = problem_on(grid, phi0, held, value, t_end=1.0, steps=500, outputs=times,
                         params=Parameters(g=0.0, r=r, k=k, beta=beta, k_alpha=0.0),
                         numerics=Numerics(advection=advection))
    c = lambda X: (X - x[0]) / (x[-1] - x[0])
    exact = solve_ivp(lambda t, X: r * c(X) / (k + c(X)), (0, 1.0), [10.0], t_eval=times, rtol=1e-10, atol=1e-10).y[0]
    for snapshot, X in zip(evolve(problem), exact):
        assert abs(front_position(x, snapshot.phi[0]) - X) < h, (snapshot.time, X)
    assert exact[-1] - exact[0] > 15 * h, "the front must cross many cells"


def test_dense_biofilm_expands_at_k_alpha():
    """phi = 1 everywhere: alpha = k_alpha t (paper Table 2 value), phi stays 1 + O(k_alpha^2)."""
    grid = Grid((6, 6, 6), 1.0)
    held = np.zeros(grid.cells_shape, bool)
    held[0, 0, 0] = True
    ds = simulate(problem_on(grid, np.ones(grid.cells_shape), held, t_end=1.0, steps=50,
                             outputs=np.linspace(0, 1, 5)))
    expected = 1e-3 * ds.time.values
    assert np.allclose(ds.alpha.values, expected[:, None, None, None], rtol=1e-5, atol=0)
    assert np.allclose(ds.phi.values, 1.0, atol=1e-6)


def test_expansion_pair_converges_to_cosh_sinh_at_first_order():
    """With k_alpha = 1 the dense pair (phi, alpha) is phi = cosh t, alpha = sinh t; error ~ dt."""
    grid = Grid((3, 3), 1.0)
    errors = []
    for steps in (20, 40, 80):
        ds = simulate(problem_on(grid, np.ones(grid.cells_shape), t_end=1.0, steps=steps,
                                 params=Parameters(k_alpha=1.0)))
        errors.append(max(abs(float(ds.alpha[-1, 0, 0]) - np.sinh(1.0)), abs(float(ds.phi[-1, 0, 0]) - np.cosh(1.0))))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 1.8) & (ratios < 2.2)), errors


def test_diffusion_alone_conserves_biofilm_mass_with_obstacles():
    """r = 0, k_alpha = 0: the phi equation is pure diffusion with zero flux: sum(phi) is conserved."""
    grid = Grid((10, 8, 6), 1.0)
    obstacle = np.zeros(grid.cells_shape, bool)
    obstacle[:, 3:5, 4:6] = True
    rng = np.random.default_rng(4)
    phi0 = np.where(obstacle, 0.0, rng.random(grid.cells_shape))
    ds = simulate(problem_on(grid, phi0, obstacle=obstacle, t_end=1.0, steps=20,
                             params=Parameters(r=0.0, k_alpha=0.0, beta=5.0)))
    mass = ds.phi.sum(dim=("z", "y", "x")).values
    assert np.allclose(mass, mass[0], rtol=1e-11)
    assert float(ds.phi[-1].std()) < 0.5 * float(ds.phi[0].std())
    assert np.isnan(ds.phi.values[:, obstacle]).all() and np.isnan(ds.c.values[:, obstacle]).all()


class MoreThanOneStep(AssertionError):
    """The giant step was bisected (the bounds may still hold)."""


# Measured: at dt = 1 the biofilm's Jacobi-preconditioned BiCGSTAB (r = 1e4: advection outweighs 1/dt) does
# not converge, so the clock bisects the step (3 times).  (The nutrient's CG at d = 1, g = 1e10 did too,
# bisected once, while it started from the previous step's c, whose residual there is 1e10 |b|; it now
# starts from 0 when a guess is worse than none, and converges: issue 20.)
# The bounds hold all the same; strict, so that a solver that manages the step makes the test say so.
LINEAR_SOLVER_GIVES_UP = pytest.mark.xfail(raises=MoreThanOneStep, strict=True,
                                           reason="a linear solver does not converge at dt = 1: bisected")


@pytest.mark.parametrize("advection", ["upwind", "tvd"])
@pytest.mark.parametrize("params", [dict(d=1e13, g=1e10),
                                    dict(d=1.0, g=1e10),
                                    pytest.param(dict(d=1e10, g=1e8, r=1e4), marks=LINEAR_SOLVER_GIVES_UP),
                                    dict(d=1e10, g=0.0, r=1e4, beta=0.0)])
def test_bounds_hold_on_stiff_cases_with_one_giant_step(advection, params, monkeypatch):
    """Stiff consumption, fast fronts, no diffusion, a single step over [0, 1]: 0 <= c <= 1, 0 <= phi <= 1.

    The written fields are projected onto their bounds, so they alone prove little: every step attempted
    (the giant one, and any bisection of it) must have kept its raw solutions within the bounds up to
    round-off (what the run projected; a bound broken beyond it would have failed the step), and the
    step must have been taken in one go: the clock's limit on a step (its front crossing at most one cell,
    docs/model.md) is lifted here, since what is tested is that the step itself stays bounded at any dt."""
    monkeypatch.setattr(timeloop, "LIMIT", np.inf)
    failures = []
    attempt = Clock._attempt

    def recording(clock, state, dt):
        try:
            return attempt(clock, state, dt)
        except StepFailure as failure:
            failures.append(failure.cause)
            raise

    monkeypatch.setattr(Clock, "_attempt", recording)
    grid = Grid((10, 10, 10), 2.0)
    x, y, z = grid.cell_coordinates()
    phi0 = ((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2 <= 25).astype(float)
    held = (x > 16) & (y > 16) & (z > 16)
    ds = simulate(problem_on(grid, phi0, held, t_end=1.0, steps=1, params=Parameters(k_alpha=0.0, **params),
                             numerics=Numerics(advection=advection)))
    assert not [cause for cause in failures if "outside" in cause], failures  # no bound broken, at any dt
    assert ds.attrs["projected_phi_largest"] < 1e-10 and ds.attrs["projected_c_largest"] < 1e-10
    for name in ("phi", "c"):
        values = ds[name].values
        assert np.isfinite(values).all() and values.min() >= 0.0 and values.max() <= 1.0, name
    assert ds.attrs["steps_bisected"] == len(failures)
    if ds.attrs["steps_taken"] != 1 or failures:
        raise MoreThanOneStep(f"{ds.attrs['steps_taken']} steps: {failures}")


def test_directional_growth_moves_toward_the_nutrient_corner():
    """Paper 4.1 shortened (20^3, T* = 0.3, 60 steps): the side facing the source corner advances
    about twice as far as the back, and the biofilm's centroid moves toward the corner.

    Early on (T* < 0.1) growth is nearly isotropic: the sphere is the sink, so grad c points
    outward all round it and the Monod speed hardly differs between front and back."""
    grid = Grid((20, 20, 20), 1.0)
    x, y, z = grid.cell_coordinates()
    phi0 = ((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2 <= 25).astype(float)
    held = (x > 17) & (y > 17) & (z > 17)
    ds = simulate(problem_on(grid, phi0, held, t_end=0.3, steps=60, outputs=[0.0, 0.3]))
    diagonal = (x + y + z - 30) / np.sqrt(3)  # µm from the centre toward the source corner
    start, end = (ds.phi.values[i] for i in (0, -1))
    dense_start, dense_end = start >= 0.5, end >= 0.5
    toward = diagonal[dense_end].max() - diagonal[dense_start].max()
    back = diagonal[dense_start].min() - diagonal[dense_end].min()
    assert toward > 1.5 * back > 0, (toward, back)
    shift = (end * diagonal).sum() / end.sum() - (start * diagonal).sum() / start.sum()
    assert shift > 0.25, shift
    assert float(ds.biofilm_volume[-1]) > 2 * float(ds.biofilm_volume[0])


def characteristic_solution(x, t, phi_initial, r, k, c_slope, c_offset):
    """beta = k_alpha = 0: phi is constant along dX/dt = r c/(k+c) with c = c_offset + c_slope X.
    Travel time from X0 to X: (X - X0 + k/c_slope ln(c(X)/c(X0))) / r; solved for X0 by bisection."""
    from scipy.optimize import brentq

    def travel(start, end):
        with np.errstate(divide="ignore"):  # end where c = 0 (the held cell): log 0 = -inf, nothing moves
            return (end - start + k / c_slope * np.log((c_offset + c_slope * end) / (c_offset + c_slope * start))) / r

    exact = np.empty_like(x)
    lowest = -c_offset / c_slope + 1e-12
    for i, xi in enumerate(x):
        if travel(lowest, xi) <= t:
            exact[i] = phi_initial(lowest)
        else:
            exact[i] = phi_initial(brentq(lambda start, xi=xi: travel(start, xi) - t, lowest, xi))
    return exact


@pytest.mark.parametrize("advection, least_order", [("upwind", 0.8), ("tvd", 1.5)])
def test_smooth_front_converges_to_the_characteristic_solution(advection, least_order):
    """A tanh front (width 2 µm) in a linear nutrient field, beta = 0: exact solution by characteristics.
    Small steps (Courant 0.05) so that the spatial error shows: upwind ~ h, TVD ~ h^2 where smooth.
    The pointwise growth velocity: the front velocity gives every cell near the front one speed, which
    keeps the profile's shape (test_front.py)."""
    length, r, k, t_end = 40.0, 100.0, 1.0, 0.15
    initial = lambda X: 0.5 * (1 - np.tanh((X - 10.0) / 2.0))
    sizes, errors = [], []
    for n in (40, 80, 160):
        h = length / n
        grid = Grid((n, 1), h)
        x = grid.centres("x")
        held = np.zeros(grid.cells_shape, bool)
        held[0, [0, -1]] = True
        value = np.zeros(grid.cells_shape)
        value[0, -1] = 1.0
        steps = int(np.ceil(t_end / (0.05 * h / 50.0)))
        ds = simulate(problem_on(grid, initial(x)[None, :], held, value, t_end=t_end, steps=steps,
                                 params=Parameters(g=0.0, r=r, k=k, beta=0.0, k_alpha=0.0),
                                 numerics=Numerics(advection=advection, growth_velocity="pointwise")))
        slope = 1.0 / (x[-1] - x[0])
        exact = characteristic_solution(x, t_end, initial, r, k, slope, -x[0] * slope)
        inner = (x > 2) & (x < length - 2)
        errors.append(np.abs(ds.phi.values[-1, 0] - exact)[inner].mean())
        sizes.append(h)
    order = np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert order > least_order, (order, errors)
