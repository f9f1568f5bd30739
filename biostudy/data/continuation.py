"""`biostudy run SCENE --continue RUN.nc`: the run a scene goes on from, checked, and the whole history written.

The run continued must be a finished run of the same scene: the same
everything but the clock (``[time]``: a later ``t_end``, other steps or
outputs), and its name and description; a failed case's record, a run that
stopped before its own ``t_end``, one of another scene, or a file that lacks
what the continuation's history joins to (the fields, the time series every
run writes, the mechanics of a scene that has it) is bad input, told in one
line before anything is computed.  A sweep's case file is a run
(`netcdf.as_run`) that keeps its accepted steps as a total, not a series
(`combine.CaseLayout`): its outputs before the last count NaN steps, not
made-up ones.  The dataset written is the whole history: the run's outputs
up to its last one, then the continuation's (`solver.restart.joined`), and
its attributes say so (``continued_from``, ``continuation``; ``history``
keeps the run's own lines before this one, CF 2.6.2).
"""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import xarray as xr

from solver.restart import joined
from solver.series import SERIES as RECORDED

from ..errors import BadInput
from ..formatting import value_text
from ..inputs.keys import flatten
from ..inputs.scene import Scene
from . import reading

FREE = ("name", "description")  # besides [time]: what a continuation may change
FIELDS = ("phi", "c", "alpha")  # on time and the cells: the state a continuation starts from
SERIES = (*(series.name for series in RECORDED), "steps_taken", "steps_bisected", "steps_rejected",
          "elapsed")  # on time: what every run writes (solver.output)


def _differences(recorded: dict, scene: dict) -> list[str]:
    """'key: here X, in the run Y' for every scene key (but the clock and the names) that differs."""
    mine = {k: v for k, v in flatten(scene).items() if not k.startswith("time.") and k not in FREE}
    theirs = {k: v for k, v in flatten(recorded).items() if not k.startswith("time.") and k not in FREE}
    return [f"{key}: {value_text(mine.get(key, '(absent)'))} here, {value_text(theirs.get(key, '(absent)'))} in "
            f"the run" for key in sorted(set(mine) | set(theirs)) if mine.get(key) != theirs.get(key)]


def _with_step_series(ds: xr.Dataset) -> xr.Dataset:
    """A case file's total of accepted steps as a series on time: NaN before the last output, the total there."""
    total = ds.get("steps_taken")
    if total is None or "time" in total.dims or total.ndim:
        return ds
    series = np.full(ds.sizes["time"], np.nan)
    series[-1] = float(total)
    return ds.assign(steps_taken=("time", series, {**total.attrs, "comment": "a case file keeps only the total "
                                                   "of the run continued: its earlier outputs' counts are unknown"}))


def _lacking(ds: xr.Dataset, scene: Scene) -> list[str]:
    """'NAME on DIMS' for every variable the continuation's history joins to that `ds` lacks (or has on other
    dimensions)."""
    cells = ("z", "y", "x")[-len(scene.grid.shape):]
    wanted = {name: {"time", *cells} for name in FIELDS} | {name: {"time"} for name in SERIES}
    if scene.mechanics is not None and scene.mechanics.enabled:
        nodes = {f"{a}_node" for a in cells}
        wanted |= {"p": {"time_mechanics", *cells}, "u": {"time_mechanics", *nodes, "component"},
                   "newton_iterations": {"time_mechanics"}}
    return [f"{name} on {', '.join(sorted(dims))}" for name, dims in wanted.items()
            if name not in ds or set(ds[name].dims) != dims]


def previous_run(path: str | Path, scene: Scene) -> xr.Dataset:
    """The finished run of `scene` that a continuation starts from, open and read lazily (its outputs one at a
    time as the history is written again: `reading.open_dataset`; close() it after); `BadInput` (naming
    RUN.nc) for anything else: not a run, a failed case, an unfinished run, a run of another scene, a t_end not
    after its end."""
    path = Path(path)
    ds = reading.open_result(path, ("run",), "--continue starts from a finished run's last state", lazy=True)
    try:
        return _checked(ds, path, scene)
    except BadInput:
        ds.close()
        raise


def _checked(ds: xr.Dataset, path: Path, scene: Scene) -> xr.Dataset:
    attrs = ds.attrs
    last = float(ds["time"].values[-1])
    if str(attrs.get("status", "done")) != "done" or last < float(attrs.get("t_end", last)) * (1 - 1e-12):
        raise BadInput(f"an unfinished run (its last output is T* = {last:g}, its t_end {attrs.get('t_end')}): "
                       "--continue starts from a finished run", path)
    try:
        recorded = tomllib.loads(str(attrs.get("scene", "")))
    except tomllib.TOMLDecodeError:
        recorded = {}
    if not recorded:
        raise BadInput("records no scene (its `scene` attribute is missing or unreadable): cannot tell whether it "
                       "is a run of this scene", path)
    differ = _differences(recorded, scene.model_dump(mode="json", exclude_none=True))
    if differ:
        count = f"{len(differ)} {'keys differ' if len(differ) > 1 else 'key differs'}"
        raise BadInput(f"a run of another scene ({count} besides [time]: {'; '.join(differ[:3])}"
                       f"{'; ...' if len(differ) > 3 else ''}); --continue takes a run of the same scene", path)
    if not scene.time.t_end > last:
        raise BadInput(f"must be after the last output of the run it continues, T* = {last:g} (got "
                       f"{scene.time.t_end:g}); give e.g. --set time.t_end={2 * last:g}", None, "time.t_end")
    ds = _with_step_series(ds)
    lacking = _lacking(ds, scene)
    if lacking:
        raise BadInput(f"lacks {'; '.join(lacking[:3])}{'; ...' if len(lacking) > 3 else ''} (damaged or edited): "
                       "--continue joins its history to the continuation's", path)
    return ds


def continued(previous: xr.Dataset, path: str | Path, continuation: xr.Dataset) -> xr.Dataset:
    """The whole history of `previous` (read from `path`) and its `continuation`, marked as such."""
    whole = joined(previous, continuation)
    start = float(previous["time"].values[-1])
    whole.attrs.update({
        "continued_from": f"{Path(path).resolve()} (T* = {start:g}; created {previous.attrs.get('created', '?')})",
        "continuation": f"whole history: outputs up to T* = {start:g} are those of the run continued, later ones "
                        "this run's; the counters and wall times add up both",
        "history_before": str(previous.attrs.get("history", "")),
    })
    return whole
