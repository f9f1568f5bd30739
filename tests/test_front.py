"""The front velocity (`solver.transport.front`): the growth speed taken at the phi = 1/2 front, carried along
its normals.

Checked against what it is built to do, with the nutrient prescribed (no consumption feedback) so that the
answers are exact: the speed at the front is r c/(k+c) N.n_c at the interpolated crossing; cells beyond the band
keep the pointwise velocity; a front whose nutrient minimum lies inside its own profile translates as a whole
(dense stays dense) where the pointwise velocity spreads the value found at the minimum (the dilution of
docs/paper.md); and the front moves at the speed the model gives it.
"""
import numpy as np
import pytest

from solver.problem import Grid, Numerics, Parameters
from solver.transport.biofilm import Biofilm, Velocity
from solver.transport.finite_volume import FiniteVolumeGrid
from solver.transport.front import FrontVelocity

R, K = 100.0, 1.0


def strip(n: int, h: float = 1.0):
    grid = Grid((n, 1), h)
    return grid, FiniteVolumeGrid(grid), grid.centres("x")


def profile(x, position, width=0.5):
    """Dense (1) below `position`, void above, a tanh edge of the given width (µm)."""
    return 0.5 * (1.0 - np.tanh((x - position) / width))


def test_speed_at_the_crossing_on_the_dense_side_and_in_the_band_pointwise_beyond():
    """Planar front at x = 10.3 in c = 0.2 + 0.02 x: F = r c/(k+c) at the crossing (N = n_c = +x) on every face of
    the dense side (phi >= 1/2) and of the void within 3 cells of the front cell; beyond, in the void, the
    pointwise r c_f/(k+c_f)."""
    grid, fv, x = strip(30)
    phi = profile(x, 10.3)
    c = 0.2 + 0.02 * x
    params = Parameters(r=R, k=K, g=0.0)
    w = FrontVelocity(fv, Velocity(fv, params, 1e-3), band=3.0)(c, phi)[0]
    i = np.flatnonzero(phi >= 0.5)[-1]  # last dense cell
    theta = (phi[i] - 0.5) / (phi[i] - phi[i + 1])
    c_front = 0.2 + 0.02 * (x[i] + theta)
    owner = i if theta < 0.5 else i + 1
    faces = fv.faces[0]
    covered = (phi >= 0.5) | (np.abs(np.arange(30) - owner) <= 3)
    near = covered[faces.lower] & covered[faces.upper]
    far = ~covered[faces.lower] & ~covered[faces.upper]
    assert np.allclose(w[near], R * c_front / (K + c_front))
    c_face = 0.5 * (c[faces.lower] + c[faces.upper])
    assert np.allclose(w[far], R * c_face[far] / (K + c_face[far]))
    assert near.sum() == owner + 3 and far.sum() == 29 - owner - 4


def march(fv, numerics, phi, c, t_end, steps, beta=0.0):
    """phi after `steps` implicit steps in the prescribed nutrient field c (held fixed)."""
    biofilm = Biofilm(fv, Parameters(r=R, k=K, g=0.0, beta=beta, k_alpha=0.0), numerics)
    alpha = np.zeros_like(phi)
    for _ in range(steps):
        phi = biofilm.step(phi, alpha, biofilm.velocity(c, phi), t_end / steps)
    return phi


@pytest.mark.parametrize("advection", ["upwind", "tvd"])
def test_a_minimum_inside_the_profile_does_not_dilute_the_dense_side(advection):
    """c has its minimum at x = 9.6, inside the front's profile: in the cell at 9.5, which holds phi = 0.73.
    Pointwise, the velocity diverges from that cell: 0.73 is carried down into the dense side at r c/(k+c)
    ~ 33 µm/T*, 3.3 µm in T* = 0.1, so that the cells 1-3 µm below the minimum fall to ~0.73.  The front
    velocity moves the whole profile at the front's speed: the dense side stays at 1, and the front advances."""
    grid, fv, x = strip(40)
    phi0 = profile(x, 10.0, width=1.0)
    c = 0.5 + 1e-3 * (x - 9.6) ** 2
    behind = (x > 6.6) & (x < 8.6)  # 1-3 µm below the minimum
    pointwise = march(fv, Numerics(advection=advection, growth_velocity="pointwise"), phi0, c, 0.1, 100)
    front = march(fv, Numerics(advection=advection, growth_velocity="front"), phi0, c, 0.1, 100)
    assert pointwise[behind].max() < 0.8, pointwise[behind]
    assert np.all(front[behind] >= phi0[behind]) and front.max() <= 1.0, (front[behind], phi0[behind])
    half = lambda p: x[np.flatnonzero(p >= 0.5)[-1]]
    assert half(front) > half(phi0) + 2.0


def crossing(x, phi):
    i = np.flatnonzero(phi >= 0.5)[-1]
    return x[i] + (phi[i] - 0.5) / (phi[i] - phi[i + 1]) * (x[i + 1] - x[i])


def test_front_moves_at_the_models_speed_and_converges():
    """In c = 0.2 + 0.02 x (no minimum) the phi = 1/2 level follows dX/dt = r c(X)/(k + c(X)), whose solution
    is X + (k/0.02) ln c(X) = X0 + (k/0.02) ln c(X0) + r t.  The front velocity's crossing converges to it."""
    t_end, x0 = 0.1, 8.0
    slope, offset = 0.02, 0.2
    from scipy.optimize import brentq

    invariant = lambda X: X + K / slope * np.log(offset + slope * X)
    exact = brentq(lambda X: invariant(X) - invariant(x0) - R * t_end, x0, 40.0)
    errors = []
    for n in (20, 40, 80):
        grid, fv, x = strip(n, 40.0 / n)
        phi = march(fv, Numerics(advection="tvd"), profile(x, x0, 1.0), offset + slope * x, t_end, 2 * n)
        errors.append(abs(crossing(x, phi) - exact))
    assert errors[-1] < 0.05 * (exact - x0), errors  # within 5 % of the distance travelled
    assert errors[2] < errors[0], errors
