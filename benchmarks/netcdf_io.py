"""Writing and reading run datasets through `biostudy.data.netcdf_io` (netCDF4 under one C lock, so that an
interruption cannot deadlock: issue 21) against xarray's own `to_netcdf` / `open_dataset`, same encoding.

    .venv/bin/python benchmarks/netcdf_io.py directional grate

Runs each bundled scene (or scene file) for a few steps with its outputs (the fields of a real run, without
its cost), then writes the dataset both ways and reads it back whole both ways, REPEATS times each,
alternating, and prints the medians (min-max).
"""
from __future__ import annotations

import os

os.environ.setdefault("FIPY_SOLVERS", "scipy")

import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import xarray as xr  # noqa: E402

from biostudy.data import netcdf, netcdf_io  # noqa: E402
from biostudy.inputs import bundled  # noqa: E402
from biostudy.inputs.scene import load_scene  # noqa: E402
from solver import simulate  # noqa: E402

REPEATS = 7


def seconds(call) -> float:
    began = time.perf_counter()
    call()
    return time.perf_counter() - began


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):.4f} ({min(values):.4f}-{max(values):.4f})"


def main(names: list[str]) -> None:
    print("| scene | cells, outputs | write: netcdf_io | write: xarray to_netcdf | read: netcdf_io | "
          "read: xarray open_dataset |")
    print("|---|---|---|---|---|---|")
    for name in names:
        scene = load_scene(bundled.resolve(name), ["time.steps=4", "mechanics.enabled=false"])
        ds = simulate(scene.problem())
        times = measure(ds, netcdf.encoding(ds))
        cells = "×".join(str(n) for n in scene.grid.shape)
        print(f"| {name} | {cells}, {ds.sizes['time']} | {spread(times['ours'])} | {spread(times['xarray'])} | "
              f"{spread(times['read ours'])} | {spread(times['read xarray'])} |", flush=True)


def measure(ds: xr.Dataset, encoding: dict) -> dict[str, list[float]]:
    """Seconds of each write and read, REPEATS times, the two ways in turn."""
    times = {key: [] for key in ("ours", "xarray", "read ours", "read xarray")}
    with tempfile.TemporaryDirectory() as directory:
        ours, theirs = Path(directory) / "ours.nc", Path(directory) / "xarray.nc"
        for _ in range(REPEATS):
            ours.unlink(missing_ok=True)
            theirs.unlink(missing_ok=True)
            times["ours"].append(seconds(lambda: netcdf_io.write(ds, ours, encoding)))
            times["xarray"].append(seconds(lambda: ds.to_netcdf(theirs, engine="netcdf4", encoding=encoding)))
            times["read ours"].append(seconds(lambda: _read_ours(ours)))
            times["read xarray"].append(seconds(lambda: _read_xarray(theirs)))
    return times


def _read_ours(path: Path) -> None:
    ds = netcdf_io.open_dataset(path)
    try:
        ds.load()
    finally:
        ds.close()


def _read_xarray(path: Path) -> None:
    with xr.open_dataset(path, engine="netcdf4") as ds:
        ds.load()


if __name__ == "__main__":
    main(sys.argv[1:] or ["directional", "grate"])
