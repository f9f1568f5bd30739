"""The tangent's storage and the multigrid's grid transfers against independent constructions.

* The stencil product (a compiled pass over half the blocks) is the derivative of the residual: K v against
  central differences of the assembly's residual along v, with obstacles and held dofs.
* Interpolation, restriction and the Galerkin operator, applied node by node without matrices, against the
  sparse matrices built the textbook way: Kronecker products of 1-D linear interpolations, rows of nodes
  without dofs dropped, rows of held dofs zeroed, and P^T A P by scipy.
* Assembling in boxes of a few rows (planes larger than `chunk`) gives what whole planes give.
"""
import numpy as np
import pytest
import scipy.sparse as sp

from solver import Grid, MechanicsSetup, Parameters
from solver.mechanics import material
from solver.mechanics.assembly import Assembler
from solver.mechanics.constraints import boundary_held
from solver.mechanics.mesh import StructuredMesh
from solver.mechanics.multigrid import Multigrid
from solver.mechanics.stencil import Stencil

PARAMS = Parameters()
EPS = MechanicsSetup().residual_stiffness
# shape (x, y[, z]), obstacle cells ([z,] y, x), clamped faces: odd and even counts, nodes without dofs
CASES = {
    "3-D": ((5, 4, 3), [(1, 1, 2), (1, 2, 2)], ("z-",)),
    "2-D": ((7, 4), [(2, 3)], ("x+",)),
    "3-D thick obstacle": ((4, 4, 4), [(z, y, x) for z in (0, 1) for y in (0, 1) for x in (0, 1)], ()),
}


def setting(name, seed=0):
    shape, obstacle_cells, clamp = CASES[name]
    grid = Grid(shape, 0.7)
    obstacle = np.zeros(grid.cells_shape, bool)
    for cell in obstacle_cells:
        obstacle[cell] = True
    mesh = StructuredMesh(grid, obstacle)
    rng = np.random.default_rng(seed)
    w = material.weight(rng.uniform(0, 1, mesh.n_elements), EPS)
    growth = (1 + rng.uniform(0, 0.1, mesh.n_elements)) ** 3
    u = 0.03 * rng.standard_normal(mesh.n_dofs)
    return mesh, boundary_held(mesh, clamp), w, growth, u, rng


@pytest.mark.parametrize("name", CASES)
def test_the_stencil_product_is_the_derivative_of_the_residual(name):
    mesh, held, w, growth, u, rng = setting(name)
    assembler = Assembler(mesh, held)
    K = assembler.evaluate(u, w, growth, PARAMS.mu, PARAMS.kappa).matrix
    v, t = rng.standard_normal(mesh.n_dofs), 1e-6
    v[held] = 0.0
    plus, minus = (assembler.evaluate(u + s * t * v, w, growth, PARAMS.mu, PARAMS.kappa, False).residual
                   for s in (1, -1))
    derivative = (plus - minus) / (2 * t)
    np.testing.assert_allclose(K @ v, derivative, atol=1e-6 * np.abs(derivative).max())
    assert np.abs(K @ v).max() > 0.1 * np.abs(derivative).max()
    both = K @ np.column_stack([v, 2 * v])
    np.testing.assert_allclose(both, np.column_stack([K @ v, 2 * (K @ v)]), rtol=1e-14)


def interpolation_1d(cells: int) -> sp.csr_matrix:
    """Fine node i from ceil(cells/2) coarse cells: on coarse node i/2, or halfway between its neighbours."""
    rows, cols, vals = [], [], []
    for i in range(cells + 1):
        for j, value in ([(i // 2, 1.0)] if i % 2 == 0 else [(i // 2, 0.5), (i // 2 + 1, 0.5)]):
            rows.append(i), cols.append(j), vals.append(value)
    return sp.csr_matrix((vals, (rows, cols)), shape=(cells + 1, (cells + 1) // 2 + 1))


def textbook_interpolation(mesh, held) -> tuple[sp.csr_matrix, np.ndarray]:
    """P (fine dofs x coarse dofs) and the coarse nodes used, as Kronecker products of 1-D interpolations."""
    d = mesh.ndim
    P = interpolation_1d(mesh.grid.cells_shape[0])
    for n in mesh.grid.cells_shape[1:]:
        P = sp.kron(P, interpolation_1d(n), format="csr")
    P = P[mesh.nodes]
    used = np.flatnonzero(np.diff(P.tocsc().indptr))
    P = sp.kron(P[:, used], sp.identity(d), format="csr")
    return sp.diags((~held).astype(float)) @ P, used


@pytest.mark.parametrize("name", CASES)
def test_transfers_and_the_galerkin_operator_are_the_textbook_matrices(name):
    mesh, held, w, growth, u, rng = setting(name)
    K = Assembler(mesh, held).evaluate(u, w, growth, PARAMS.mu, PARAMS.kappa).matrix
    cycle = Multigrid(mesh, held, coarsest=1, degree=3)
    P, used = textbook_interpolation(mesh, held)
    coarse = cycle.levels[1]
    np.testing.assert_array_equal(coarse.nodes, used)
    xc, x = rng.standard_normal(P.shape[1]), rng.standard_normal(P.shape[0])
    np.testing.assert_allclose(cycle.prolong(0, xc), P @ xc, rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(cycle.restrict(0, x), P.T @ x, rtol=1e-14, atol=1e-14)
    cycle.build(K)
    expected = (P.T @ K.tocsr() @ P).toarray()
    unsupported = np.flatnonzero(np.diag(expected) == 0)  # coarse dofs whose support is all held
    expected[unsupported, unsupported] = 1.0
    assert np.abs(expected).max() > 0
    found = coarse.A.toarray() if len(cycle.levels) > 2 else None
    if found is None:  # two levels: the coarsest operator is factorised; its product is the test
        probe = rng.standard_normal(P.shape[1])
        np.testing.assert_allclose(cycle.coarse_solve(expected @ probe), probe, rtol=1e-8)
    else:
        np.testing.assert_allclose(found, expected, atol=1e-13 * np.abs(expected).max())


def test_a_galerkin_operator_that_a_held_dof_would_change_does_change():
    """The held rows matter: the same tangent without them held gives another coarse operator (the comparison
    above is not vacuous)."""
    mesh, held, w, growth, u, _ = setting("3-D")
    K = Assembler(mesh, held).evaluate(u, w, growth, PARAMS.mu, PARAMS.kappa).matrix
    cycles = [Multigrid(mesh, h, coarsest=1, degree=3) for h in (held, np.zeros_like(held))]
    for cycle in cycles:
        cycle.build(K)
    assert not np.allclose(cycles[0].levels[1].A.toarray(), cycles[1].levels[1].A.toarray())


@pytest.mark.parametrize("name", CASES)
def test_assembling_rows_of_a_plane_at_a_time_gives_what_whole_planes_give(name):
    mesh, held, w, growth, u, _ = setting(name)
    small = Assembler(mesh, held, chunk=3)
    assert any(box.shape[0] == 1 and box.shape[1] < mesh.grid.cells_shape[1] for box in small.boxes) or mesh.ndim < 3
    whole, parts = (a.evaluate(u, w, growth, PARAMS.mu, PARAMS.kappa) for a in (Assembler(mesh, held), small))
    np.testing.assert_allclose(parts.residual, whole.residual, atol=1e-13 * np.abs(whole.residual).max())
    dense = whole.matrix.toarray()
    np.testing.assert_allclose(parts.matrix.toarray(), dense, atol=1e-13 * np.abs(dense).max())
    np.testing.assert_allclose(parts.pressure, whole.pressure, rtol=1e-14, atol=1e-14 * np.abs(whole.pressure).max())
    assert parts.energy == pytest.approx(whole.energy, rel=1e-14)


def test_the_stencil_as_a_matrix_is_symmetric_and_keeps_the_linked_pattern():
    mesh, held, w, growth, u, _ = setting("3-D thick obstacle")
    K = Assembler(mesh, held).evaluate(u, w, growth, PARAMS.mu, PARAMS.kappa).matrix
    assert isinstance(K, Stencil)
    B = K.tobsr()
    dense = B.toarray()
    np.testing.assert_allclose(dense, dense.T, atol=1e-14 * np.abs(dense).max())  # diagonal blocks to round-off
    np.testing.assert_array_equal(dense != 0, dense.T != 0)
    # node pairs an open cell links: the nodes of one cell, which the textbook pattern of Q1 couples
    links = sp.csr_matrix((np.ones(mesh.connectivity.size * 8),
                           (np.repeat(mesh.connectivity, 8, axis=1).ravel(), np.tile(mesh.connectivity, 8).ravel())),
                          shape=(mesh.n_nodes,) * 2)
    assert B.nnz == links.nnz * mesh.ndim**2
