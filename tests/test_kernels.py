"""The compiled kernels (solver/transport/kernels.py) against the numpy forms they replaced."""
import numpy as np
import pytest
from scipy import ndimage

from solver import Grid, Numerics, Problem
from solver.transport import Transport
from solver.transport.kernels import subgraph, within_reach


def transport_on(shape, advection, seed=0):
    grid = Grid(shape, 0.8)
    rng = np.random.default_rng(seed)
    obstacle = rng.random(grid.cells_shape) < 0.1
    problem = Problem(grid=grid, phi0=np.zeros(grid.cells_shape), nutrient_held=np.zeros(grid.cells_shape, bool),
                      obstacle=obstacle, t_end=1.0, steps=1, output_times=[0.0, 1.0],
                      numerics=Numerics(advection=advection))
    return Transport(problem)


def numpy_advection(biofilm, w, phi):
    """The advection's CSR data as whole-array numpy (the form before issue 20), entry order and all."""
    h = biofilm.fv.grid.spacing
    positions, values = [], []
    for axis, (f, wf) in enumerate(zip(biofilm.fv.faces, w)):
        pos = biofilm.positions(axis)
        forward = wf > 0
        a = np.abs(wf) / h
        if biofilm.tvd:
            up, down = np.where(forward, f.lower, f.upper), np.where(forward, f.upper, f.lower)
            far = np.where(forward, f.lower_out, f.upper_out)
            num = np.where(far >= 0, phi[up] - phi[np.maximum(far, 0)], 0.0)
            den = phi[down] - phi[up]
            smooth = num * den > 0
            total = np.where(smooth, num + den, 1.0)
            psi = np.where(smooth, 2.0 * num / total, 0.0)
            psi_over_r = np.where(smooth, 2.0 * den / total, 0.0)
            inflow, outflow = a * (1.0 - 0.5 * psi), a * 0.5 * psi_over_r
        else:
            inflow, outflow = a, None
        positions += [np.where(forward, pos[1], pos[0]), np.where(forward, pos[2], pos[3])]
        values += [inflow, -inflow]
        if outflow is not None:
            positions += [np.where(forward, pos[0], pos[1]), np.where(forward, pos[4], pos[5])]
            values += [outflow, -outflow]
    return np.bincount(np.concatenate(positions), weights=np.concatenate(values),
                       minlength=biofilm.matrix.nnz)


@pytest.mark.parametrize("advection", ["upwind", "tvd"])
@pytest.mark.parametrize("shape", [(7, 6, 5), (9, 8)])
def test_advection_kernel_is_the_numpy_form_bit_for_bit(advection, shape):
    transport = transport_on(shape, advection)
    rng = np.random.default_rng(7)
    w = [rng.normal(scale=30, size=f.lower.size) * (rng.random(f.lower.size) > 0.1) for f in transport.fv.faces]
    phi = np.round(rng.random(transport.fv.n), 1)  # ties: flat stretches where the limiter switches off
    assert np.array_equal(transport.biofilm.advection(w, phi), numpy_advection(transport.biofilm, w, phi))


@pytest.mark.parametrize("shape", [(9, 8, 7), (12, 10)])
def test_within_reach_is_the_cross_dilation(shape):
    rng = np.random.default_rng(8)
    start = np.flatnonzero(rng.random(int(np.prod(shape))) < 0.02)
    for reach in (1, 3):
        seeds = np.zeros(int(np.prod(shape)), bool)
        seeds[start] = True
        dilated = ndimage.binary_dilation(seeds.reshape(shape), structure=ndimage.generate_binary_structure(
            len(shape), 1), iterations=reach)
        assert np.array_equal(within_reach(start, np.asarray(shape, np.int64), reach), dilated.ravel())


def test_subgraph_is_scipys_fancy_indexing():
    """The same CSR pattern (order within rows too: Dijkstra's ties follow it), the diagonal left out."""
    transport = transport_on((8, 7, 6), "upwind")
    adjacency = transport.fv.laplacian.copy()
    adjacency.setdiag(0)
    adjacency.eliminate_zeros()
    laplacian = transport.fv.laplacian
    keep = np.random.default_rng(9).random(transport.fv.n) < 0.4
    candidates = np.flatnonzero(keep)
    local = np.full(transport.fv.n, -1, np.int32)
    local[candidates] = np.arange(candidates.size)
    indices = np.empty(laplacian.nnz, np.int32)
    indptr = subgraph(laplacian.indptr, laplacian.indices, keep, local, indices)
    expected = adjacency[candidates][:, candidates]
    assert np.array_equal(indptr, expected.indptr) and np.array_equal(indices[:indptr[-1]], expected.indices)
    assert expected.nnz > 0
