"""The project's mechanics assembler against scikit-fem's forms (tests/mechanics_oracle.py), entry by entry.

Same mesh, same random displacement, non-uniform phi (void cells included) and alpha, in 2-D (plane
strain) and 3-D, with and without obstacles and held faces: residual, tangent, element pressure and
energy agree within `roundings(shape)` unit round-offs of each entry's own scale (the sum of its terms' absolute
values), the bound of floating point for two ways of adding the same terms.  The oracle itself is
checked against central differences of its own residual and energy.
"""
import numpy as np
import pytest
from mechanics_oracle import MechanicsOracle, roundings, roundoff_ratio

from solver import Grid, MechanicsSetup, Parameters
from solver.mechanics import material
from solver.mechanics.assembly import Assembler
from solver.mechanics.constraints import boundary_held
from solver.mechanics.mesh import StructuredMesh

PARAMS = Parameters()
MU, KAPPA = PARAMS.mu, PARAMS.kappa
EPS = MechanicsSetup().residual_stiffness

# shape (x, y[, z]), obstacle cells ([z,] y, x), clamp, slide
CASES = {
    "3-D free": ((3, 2, 2), [], (), ()),
    "2-D free": ((4, 3), [], (), ()),
    "3-D obstacle, clamped z-, sliding x+": ((4, 3, 2), [(0, 1, 1)], ("z-",), ("x+",)),
    "2-D obstacles, clamped y-, sliding x-": ((5, 4), [(1, 2), (3, 0)], ("y-",), ("x-",)),
}


def scene(shape, obstacle_cells, seed=0):
    """Grid, obstacle mask, phi (a third of the cells void) and alpha per cell, both assemblers' meshes."""
    grid = Grid(shape, 0.7)
    obstacle = np.zeros(grid.cells_shape, bool)
    for cell in obstacle_cells:
        obstacle[cell] = True
    rng = np.random.default_rng(seed)
    phi = np.where(rng.uniform(size=grid.cells_shape) < 1 / 3, 0.0, rng.uniform(0, 1, grid.cells_shape))
    alpha = rng.uniform(0, 0.2, grid.cells_shape)
    return grid, obstacle, phi, alpha, StructuredMesh(grid, obstacle), MechanicsOracle(shape, grid.spacing, obstacle)


def project_evaluation(mesh, held, u, phi, alpha):
    """The project's evaluation, with w and Jg per element as `GrowthMechanics` makes them."""
    w = material.weight(phi.ravel()[mesh.cells], EPS)
    return Assembler(mesh, held).evaluate(u, w, (1 + alpha.ravel()[mesh.cells]) ** 3, MU, KAPPA)


def per_cell(values, cells, n_cells):
    out = np.full(n_cells, np.nan)
    out[cells] = values
    return out


def comparison(name, seed=0, perturb=None):
    """Worst round-off ratio of residual, tangent, pressure and energy (project vs oracle, oracle's scale)."""
    shape, obstacle_cells, clamp, slide = CASES[name]
    grid, obstacle, phi, alpha, mesh, oracle = scene(shape, obstacle_cells, seed)
    order = oracle.dofs_at(mesh.node_coordinates()).ravel()  # project dof -> oracle dof
    held = boundary_held(mesh, clamp, slide)
    u = 0.05 * grid.spacing * np.random.default_rng(seed + 1).standard_normal(mesh.n_dofs)
    ours = project_evaluation(mesh, held, u, phi, perturb(alpha) if perturb else alpha)
    u_o, held_o = np.zeros(oracle.u_basis.N), np.zeros(oracle.u_basis.N, bool)
    u_o[order], held_o[order] = u, held
    theirs = oracle.evaluate(u_o, phi, alpha, MU, KAPPA, EPS, held_o)
    scale = oracle.magnitudes(u_o, phi, alpha, MU, KAPPA, EPS, held_o)
    both = np.ix_(order, order)
    open_cells = mesh.cells
    return {
        "residual": roundoff_ratio(ours.residual, theirs.residual[order], scale.residual[order]),
        "tangent": roundoff_ratio(ours.matrix.toarray(), theirs.tangent.toarray()[both], scale.tangent.toarray()[both]),
        "pressure": roundoff_ratio(per_cell(ours.pressure, mesh.cells, grid.n_cells)[open_cells],
                                   per_cell(theirs.pressure, oracle.cells, grid.n_cells)[open_cells],
                                   per_cell(scale.pressure, oracle.cells, grid.n_cells)[open_cells]),
        "energy": roundoff_ratio(ours.energy, theirs.energy, scale.energy),
    }


@pytest.mark.parametrize("name", CASES)
def test_residual_tangent_pressure_and_energy_agree_with_scikit_fem_to_round_off(name):
    ratios = comparison(name)
    assert max(ratios.values()) <= roundings(CASES[name][0]), ratios


def test_a_change_of_one_part_in_a_billion_in_one_cell_is_seen():
    """The bound is not vacuous: alpha changed by 1e-9 (relative) in one cell on the project's side only."""
    def perturb(alpha):
        changed = alpha.copy()
        changed.flat[3] *= 1 + 1e-9
        return changed

    ratios = comparison("3-D free", perturb=perturb)
    bound = roundings(CASES["3-D free"][0])
    assert ratios["residual"] > 10 * bound and ratios["pressure"] > 10 * bound, ratios


@pytest.mark.parametrize("name", CASES)
def test_held_dofs_are_the_faces_and_obstacle_faces_scikit_fem_finds(name):
    shape, obstacle_cells, clamp, slide = CASES[name]
    _, _, _, _, mesh, oracle = scene(shape, obstacle_cells)
    order = oracle.dofs_at(mesh.node_coordinates()).ravel()
    np.testing.assert_array_equal(boundary_held(mesh, clamp, slide), oracle.held(clamp, slide)[order])


@pytest.mark.parametrize("name", ["3-D free", "2-D free"])
def test_the_oracle_tangent_and_residual_are_derivatives_of_its_residual_and_energy(name):
    """Central differences along random directions: an error O(t^2) + O(u / t), both below 1e-7 here."""
    shape, obstacle_cells, _, _ = CASES[name]
    grid, _, phi, alpha, _, oracle = scene(shape, obstacle_cells)
    rng = np.random.default_rng(2)
    u = 0.05 * grid.spacing * rng.standard_normal(oracle.u_basis.N)
    at = oracle.evaluate(u, phi, alpha, MU, KAPPA, EPS)
    t = 1e-6 * grid.spacing
    for _ in range(3):
        v = rng.standard_normal(u.size)
        plus = oracle.evaluate(u + t * v, phi, alpha, MU, KAPPA, EPS, tangent=False)
        minus = oracle.evaluate(u - t * v, phi, alpha, MU, KAPPA, EPS, tangent=False)
        Kv = at.tangent @ v
        np.testing.assert_allclose((plus.residual - minus.residual) / (2 * t), Kv, atol=1e-7 * np.abs(Kv).max())
        assert (plus.energy - minus.energy) / (2 * t) == pytest.approx(at.residual @ v, rel=1e-7)
    np.testing.assert_allclose(at.tangent.toarray(), at.tangent.toarray().T, atol=1e-14 * abs(at.tangent).max())
