"""A study's case files read for combining into study.nc (`combine`): what is small at once, the fields lazily.

Each case file is opened for its attributes and every variable without a spatial dimension (the observables and
other time series, the parameters, the coordinates), read then; it is closed again before the next is opened.  The
variables with a spatial dimension (the fields phi, c, alpha, u, p, the masks) become dask arrays whose reads open
the file, read them (all at once, or in blocks along their first dimension for a case larger than `AT_ONCE`) and
close it, when they are computed: no case file stays open (a study of thousands of cases would pass the number of
files a process may hold open), and the fields go from the case files to study.nc one case at a time, never all
in memory (study.nc itself copies their compressed chunks: `study_fill`).

The first finished case is read through xarray, whose decoding it records (`Template`); a case file with the same
variables, dimensions and types (every case of most studies; its attributes and layout read through netCDF4) then
has its small variables read through h5py, each as stored, which is what xarray decodes it to where the template
says so (`as_stored`: no scale or offset, no fill value but NaN in a float): the same values at a fraction of the
cost (h5py opens a file in 0.13 ms, reads a small variable in ~20 us; netCDF4's reads cost ~80 us each), kept as
arrays (`Case.values`: the study's arrays are filled from them, `study_arrays`; `Reader.dataset` makes a case's
dataset where one is needed).  Any other case file is read through xarray.  Observables a case file lacks
(written before an observable existed, or measured on another substratum than its scene says now) are computed
from its fields then (nothing is simulated again).
"""
from __future__ import annotations

import contextlib
import dataclasses
import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from ..quantities import observables
from . import netcdf, netcdf_io
from .case_files import CASE_VARIABLES

SPATIAL = frozenset({"x", "y", "z", "x_node", "y_node", "z_node"})
AT_ONCE = 64e6  # bytes of a case's fields read at once when study.nc is written; a larger case is read in blocks
SOURCE = {new: old for old, new in netcdf.OLD_NAMES.items()}  # a variable's name in files written before a rename


@dataclass(frozen=True)
class Case:
    """One case of a study as its file says: status, message, attributes, and (done) its run's dataset."""

    status: str  # "done", "failed", or "missing" (no file, or one that cannot be read)
    message: str
    attrs: dict
    run: xr.Dataset | None = None  # a finished case as its run wrote it: small variables read, fields lazy
    computed: bool = False  # observables it lacked were computed from its fields
    path: Path | None = None  # its file (finished)
    lazy: dict = field(default_factory=dict)  # name -> (shape, dtype, as stored) of its lazy variables (`read_fields`)
    values: dict | None = None  # read as the template says: its small variables' values (run None: `Reader.dataset`)
    now: dict = field(default_factory=dict)  # the substratum attributes its scene has now (its run's, beside `attrs`)


@dataclass
class Template:
    """The first finished case as xarray decoded it: its variables' layout in the file, and the small ones' decoded
    form; None until it is read, `usable` False where a small variable is not read as stored."""

    layout: dict  # file variable name -> (dimensions, shape, dtype) as stored
    run: xr.Dataset  # the case as its run wrote it (small variables read, fields lazy)
    usable: bool
    lazy: dict  # its `Case.lazy`

    @functools.cached_property
    def small(self) -> dict[str, tuple]:
        """{name: (dtype, shape)} of its small variables and coordinates, as a case of its layout is read."""
        return {name: (var.dtype, var.shape) for name, var in self.run.variables.items() if name not in self.lazy}


@dataclass
class Reader:
    """The case files of one study (`coords`: the study's coordinates, which each case's layout adds)."""

    coords: dict
    template: Template | None = field(default=None)

    def read(self, path: Path, now: dict) -> Case:
        """The case file at `path` (`now`: the substratum attributes its scene has now)."""
        if not path.is_file():
            return Case("missing", "", {})
        with contextlib.ExitStack() as stack:
            try:
                nc = stack.enter_context(netcdf_io.opened(path))
                attrs = {name: nc.getncattr(name) for name in nc.ncattrs()}
                layout = {name: (v.dimensions, v.shape, v.dtype) for name, v in nc.variables.items()
                          if name not in CASE_VARIABLES and name not in self.coords}
            except Exception:  # unreadable: as good as missing (a damaged file is named and run again by the sweep)
                return Case("missing", "", {})
            status, message = str(attrs.get("status", "missing")), str(attrs.get("message", ""))
            if status != "done":
                return Case(status, message, attrs)
            fits = self._fits(layout, attrs, now)
        if fits:  # netCDF4 closed it: its small variables through h5py
            return Case(status, message, attrs, None, False, path, self.template.lazy, self._values(path, layout), now)
        case = read(path, self.coords, now)
        if self.template is None and case.run is not None:
            fine = set(case.run.data_vars) - set(_lazy_names(case.run))
            usable = not case.computed and all(as_stored(case.run[name]) for name in [*fine, *case.run.coords])
            self.template = Template(layout, case.run, usable, case.lazy)
        return case

    def _fits(self, layout: dict, attrs: dict, now: dict) -> bool:
        """Whether a finished case file can be read as the template says: the same variables, dimensions and types,
        and measured on the substratum its scene says now."""
        return (self.template is not None and self.template.usable and layout == self.template.layout
                and not observables.remeasured(attrs, now))

    def _values(self, path: Path, layout: dict) -> dict[str, np.ndarray]:
        """A case file of the template's layout: its small variables and coordinates as stored (read through h5py,
        which opens a file 25 times faster than netCDF4; `layout`: their stored shapes and types), in the
        template's types and shapes."""
        from h5py import h5d, h5s

        values = {}
        with netcdf_io.opened_hdf5(path) as file:
            for name, (dtype, shape) in self.template.small.items():
                stored = SOURCE[name] if SOURCE.get(name) in layout else name
                data = np.empty(layout[stored][1], np.dtype(layout[stored][2]).newbyteorder("="))
                if data.size:
                    h5d.open(file.id, stored.encode("utf-8")).read(h5s.ALL, h5s.ALL, data)
                values[name] = np.asarray(data, dtype=dtype).reshape(shape)
        return values

    def dataset(self, case: Case) -> Case:
        """`case` with its run's dataset: read as the template says (`values`), made from them and the template
        (small variables as read, fields lazy); any other case as it is."""
        if case.values is None:
            return case
        template = self.template.run

        def variable(name: str) -> xr.Variable:
            var = template.variables[name]
            return xr.Variable(var.dims, case.values[name], var.attrs, var.encoding)

        small = {name: variable(name) for name in template.data_vars if name not in self.template.lazy}
        coords = {name: variable(name) for name in template.coords}
        fields = lazy_fields(case.path, {name: template[name] for name in self.template.lazy})
        run = xr.Dataset({**small, **fields}, coords, attrs={**case.attrs, **case.now})
        return dataclasses.replace(case, run=run, values=None)


def spatial(var: xr.DataArray | xr.Variable) -> bool:
    return bool(SPATIAL & set(var.dims))


def _lazy_names(run: xr.Dataset) -> list[str]:
    return [name for name in run.data_vars if spatial(run[name])]


def read(path: Path, coords: dict, now: dict) -> Case:
    """The case file at `path` through xarray (`coords`: the study's coordinates, which its layout adds; `now`:
    the substratum attributes its scene has now)."""
    try:
        opened = netcdf_io.open_dataset(path)
    except Exception:  # unreadable: as good as missing
        return Case("missing", "", {})
    with opened as ds:
        attrs = dict(ds.attrs)
        status = str(attrs.get("status", "missing"))
        if status != "done":
            return Case(status, str(attrs.get("message", "")), attrs)
        run = observables.as_measured(as_run(ds, coords), now)
        missing = [name for name, o in observables.REGISTRY.items()
                   if name not in run and observables.available(run, o)]
        computed = observables.variables(run, names=missing) if missing else {}
        lazy = _lazy_names(run)
        small = run.drop_vars(lazy).load()
        fields = lazy_fields(path, {name: run[name] for name in lazy})
    return Case(status, str(attrs.get("message", "")), attrs, small.assign(fields).assign(computed), bool(computed),
                path, _specs({name: run[name] for name in lazy}))


def _specs(variables: dict[str, xr.DataArray]) -> dict[str, tuple]:
    return {name: (var.shape, var.dtype, as_stored(var)) for name, var in variables.items()}


def as_run(ds: xr.Dataset, coords: dict) -> xr.Dataset:
    """A case file as its run wrote it: without the study's coordinates and the per-case variables (nor a
    swept parameter as a variable, as a case file written without its layout has it)."""
    dims = [d.strip() for d in str(ds.attrs.get(netcdf.CASE_DIMENSIONS, "")).split(",") if d.strip()]
    ds = netcdf.renamed(ds).isel({d: 0 for d in dims if d in ds.dims}, drop=True)
    return ds.drop_vars([n for n in (*CASE_VARIABLES, *coords) if n in ds.variables])


def as_stored(var: xr.DataArray | xr.Variable) -> bool:
    """Whether a variable's stored values are its decoded ones: the same type, no scale or offset, no fill value
    but NaN in a float."""
    encoding = var.encoding
    fill = encoding.get("_FillValue", encoding.get("missing_value"))
    return (var.dtype.kind in "fiu" and np.dtype(encoding.get("dtype", var.dtype)) == var.dtype
            and "scale_factor" not in encoding and "add_offset" not in encoding
            and (fill is None or (var.dtype.kind == "f" and np.isnan(fill))))


def lazy_fields(path: Path, variables: dict[str, xr.DataArray]) -> dict[str, xr.Variable]:
    """The case file's `variables` as dask arrays: one read of them all (a case of at most `AT_ONCE` bytes), or
    one per block of at most that along each one's first dimension; Variables, their coordinates the dataset's."""
    import dask
    import dask.array as da

    token = dask.base.tokenize(str(path), sorted(variables))
    names = _specs(variables)
    if sum(var.nbytes for var in variables.values()) <= AT_ONCE:
        together = dask.delayed(read_fields, pure=True)(str(path), names)
        data = {name: da.from_delayed(together[name], var.shape, var.dtype, name=f"case-{token}-{name}")
                for name, var in variables.items()}
    else:
        data = {name: _blocks(path, name, var, names[name][2], f"case-{token}-{name}")
                for name, var in variables.items()}
    return {name: xr.Variable(var.dims, data[name], var.attrs, var.encoding) for name, var in variables.items()}


def _blocks(path: Path, name: str, var: xr.DataArray, stored: bool, key: str):
    """`var` read in blocks of at most `AT_ONCE` bytes along its first dimension (one read each)."""
    import dask
    import dask.array as da

    if not var.ndim:
        return da.from_delayed(dask.delayed(read_fields)(str(path), {name: (var.shape, var.dtype, stored)})[name],
                               var.shape, var.dtype, name=key)
    step = max(1, int(AT_ONCE // max(var.nbytes / max(var.shape[0], 1), 1)))
    parts = []
    for start in range(0, var.shape[0], step):
        stop = min(start + step, var.shape[0])
        block = dask.delayed(_read_block, pure=True)(str(path), name, start, stop, var.shape, var.dtype, stored)
        parts.append(da.from_delayed(block, (stop - start, *var.shape[1:]), var.dtype, name=f"{key}-{start}"))
    return da.concatenate(parts)


def read_fields(path: str | Path, names: dict) -> dict[str, np.ndarray]:
    """The values of a case file's variables `names` ({name: (shape, dtype, as stored)}: `Case.lazy`), their study
    dimensions (of length 1) dropped: as stored where that is what xarray decodes them to, else through xarray."""
    with netcdf_io.opened(path) as nc:
        values = {}
        for name, (shape, dtype, stored) in names.items():
            if stored:
                variable = nc.variables[SOURCE[name] if SOURCE.get(name) in nc.variables else name]
                variable.set_auto_maskandscale(False)
                values[name] = np.asarray(variable[...], dtype=dtype).reshape(shape)
    decoded = [name for name, (_, _, stored) in names.items() if not stored]
    if decoded:
        with netcdf_io.open_dataset(path) as ds:
            ds = netcdf.renamed(ds)
            values.update({name: np.asarray(ds[name].values, dtype=names[name][1]).reshape(names[name][0])
                           for name in decoded})
    return values


def _read_block(path: str, name: str, start: int, stop: int, shape: tuple, dtype, stored: bool) -> np.ndarray:
    """Entries start:stop along the first dimension of variable `name` (of the run's `shape`)."""
    return read_fields(path, {name: (shape, dtype, stored)})[name][start:stop] if not stored else \
        _stored_block(path, name, start, stop, shape, dtype)


def _stored_block(path: str, name: str, start: int, stop: int, shape: tuple, dtype) -> np.ndarray:
    with netcdf_io.opened(path) as nc:
        variable = nc.variables[SOURCE[name] if SOURCE.get(name) in nc.variables else name]
        variable.set_auto_maskandscale(False)
        axis = variable.ndim - len(shape)  # the study's dimensions (of length 1) lead (`case_files.CaseLayout`)
        index = tuple(slice(start, stop) if i == axis else slice(None) for i in range(variable.ndim))
        return np.asarray(variable[index], dtype=dtype).reshape((stop - start, *shape[1:]))
