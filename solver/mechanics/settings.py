"""Every heuristic of the mechanics solve in one place, with the reason for its value.

`MechanicsSetup` (solver.problem) holds what a scene chooses (boundary
conditions, tolerance, which pressure, which preconditioner); `Settings`
holds how hard and how long the solver tries.  Every loop below has a cap,
so a snapshot ends, solved or with a `MechanicsError`, after a bounded
amount of work: at most ``max_load_steps`` Newton solves of at most
``max_newton_iterations`` steps each (and ``max_total_newton`` in all), each
step at most ``max_krylov`` Krylov iterations (``krylov_budget`` in all) and
``max_halvings + 1`` residual evaluations, and at most ``max_builds``
preconditioner builds.  Tests and benchmarks pass their own `Settings`;
measurements behind the defaults are in docs/mechanics.md.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Settings:
    # -- load stepping (growth.py, loading.py) ---------------------------------------------
    smallest_load_step: float = 1.0 / 64  # of the way between two snapshots; below it: refused
    max_load_steps: int = 24  # Newton solves per snapshot, failed ones included
    max_total_newton: int = 80  # Newton steps per snapshot over all load steps

    pin_in_biofilm: bool = True  # rigid-body pins in the stiffest biofilm, not at the corner (constraints.py)

    # -- Newton (newton.py) ------------------------------------------------------------------
    max_halvings: int = 8  # backtracking: step lengths 1, 1/2, ..., 1/256
    armijo: float = 1e-4  # sufficient energy decrease
    retangent: float = 0.1  # keep the operator while every step cuts |R| tenfold, else reassemble it
    forcing_min: float = 1e-8  # below it the Krylov residual stagnates in round-off
    forcing_max: float = 0.1  # a step that solves its linear system to less than this is not Newton's
    forcing_first: float = 1e-3  # the first step's forcing when no contraction has been seen yet
    forcing_safety: float = 0.5  # no linear solve aims below safety * tolerance * |R_ref|

    # -- Krylov (linear.py) ------------------------------------------------------------------
    krylov: str = "cg"  # scipy's CG; GMRES (restarted) when CG fails, e.g. on an indefinite tangent
    max_krylov: int = 150  # iterations per linear solve (each Krylov method)
    krylov_budget: int = 1500  # iterations per snapshot
    gmres_restart: int = 50
    rebuild_after: int = 25  # a stale preconditioner is rebuilt when the solve needs more than this
    accept_inexact: float = 0.1  # a solve that missed its tolerance still counts if it cut |r| 10x
    max_builds: int = 12  # preconditioner builds per snapshot

    # -- preconditioners (preconditioners.py, multigrid.py) ----------------------------------
    direct_limit: int = 6_000  # "auto": a factorisation up to this many dofs, multigrid beyond
    coarsest: int = 1_000  # multigrid: factorise the first level with at most this many dofs (3-D fill)
    smoothing: int = 3  # multigrid: degree of the Chebyshev smoother before and after the coarse correction
    deflate: bool = False  # solve the rigid motions of floating dense bodies exactly (constraints.body_modes)

    # -- assembly and machine --------------------------------------------------------------
    chunk: int = 2048  # cells assembled at once (whole grid planes or rows of one): bounds the temporaries,
    # which `biostudy.inputs.resources` counts per cell; smaller boxes cost more Python per assembly
    blas_threads: int | None = 1  # BLAS threads during a solve (None: the library's default): the
    # products here are small or tall and thin, and on busy cores threads cost more than they
    # bring (docs/mechanics.md)


DEFAULT = Settings()


def linear_solver_for(method: str, n_dofs: int, settings: Settings | None = None) -> str:
    """The preconditioner a `MechanicsSetup.linear_solver` choice means for `n_dofs` unknowns: "auto" is a
    factorisation up to `Settings.direct_limit` dofs, multigrid beyond; any other choice is itself."""
    if method != "auto":
        return method
    return "direct" if n_dofs <= (settings or Settings()).direct_limit else "multigrid"
