"""A run that writes a file streams its outputs (issue 29.1): the same file as the dataset held in memory, and
memory that does not grow with the number of outputs."""
from __future__ import annotations

import gc
import weakref

import netCDF4
import numpy as np
import pytest

import solver
from biostudy.commands import run as command
from biostudy.data import reading, writing
from biostudy.quantities import observables

VOLATILE_ATTRS = {"created", "history", "wall_time", "mechanics_seconds", "cpu_time_loop", "cpu_time_first",
                  "cpu_time_setup"}  # timings


@pytest.fixture(autouse=True)
def every_run_streams(monkeypatch):
    """The tiny scene's outputs are far below `resources.STREAM_ABOVE`: these tests stream them all the same."""
    from biostudy.inputs import resources

    monkeypatch.setattr(resources, "STREAM_ABOVE", 0.0)


def _layout(path) -> dict:
    """Each variable's dimensions, type, chunks, filters and attributes as netCDF4 reads them."""
    with netCDF4.Dataset(path) as nc:
        return {name: (var.dimensions, str(var.dtype), var.chunking(), var.filters(),
                       {k: str(var.getncattr(k)) for k in var.ncattrs()}) for name, var in nc.variables.items()}


def test_a_streamed_run_writes_the_file_the_dataset_held_in_memory_writes(tiny_scene, tmp_path):
    overrides = ("time.outputs=5", "mechanics.enabled=true", "mechanics.every=2")
    streamed = tmp_path / "streamed.nc"
    command.compute(command.load(tiny_scene, set=overrides, output=streamed))
    held = command._simulated(command.load(tiny_scene, set=overrides, write=False), None)
    writing.write_atomic(held, tmp_path / "held.nc")

    assert _layout(streamed) == _layout(tmp_path / "held.nc")
    a, b = reading.open_dataset(streamed), reading.open_dataset(tmp_path / "held.nc")
    assert a.sizes["time_mechanics"] == 3
    for name in a.variables:
        if name != "elapsed":  # wall time
            assert a[name].equals(b[name]), name
    same = {k for k in a.attrs if not k.startswith("wall_time_") and k not in VOLATILE_ATTRS}
    assert same == {k for k in b.attrs if not k.startswith("wall_time_") and k not in VOLATILE_ATTRS}
    assert all(str(a.attrs[k]) == str(b.attrs[k]) for k in same)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["held.nc", "streamed.nc", "tiny.toml"]  # no spool left


def test_observables_measured_in_blocks_of_outputs_equal_those_measured_at_once(tiny_scene):
    loaded = command.load(tiny_scene, set=("time.outputs=7", "mechanics.enabled=true", "mechanics.every=3"),
                          write=False)
    ds = command._simulated(loaded, None)
    whole = observables.variables(ds)
    one_output = ds["phi"].isel(time=0).nbytes + ds["c"].isel(time=0).nbytes
    for block in (one_output, 3 * one_output):
        blocked = observables.variables(ds, block_bytes=block)
        assert list(blocked) == list(whole)
        for name in whole:
            assert blocked[name].equals(whole[name]) and blocked[name].attrs == whole[name].attrs, name


def test_a_lazy_run_is_measured_in_the_calling_thread_alone(tiny_scene, tmp_path, monkeypatch):
    """HDF5 is not thread-safe: a sweep's lazily opened case files are read in the thread that measures them, never
    in dask's thread pool while another thread (a notebook's garbage collector) closes a file."""
    import threading

    from xarray.backends.netCDF4_ import NetCDF4ArrayWrapper

    from biostudy.data import netcdf_io

    path = tmp_path / "run.nc"
    command.compute(command.load(tiny_scene, set=("time.outputs=5",), output=path))
    threads = set()
    read = NetCDF4ArrayWrapper.__getitem__

    def reading_in(self, key):
        threads.add(threading.get_ident())
        return read(self, key)

    monkeypatch.setattr(NetCDF4ArrayWrapper, "__getitem__", reading_in)
    with netcdf_io.open_dataset(path, chunks={}) as ds:
        for block in (1e12, ds["phi"].isel(time=0).nbytes):
            observables.variables(ds, block_bytes=block)
    assert threads == {threading.get_ident()}


class Counting:
    """An output sink that keeps nothing but weak references to the fields it is given, and counts at each
    output how many fields of earlier outputs are still alive somewhere."""

    def __init__(self) -> None:
        self.seen: list[weakref.ref] = []
        self.alive: list[int] = []

    def add(self, snapshot) -> None:
        gc.collect()
        self.alive.append(sum(ref() is not None for ref in self.seen))
        self.seen += [weakref.ref(getattr(snapshot, name)) for name in ("phi", "c", "alpha", "u", "p")
                      if getattr(snapshot, name) is not None]

    def fields(self) -> dict:
        return {}


def test_the_time_loop_holds_no_output_it_gave_its_sink(tiny_scene):
    problem = command.load(tiny_scene, set=("time.outputs=6",), write=False).scene.problem()
    sink = Counting()
    with pytest.raises(KeyError):  # a sink that kept nothing has no fields to give
        solver.simulate(problem, sink=sink)
    assert len(sink.alive) == 6
    assert max(sink.alive) <= 3  # the last output's phi, c, alpha at most (the loop's variable), never more


@pytest.mark.parametrize("shape", [(6,), (2, 3)])
def test_the_growing_file_appends_one_output_at_a_time(tmp_path, shape):
    from biostudy.data import netcdf_io

    grown = netcdf_io.Growing(tmp_path / "g.nc", {})
    values = [np.full(shape, float(i)) for i in range(3)]
    for v in values:
        grown.append("f", v)
    grown.close()
    with netCDF4.Dataset(tmp_path / "g.nc") as nc:
        np.testing.assert_array_equal(nc["f"][:], np.stack(values))
        assert nc.dimensions["f_output"].isunlimited()


def test_small_outputs_are_read_back_in_blocks_not_one_chunk_each(tmp_path):
    """Issue 39.7: every output was its own dask chunk, a few kB of bookkeeping each to read it back and to write
    it again: 6001 outputs of 32² peaked at 415 MB where 356 MB were estimated (17 kB an output measured from
    3001 and 6001 outputs; 3.6 kB in blocks).  A field comes back in blocks of at most `CHUNK_BYTES` (one output
    of a large grid at least), the same values."""
    from types import SimpleNamespace

    from biostudy.data import spool

    small, large = spool.Spool(tmp_path / "small.nc"), spool.Spool(tmp_path / "large.nc")
    fields = {"phi": (np.arange(300, dtype=float).reshape(300, 1, 1) * np.ones((300, 8, 8))),
              "big": np.arange(3, dtype=float).reshape(3, 1, 1) * np.ones((3, 200, 200))}
    for i in range(300):
        small.add(SimpleNamespace(phi=fields["phi"][i], c=fields["phi"][i], alpha=fields["phi"][i], p=None, u=None))
    for i in range(3):
        large.add(SimpleNamespace(phi=fields["big"][i], c=fields["big"][i], alpha=fields["big"][i], p=None, u=None))
    try:
        back, whole = small.fields(), large.fields()
        assert back["phi"].chunks[0] == (300,)  # 512 bytes an output: 500 to a block of 256 kB
        assert whole["phi"].chunks[0] == (1, 1, 1)  # 320 kB an output: one at a time
        np.testing.assert_array_equal(back["phi"].compute(), fields["phi"])
        np.testing.assert_array_equal(whole["phi"].compute(), fields["big"])
    finally:
        small.close()
        large.close()
    assert not list(tmp_path.iterdir())
