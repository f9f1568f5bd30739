"""A growing biofilm sphere in void: Newton's rate, the inclusion pressure against the
Lame solution, mesh convergence of p, warm starts, and the multigrid path.

The sphere (radius a = 4 µm, centre at the corner of the octant) is modelled
in one octant of a 16 µm cube with slide on the three symmetry planes x-, y-,
z-: the same problem as the whole cube, at an eighth of the cost.
"""
import numpy as np
import pytest
from scipy.optimize import brentq

from solver import Grid, MechanicsSetup, Parameters
from solver.mechanics import GrowthMechanics, Settings, material

PARAMS = Parameters()
KAPPA, MU = PARAMS.kappa, PARAMS.mu
EPS = MechanicsSetup().residual_stiffness
OCTANT = MechanicsSetup(slide=("x-", "y-", "z-"))
L, A = 8.0, 4.0  # octant edge and sphere radius, µm


def octant(n, smooth=None):
    grid = Grid((n, n, n), L / n)
    x, y, z = grid.cell_coordinates()
    r = np.sqrt(x**2 + y**2 + z**2)
    phi = (r <= A).astype(float) if smooth is None else 0.5 * (1 - np.tanh((r - A) / smooth))
    return grid, r, phi


def lame_inclusion_pressure(a, b, alpha, eps=EPS):
    """Linear elasticity: a sphere (kappa, mu) growing by alpha inside a shell a < r < b of
    (eps kappa, eps mu), outer surface free.  u = A r inside, B r + C / r^2 outside."""
    k1, k2, m2 = KAPPA, eps * KAPPA, eps * MU
    matrix = np.array([[a, -a, -1 / a**2],  # continuous displacement at r = a
                       [3 * k1, -3 * k2, 4 * m2 / a**3],  # continuous radial traction at r = a
                       [0, 3 * k2, -4 * m2 / b**3]])  # free at r = b
    Ai, _, _ = np.linalg.solve(matrix, [0, 3 * k1 * alpha, 0])
    return 3 * k1 * (Ai - alpha)


def test_newton_converges_quadratically():
    """With the tangent reassembled at every iterate (retangent = 0) and every linear solve to 1e-10,
    the rate log(r_k+1/r0) / log(r_k/r0) -> 2: the tangent is the residual's exact derivative."""
    grid, r, phi = octant(8, smooth=1.0)
    exact = Settings(retangent=0.0, forcing_first=1e-10, forcing_min=1e-10, forcing_max=1e-10)
    mech = GrowthMechanics(grid, PARAMS, OCTANT, settings=exact)
    result = mech.solve(phi, 0.05 * phi, 1.0)
    history = np.array(result.residual_history)
    scaled = history / history[0]
    usable = scaled[scaled > 1e-13]  # above round-off
    rates = np.log(usable[2:]) / np.log(usable[1:-1])  # from the first exact-tangent step on
    assert len(rates) >= 2, history
    assert rates[-1] > 1.7, (history, rates)
    assert np.all(rates > 1.5), (history, rates)


def test_growing_sphere_is_compressed_inside_and_the_void_carries_little():
    """Sharp sphere, alpha = 0.01: p < 0 inside; its magnitude lies near the Lame inclusion
    pressure for an outer radius between the cube's inscribed (8 µm) and circumscribed
    (13.9 µm) spheres, approaching it from above as the staircase refines (measured:
    2.0, 1.5, 1.2 times at h = 1, 1/2, 1/3); the void's stress stays below its own
    bulk stress scale 3 eps kappa alpha."""
    alpha = 0.01
    grid, r, phi = octant(16)
    result = GrowthMechanics(grid, PARAMS, OCTANT).solve(phi, alpha * phi, 1.0)
    a_equivalent = (8 * phi.sum() * grid.cell_volume * 3 / (4 * np.pi)) ** (1 / 3)
    inscribed = lame_inclusion_pressure(a_equivalent, L, alpha)
    circumscribed = lame_inclusion_pressure(a_equivalent, L * np.sqrt(3), alpha)
    inner = result.p[r < A / 2]
    assert np.all(inner < 0)
    assert circumscribed < inscribed < 0
    assert 1.0 * circumscribed > inner.mean() > 2.0 * circumscribed
    void = np.abs(result.p[phi == 0])
    assert void.max() < 0.5 * 3 * EPS * KAPPA * alpha
    # against what the biofilm would carry if the void held it: 3 kappa alpha = 5 Pa
    assert void.max() < 1e-4 * 3 * KAPPA * alpha


def test_pressure_converges_under_refinement():
    """Smooth sphere (tanh profile, width 1 µm): Q = weighted mean of p near the centre on
    h = 4/3, 2/3, 1/3.  Observed order log2(|Q1 - Q2| / |Q2 - Q3|).  The element pressure (P0) is
    first order; the recovered one, which only drops modes the equilibrium cannot see, must
    converge at least as fast: order >= 1 and its last change no larger than the element one's."""
    Q = {"element": [], "recovered": []}
    for n in (6, 12, 24):
        grid, r, phi = octant(n, smooth=1.0)
        mech = GrowthMechanics(grid, PARAMS, MechanicsSetup(slide=OCTANT.slide, pressure="element"))
        p = mech.solve(phi, 0.01 * phi, 1.0).p
        recovered = mech.pressure.recover(p.ravel()[mech.mesh.cells], material.weight(phi.ravel(), EPS))
        weight = np.exp(-(r / 2) ** 2)
        for name, field in (("element", p.ravel()), ("recovered", recovered)):
            Q[name].append((field * weight.ravel()).sum() / weight.sum())
    changes = {name: np.abs(np.diff(q)) for name, q in Q.items()}
    orders = {name: np.log2(c[0] / c[1]) for name, c in changes.items()}
    assert orders["element"] > 0.9, (Q, orders)
    assert orders["recovered"] >= 1.0, (Q, orders)
    assert changes["recovered"][1] <= changes["element"][1], (Q, changes)
    assert changes["recovered"][1] < 0.01 * abs(Q["recovered"][-1])


def test_warm_start_reuses_the_state():
    grid, r, phi = octant(6, smooth=1.0)
    tight = MechanicsSetup(slide=OCTANT.slide, newton_tolerance=1e-10)
    mech = GrowthMechanics(grid, PARAMS, tight)
    first = mech.solve(phi, 0.01 * phi, 1.0)
    again = mech.solve(phi, 0.01 * phi, 1.0)
    assert again.newton_iterations == 0
    np.testing.assert_array_equal(again.u, first.u)
    grown = mech.solve(phi, 0.011 * phi, 1.1)
    cold = GrowthMechanics(grid, PARAMS, tight).solve(phi, 0.011 * phi, 1.1)
    np.testing.assert_allclose(grown.u, cold.u, atol=1e-7 * np.abs(cold.u).max())
    np.testing.assert_allclose(grown.p, cold.p, atol=1e-7 * np.abs(cold.p).max())


@pytest.mark.parametrize("method, changes", [("multigrid", {}), ("multigrid", {"deflate": True}),
                                             ("amg", {})])
def test_iterative_preconditioners_agree_with_the_factorisation(method, changes):
    """Geometric multigrid (plain and deflated) and smoothed aggregation give the direct solve's answer."""
    grid, r, phi = octant(8, smooth=1.0)
    setup = dict(slide=OCTANT.slide, newton_tolerance=1e-10)
    direct = GrowthMechanics(grid, PARAMS, MechanicsSetup(linear_solver="direct", **setup))
    other = GrowthMechanics(grid, PARAMS, MechanicsSetup(linear_solver=method, **setup),
                            settings=Settings(coarsest=1000, **changes))
    a, b = (m.solve(phi, 0.02 * phi, 1.0) for m in (direct, other))
    name = b.info["linear_solver"]
    assert ("multigrid(" in name and "levels" in name) if method == "multigrid" else "aggregation" in name
    assert ("deflated" in name) == bool(changes)
    np.testing.assert_allclose(b.p, a.p, atol=1e-6 * np.abs(a.p).max())
    np.testing.assert_allclose(b.u, a.u, atol=1e-5 * np.abs(a.u).max())


@pytest.mark.parametrize("shape", [(5, 4, 3), (7, 5)])
def test_multigrid_handles_odd_cell_counts(shape):
    """Uniform growth of a free block, whose exact answer is known: u = alpha X in 3-D; in plane
    strain u = (lambda - 1) X with lambda from the 1-D equilibrium (as in test_mechanics)."""
    grid = Grid(shape, 1.0)
    mech = GrowthMechanics(grid, PARAMS, MechanicsSetup(linear_solver="multigrid", newton_tolerance=1e-12),
                           settings=Settings(coarsest=20))
    assert len(mech.linear.preconditioner.cycle.levels) >= 2
    alpha = 0.02
    result = mech.solve(np.ones(grid.cells_shape), np.full(grid.cells_shape, alpha), 0.3)
    positions = np.stack(np.meshgrid(*(grid.nodes(a) for a in reversed(grid.axes)), indexing="ij")[::-1], -1)
    if grid.ndim == 3:
        stretch = 1 + alpha
    else:
        Jg = (1 + alpha) ** 3
        stretch = brentq(lambda s: KAPPA * (s**2 / Jg - 1) + MU * Jg * s ** (-10 / 3) * (s**2 - 1) / 3, 1.0, 1.2)
    np.testing.assert_allclose(result.u, (stretch - 1) * positions, atol=1e-9)


def test_without_pardiso_the_scipy_fallback_gives_the_same_answer(monkeypatch):
    """pypardiso is x86_64-only: elsewhere SuperLU factorises (the multigrid's coarsest grid always uses it)."""
    from solver.mechanics import preconditioners

    grid, r, phi = octant(6, smooth=1.0)
    tight = dict(slide=OCTANT.slide, newton_tolerance=1e-10)
    reference = GrowthMechanics(grid, PARAMS, MechanicsSetup(**tight)).solve(phi, 0.01 * phi, 1.0)
    monkeypatch.setattr(preconditioners, "pypardiso", None)
    for method in ("auto", "direct", "multigrid"):
        mech = GrowthMechanics(grid, PARAMS, MechanicsSetup(linear_solver=method, **tight),
                               settings=Settings(coarsest=300))
        result = mech.solve(phi, 0.01 * phi, 1.0)
        assert "pardiso" not in result.info["linear_solver"]
        assert method == "multigrid" or "superlu" in result.info["linear_solver"]
        np.testing.assert_allclose(result.p, reference.p, atol=1e-6 * np.abs(reference.p).max())


def test_the_environment_is_searched_for_pardiso_once(monkeypatch):
    """Making a PARDISO handle searches the environment's directories for MKL's library unless
    PYPARDISO_MKL_RT names it (a second or more in a large environment): the first factoriser names what it
    found there, and the next makes no search."""
    wrapper = pytest.importorskip("pypardiso.pardiso_wrapper")
    from solver.mechanics import preconditioners

    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    preconditioners.Factoriser()

    def searched(*args, **kwargs):
        raise AssertionError("searched again")

    monkeypatch.setattr(wrapper, "find_library", searched)
    monkeypatch.setattr(wrapper.glob, "glob", searched)
    preconditioners.Factoriser()
