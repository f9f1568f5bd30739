"""The cached operators against FiPy's own, and the plain FiPy run against the fast path."""
import numpy as np
import pytest
import scipy.sparse as sp
from fipy_reference import FipyTransport

from solver import Grid, Numerics, Parameters, Problem
from solver.transport import Transport
from solver.transport.biofilm import Biofilm
from solver.transport.finite_volume import FiniteVolumeGrid, fipy_laplacian
from solver.transport.nutrient import Nutrient


def second_difference(n, h):
    """1-D zero-flux second difference (independent of FiPy)."""
    main = -2.0 * np.ones(n)
    main[[0, -1]] = -1.0
    return sp.diags([np.ones(n - 1), main, np.ones(n - 1)], [-1, 0, 1]) / h**2


def test_fipy_laplacian_is_the_seven_point_stencil_with_zero_flux():
    grid = Grid((5, 4, 3), 0.5)
    nx, ny, nz = grid.shape
    eye = lambda n: sp.identity(n)
    expected = (sp.kron(eye(nz), sp.kron(eye(ny), second_difference(nx, 0.5)))
                + sp.kron(eye(nz), sp.kron(second_difference(ny, 0.5), eye(nx)))
                + sp.kron(second_difference(nz, 0.5), sp.kron(eye(ny), eye(nx))))
    assert abs(FiniteVolumeGrid(grid).laplacian - expected).max() < 1e-12


def test_obstacle_cells_are_removed_and_their_faces_closed():
    grid = Grid((6, 5), 1.0)
    obstacle = np.zeros(grid.cells_shape, bool)
    obstacle[2, 1:4] = True
    fv = FiniteVolumeGrid(grid, obstacle)
    assert fv.n == 30 - 3
    lap = fv.laplacian
    assert np.allclose(np.asarray(lap.sum(axis=1)).ravel(), 0.0)  # zero flux everywhere, obstacles included
    # the cell just below the obstacle's middle has lost its upper neighbour
    below = fv.full_to_active[np.ravel_multi_index((1, 2), grid.cells_shape)]
    assert lap[below, below] == -3.0
    for faces in fv.faces:
        assert not np.isin(fv.cells[np.concatenate([faces.lower, faces.upper])],
                           np.flatnonzero(obstacle.ravel())).any()


def directional(n, steps, t_end):
    grid = Grid((n, n, n), 20.0 / n)
    x, y, z = grid.cell_coordinates()
    phi0 = ((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2 <= 25).astype(float)
    return Problem(grid=grid, phi0=phi0, nutrient_held=(x > 16) & (y > 16) & (z > 16),
                   t_end=t_end, steps=steps, output_times=[0, t_end], params=Parameters(k_alpha=0.5),
                   numerics=Numerics(growth_velocity="pointwise"))  # the FiPy reference has the pointwise velocity


def run_both(steps, t_end=0.02, n=8):
    problem = directional(n, steps, t_end)
    fast = Transport(problem)
    state = fast.initial()
    reference = FipyTransport(problem, solvers="default")
    reference.solve_nutrient()
    initial_c = np.abs(fast.full(state.c) - reference.fields()["c"]).max()
    for _ in range(steps):
        state = fast.step(state, t_end / steps)
        reference.step(t_end / steps)
    fields = reference.fields()
    return initial_c, {k: np.abs(fast.full(getattr(state, k)) - fields[k]).max() for k in ("phi", "c", "alpha")}


def test_plain_fipy_run_agrees_with_the_fast_path():
    """Same equations: c identical to round-off; phi differs only by FiPy's explicit treatment of the
    source part of -phi div(v) (ImplicitSourceTerm is implicit only where it is a sink), an O(dt) split."""
    initial_c, coarse = run_both(steps=5)
    _, fine = run_both(steps=20)
    assert initial_c < 1e-10
    assert coarse["phi"] < 0.05
    assert 3.0 < coarse["phi"] / fine["phi"] < 5.0, (coarse, fine)  # O(dt): 4x the steps, 1/4 the gap


def test_a_failed_step_names_its_cell_in_grid_coordinates_past_the_obstacles():
    """An active cell's index skips obstacle cells; the message names the grid cell and its centre (µm)."""
    grid = Grid((4, 3), 2.0)
    obstacle = np.zeros(grid.cells_shape, bool)
    obstacle[0, :2] = True  # (y, x): the first two cells of the bottom row
    fv = FiniteVolumeGrid(grid, obstacle)
    assert fv.describe(0) == "cell (y, x) = (0, 2) (y = 1 µm, x = 5 µm)"
    assert fv.describe(fv.n - 1) == "cell (y, x) = (2, 3) (y = 5 µm, x = 7 µm)"


def same_csr(a: sp.csr_matrix, b: sp.csr_matrix) -> bool:
    """The same CSR arrays: shape, row pointers, column indices and values, bit for bit."""
    return (a.shape == b.shape and np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
            and np.array_equal(a.data, b.data))


@pytest.mark.parametrize("seed", range(6))
def test_the_laplacian_is_fipys_entry_for_entry(seed):
    """The Laplacian made from the grid's indices is FiPy's DiffusionTerm matrix (the definition) bit for bit: 2-D
    and 3-D, spacings whose products round (1/3, 20/64, random), obstacles, cells walled in on every side."""
    rng = np.random.default_rng(seed)
    for trial in range(8):
        shape = tuple(int(n) for n in rng.integers(1, 9, 2 + (seed + trial) % 2))
        spacing = [1.0, 0.5, 1 / 3, 20 / 64, 0.1, float(np.exp(rng.uniform(-4, 2)))][trial % 6]
        grid = Grid(shape, spacing)
        obstacle = rng.random(grid.cells_shape) < [0.0, 0.15, 0.45][trial % 3]
        if obstacle.all():
            continue
        fv = FiniteVolumeGrid(grid, obstacle)
        assert same_csr(fv.laplacian, fipy_laplacian(grid, ~obstacle)), (shape, spacing)


@pytest.mark.parametrize("shape", [(9, 8, 7), (14, 11)])
def test_the_nutrient_and_biofilm_operators_are_those_made_on_fipys_laplacian(shape):
    """Held cells, held faces, obstacles and a region walled off from every source: the nutrient's matrix and
    inflow and the biofilm's diffusion made on the fast Laplacian are those made on FiPy's, bit for bit."""
    grid = Grid(shape, 0.8)
    centres = grid.cell_coordinates()
    obstacle = np.abs(centres[0] - 3.0) < 0.5  # a wall across x ...
    obstacle &= centres[1] > 1.0  # ... with a gap below, and a sealed pocket beyond it
    obstacle |= (np.abs(centres[0] - 5.5) < 0.5) | (np.abs(centres[1] - 5.0) < 0.5) & (centres[0] > 5.5)
    held = (centres[0] > 6.5) & (centres[1] < 1.0)
    faces = (("y-", 0.8),) if len(shape) == 2 else (("y-", 0.8), ("x-", 0.3))
    built = []
    for fipys in (False, True):
        fv = FiniteVolumeGrid(grid, obstacle)
        if fipys:
            fv._laplacian = fipy_laplacian(grid, ~obstacle)
        nutrient = Nutrient(fv, Parameters(), "first-order", held & ~obstacle, np.full(grid.cells_shape, 0.9),
                            faces=faces)
        biofilm = Biofilm(fv, Parameters(), Numerics(advection="tvd"), nutrient.faces)
        built.append((nutrient, biofilm))
    (fast, fast_biofilm), (fipy, fipy_biofilm) = built
    assert np.array_equal(fast.free, fipy.free) and fast.free.size < fast.fv.n - np.count_nonzero(held)
    assert same_csr(fast.stiffness, fipy.stiffness) and np.array_equal(fast.rhs, fipy.rhs)
    assert fast_biofilm.neighbour == fipy_biofilm.neighbour and np.array_equal(fast_biofilm.own, fipy_biofilm.own)
    assert same_csr(fast_biofilm.matrix, fipy_biofilm.matrix)


def test_a_run_makes_its_laplacian_without_fipy(monkeypatch):
    """No FiPy mesh is built for a run (FiPy's cost 5.9 s and 0.93 GB at 80^3)."""
    from solver.transport import finite_volume

    def refused(grid):
        raise AssertionError("a FiPy mesh was built")

    monkeypatch.setattr(finite_volume, "fipy_mesh", refused)
    assert FiniteVolumeGrid(Grid((5, 4, 3), 1.0)).laplacian.shape == (60, 60)
