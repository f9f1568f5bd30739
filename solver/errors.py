"""Failures the solver reports instead of returning garbage.

Every error names the simulated time, the cause and, where it has one, the
place (cell index in ``(z, y, x)`` order and its centre in µm).  A
`StepFailure` is recoverable (the time loop bisects the step); a
`SimulationError` ends the run.
"""
from __future__ import annotations

from typing import Any


class StepFailure(Exception):
    """One time step could not be taken at this step size (NaN, bounds, no convergence)."""

    def __init__(self, cause: str, where: str = ""):
        self.cause = cause
        self.where = where
        super().__init__(f"{cause}{' at ' + where if where else ''}")


class SimulationError(RuntimeError):
    """The run cannot continue: says when, what and where.

    What was computed before is not lost: the time loop attaches the last state it accepted (`last`, a
    `transport.State`), `Simulation` that state's fields (`stopped`, a `Snapshot` at the time it stopped) and
    `simulate` the dataset of every output made and that state (`partial`), for the caller to keep."""

    def __init__(self, time: float, cause: str, where: str = ""):
        self.time = float(time)
        self.cause = cause
        self.where = where
        self.last: Any = None  # transport.State
        self.stopped: Any = None  # snapshot.Snapshot
        self.partial: Any = None  # xarray.Dataset
        place = f" at {where}" if where else ""
        super().__init__(f"t = {self.time:.6g}: {cause}{place}")


class Runaway(SimulationError):
    """The fields outgrew what the solver can resolve (`transport.bounds.CEILING`): the expansion feedback of
    Eqs. 34 and 36 runs away."""


class MechanicsError(SimulationError):
    """Growth mechanics failed: det F <= 0, or no equilibrium within the solver's caps.

    `tried` counts what the snapshot's solve spent (load steps, Newton steps,
    Krylov iterations, preconditioner builds), so a caller can see the work
    was bounded."""

    def __init__(self, time: float, cause: str, where: str = "", tried: dict | None = None):
        super().__init__(time, cause, where)
        self.tried = dict(tried or {})


def describe_cell(index: tuple[int, ...], spacing: float) -> str:
    """'cell (z, y, x) = (..) at x = .. µm, ...' for messages."""
    names = "zyx"[3 - len(index):]
    centre = ", ".join(f"{a} = {(i + 0.5) * spacing:g} µm" for a, i in zip(names, index))
    return f"cell ({', '.join(names)}) = {tuple(int(i) for i in index)} ({centre})"
