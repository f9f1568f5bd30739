"""`biostudy show FILE` of one run at a glance: read with netCDF4 alone, no xarray, no solver.

A run's file (and a sweep's case file) holds its observables and lists them
in its ``observables`` attribute (`netcdf.with_observables`), so its summary
needs only the attributes and those time series: `show` of a small file
starts and ends in a fraction of a second.  The file is still read whole
first, checksums verified (`netcdf_io.intact`): a damaged file goes to the full
reader, which calls it damaged.  Anything else (a study.nc, a file written
before the observables were stored) goes there too.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from rich.console import Group

from ..data.netcdf import OBSERVABLES
from .show import ERROR, summary_of

Series = list[tuple[str, np.ndarray, dict]]  # observables: name, values over time, their attributes


def glance(path: str | Path) -> Group | None:
    """The summary of a run, a case or a failed case's record, or None when the full reader must do it."""
    found = read(path)
    return summary_of(*found) if found is not None else None


def read(path: str | Path) -> tuple[dict, np.ndarray | None, Series] | None:
    """A run's attributes, output times and observables, read with netCDF4 alone; None when the full reader
    must do it (not a run's file, observables not stored, damaged)."""
    from ..data.netcdf_io import (
        intact,  # lazily: only to tell a damaged file
        opened,
    )

    try:
        with opened(path) as nc:
            nc.set_auto_mask(False)
            attrs = {name: nc.getncattr(name) for name in nc.ncattrs()}
            if "biostudy_version" not in attrs or "sweep_mode" in attrs:
                return None
            if attrs.get("status") == "failed" and not nc.variables:
                return attrs, None, []
            names = [n.strip() for n in str(attrs.get(OBSERVABLES, "")).split(",") if n.strip()]
            if not names or "time" not in nc.variables or any(n not in nc.variables for n in names):
                return None
            times = np.asarray(nc["time"][:], dtype=float).ravel()
            series = []
            for name in names:
                var = nc[name]
                values = np.asarray(var[:], dtype=float).reshape(-1)
                if values.shape != times.shape:
                    return None
                shown = {key: var.getncattr(key) for key in var.ncattrs()}
                if f"{name}_error" in nc.variables:  # error bars (`--error-estimate`)
                    shown[ERROR] = np.asarray(nc[f"{name}_error"][:], dtype=float).reshape(-1)
                series.append((name, values, shown))
    except (OSError, RuntimeError, ValueError, KeyError, AttributeError):
        return None
    return (attrs, times, series) if intact(path) else None
