"""Preconditioners for the tangent, apart from the Krylov loop: `build(A)`, then `M(r) ~ A^-1 r`.

* `Direct`: a sparse factorisation, PARDISO (pypardiso, symmetric
  indefinite, x86_64 wheels: the `pardiso` extra) or scipy's SuperLU
  without it (docs/install.md: what PARDISO gains).  Exact, but its
  cost grows like n^2 in 3-D: the choice for small problems only.
* `GeometricMultigrid`: `multigrid.Multigrid`, the default beyond
  `Settings.direct_limit` dofs.
* `SmoothedAggregation`: pyamg's smoothed-aggregation AMG with the rigid-body
  modes as near-null space; selectable for comparison (docs/mechanics.md).
* `Deflated`: a wrapper correcting the rigid-body modes exactly around any
  of the above (a balancing two-level step).

All are symmetric when A is, so CG may use them.  `build(A)` is the expensive
part; `prepare(A)`, where defined, adapts a built preconditioner cheaply to
another operator.
"""
from __future__ import annotations

import os

import numpy as np
import pyamg
import scipy.sparse as sp

from .multigrid import Multigrid, superlu
from .settings import linear_solver_for

try:  # PARDISO from PyPI wheels (x86_64, `pip install biostudy[pardiso]`); SuperLU without it
    import pypardiso
except ImportError:  # pragma: no cover - depends on the platform
    pypardiso = None


class Factoriser:
    """factor(A) -> solve(b): PARDISO's symmetric indefinite LDL^T if available, else SuperLU.

    Keeps one PARDISO handle and so one factorisation at a time: a new one
    replaces the last.  The handle is made with the factoriser, before the
    time loop: making it searches the environment's directories for MKL's
    library (pypardiso, unless PYPARDISO_MKL_RT names it), a second or more
    in a large environment that the first mechanics solve would otherwise
    carry, and a time-left estimate would take for the price of every solve.
    The library found is named in PYPARDISO_MKL_RT, so that the search is
    made once per process (and by none of the processes it starts)."""

    def __init__(self):
        self._pardiso, self._factored = None, False
        if pypardiso is not None:
            self._pardiso = pypardiso.PyPardisoSolver(mtype=-2)
            os.environ.setdefault("PYPARDISO_MKL_RT", self._pardiso.libmkl._name)

    def __call__(self, A: sp.spmatrix):
        if self._pardiso is None:
            return superlu(A)
        if self._factored:
            self._pardiso.free_memory()  # the last factors
        self._factored = True
        upper = sp.triu(A, format="csr")
        upper.sort_indices()
        self._pardiso.factorize(upper)
        return lambda b: self._pardiso.solve(upper, b)


def backend() -> str:
    return "pardiso" if pypardiso is not None else "superlu"


class Preconditioner:
    """What the tangent solver asks of a preconditioner: `build` for a new tangent, `constrain` when other
    dofs are held, `prepare` for an operator close to the built one, `detach` before the one it was built
    from is dropped, `release` when it will be rebuilt anyway, and `follow` for the rigid-body modes of the
    dense bodies (only a deflated preconditioner uses them: `uses_modes`)."""

    name = "preconditioner"
    uses_modes = False

    def build(self, A: sp.spmatrix):
        raise NotImplementedError

    def constrain(self, constrained: np.ndarray):
        raise NotImplementedError

    def prepare(self, A: sp.spmatrix):
        """Nothing to redo for another operator: the built preconditioner serves as it is."""

    def release(self):
        """Forget what `build` made (it will not be used again before the next `build`)."""

    def detach(self):
        """The tangent it was built from is about to be dropped by the solver (a newer one comes): keep what
        solving with the newer one needs, in less memory if possible."""

    def follow(self, modes: np.ndarray):
        """Nothing to do with the modes of the bodies (see `Deflated`)."""

    def __call__(self, r: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class Direct(Preconditioner):
    """Factor once, solve many."""

    def __init__(self):
        self.name = f"direct({backend()})"
        self._factorise = Factoriser()
        self._solve = None

    def build(self, A: sp.spmatrix):
        self._solve = self._factorise(A.tocsr())

    def release(self):
        self._solve = None

    def constrain(self, constrained: np.ndarray):
        pass  # the factors come from the (constrained) matrix itself

    def __call__(self, r: np.ndarray) -> np.ndarray:
        return self._solve(r)


class GeometricMultigrid(Preconditioner):
    """V-cycles on the grid's own coarse spaces; the coarsest level factorised."""

    def __init__(self, mesh, constrained: np.ndarray, coarsest: int, degree: int):
        self.cycle = Multigrid(mesh, constrained, coarsest=coarsest, degree=degree)
        self.name = f"multigrid({len(self.cycle.levels)} levels)"

    def build(self, A: sp.spmatrix):
        self.cycle.build(A)

    def release(self):
        self.cycle.release()

    def detach(self):
        self.cycle.detach()

    def constrain(self, constrained: np.ndarray):
        self.cycle.constrain(constrained)

    def __call__(self, r: np.ndarray) -> np.ndarray:
        return self.cycle(r)


class SmoothedAggregation(Preconditioner):
    """pyamg's smoothed aggregation, rigid-body modes (zero at constrained dofs) as near-null space."""

    def __init__(self, modes: np.ndarray, constrained: np.ndarray, ndim: int, coarsest: int):
        self.all_modes, self.d, self.coarsest = modes, ndim, coarsest
        self.name = "smoothed aggregation(pyamg)"
        self._cycle = None
        self.constrain(constrained)

    def constrain(self, constrained: np.ndarray):
        self.modes = np.where(np.asarray(constrained, bool)[:, None], 0.0, self.all_modes)

    def build(self, A: sp.spmatrix):
        hierarchy = pyamg.smoothed_aggregation_solver(
            A.tobsr(blocksize=(self.d, self.d)), B=self.modes, symmetry="symmetric",
            strength=("symmetric", {"theta": 0.0}), smooth=("jacobi", {"omega": 4.0 / 3.0}),
            presmoother=("block_gauss_seidel", {"sweep": "symmetric"}),
            postsmoother=("block_gauss_seidel", {"sweep": "symmetric"}),
            max_coarse=self.coarsest, coarse_solver="splu", keep=False)
        self._cycle = hierarchy.aspreconditioner(cycle="V")

    def release(self):
        self._cycle = None

    def __call__(self, r: np.ndarray) -> np.ndarray:
        return self._cycle @ r


class Deflated(Preconditioner):
    """Another preconditioner M with the rigid-body modes corrected exactly (balancing form):
    M_d = Z E^-1 Z^T + (I - Z E^-1 Z^T A) M (I - A Z E^-1 Z^T),  E = Z^T A Z.

    The modes left free by pinning single nodes of the soft void are the
    softest of the tangent; a preconditioner built from another tangent can
    leave errors in them that neither the residual nor the energy shows.  The
    Galerkin correction in span(Z) (Z the rigid-body modes, zero at constrained
    dofs) removes them before and after M, keeping symmetry."""

    uses_modes = True

    def __init__(self, inner):
        self.inner = inner
        self.name = f"deflated {inner.name}"
        self.Z = None  # orthonormal modes (dofs, k): `follow` sets them before `build` (they follow the biofilm)
        self._A = self._AZ = self._Einv = None

    def follow(self, modes: np.ndarray):
        self.Z = modes

    def build(self, A: sp.spmatrix):
        self.inner.build(A)
        self.prepare(A)

    def constrain(self, constrained: np.ndarray):
        self.inner.constrain(constrained)

    def release(self):
        self.inner.release()
        self._A = self._AZ = self._Einv = None

    def detach(self):
        self.inner.detach()
        self._A = None  # `prepare` gives the next operator before it is used

    def prepare(self, A: sp.spmatrix):
        """The exact part for operator A (k products with A); the inner preconditioner stays."""
        self._A = A
        self._AZ = np.asarray(A @ self.Z)
        self._Einv = np.linalg.pinv(self.Z.T @ self._AZ, rcond=1e-12)

    def __call__(self, r: np.ndarray) -> np.ndarray:
        Z, Einv = self.Z, self._Einv
        x = Z @ (Einv @ (Z.T @ r))
        x += self.inner(r - self._AZ @ (Einv @ (Z.T @ r)))
        return x + Z @ (Einv @ (Z.T @ (r - self._A @ x)))


def choose(method: str, n_dofs: int, mesh, constrained: np.ndarray, modes: np.ndarray, settings):
    """The preconditioner a `MechanicsSetup.linear_solver` names ("auto": by size), deflated if asked."""
    method = linear_solver_for(method, n_dofs, settings)
    if method == "direct":
        inner = Direct()
    elif method == "multigrid":
        inner = GeometricMultigrid(mesh, constrained, settings.coarsest, settings.smoothing)
    elif method == "amg":
        inner = SmoothedAggregation(modes, constrained, mesh.ndim, settings.coarsest)
    else:
        raise ValueError(f"unknown linear solver {method!r}")
    return Deflated(inner) if settings.deflate else inner
