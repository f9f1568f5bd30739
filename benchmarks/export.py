"""`biostudy export` of a finished run in each ParaView format: the files' size against the netCDF dataset's, and
the time to write them (issue 36.4: VTK image data instead of unstructured hexahedra).

    .venv/bin/biostudy run directional -o /tmp/directional.nc
    .venv/bin/python benchmarks/export.py /tmp/directional.nc

Exports the run REPEATS times per format into a temporary directory (vti, vtu alternating) and prints the total
size and the median (min-max) wall time of each, with the load average beside.
"""
from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

from biostudy.commands.export import export

REPEATS = 3


def main(run: Path) -> None:
    with open("/proc/loadavg") as handle:
        load = " ".join(handle.read().split()[:3])
    times: dict[str, list[float]] = {"vti": [], "vtu": []}
    sizes: dict[str, tuple[int, int]] = {}
    with tempfile.TemporaryDirectory() as scratch:
        for repeat in range(REPEATS):
            for format in times:  # noqa: A001
                began = time.perf_counter()
                written = export(run, Path(scratch) / f"{format}{repeat}", format=format)
                times[format].append(time.perf_counter() - began)
                sizes[format] = (len(written), sum(p.stat().st_size for p in written))
    print(f"{run} ({run.stat().st_size / 1e6:.1f} MB netCDF); load average {load}")
    print("| format | files | MB | seconds (median, min-max) |")
    print("|---|---|---|---|")
    for format, spent in times.items():  # noqa: A001
        files, size = sizes[format]
        print(f"| {format} | {files} | {size / 1e6:.1f} | {statistics.median(spent):.2f} ({min(spent):.2f}-"
              f"{max(spent):.2f}) |")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
