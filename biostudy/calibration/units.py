"""The units of estimated parameters in calibration.nc, calibration.md and the fit's figures (issue 26.1).

A parameter has the model's units (`solver.problem.parameter_infos`: r is
µm/T*, g 1/T*, d µm²/T*).  Variables along `parameter` mix units, so they
carry none (a units of "1" made pint read r as dimensionless); the `units`
coordinate gives each one's udunits spelling and `units_model` its model units
(µm/T*), which tables and axes show.  What pint reads is one scalar variable
per parameter and end: ``estimate_r``, ``lower_r``, ``upper_r`` (and the
posterior's ``median_r``, ...) in udunits ("um": T* is dimensionless, the long
name says µm/T*), and, when the calibration has a t_ref, a rate per T* also per
unit of real time: ``estimate_r_real`` in "um/h" (r / t_ref).
"""
from __future__ import annotations

import numpy as np

from solver.output import cf_units

from ..formatting import number, units_text
from ..inputs.real_time import RealTime, real_time
from ..inputs.scene import key_info

PER_T_STAR = "/T*"
MIXED = {"comment": "each in its own units: see the units (udunits) and units_model coordinates, or the scalar "
                    "variables per parameter (estimate_NAME, ...)"}


def model_units(key: str) -> str:
    """A scene key's units in the model's spelling ('um/T*')."""
    return key_info(key)[1]


def clock_of(plan) -> RealTime | None:
    """A calibration's real time (`problem.CalibrationPlan`): its table's t_ref, else its scene's
    (they agree: `real_time.check_agree`)."""
    text = plan.spec.data.t_ref or plan.base.time.t_ref
    return real_time(text) if text else None


def per_real_time(units: str, clock: RealTime) -> tuple[str, float] | None:
    """A rate per T* as a rate per unit of real time: ('um/h', 1 / 48) for 'um/T*' with t_ref = 48 h; None for
    a unit that is not per T*."""
    if not units.endswith(PER_T_STAR):
        return None
    return f"{units[:-len(PER_T_STAR)]}/{clock.unit}", 1.0 / clock.t_ref


def scalar_variables(names: list[str], keys: list[str], ends: dict[str, tuple[np.ndarray, str]],
                     clock: RealTime | None) -> dict:
    """One scalar variable per parameter and end (`ends`: prefix -> (values along `parameter`, what it is)), in
    udunits; with a clock, rates per T* also per unit of real time (suffix _real)."""
    found = {}
    for j, (name, key) in enumerate(zip(names, keys)):
        units = model_units(key)
        real = per_real_time(units, clock) if clock is not None else None
        for prefix, (values, what) in ends.items():
            value = float(values[j])
            found[f"{prefix}_{name}"] = ((), value, {"units": cf_units(units),
                                                     "long_name": f"{name}: {what} [{units}]"})
            if real is not None:
                found[f"{prefix}_{name}_real"] = ((), value * real[1], {
                    "units": real[0], "long_name": f"{name}: {what}, per {clock.unit} (t_ref = {clock.text})"})
    return found


def shown(ds, j: int) -> str:
    """A parameter's units as tables and axes show them: the model's ('µm/T*'), else udunits' (older files)."""
    coordinate = "units_model" if "units_model" in ds.coords else "units"
    return units_text(str(ds[coordinate].values[j]))


def real_rows(ds, ends: tuple[str, str, str] = ("estimate", "lower", "upper"), value: str = "estimate",
              interval: str = "95 % profile interval") -> list[str]:
    """calibration.md's rates in real time (a calibration with t_ref): one row per rate per T* (`ends`: the
    prefixes of the value and the interval's ends)."""
    rows = []
    for name in ds.parameter.values:
        middle, low, high = (f"{end}_{name}_real" for end in ends)
        if middle not in ds:
            continue
        units = units_text(ds[middle].attrs["units"])
        ends_shown = f"[{number(float(ds[low]))}, {number(float(ds[high]))}]" if np.isfinite(float(ds[low])) else "-"
        rows.append(f"| {name} | {number(float(ds[middle]))} {units} | {ends_shown} |")
    if not rows:
        return []
    return ["", f"Rates in real time (t_ref = {ds.attrs.get('t_ref')}):", "",
            f"| parameter | {value} | {interval} |", "|---|---|---|", *rows]
