"""The transport written plainly in FiPy terms: the reference for the fast path.

Paper Eqs. 34-36 as FiPy equations, rebuilt and solved by FiPy at every step:

    nutrient:  DiffusionTerm(d) == ImplicitSourceTerm(g phi)          (first order)
    biofilm:   TransientTerm() + UpwindConvectionTerm(v) - ImplicitSourceTerm(div v)
                   == DiffusionTerm(beta) + k_alpha alpha               (Eq. 34)
    expansion: alpha += dt k_alpha phi                                  (Eq. 36)

``UpwindConvectionTerm(v) - ImplicitSourceTerm(div v)`` is FiPy's
conservative div(v phi) minus phi div(v): the non-conservative v . grad(phi).
Tests compare these matrices with `Biofilm`/`Nutrient` and a short run with
`Transport`; the benchmark times it with FiPy's default solvers (LU) and with
iterative ones.  The default laws only (`solver.Laws()`), no obstacles.
"""
from __future__ import annotations

import numpy as np

from solver.laws import Laws
from solver.problem import Problem
from solver.transport.finite_volume import fipy_mesh

HOLD = 1e12  # held cells: implicit source this many times stiffer than diffusion


class FipyTransport:
    """Steps phi, c, alpha of `problem` with FiPy rebuilding every matrix."""

    def __init__(self, problem: Problem, solvers: str = "default", tolerance: float = 1e-10):
        import fipy

        if problem.obstacle.any() or problem.laws != Laws():
            raise ValueError("the FiPy reference covers the default laws (first-order consumption, Eq. 36, "
                             "quasi-steady c) without obstacles")
        self.fipy = fipy
        self.problem = problem
        p = problem.params
        mesh = self.mesh = fipy_mesh(problem.grid)
        self.phi = fipy.CellVariable(mesh=mesh, value=problem.phi0.ravel(), hasOld=True)
        self.alpha = fipy.CellVariable(mesh=mesh, value=0.0)
        self.c = fipy.CellVariable(mesh=mesh, value=0.0)
        # held cells by a stiff implicit source: FiPy's c.constrain(where=cell mask) decouples the
        # held cells from their neighbours (measured: c = 0 beside a held c = 1 with FiPy 4.0.3)
        stiff = HOLD * max(p.d / problem.grid.spacing**2, p.g)
        self.held = fipy.CellVariable(mesh=mesh, value=stiff * problem.nutrient_held.ravel())
        if solvers == "default":
            self.nutrient_solver = self.biofilm_solver = None
        else:
            # the held rows dominate any relative residual norm: judge the nutrient's residual
            # absolutely, on the scale of one diffusive flux d h^(ndim-2)
            flux = p.d * problem.grid.spacing ** (problem.grid.ndim - 2)
            self.nutrient_solver = fipy.LinearPCGSolver(tolerance=tolerance * flux, criterion="unscaled",
                                                        iterations=5000)
            self.biofilm_solver = fipy.LinearGMRESSolver(tolerance=tolerance, iterations=2000)
        self.t = 0.0

    def velocity(self):
        """Face velocity r c/(k+c) grad c / max(|grad c|, floor) as a FiPy FaceVariable."""
        p, fipy = self.problem.params, self.fipy
        grad = self.c.faceGrad
        magnitude = grad.mag
        floor = self.problem.numerics.gradient_floor * float(np.max(magnitude.value))
        cf = self.c.arithmeticFaceValue
        speed = p.r * cf / (p.k + cf) / fipy.FaceVariable(mesh=self.mesh, value=np.maximum(magnitude.value, floor))
        return fipy.FaceVariable(mesh=self.mesh, rank=1, value=(speed * grad).value)

    def biofilm_equation(self, v):
        fipy, p = self.fipy, self.problem.params
        return (fipy.TransientTerm() + fipy.UpwindConvectionTerm(coeff=v)
                - fipy.ImplicitSourceTerm(coeff=v.divergence)
                == fipy.DiffusionTerm(coeff=p.beta) + p.k_alpha * self.alpha)

    def nutrient_equation(self):
        fipy, p = self.fipy, self.problem.params
        return (fipy.DiffusionTerm(coeff=p.d) == fipy.ImplicitSourceTerm(coeff=p.g * self.phi)
                + fipy.ImplicitSourceTerm(coeff=self.held) - self.held * self.problem.nutrient_value.ravel())

    def solve_nutrient(self):
        """FiPy's default criterion is relative to |b|, which the held rows dominate: warm-started
        from the previous c, the default (LU) solver judged itself converged after zero iterations
        and returned the previous step's c (FiPy 4.0.3).  So LU starts from zero; CG uses an
        absolute criterion (see __init__) and may start warm."""
        if self.nutrient_solver is None:
            self.c.setValue(0.0)
        self.nutrient_equation().solve(var=self.c, solver=self.nutrient_solver)

    def step(self, dt: float):
        """One step in the order of `Transport.step`: velocity from c^n, phi, alpha, then c."""
        self.phi.updateOld()
        v = self.velocity()
        self.biofilm_equation(v).solve(var=self.phi, dt=dt, solver=self.biofilm_solver)
        self.alpha.setValue(self.alpha.value + dt * self.problem.params.k_alpha * self.phi.value)
        self.solve_nutrient()
        self.t += dt

    def fields(self) -> dict:
        shape = self.problem.grid.cells_shape
        return {name: np.asarray(getattr(self, name).value).reshape(shape) for name in ("phi", "c", "alpha")}
