"""File size and write time of run datasets: uncompressed contiguous float64 (as before issue 11) against the
encoding `biostudy.data.netcdf.encoding` gives them (zlib + shuffle, one snapshot per chunk).

    .venv/bin/python benchmarks/compression.py directional grate

Runs each bundled scene (or scene file) once as `biostudy run` would, writes its dataset both ways five
times and prints the median write time, the file size, and the time to read one snapshot of phi back.
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

from biostudy.data import netcdf  # noqa: E402
from biostudy.inputs import bundled
from biostudy.inputs.scene import load_scene  # noqa: E402
from solver import simulate  # noqa: E402

REPEATS = 5


def plain(ds: xr.Dataset) -> dict:
    """The encoding of every file before: xarray's defaults (contiguous, uncompressed)."""
    return {name: {"_FillValue": None} if name in ds.coords else {} for name in ds.variables}


def measure(ds: xr.Dataset, encoding: dict, path: Path) -> tuple[float, int, float]:
    writes = []
    for _ in range(REPEATS):
        path.unlink(missing_ok=True)
        began = time.perf_counter()
        ds.to_netcdf(path, engine="netcdf4", format="NETCDF4", encoding=encoding)
        writes.append(time.perf_counter() - began)
    began = time.perf_counter()
    with xr.open_dataset(path, engine="netcdf4") as back:
        back["phi"].isel(time=-1).load()
    return statistics.median(writes), path.stat().st_size, time.perf_counter() - began


def main(names: list[str]) -> None:
    print(f"load average at the start: {os.getloadavg()[0]:.1f}")
    print("| scene | cells | outputs | layout | file MB | write s (median of 5) | read last phi s |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as scratch:
        for name in names:
            scene = load_scene(bundled.resolve(name))
            ds = simulate(scene.problem())
            cells = "×".join(map(str, scene.grid.shape))
            for layout, encoding in (("before: contiguous float64", plain(ds)),
                                     ("zlib 4 + shuffle, snapshot chunks", netcdf.encoding(ds))):
                seconds, size, read = measure(ds, encoding, Path(scratch) / "run.nc")
                print(f"| {scene.name} | {cells} | {ds.sizes['time']} | {layout} | {size / 1e6:.2f} | "
                      f"{seconds:.3f} | {read:.3f} |", flush=True)
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main(sys.argv[1:] or ["directional", "grate"])
