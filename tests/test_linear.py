"""The transport's linear-algebra parts (solver/transport/linear.py, krylov.py) against plain scipy answers."""
import copy

import numpy as np
import pyamg
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from solver.transport.krylov import jacobi_bicgstab, pcg
from solver.transport.linear import KeptDiagonal, ReusedAMG, VCycle


def laplacian_3d(n: int) -> sp.csr_matrix:
    """-lap on n^3 cells with zero flux (the nutrient's K without its held cells)."""
    one = sp.diags([-np.ones(n - 1), np.r_[1.0, 2.0 * np.ones(n - 2), 1.0], -np.ones(n - 1)], [-1, 0, 1])
    eye = sp.identity(n)
    return sp.csr_matrix(sp.kron(sp.kron(one, eye), eye) + sp.kron(sp.kron(eye, one), eye)
                         + sp.kron(sp.kron(eye, eye), one))


def nutrient_like(n: int, seed: int = 0):
    """K + 2 e_0 e_0^T (a held corner) and a demand gamma phi: the shape of the nutrient's matrix."""
    rng = np.random.default_rng(seed)
    base = laplacian_3d(n) + sp.csr_matrix(([2.0], ([0], [0])), shape=(n**3,) * 2)
    return sp.csr_matrix(base), 0.05 * rng.random(n**3)


def test_kept_diagonal_equals_a_fresh_sum_every_time():
    """The kept matrix with its diagonal rewritten is bit for bit K + diag(d), also after other d's."""
    base, _ = nutrient_like(5)
    kept = KeptDiagonal(base)
    rng = np.random.default_rng(3)
    for demand in (rng.random(base.shape[0]), np.zeros(base.shape[0]), 1e3 * rng.random(base.shape[0])):
        fresh = sp.csr_matrix(base + sp.diags(demand))
        fresh.sort_indices()
        matrix = kept(demand)
        assert np.array_equal(matrix.indptr, fresh.indptr) and np.array_equal(matrix.indices, fresh.indices)
        assert np.array_equal(matrix.data, fresh.data)


def test_kept_diagonal_refuses_a_pattern_without_its_diagonal():
    with pytest.raises(ValueError, match="diagonal"):
        KeptDiagonal(sp.csr_matrix(np.array([[0.0, 1.0], [1.0, 2.0]])))


def test_v_cycle_is_a_symmetric_positive_preconditioner():
    """CG needs M = M^T > 0: <M a, b> = <a, M b> to round-off, <M a, a> > 0, also with the fine level's
    matrix changed on its diagonal after the hierarchy was built (the nutrient's stale hierarchy)."""
    matrix, demand = nutrient_like(8)
    cycle = VCycle(pyamg.ruge_stuben_solver(matrix, max_coarse=50))
    changed = KeptDiagonal(matrix)(demand)
    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(2, matrix.shape[0]))
    for fine in (matrix, changed):
        left, right = cycle(fine, a) @ b, a @ cycle(fine, b)
        assert abs(left - right) < 1e-12 * abs(left)
        assert cycle(fine, a) @ a > 0


def test_pcg_with_the_v_cycle_meets_the_true_residual_and_the_direct_answer():
    matrix, demand = nutrient_like(8, seed=1)
    matrix = KeptDiagonal(matrix)(demand)
    rhs = np.zeros(matrix.shape[0])
    rhs[0] = 2.0  # inflow at the held corner
    exact = spla.spsolve(sp.csc_matrix(matrix), rhs)
    amg = ReusedAMG(1e-10)
    x = amg.solve(matrix, rhs)
    assert np.linalg.norm(rhs - matrix @ x) <= 1e-10 * np.linalg.norm(rhs)
    assert np.abs(x - exact).max() < 1e-8 * np.abs(exact).max()
    assert 0 < amg.iterations < 30 and amg.rebuilds == 1


def test_pcg_drops_a_guess_worse_than_none():
    """From a guess whose residual is 1e12 |b| no iteration in double precision reaches 1e-10 |b|; from 0 it does."""
    matrix, demand = nutrient_like(6, seed=2)
    matrix = KeptDiagonal(matrix)(demand)
    rhs = np.zeros(matrix.shape[0])
    rhs[0] = 1.0
    cycle = VCycle(pyamg.ruge_stuben_solver(matrix, max_coarse=50))
    guess = np.full(matrix.shape[0], 1e12)
    x, iterations, residual, info = pcg(matrix, rhs, guess, lambda r: cycle(matrix, r), 1e-10, 100)
    assert info == 0 and residual <= 1e-10 and np.linalg.norm(rhs - matrix @ x) <= 1e-10


def test_jacobi_bicgstab_meets_the_true_residual_on_an_advection_matrix():
    """A non-symmetric M-matrix dominated by 1/dt, as the biofilm step's."""
    n = 6**3
    rng = np.random.default_rng(5)
    advection = sp.random(n, n, density=0.02, random_state=6, data_rvs=lambda k: -rng.random(k))
    advection = sp.csr_matrix(advection - sp.diags(np.asarray(advection.sum(axis=1)).ravel()))
    matrix = sp.csr_matrix(advection + laplacian_3d(6) + 1e3 * sp.identity(n))
    rhs = rng.random(n)
    x, iterations = jacobi_bicgstab(matrix, rhs, np.zeros(n), 1e-12, matrix.diagonal())
    assert np.linalg.norm(rhs - matrix @ x) <= 1e-12 * np.linalg.norm(rhs)
    assert 1 <= iterations < 20
    again, none = jacobi_bicgstab(matrix, rhs, x, 1e-12, matrix.diagonal())  # already converged: no iteration
    assert none == 0 and np.array_equal(again, x)


def test_a_passed_level_is_the_hierarchy_without_it():
    """Passing level 1 is the cycle of the hierarchy with level 1 removed and P_01 P_12 as the first
    interpolation, built here by hand from pyamg's levels; and on the 7-point operator it lowers the work of a
    solve from zero, CG iterations times the nonzeros a cycle reads (per smoothed level two sweeps and a
    residual of A, a restriction and an interpolation of P; the fine matrix once more for CG's product),
    against smoothing every level (here 16 against 12 iterations, 1.1e6 against 1.35e6)."""
    matrix, demand = nutrient_like(12, seed=7)
    hierarchy = pyamg.ruge_stuben_solver(matrix, max_coarse=50)
    assert len(hierarchy.levels) >= 4
    shortened = copy.deepcopy(hierarchy)
    shortened.levels[0].P = hierarchy.levels[0].P @ hierarchy.levels[1].P
    del shortened.levels[1]
    fine = KeptDiagonal(matrix)(demand)
    r = np.random.default_rng(8).normal(size=matrix.shape[0])
    passed, by_hand = VCycle(hierarchy)(fine, r), VCycle(shortened, passed=())(fine, r)
    assert np.abs(passed - by_hand).max() <= 1e-12 * np.abs(by_hand).max()
    rhs = np.zeros(matrix.shape[0])
    rhs[0] = 2.0
    work = []
    for cycle in (VCycle(hierarchy), VCycle(hierarchy, passed=())):
        x, iterations, residual, info = pcg(fine, rhs, np.zeros_like(rhs), lambda v, c=cycle: c(fine, v),
                                            1e-10 * np.linalg.norm(rhs), 100)
        assert info == 0 and residual <= 1e-10 * np.linalg.norm(rhs)
        per_cycle = fine.nnz + sum(3 * a.nnz + 2 * p.nnz for a, p in zip(cycle.operators, cycle.prolongations))
        work.append(iterations * per_cycle)
    assert work[0] < work[1]
