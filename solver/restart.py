"""Continuing a run: its last state read back from its dataset, and the two histories joined into one.

`start_state(ds)` is what `Problem` needs to go on where a finished run
stopped (``dataclasses.replace(problem, **start_state(ds))``): the time of its
last output, phi, alpha and c there, the displacement the mechanics last
converged to (the last output always has it) and the clock's step.  The
fields are the float64 values the run wrote, so a run continued from its
file takes the same steps from the same state as a run straight to the later
end: the fields agree to the linear solvers' tolerances (the nutrient's AMG
hierarchy is built afresh at the start instead of being reused from earlier
steps; the mechanics starts from the same u, and its Newton iterations agree to
their tolerance).

`joined(before, after)` is the whole history: the outputs of both along
``time`` (and ``time_mechanics``), the step counters and the elapsed time of
the continuation counted on from the first run's, and the run's counters
added up (`counters.LARGEST` the larger of both, `counters.LAST` the
continuation's).
"""
from __future__ import annotations

import numpy as np
import xarray as xr

from .counters import LARGEST, LAST, MEANINGS

MECHANICS_TIME = "time_mechanics"
COUNTED = ("steps_taken", "steps_bisected", "steps_rejected")  # time series of counts since the start


def _cells(da: xr.DataArray) -> np.ndarray:
    """A cell field as the solver holds it: (z, y, x) / (y, x), obstacles (NaN) as 0."""
    return np.nan_to_num(da.transpose(*[d for d in ("z", "y", "x") if d in da.dims]).values.astype(float))


def start_state(ds: xr.Dataset) -> dict:
    """The fields of `Problem` that continue the run of `ds` from its last output."""
    last = ds.isel(time=-1)
    start = float(ds["time"].values[-1])
    state: dict[str, object] = {"start_time": start, "phi0": _cells(last["phi"]),
             "alpha0": _cells(last["alpha"]), "c0": _cells(last["c"])}
    if "next_step" in ds.attrs:
        state["first_step"] = float(ds.attrs["next_step"])
    if float(ds.attrs.get("step_limit", 0.0)) > 0:
        state["step_limit"] = float(ds.attrs["step_limit"])
    if "u" in ds and MECHANICS_TIME in ds.dims and ds[MECHANICS_TIME].size \
            and np.isclose(float(ds[MECHANICS_TIME].values[-1]), start):
        u = ds["u"].isel({MECHANICS_TIME: -1})
        nodes = [f"{a}_node" for a in ("z", "y", "x") if f"{a}_node" in u.dims]
        state["u0"] = np.nan_to_num(u.transpose(*nodes, "component").values.astype(float))
    return state


def _along(before: xr.DataArray, after: xr.DataArray, dim: str) -> xr.DataArray:
    return xr.concat([before.drop_vars([c for c in before.coords if c != dim and c not in after.coords]),
                      after], dim=dim, join="exact", combine_attrs="override")


def joined(before: xr.Dataset, after: xr.Dataset) -> xr.Dataset:
    """One dataset of the whole history: `before` (the run continued) and `after` (its continuation, which
    starts after before's last output).  Variables are after's; counters add up (module docstring)."""
    if float(after["time"].values[0]) <= float(before["time"].values[-1]):
        raise ValueError("the continuation must start after the last output of the run it continues")
    series = {}
    for name, var in after.data_vars.items():
        timed = [d for d in (*("time",), MECHANICS_TIME) if d in var.dims]
        if not timed:
            continue
        if name not in before or set(before[name].dims) != set(var.dims):
            raise ValueError(f"the run continued has no {name} on {', '.join(map(str, var.dims))}")
        first = before[name].transpose(*var.dims)
        if name in COUNTED:
            var = var + int(first.values[-1])
        elif name == "elapsed":
            var = var + float(first.values[-1])
        series[name] = _along(first, var.assign_attrs(after[name].attrs), timed[0])
    whole = after.drop_vars(list(series)).drop_dims([d for d in ("time", MECHANICS_TIME) if d in after.dims])
    whole = whole.assign(series)
    for coordinate in ("time", MECHANICS_TIME):
        if coordinate in whole.coords:
            whole[coordinate].attrs = after[coordinate].attrs
    attrs = dict(after.attrs)
    for name in MEANINGS:
        if name in LAST or name not in attrs or name not in before.attrs:
            continue
        mine, theirs = attrs[name], before.attrs[name]
        attrs[name] = max(mine, theirs) if name in LARGEST else mine + theirs
    for name in [n for n in attrs if n == "wall_time" or n.startswith("wall_time_")]:
        attrs[name] = float(attrs[name]) + float(before.attrs.get(name, 0.0))
    whole.attrs = attrs
    return whole
