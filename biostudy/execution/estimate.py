"""The error estimate of a run: its companions run here, one after the other, and the error bars made of them.

`plans.companions` says which companions a scene has (or why one cannot be
made); each runs in this process as a run would (`worker.solve`: a failure is a
reason, not an exception) and is finished as a run's dataset is (`data.finish`:
stamped, its observables, its alerts); `quantities.error_bars` turns them into one ``Q_error`` per
observable of the run.  What the companions cost (their wall time, set-up
included) is recorded beside the run's own: ``error_estimate_wall_time`` and
``error_estimate_cost`` (its ratio to the run's wall time).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import xarray as xr

from ..data.finish import Record, finish
from ..inputs.scene import Scene
from ..plans import companions
from ..quantities import error_bars
from . import worker


@dataclass
class Estimate:
    """Error bars of a run: the ``Q_error`` variables and the dataset attributes saying how they were made."""

    variables: dict[str, xr.DataArray]
    attrs: dict[str, str | float]
    runs: dict[str, xr.Dataset] = field(default_factory=dict)  # the companions that ran, by name
    notes: dict[str, str] = field(default_factory=dict)  # what each companion ran, or why it did not

    def applied(self, ds: xr.Dataset) -> xr.Dataset:
        """`ds` with the error variables and attributes (replacing earlier ones)."""
        out = ds.assign(self.variables)
        out.attrs.update(self.attrs)
        return out


def measured(scene: Scene, file: str | Path, threads: int | None = None) -> xr.Dataset | str:
    """One companion run with its observables (a dataset), or the reason it failed (`threads`: the run's)."""
    outcome = worker.solve(worker.with_threads(scene.problem(), threads=threads))
    if outcome.status != "done" or outcome.dataset is None:
        return f"failed: {outcome.message}"
    return finish(outcome.dataset, Record.of(scene, file, ""))


def estimate(scene: Scene, file: str | Path, ds: xr.Dataset, announce: Callable[[str], None] | None = None,
             threads: int | None = None) -> Estimate:
    """The error estimate of `ds`, the run of `scene`: its companions run here (`announce` hears of each), on
    `threads` as the run was (``--threads``)."""
    began = time.perf_counter()
    notes, runs = {}, {}
    for planned in companions.plan(scene, file):
        name = planned.companion.name
        notes[name] = planned.describe()
        if planned.scene is None:
            continue
        if announce is not None:
            announce(notes[name])
        found = measured(planned.scene, file, threads)
        if isinstance(found, str):
            notes[name] = f"{notes[name]}: {found}"
            continue
        runs[name] = found
    variables, attrs = error_bars.estimate(ds, runs, notes, scene.numerics.advection)
    seconds = time.perf_counter() - began
    attrs = {**attrs, "error_estimate_wall_time": seconds,
             "error_estimate_cost": seconds / float(ds.attrs["wall_time"]) if ds.attrs.get("wall_time") else
             float("nan")}
    return Estimate(variables, attrs, runs, notes)
