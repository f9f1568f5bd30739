"""A study's cases stacked into study-wide arrays (`combine`), without a dataset per case.

The common study: every finished case file has the first's layout (`study_cases.Reader` read it as the template
says: `Case.values`) and the first's coordinates.  Then every variable of the first case stacks, and each
case's small variables (observables, time series) go straight from the values read into one preallocated
array per variable; its fields stay lazy (one read of each case file when study.nc is written).  The result is
what `combine` makes of one dataset per case (`combine._case_parts`, `_stacked`: held identical by
tests/test_sweep.py), without the xarray objects of a thousand cases (most of the time of combining them).
Any other study (cases of different layouts or coordinates): None, and `combine` stacks a dataset per case.
"""
from __future__ import annotations

import numpy as np
import xarray as xr

from .case_files import CASE_ATTRS, case_scalars
from .study_cases import Case, Reader, lazy_fields


def floats(ds: xr.Dataset) -> xr.Dataset:
    """Integer variables as float, so a case that did not finish can be NaN (flag values follow: CF 3.5)."""
    def floating(var: xr.DataArray) -> xr.DataArray:
        var = var.astype(float)
        if "flag_values" in var.attrs:
            var.attrs["flag_values"] = np.asarray(var.attrs["flag_values"], dtype=float)
        return var

    return ds.assign({n: floating(ds[n]) for n in ds.data_vars if not np.issubdtype(ds[n].dtype, np.floating)})


def part(found: Case, case_id: str, shared: list[str], template: xr.Dataset | None) -> xr.Dataset:
    """One case's dataset in the study (`found` with its run, `Reader.dataset`): its `shared` variables (as
    `template`, NaN, where it did not finish) and its status, message, wall time, steps and id."""
    if found.run is not None:
        ds = floats(found.run[shared])
        attrs = found.run.attrs
    else:
        ds = xr.full_like(template, np.nan) if template is not None else xr.Dataset()
        attrs = found.attrs  # a failure record has the wall time until it failed
    ds.attrs = {}
    ds = ds.assign(case_scalars(found.status, found.message, attrs))
    ds["case_id"] = ((), np.array(case_id, dtype=object), CASE_ATTRS)
    return ds


def nest(items: list, sizes: list[int]) -> list:
    """Flat list (last index fastest) -> nested lists of the given sizes."""
    if len(sizes) == 1:
        return items
    step = len(items) // sizes[0]
    return [nest(items[i * step:(i + 1) * step], sizes[1:]) for i in range(sizes[0])]


def stack(nested: list):
    """Nested lists of arrays (numpy or dask) as one array, a dimension per level."""
    import dask

    rows = [stack(item) if isinstance(item, list) else item for item in nested]
    if any(dask.is_dask_collection(row) for row in rows):
        import dask.array as da

        return da.stack(rows)
    return np.stack(rows)


def stacked(reader: Reader, cases: list[tuple[str, Case]], dims: list[str], sizes: list[int],
            once: list[str], unread: bool = False) -> xr.Dataset | None:
    """The cases (case id, Case in the plan's order; the study's `dims` of `sizes`, the last fastest) stacked, every
    variable of the first finished case's but those written `once`: None unless each finished case but the first
    was read as the template says and has its coordinates.  `unread`: the fields are dask arrays of their shape
    and type that read nothing, one chunk per case (study.nc's writer fills them itself, `study_fill`), not
    reads of the case files (a thousand cases' dask graphs cost a second)."""
    template = reader.template
    done = [found for _, found in cases if found.status == "done"]
    if template is None or not done or done[0].run is not template.run or any(
            found.values is None for found in done[1:]):
        return None
    first = template.run
    coords = {name: first[name].values for name in first.coords}
    if any(not np.array_equal(found.values[name], values) for found in done[1:] for name, values in coords.items()):
        return None
    shared = [name for name in first.data_vars if name not in once]
    model = part(done[0], cases[0][0], shared, None)  # each variable's type, attributes and encoding in the study
    lazy = [name for name in shared if name in template.lazy]
    empty = xr.full_like(floats(first[lazy]), np.nan)
    fields = {name: [] for name in lazy}
    small = {name: np.empty((len(cases), *var.shape), var.dtype) for name, var in model.data_vars.items()
             if name not in template.lazy}
    for number, (case_id, found) in enumerate(cases):
        attrs = found.run.attrs if found.run is not None else \
            {**found.attrs, **found.now} if found.values is not None else found.attrs
        scalars = case_scalars(found.status, found.message, attrs)
        values = found.values if found.values is not None else \
            {name: first[name].values for name in shared if name in small} if found.run is not None else {}
        lazily = {} if unread else lazy_fields(found.path, {name: first[name] for name in lazy}) \
            if found.status == "done" else {name: empty.variables[name] for name in lazy}
        for name, array in small.items():
            if name in scalars:
                array[number] = np.asarray(scalars[name][1])[()]
            elif name == "case_id":
                array[number] = case_id
            else:
                array[number] = values[name] if name in values else np.nan
        for name in lazily:  # integer fields (masks) as float, as `floats` makes them
            data = lazily[name].data
            fields[name].append(data if data.dtype == model[name].dtype else data.astype(model[name].dtype))
    variables = {}
    for name, var in model.data_vars.items():
        data = small[name].reshape((*sizes, *var.shape)) if name in small else \
            _unread((*sizes, *var.shape), var.dtype, len(sizes)) if unread else stack(nest(fields[name], sizes))
        variables[name] = xr.Variable([*dims, *var.dims], data, dict(var.variable.attrs), dict(var.encoding))
    return xr.Dataset(variables, model.coords)


def _unread(shape: tuple, dtype, lead: int):
    """A dask array of `shape` and `dtype` in one chunk per case (its first `lead` dimensions) that reads nothing."""
    import dask.array as da

    return da.empty(shape, dtype=dtype, chunks=(1,) * lead + shape[lead:])
