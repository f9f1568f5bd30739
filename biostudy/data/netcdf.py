"""How datasets are laid out in their netCDF files: compression, chunks, history; a case file read as a run.

* `encoding`: what `writing.write_atomic` passes to ``to_netcdf``.  Fields are
  zlib-compressed with the shuffle filter, one snapshot per chunk (length 1
  along time, time_mechanics and a study's dimensions, whole along x, y, z and
  the nodes), so reading one time of one case reads one chunk; masks and bounds
  are compressed whole; time series and scalars are not compressed (too small
  to gain).  Every numeric variable of more than one value carries a fletcher32
  checksum per chunk (so `netcdf_io.intact` tells a damaged file from a good one;
  HDF5 filters need chunked storage, so only scalars and strings stay
  contiguous).  Coordinates have no ``_FillValue`` (CF 2.5.1).  Text (a case
  file's status, message and case id, study coordinates such as ``case``) is
  written as characters (CF 2.2), not as variable-length strings: reading
  those through a second handle of a file held open in the same process
  (a case open in a notebook while a sweep resumes, which reads every finished
  case back) corrupts HDF5's state and crashes a later open (HDFGroup/hdf5#5359,
  Unidata/netcdf-c#2510).  Measured in docs/results.md.
* `history`: the CF ``history`` attribute, the command line that made the file
  (or the Python call, inside `called`: the API's, not a notebook kernel's argv).
* `with_observables`: a run's dataset with every observable as a variable,
  listed in its ``observables`` attribute, so that `show` reads them from the
  file without computing anything (`reports.glance`).
* `as_run`: a sweep's case file carries its place in the study as dimensions of
  length 1 (`combine.CaseLayout`, so that ``xr.open_mfdataset`` combines the
  cases by itself); read as one run, they are squeezed to scalar coordinates.
  A file written before takes today's names and unit spellings (`renamed`: 'um3' is 'um^3').
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import shlex
import sys
from contextvars import ContextVar
from pathlib import Path
from typing import TYPE_CHECKING, Iterator

if TYPE_CHECKING:
    import xarray as xr  # the functions here take datasets; importing this module costs nothing (`show`)

COMPRESSION = {"zlib": True, "complevel": 4, "shuffle": True}
# Dimensions a snapshot spans whole; every other dimension (time, time_mechanics, a study's) is cut in 1s.
SNAPSHOT_DIMS = frozenset({"x", "y", "z", "x_node", "y_node", "z_node", "component", "bounds"})
CASE_DIMENSIONS = "case_dimensions"  # attribute of a case file: its study dimensions (length 1)
OBSERVABLES = "observables"  # attribute of a run's or case's file: the observables it holds, in order
OLD_NAMES = {"steps_bisections": "steps_bisected"}  # a run's variables as named before issue 11


def encoding(ds: xr.Dataset) -> dict[str, dict]:
    """Per-variable netCDF encoding of `ds` (replacing what its variables carry from files they were read
    from, whose chunks may not fit the new shapes)."""
    result = {}
    for name, var in ds.variables.items():
        if name in ds.coords:
            result[name] = {"_FillValue": None}
        elif var.dtype.kind in "fiu" and set(var.dims) & SNAPSHOT_DIMS:
            chunks = tuple(size if dim in SNAPSHOT_DIMS else 1 for dim, size in zip(var.dims, var.shape))
            result[name] = {**COMPRESSION, "chunksizes": chunks}
        else:
            result[name] = {key: var.encoding[key] for key in ("_FillValue", "dtype") if key in var.encoding}
        if var.ndim and var.size > 1 and var.dtype.kind in "biuf":
            result[name].update(fletcher32=True, contiguous=False)
        if var.dtype.kind in "OUS" and var.size and all(isinstance(v, str) for v in var.values.ravel()):
            result[name]["dtype"] = "S1"  # characters, not variable-length strings (see above)
    return result


_CALL: ContextVar[str | None] = ContextVar("biostudy_call", default=None)


@contextlib.contextmanager
def called(call: str) -> Iterator[None]:
    """Within the block, files record `call` as what made them (e.g. "biostudy.run('directional')"), not the
    process's command line."""
    token = _CALL.set(call)
    try:
        yield
    finally:
        _CALL.reset(token)


def made_by(argv: list[str] | None = None) -> str:
    """What makes a file: 'biostudy run directional -o d.nc', the command line of this process (`python -m
    biostudy` is written as biostudy), or the Python call inside `called`; a worker writing a case file is told
    it by the sweep's process (`execution.worker.Task`)."""
    if argv is None and _CALL.get() is not None:
        return str(_CALL.get())
    argv = list(sys.argv if argv is None else argv) or ["python"]
    program = Path(argv[0]).name
    if Path(argv[0]).parts[-2:] == ("biostudy", "__main__.py"):
        program = "biostudy"
    return shlex.join([program, *argv[1:]])


def history(argv: list[str] | None = None) -> str:
    """'2026-01-31T12:00:00Z: biostudy run directional -o d.nc': when, and what made the file (`made_by`; CF
    2.6.2)."""
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    return f"{stamp}: {made_by(argv)}"


def renamed(ds: xr.Dataset) -> xr.Dataset:
    """A dataset written before a variable was renamed, or before units were spelled for pint too ('um3', 'um-1'),
    with today's names and spellings (`formatting.current_units`)."""
    from ..formatting import current_units

    old = {name: new for name, new in OLD_NAMES.items() if name in ds.variables and new not in ds.variables}
    ds = ds.rename(old) if old else ds
    spelled = {name: current_units(str(var.attrs["units"])) for name, var in ds.variables.items()
               if "units" in var.attrs and current_units(str(var.attrs["units"])) != str(var.attrs["units"])}
    if not spelled:
        return ds
    ds = ds.copy(deep=False)
    for name, units in spelled.items():
        ds.variables[name].attrs = {**ds.variables[name].attrs, "units": units}
    return ds


def as_run(ds: xr.Dataset) -> xr.Dataset:
    """A sweep's case file as one run: its study dimensions (length 1) squeezed into scalar coordinates.
    Any other dataset is returned as it is (with today's names)."""
    ds = renamed(ds)
    dims = [d.strip() for d in str(ds.attrs.get(CASE_DIMENSIONS, "")).split(",") if d.strip()]
    dims = [d for d in dims if ds.sizes.get(d) == 1]
    return ds.squeeze(dims) if dims else ds


def with_observables(ds: xr.Dataset) -> xr.Dataset:
    """A run's dataset with every observable its fields give as a variable (those it has are kept), listed in
    its ``observables`` attribute in the registry's order (`quantities.observables`): the file says what it
    holds, and `show` reads them without computing anything (`reports.glance`)."""
    from ..quantities import observables  # lazily: scipy and xarray only where a run's dataset is made

    found = [name for name, observable in observables.REGISTRY.items() if observables.available(ds, observable)]
    ds = ds.assign(observables.variables(ds, names=[name for name in found if name not in ds]))
    ds.attrs[OBSERVABLES] = ", ".join(found)
    return ds
