"""The real-time coordinates of a dataset whose scene gives ``[time] t_ref`` (docs/time.md).

`time` stays T*; ``time_real`` is a non-dimension coordinate along it (and
``time_mechanics_real`` along ``time_mechanics``) in the unit t_ref was written
in, with a udunits unit of time ("hours"): pint (pint-xarray, cf_xarray)
reads it as a time.  It has no ``standard_name = "time"``: CF's checker then
demands "hours since <epoch>" (§3.1, §4.4), and an epoch would make xarray
decode the coordinate into calendar dates a simulation does not have; an
elapsed time is a duration, which a plain unit of time says.  A dataset without a ``t_ref``
attribute is returned as it is.  `shown` (`inputs.real_time`) gives what
tables, plots and exports print: the real time with its unit when there is
one, else T*.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import InvalidAt
from ..inputs.real_time import clock, parse_time, shown

__all__ = ["clock", "shown", "t_star", "with_real_time"]

if TYPE_CHECKING:
    import xarray as xr

REAL = {"time": "time_real", "time_mechanics": "time_mechanics_real"}


def with_real_time(ds: xr.Dataset) -> xr.Dataset:
    """`ds` with time_real (and time_mechanics_real) from its ``t_ref`` attribute; unchanged without one."""
    found = clock(ds)
    if found is None:
        return ds
    coords = {}
    for dim, name in REAL.items():
        if dim in ds.dims:
            coords[name] = (dim, found.real(np.asarray(ds[dim].values, float)),
                            {"units": found.cf, "long_name": f"real time t = T* t_ref (t_ref = {found.text}), "
                                                             "since the start of the run"})
    return ds.assign_coords(coords)


def t_star(ds: xr.Dataset | dict, given: str | float, option: str = "--time") -> float:
    """A time a user asked for, as T*: a plain number is T*; a time with a unit ("12 h") is read with the
    dataset's t_ref.  ValueError (one line) for a real time the dataset has no t_ref for, or not a time."""
    if isinstance(given, (int, float)):
        return float(given)
    try:
        return float(given)
    except ValueError:
        pass
    found = clock(ds)
    if found is None:
        raise ValueError(f"{option} {given!r}: the dataset is in T* alone (its scene has no [time] t_ref); give T*, "
                         "e.g. 0.25")
    try:
        asked = parse_time(given, option)
    except InvalidAt as error:
        raise ValueError(f"{option}: {error.problem}; give T* (0.25) or a real time (12 h)") from None
    reference = parse_time(found.text, "t_ref")
    return float((asked / reference).to("dimensionless").magnitude)
