"""biostudy's numerical core: Hamilton-principle biofilm growth (paper Eqs. 34-36).

A plain numerical library: numpy arrays and frozen dataclasses in, an
xarray.Dataset out.  FiPy builds the finite-volume operators of the
transport (phi, c, alpha); scikit-fem the growth mechanics (u, p).
Nothing here knows about files, schemas or command lines.
"""
from .errors import MechanicsError, SimulationError, StepFailure
from .problem import Grid, MechanicsSetup, Numerics, Parameters, Problem
from .timeloop import Progress, Run, Snapshot, evolve, simulate

__all__ = [
    "Grid", "Parameters", "Numerics", "MechanicsSetup", "Problem",
    "simulate", "evolve", "Run", "Snapshot", "Progress",
    "SimulationError", "MechanicsError", "StepFailure",
]
