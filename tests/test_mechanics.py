"""Growth mechanics against exact answers: uniform growth, clamped growth, plane strain,
obstacles, failure reports, and the discrete operators themselves (tangent = dR/du)."""
import numpy as np
import pytest
from scipy.optimize import brentq

from solver import Grid, MechanicsError, MechanicsSetup, Parameters
from solver.mechanics import GrowthMechanics, MechanicsResult, Settings
from solver.mechanics.assembly import Assembler
from solver.mechanics.mesh import StructuredMesh

PARAMS = Parameters()
KAPPA, MU = PARAMS.kappa, PARAMS.mu
EXACT = MechanicsSetup(newton_tolerance=1e-13)  # exact answers: iterate to round-off, not to the default 1e-8


def node_positions(grid: Grid) -> np.ndarray:
    """(nodes_shape + (ndim,)) node coordinates, components x, y[, z]."""
    grids = np.meshgrid(*(grid.nodes(a) for a in reversed(grid.axes)), indexing="ij")
    return np.stack(grids[::-1], axis=-1)


def solve(grid, phi, alpha, setup=MechanicsSetup(), obstacle=None, time=0.5):
    mech = GrowthMechanics(grid, PARAMS, setup, obstacle)
    return mech, mech.solve(np.broadcast_to(phi, grid.cells_shape), np.broadcast_to(alpha, grid.cells_shape), time)


# -- exact solutions --------------------------------------------------------------------------

@pytest.mark.parametrize("alpha", [1e-3, 0.05, 0.3])
def test_uniform_growth_of_a_free_block_is_u_equals_alpha_x_without_stress(alpha):
    """Fg = (1+alpha) I is compatible: F = Fg, u = alpha X about the pinned origin, sigma = 0."""
    grid = Grid((4, 3, 2), 0.5)
    _, result = solve(grid, 1.0, alpha, EXACT)
    assert isinstance(result, MechanicsResult)
    assert result.u.shape == grid.nodes_shape + (3,)
    np.testing.assert_allclose(result.u, alpha * node_positions(grid), rtol=0, atol=1e-10)
    np.testing.assert_allclose(result.p, 0.0, atol=1e-10)
    assert result.info["rigid_body_pins"] == 6


def test_uniform_growth_on_symmetry_planes_slides_freely():
    """Slide on x-, y-, z- (symmetry planes through the origin): still u = alpha X, no stress."""
    grid = Grid((3, 3, 3), 1.0)
    setup = MechanicsSetup(slide=("x-", "y-", "z-"), newton_tolerance=1e-13)
    mech, result = solve(grid, 1.0, 0.04, setup)
    np.testing.assert_allclose(result.u, 0.04 * node_positions(grid), rtol=0, atol=1e-12)
    np.testing.assert_allclose(result.p, 0.0, atol=1e-10)
    assert mech.pins == []  # the three planes already remove all six rigid modes


@pytest.mark.parametrize("alpha", [1e-3, 0.1])
@pytest.mark.parametrize("phi", [1.0, 0.5, 0.0])
@pytest.mark.parametrize("pressure", ["recovered", "element"])
def test_clamped_growth_has_the_bulk_pressure(alpha, phi, pressure):
    """All faces clamped, uniform growth: F = I, Je = (1+alpha)^-3, p = w kappa (Je - 1) exactly, where
    w = phi^2 (paper Eq. 20) with the void kept at the residual stiffness: eps + (1 - eps) phi^2."""
    grid = Grid((3, 2, 2), 1.0)
    setup = MechanicsSetup(clamp=("x-", "x+", "y-", "y+", "z-", "z+"), pressure=pressure)
    _, result = solve(grid, phi, alpha, setup)
    eps = setup.residual_stiffness
    np.testing.assert_allclose(result.u, 0.0, atol=1e-14)
    np.testing.assert_allclose(result.p, (eps + (1 - eps) * phi**2) * KAPPA * ((1 + alpha) ** -3 - 1), rtol=1e-12)


def test_plane_strain_uniform_growth_matches_the_one_dimensional_equilibrium():
    """2-D is plane strain (F_zz = 1): a free block stretches by lambda in the plane, where
    sigma_xx = kappa (lambda^2/Jg - 1) + mu Jg lambda^(-10/3) (lambda^2 - 1) / 3 = 0."""
    alpha = 0.05
    Jg = (1 + alpha) ** 3
    lam = brentq(lambda s: KAPPA * (s**2 / Jg - 1) + MU * Jg * s ** (-10 / 3) * (s**2 - 1) / 3, 1.0, 1.2)
    grid = Grid((5, 3), 0.5)
    _, result = solve(grid, 1.0, alpha, EXACT)
    assert result.u.shape == grid.nodes_shape + (2,)
    np.testing.assert_allclose(result.u, (lam - 1) * node_positions(grid), rtol=0, atol=1e-11)
    np.testing.assert_allclose(result.p, KAPPA * (lam**2 / Jg - 1), rtol=1e-9)
    assert lam - 1 > alpha  # no growth room in z: the plane takes it (and p = sigma_zz/3 < 0)
    assert np.all(result.p < 0)


def test_plane_strain_clamped_pressure():
    grid = Grid((3, 3), 1.0)
    _, result = solve(grid, 1.0, 0.02, MechanicsSetup(clamp=("x-", "x+", "y-", "y+")))
    np.testing.assert_allclose(result.p, KAPPA * (1.02**-3 - 1), rtol=1e-12)


# -- obstacles and boundary conditions ----------------------------------------------------

def test_block_growing_against_an_obstacle_column_slides_along_it():
    """Obstacle cells x in [4, 5), y in [1, 3), all z: rigid, frictionless."""
    grid = Grid((6, 4, 3), 1.0)
    obstacle = np.zeros(grid.cells_shape, bool)
    obstacle[:, 1:3, 4] = True
    phi = np.zeros(grid.cells_shape)
    phi[:, :, 1:4] = 1.0
    _, result = solve(grid, phi, 0.05 * phi, obstacle=obstacle)
    u = result.u  # (z, y, x, component)
    assert np.isnan(result.p[obstacle]).all() and np.isfinite(result.p[~obstacle]).all()
    # faces with normal x: planes x = 4 and x = 5, y in [1, 3]
    for plane in (4, 5):
        np.testing.assert_allclose(u[:, 1:4, plane, 0], 0.0, atol=1e-13)
    # faces with normal y: planes y = 1 and y = 3, x in [4, 5]
    for plane in (1, 3):
        np.testing.assert_allclose(u[:, plane, 4:6, 1], 0.0, atol=1e-13)
    tangential = np.abs(u[:, 2, 4, 1:]).max()  # middle of the x = 4 face: y and z are free
    assert tangential > 1e-4
    assert np.abs(u[:, 2, 4, 2]).max() > 1e-4  # and z moves too
    assert np.abs(u[..., 0]).max() > 1e-2  # the block does grow
    # nodes strictly inside the obstacle carry no displacement at all
    inside = np.isnan(u[..., 0])
    assert not inside.any()  # a one-cell-thick column has no interior nodes


def test_nodes_inside_a_thick_obstacle_are_nan():
    grid = Grid((5, 5), 1.0)
    obstacle = np.zeros(grid.cells_shape, bool)
    obstacle[1:4, 1:4] = True
    _, result = solve(grid, 1.0, 0.01, obstacle=obstacle)
    assert np.isnan(result.u[2, 2]).all() and np.isnan(result.u[3, 3]).all()
    assert np.isfinite(result.u[1, 1]).all()


def test_z_faces_do_not_exist_in_2d():
    with pytest.raises(ValueError, match="z-"):
        GrowthMechanics(Grid((3, 3)), PARAMS, MechanicsSetup(clamp=("z-",)))


# -- failures --------------------------------------------------------------------------------

@pytest.mark.parametrize("method, krylov_budget, binding", [("direct", 400, "Newton steps spent"),
                                                             ("multigrid", 150, "linear solver's budget is spent")])
def test_a_hard_one_shot_load_is_refused_within_the_caps(method, krylov_budget, binding):
    """A dense core growing eightfold in volume inside a clamped box of near-empty void, in one
    snapshot: no equilibrium without crushing the void.  The solve must stop with time, cause, cell
    and what it tried, after bounded work: every count within its cap (iterations, not seconds).
    The caps are set so that once the Newton steps, once the Krylov iterations run out first."""
    grid = Grid((6, 6, 6), 1.0)
    phi = np.zeros(grid.cells_shape)
    phi[2:4, 2:4, 2:4] = 1.0
    setup = MechanicsSetup(clamp=("x-", "x+", "y-", "y+", "z-", "z+"), residual_stiffness=1e-8, linear_solver=method)
    caps = Settings(coarsest=100, max_load_steps=10, max_total_newton=30, krylov_budget=krylov_budget, max_builds=6)
    mech = GrowthMechanics(grid, PARAMS, setup, settings=caps)
    with pytest.raises(MechanicsError) as failure:
        mech.solve(phi, 1.0 * phi, 0.75)
    message, tried = str(failure.value), failure.value.tried
    assert failure.value.time == 0.75 and message.startswith("t = 0.75:")
    assert "cell (z, y, x) = (" in message and "µm" in message
    assert "tried" in message and "Krylov iterations" in message and "load steps" in message
    assert binding in message
    assert 1 <= tried["load_steps"] <= caps.max_load_steps
    assert tried["newton"] <= caps.max_total_newton
    assert tried["krylov"] <= caps.krylov_budget
    assert tried["builds"] <= caps.max_builds


def test_inverted_element_is_reported_by_the_check():
    mech = GrowthMechanics(Grid((2, 2, 2), 1.0), PARAMS, MechanicsSetup(), None)
    evaluation = mech.assembler.evaluate(np.zeros(mech.mesh.n_dofs), np.ones(8), np.ones(8), MU, KAPPA)
    evaluation.min_det[5] = -0.1
    with pytest.raises(MechanicsError, match=r"t = 2: det F = -0.1 <= 0.*cell \(z, y, x\) = \(1, 0, 1\)"):
        mech._check_inversion(2.0, evaluation)


def test_nan_input_is_reported():
    mech = GrowthMechanics(Grid((2, 2)), PARAMS, MechanicsSetup(), None)
    alpha = np.zeros((2, 2))
    alpha[1, 0] = np.nan
    with pytest.raises(MechanicsError, match=r"alpha is not finite at cell \(y, x\) = \(1, 0\)"):
        mech.solve(np.ones((2, 2)), alpha, 0.1)


# -- the discrete operators ------------------------------------------------------------------

@pytest.mark.parametrize("shape", [(2, 2, 2), (3, 2)])
def test_tangent_is_the_derivative_of_the_residual_and_residual_of_the_energy(shape):
    mesh = StructuredMesh(Grid(shape, 0.7))
    assembler = Assembler(mesh, np.zeros(mesh.n_dofs, bool))
    rng = np.random.default_rng(0)
    u = 0.05 * rng.standard_normal(mesh.n_dofs)
    w, Jg = rng.uniform(0.1, 1, mesh.n_elements), (1 + rng.uniform(0, 0.1, mesh.n_elements)) ** 3
    ev = assembler.evaluate(u, w, Jg, MU, KAPPA)
    K, h = ev.matrix.toarray(), 1e-6
    np.testing.assert_allclose(K, K.T, atol=1e-12 * np.abs(K).max())
    for j in range(mesh.n_dofs):
        e = np.zeros(mesh.n_dofs)
        e[j] = h
        plus = assembler.evaluate(u + e, w, Jg, MU, KAPPA, False)
        minus = assembler.evaluate(u - e, w, Jg, MU, KAPPA, False)
        np.testing.assert_allclose((plus.residual - minus.residual) / (2 * h), K[:, j], atol=1e-6 * np.abs(K).max())
        slope = (plus.energy - minus.energy) / (2 * h)
        assert slope == pytest.approx(ev.residual[j], abs=1e-6 * np.abs(ev.residual).max())


def test_the_memory_estimate_knows_every_preconditioner_and_the_solvers_auto_limit():
    """The estimate asks the solver what "auto" means (one rule), and has a per-node figure for every choice a
    scene can make."""
    from biostudy.inputs import resources
    from solver.mechanics import linear_solver_for
    from solver.problem import LINEAR_SOLVERS

    limit = Settings().direct_limit
    assert [linear_solver_for("auto", n) for n in (limit, limit + 1)] == ["direct", "multigrid"]
    assert {(m, d) for m in LINEAR_SOLVERS if m != "auto" for d in (2, 3)} == set(resources.MECHANICS_PER_NODE)
