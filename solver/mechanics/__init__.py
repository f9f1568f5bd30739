"""Growth mechanics with scikit-fem (paper 2.1, 2.3.1, 3): u at grid nodes, p per cell.

One file per concept:
  material         energy, stress coefficients and tangent at quadrature points (pure functions)
  mesh             the transport grid as a Q1 mesh (scikit-fem reference element)
  assembly         residual and consistent tangent, vectorised over elements
  stencil          the tangent's storage: half a stencil of blocks on the grid's nodes, its product
  constraints      clamp / slide faces, obstacles, rigid-body modes
  pressure         the dataset's pressure: Q1/P0 element values or recovered without checkerboards
  multigrid        geometric multigrid V-cycle on the structured grid
  transfer         its interpolation, restriction and Galerkin operator, node by node
  preconditioners  direct, multigrid, smoothed aggregation, deflation (build, then apply)
  linear           scipy's Krylov solvers around a reused preconditioner
  newton           safeguarded, capped Newton iteration
  loading          load stepping between snapshots, with its caps
  settings         every heuristic and cap in one object
  growth           `GrowthMechanics`: checks, load stepping, result
"""
from .settings import Settings, linear_solver_for

__all__ = ["GrowthMechanics", "MechanicsResult", "Settings", "linear_solver_for"]


def __getattr__(name: str):
    # the assembly and its solvers are imported when first asked for, not with the settings: a scene's
    # memory estimate (`linear_solver_for`) must not pay for scikit-fem's import
    if name in ("GrowthMechanics", "MechanicsResult"):
        from . import growth

        return getattr(growth, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
