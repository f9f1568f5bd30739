"""netCDF files read and written through netCDF4 itself, under one lock: an interruption anywhere is safe.

xarray opens netCDF files through its file cache and guards them with locks
of its own, one of them made of two locks taken one after the other in
Python code.  A KeyboardInterrupt (Ctrl-C, or SIGTERM, which `biostudy`
turns into one) that lands between the two leaves the first one held, and
closing the file on the way out then waits for it forever: SIGTERM while
`run -o` wrote its dataset hung 3 of 8 tries (issue 21).  Here a file is
opened with `netCDF4.Dataset` and handed to xarray as an open file
(`DummyFileManager`), guarded by one re-entrant lock implemented in C
(`HDF5`: held or not, never half), and lazy (dask) data are computed in
this thread while they are written.  Interrupted at any point, the file is
closed on the way out (`atomic` removes the temporary) and nothing waits.

HDF5 is not thread-safe either: two threads of a notebook opening files at
once crashed the interpreter (SIGSEGV, issue 25).  So every call into
netCDF4 (opening, reading metadata, writing, closing, and the lazy reads
xarray makes later) is made under `HDF5`: `opened` holds it for a block,
`write` for the whole file, a lazy dataset's reads and close take it.  The
same lock guards h5py (`opened_hdf5`), whose HDF5 library is another one in
the same process: a study's case files are read and its fields copied
through it (`study_cases`, `study_fill`).
"""
from __future__ import annotations

import contextlib
import functools
import math
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Collection, Iterator

import numpy as np

if TYPE_CHECKING:  # imported where a dataset is made: `show` of a run's file reads it with netCDF4 alone
    import h5py
    import netCDF4
    import xarray as xr
    from xarray.backends import NetCDF4DataStore

    Deferred = tuple[Collection[str], Callable[[Path], None]]  # see `write`

HDF5 = threading.RLock()  # the HDF5 library is not thread-safe: every call into it is made under this lock


@contextlib.contextmanager
def opened(path: str | Path) -> Iterator[netCDF4.Dataset]:
    """A netCDF file open with netCDF4 for the block, which holds `HDF5` (no other thread touches HDF5)."""
    import netCDF4

    with HDF5, netCDF4.Dataset(path) as nc:
        yield nc


@contextlib.contextmanager
def opened_hdf5(path: str | Path, mode: str = "r") -> Iterator[h5py.File]:
    """A netCDF-4 (HDF5) file open with h5py for the block, which holds `HDF5`: h5py brings an HDF5 library of its
    own beside netCDF4's, neither thread-safe.  h5py opens a file in 0.13 ms, netCDF4 in 3.4 ms (it reads every
    variable's metadata): for a read of a few known variables (`study_cases`, `study_fill`)."""
    import h5py

    with HDF5, h5py.File(path, mode) as file:
        yield file


@functools.cache
def _manager() -> type:
    """xarray's manager of a file opened elsewhere, closing it under `HDF5` (made once, when first needed)."""
    from xarray.backends import DummyFileManager

    class Locked(DummyFileManager):
        def close(self, needs_lock: bool = True) -> None:
            with HDF5:
                super().close(needs_lock)

    return Locked


def _store(nc) -> NetCDF4DataStore:
    """xarray's store of an open file; its reads and its close are made under `HDF5`."""
    from xarray.backends import NetCDF4DataStore

    return NetCDF4DataStore(_manager()(nc, lock=HDF5), lock=HDF5)


def open_dataset(path: str | Path, chunks: dict | None = None, one_chunk_cached: bool = False) -> xr.Dataset:
    """A netCDF file as a lazy xarray Dataset (`chunks` as for `xr.open_dataset`); its close() closes the file.
    `one_chunk_cached`: HDF5 keeps one chunk of each variable read, not as many as its cache takes (a file
    read once through, whose reading must not hold more memory the longer it is).
    Errors are netCDF4's (OSError for a file it cannot open, RuntimeError or AttributeError for damage)."""
    import netCDF4
    import xarray as xr

    with HDF5:  # xarray reads the metadata here, outside its store's lock
        nc = netCDF4.Dataset(path)
        if one_chunk_cached:
            for variable in nc.variables.values():
                _cache_one_chunk(variable)
        try:
            return xr.open_dataset(_store(nc), chunks=chunks)
        except BaseException:
            with contextlib.suppress(Exception):
                nc.close()
            raise


def write(ds: xr.Dataset, path: str | Path, encoding: dict, deferred: Deferred | None = None) -> None:
    """`ds` to a new netCDF4 file at `path` with the per-variable `encoding` (as `to_netcdf` takes it).
    `deferred`: (names, fill): the lazy variables of those names are made as xarray makes them (not written), and
    then written by fill(path) once netCDF4 has closed the file, under `HDF5` still (a study's fields, case by
    case, through h5py: `combine.write_study`)."""
    import dask
    import dask.local
    import netCDF4
    from xarray.backends.common import ArrayWriter

    # the whole file under HDF5 (xarray writes metadata outside its store's lock); lazy data (a study's case
    # files) are computed chunk by chunk in this thread, as a thread pool's reads would wait for the lock forever
    # (the scheduler itself, not its name: named, dask imports `distributed` to look for a client, 0.23 s)
    with HDF5, dask.config.set(scheduler=dask.local.get_sync):
        nc = netCDF4.Dataset(path, "w", format="NETCDF4")
        store = _store(nc)
        try:
            writer = ArrayWriter(lock=HDF5)
            ds.dump_to_store(store, writer=writer, encoding=encoding)  # numpy data are written here
            if writer.sources:  # lazy data (a streamed run, a study's case files): chunk by chunk, one cached
                for variable in nc.variables.values():
                    _cache_one_chunk(variable)
                if deferred is not None:
                    kept = [i for i, target in enumerate(writer.targets) if target.variable_name not in deferred[0]]
                    for name in ("sources", "targets", "regions"):
                        setattr(writer, name, [getattr(writer, name)[i] for i in kept])
                writer.sync()
        except BaseException:
            with contextlib.suppress(Exception):  # the reason it stopped is what is told, not a failed close
                store.close()
            raise
        store.close()  # flushes: a disk that fills up here is an error too
        if deferred is not None:
            deferred[1](Path(path))


def _cache_one_chunk(variable) -> None:
    """HDF5 caches a variable's chunks as they are written (up to its cache size): keep one, so that writing
    many outputs holds no more memory than writing one."""
    chunks = variable.chunking()
    if chunks != "contiguous" and variable.dtype != str:
        size = int(np.prod(chunks)) * np.dtype(variable.dtype).itemsize
        variable.set_var_chunk_cache(size=max(size, 1))


class Growing:
    """A new netCDF4 file whose variables grow by one slab (one output) at a time along an unlimited first
    dimension of their own, every netCDF call under `HDF5`: a writer that keeps nothing of what it wrote."""

    def __init__(self, path: str | Path, compression: dict):
        import netCDF4

        self.compression = compression
        with HDF5:
            self.nc = netCDF4.Dataset(path, "w", format="NETCDF4")

    def append(self, name: str, values) -> None:
        """`values` (one output of the variable `name`) after those appended before."""
        with HDF5:
            if name not in self.nc.variables:
                dims = [f"{name}_output", *(f"{name}_{axis}" for axis in range(values.ndim))]
                self.nc.createDimension(dims[0], None)
                for dim, length in zip(dims[1:], values.shape):
                    self.nc.createDimension(dim, length)
                variable = self.nc.createVariable(name, values.dtype, dims, fill_value=False,
                                                  chunksizes=(1, *values.shape), **self.compression)
                _cache_one_chunk(variable)
            variable = self.nc.variables[name]
            variable[variable.shape[0]] = values

    def close(self) -> None:
        with HDF5:
            if self.nc.isopen():
                self.nc.close()


def intact(path: str | Path, slab_bytes: int = 1 << 26) -> bool:
    """Whether a netCDF file reads back whole: every attribute, and every numeric variable (checksums verified
    where it has them), read in slabs of at most `slab_bytes`; False for a file that cannot be opened.

    Variable-length strings (in files written before text became characters, `netcdf.encoding`) carry no
    checksum and are not read: read through a second handle of a file that is open elsewhere in this
    process, they leave HDF5 in a state that crashes a later open (HDFGroup/hdf5#5359)."""
    try:
        with opened(path) as nc:
            nc.set_auto_mask(False)
            for name in nc.ncattrs():
                nc.getncattr(name)
            for var in nc.variables.values():
                for name in var.ncattrs():
                    var.getncattr(name)
                if not isinstance(var.dtype, np.dtype):
                    continue  # a variable-length string: no checksum to verify
                if not var.ndim or not var.shape[0]:
                    var[...]  # a scalar or an empty variable
                    continue
                row = math.prod(var.shape[1:]) * var.dtype.itemsize
                step = max(1, slab_bytes // max(row, 1))
                for start in range(0, var.shape[0], step):
                    var[start:start + step]
    except Exception:  # whatever HDF5 makes of damage: OSError, RuntimeError, AttributeError, IndexError, ...
        return False
    return True
