"""Quasi-steady nutrient against exact steady profiles (paper Eq. 35; docs/model.md)."""
import numpy as np
import pytest
import scipy.sparse.linalg as spla

from solver.problem import Grid, Parameters
from solver.transport.finite_volume import FiniteVolumeGrid
from solver.transport.nutrient import Nutrient

LENGTH = 16.0  # µm; c = 1 held in the first column of cells, zero flux at x = LENGTH


def strip(n, gamma, consumption, ny=2):
    """Uniform biofilm strip along x: c held at 1 in the first cell column; returns (x, c along x)."""
    grid = Grid((n, ny), LENGTH / n)
    fv = FiniteVolumeGrid(grid)
    held = np.zeros(grid.cells_shape, bool)
    held[:, 0] = True
    nutrient = Nutrient(fv, Parameters(d=1.0, g=gamma), consumption, held, np.ones(grid.cells_shape))
    c = fv.to_full(nutrient.solve(np.ones(fv.n)))
    assert np.allclose(c, c[0]), "profile must not depend on y"
    return grid.centres("x"), c[0], nutrient


def observed_order(sizes, errors):
    return np.polyfit(np.log(sizes), np.log(errors), 1)[0]


def test_first_order_cosh_profile_converges_at_second_order():
    """d c'' = g c in the strip: c = cosh(m (L - x)) / cosh(m (L - x0)), m = sqrt(g/d)."""
    gamma = 0.25
    m = np.sqrt(gamma)
    errors, sizes = [], []
    for n in (16, 32, 64, 128):
        x, c, _ = strip(n, gamma, "first-order")
        exact = np.cosh(m * (LENGTH - x)) / np.cosh(m * (LENGTH - x[0]))
        errors.append(np.abs(c - exact).max())
        sizes.append(LENGTH / n)
    order = observed_order(sizes, errors)
    assert 1.8 < order < 2.3, (order, errors)
    assert errors[-1] < 1e-4


def test_zero_order_parabola_is_exact_while_nutrient_lasts():
    """d c'' = g with c'(L) = 0: c = 1 + g/2d ((x - L)^2 - (x0 - L)^2); the FV scheme is exact on it."""
    gamma = 0.005  # drop 0.64 over the strip: c stays positive
    x, c, nutrient = strip(32, gamma, "zero-order")
    exact = 1 + 0.5 * gamma * ((x - LENGTH) ** 2 - (x[0] - LENGTH) ** 2)
    assert exact.min() > 0.3
    assert np.abs(c - exact).max() < 1e-8
    assert not nutrient.active_set.any()


def test_zero_order_exhausted_region_converges_and_stays_zero():
    """Demand exceeds supply: c = g/2d (x - x*)^2 before x* = x0 + sqrt(2d/g), c = 0 beyond."""
    gamma = 1.0
    errors, sizes = [], []
    for n in (64, 128, 256, 512):
        x, c, nutrient = strip(n, gamma, "zero-order")
        front = x[0] + np.sqrt(2.0 / gamma)
        exact = np.where(x < front, 0.5 * gamma * (x - front) ** 2, 0.0)
        assert c.min() >= 0.0
        assert np.all(c[x > front + 2 * (LENGTH / n)] == 0.0), "exhausted cells hold exactly zero"
        errors.append(np.abs(c - exact).max())
        sizes.append(LENGTH / n)
    assert observed_order(sizes, errors) > 0.9, errors
    assert all(e < 0.02 * h for e, h in zip(errors, sizes)), "free boundary resolved to O(h)"


def test_literal_zero_order_would_go_negative_but_constrained_does_not():
    """Eq. 35 taken literally (the same discrete operator, no constraint) drives c far below 0; the
    constrained law is the complementarity problem c >= 0, unmet demand lambda = K c - b + g/d phi >= 0,
    c lambda = 0: where nutrient is left it is all consumed as the law says, where it is exhausted c = 0."""
    gamma = 1.0
    x, c_full, nutrient = strip(64, gamma, "zero-order")
    free = nutrient.free
    demand = nutrient.gamma * np.ones(free.size)
    literal = spla.spsolve(nutrient.stiffness.tocsc(), nutrient.rhs - demand)
    assert literal.min() < -100  # about 1 - gamma L^2 / 2 at the far end
    c = nutrient.solve(np.ones(nutrient.fv.n))[free]
    unmet = nutrient.stiffness @ c - nutrient.rhs + demand
    scale = np.abs(nutrient.rhs).max() + demand.max()
    assert c.min() == 0.0 and np.count_nonzero(c == 0.0) > free.size // 2  # most of the strip is exhausted
    assert unmet.min() > -1e-8 * scale  # never more consumed than demanded
    assert np.abs(unmet[c > 0]).max() < 1e-8 * scale  # where c > 0 the law holds exactly
    assert c_full.max() == pytest.approx(1.0)


def test_walled_off_pocket_receives_no_nutrient():
    """Cells no source can reach (enclosed by obstacles) hold c = 0, even without consumption."""
    grid = Grid((10, 10), 1.0)
    obstacle = np.zeros(grid.cells_shape, bool)
    obstacle[2:8, 2] = obstacle[2:8, 7] = obstacle[2, 2:8] = obstacle[7, 2:8] = True
    held = np.zeros(grid.cells_shape, bool)
    held[0, 0] = True
    fv = FiniteVolumeGrid(grid, obstacle)
    c = fv.to_full(Nutrient(fv, Parameters(g=0.0), "first-order", held, np.ones(grid.cells_shape))
                   .solve(np.zeros(fv.n)))
    assert np.all(c[3:7, 3:7] == 0.0)
    outside = ~obstacle
    outside[3:7, 3:7] = False
    assert np.allclose(c[outside], 1.0)
    assert np.isnan(c[obstacle]).all()


@pytest.mark.parametrize("consumption", ["first-order", "zero-order"])
@pytest.mark.parametrize("d, g", [(1.0, 1e10), (1e13, 1e10), (1e13, 0.0), (1e10, 1e8)])
def test_bounds_hold_on_stiff_nutrient(consumption, d, g):
    """0 <= c <= 1 for diffusivity and consumption spanning 23 orders of magnitude (3-D, 8^3)."""
    grid = Grid((8, 8, 8), 2.5)
    x, y, z = grid.cell_coordinates()
    phi = ((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2 <= 25).astype(float)
    held = (x > 15) & (y > 15) & (z > 15)
    fv = FiniteVolumeGrid(grid)
    c = Nutrient(fv, Parameters(d=d, g=g), consumption, held, np.ones(grid.cells_shape)).solve(fv.to_active(phi))
    assert np.isfinite(c).all()
    assert c.min() >= 0.0 and c.max() <= 1.0
    if g == 0.0:
        assert np.allclose(c, 1.0, atol=1e-8)


@pytest.mark.parametrize("face", ["x-", "x+"])
def test_held_face_cosh_profile_converges_at_second_order(face):
    """c = 1 held on the boundary face itself (no source cells): c = cosh(m (L - s)) / cosh(m L), s the distance
    from the face; the cells beside the face stay free.  The velocity's cell gradient there uses the face value."""
    from solver.transport.biofilm import Velocity

    gamma, m = 0.25, 0.5
    errors, slopes, sizes = [], [], []
    for n in (16, 32, 64, 128):
        grid = Grid((n, 2), LENGTH / n)
        fv = FiniteVolumeGrid(grid)
        nutrient = Nutrient(fv, Parameters(d=1.0, g=gamma), "first-order", np.zeros(grid.cells_shape, bool),
                            np.ones(grid.cells_shape), faces=((face, 1.0),))
        c_active = nutrient.solve(np.ones(fv.n))
        c = fv.to_full(c_active)[0]
        x = grid.centres("x")
        s = x if face == "x-" else LENGTH - x
        exact = np.cosh(m * (LENGTH - s)) / np.cosh(m * LENGTH)
        errors.append(np.abs(c - exact).max())
        exact_slope = (-np.sinh(m * (LENGTH - x)) if face == "x-" else np.sinh(m * x)) * m / np.cosh(m * LENGTH)
        beside = fv.boundary_cells(face)
        slope = Velocity(fv, Parameters(), 1e-3, nutrient.faces).cell_gradient(c_active)[0][beside]
        slopes.append(np.abs(slope - exact_slope[0 if face == "x-" else -1]).max())
        sizes.append(LENGTH / n)
        assert not np.isin(beside, nutrient.free, invert=True).any(), "cells beside a held face stay free"
    assert 1.8 < observed_order(sizes, errors) < 2.3, errors
    assert observed_order(sizes, slopes) > 0.9, slopes
