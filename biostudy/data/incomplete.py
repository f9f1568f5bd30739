"""A run that stopped keeps what it computed: its dataset, marked incomplete.

When a simulation stops (`solver.SimulationError`: a runaway, a step bisected below its smallest, a mechanics
solve refused), the solver hands back the dataset of every output it made and of the state where it stopped
(`partial`).  `biostudy run` writes it to the run's output as it would a finished run's (atomically, the same
observables), with the attribute `incomplete` saying when and why it stopped; `show` prints it, and `run
--continue` refuses to go on from it (its last output lies before its t_end).
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # `show` reads INCOMPLETE at a glance, without xarray (reports.glance)
    import xarray as xr

INCOMPLETE = "incomplete"  # the attribute: why the run stopped where it did


def marked(ds: xr.Dataset, why: str) -> xr.Dataset:
    """`ds` (a stopped run's partial dataset) with the attribute saying it is incomplete, and why."""
    last = float(ds["time"].values[-1])
    return ds.assign_attrs({INCOMPLETE: f"the run stopped at T* = {last:.6g}, before its end: {why}"})


def kept(ds: xr.Dataset, target: Path) -> str:
    """What the message of a stopped run adds: where its outputs went."""
    times = ds["time"].values
    return (f"wrote the {len(times)} output{'s' if len(times) != 1 else ''} computed up to T* = {times[-1]:.6g} to "
            f"{target} (marked incomplete)")
