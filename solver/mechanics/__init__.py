"""Growth mechanics with scikit-fem (SPEC 1, paper 2.1, 2.3.1, 3): u at grid nodes, p per cell.

One file per concept:
  material     energy, stress and tangent at quadrature points (pure functions)
  mesh         the transport grid as a Q1 mesh (scikit-fem reference element)
  assembly     residual and consistent tangent, vectorised over elements
  constraints  clamp / slide faces, obstacles, rigid-body modes
  multigrid    geometric multigrid preconditioner on the structured grid
  linear       GMRES with a reused preconditioner (direct or multigrid)
  newton       safeguarded Newton iteration
  growth       `GrowthMechanics`: load stepping, warm start, results
"""
from .growth import GrowthMechanics, MechanicsResult

__all__ = ["GrowthMechanics", "MechanicsResult"]
