"""biostudy's numerical core: Hamilton-principle biofilm growth (paper Eqs. 34-36).

A plain numerical library: numpy arrays and frozen dataclasses in, an
xarray.Dataset out.  FiPy builds the finite-volume Laplacian of the
transport once per run; scikit-fem supplies the Q1 reference element of the
growth mechanics; the rest (advection, assembly, time loop, every linear
solver) is written here, for speed (docs/transport.md, docs/mechanics.md).
The equations and where they depart from the paper: docs/model.md.
Nothing here knows about files, schemas or command lines.
"""
from .errors import MechanicsError, SimulationError, StepFailure
from .laws import Laws
from .problem import Grid, MechanicsSetup, Numerics, Parameters, Problem

_TIMELOOP = ("Progress", "Simulation", "Snapshot", "evolve", "simulate")


def __getattr__(name: str):
    # the time loop (and with it FiPy and the transport) is imported when first used, not with the problem's
    # description: a scene's validation or `biostudy show` do not pay for it
    if name in _TIMELOOP:
        from . import timeloop

        return getattr(timeloop, name)
    raise AttributeError(f"module 'solver' has no attribute {name!r}")


__all__ = [
    "Grid", "Parameters", "Laws", "Numerics", "MechanicsSetup", "Problem",
    "simulate", "evolve", "Simulation", "Snapshot", "Progress",
    "SimulationError", "MechanicsError", "StepFailure",
]
