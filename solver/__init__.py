"""biostudy's numerical core: Hamilton-principle biofilm growth (paper Eqs. 34-36).

A plain numerical library: numpy arrays and frozen dataclasses in, an
xarray.Dataset out.  FiPy builds the finite-volume operators of the
transport (phi, c, alpha); scikit-fem the growth mechanics (u, p).
Nothing here knows about files, schemas or command lines.
"""
import os

os.environ.setdefault("FIPY_SOLVERS", "scipy")

from .errors import MechanicsError, SimulationError, StepFailure  # noqa: E402
from .problem import Grid, MechanicsSetup, Numerics, Parameters, Problem  # noqa: E402
from .timeloop import Progress, Run, Snapshot, evolve, simulate  # noqa: E402

__all__ = [
    "Grid", "Parameters", "Numerics", "MechanicsSetup", "Problem",
    "simulate", "evolve", "Run", "Snapshot", "Progress",
    "SimulationError", "MechanicsError", "StepFailure",
]
