"""The cached operators against FiPy's own, and the plain FiPy run against the fast path."""
import numpy as np
import scipy.sparse as sp
from fipy_reference import FipyTransport

from solver import Grid, Numerics, Parameters, Problem
from solver.transport import Transport
from solver.transport.finite_volume import FiniteVolumeGrid


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


def test_fipys_mesh_is_freed_once_the_laplacian_is_made_on_a_large_grid(monkeypatch):
    """FiPy's mesh and variables refer to each other, so without a collection their arrays would outlive the
    Laplacian (a large part of a big run's peak memory); from `COLLECT_ABOVE` cells on they are collected at once:
    no FiPy mesh is left, though nothing else collects (here: 60 cells counted as large)."""
    import gc

    from fipy.meshes.abstractMesh import AbstractMesh

    from solver.transport import finite_volume

    monkeypatch.setattr(finite_volume, "COLLECT_ABOVE", 60)
    gc.collect()
    gc.disable()  # no collection but the one under test
    try:
        assert FiniteVolumeGrid(Grid((5, 4, 3), 1.0)).laplacian.shape == (60, 60)
        meshes = sum(isinstance(item, AbstractMesh) for item in gc.get_objects())
    finally:
        gc.enable()
    assert meshes == 0
