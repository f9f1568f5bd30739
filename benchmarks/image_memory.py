"""Peak memory of an image region per voxel: reading a stack and averaging it onto a grid, or measuring it.

    python benchmarks/image_memory.py              # 64 x 512 x 512 uint8 (float32 averaging) and 32 x 512 x 512
    python benchmarks/image_memory.py --slices 16 --dtype uint16
    python benchmarks/image_memory.py --measure    # biostudy measure's reading and counting, connected or not

For each stack (uint8 unless --dtype says otherwise, ImageJ-calibrated, written to a temporary folder) it
reads the file and averages it onto a 3-D grid the way a scene does, in a
fresh interpreter each (`image_files.read`, then `images._averaged` of the
region by `threshold` and of the grey values by `scale`), and prints the
peak that numpy allocated above the start (tracemalloc) and the growth of the
process's peak resident memory (VmHWM), both per voxel of the stack.  The
memory check counts the values' item size plus `image_files.AVERAGING_BYTES`
per voxel, the largest of these beyond the values; with --measure, `inputs.stacks.load` and
`quantities.stack_measures.measure` (threshold 128, with and without the connected-volume filter), against the
item size plus `stacks.MEASURING.per_voxel`.  Asserts nothing.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = """
import sys, tracemalloc
import numpy as np, tifffile
from biostudy.inputs import image_files, images

def hwm():
    return next(int(l.split()[1]) * 1024 for l in open("/proc/self/status") if l.startswith("VmHWM"))

path, of, cells = sys.argv[1], sys.argv[2], int(sys.argv[3])
with tifffile.TiffFile(path) as tif:
    shape = tif.series[0].shape
before = hwm()
tracemalloc.start()
stack = image_files.read(path, 0, 0)
threshold = 128.0 if of == "region" else None
images._averaged(path, 0, 0, of, threshold, stack.voxel, (0.0, 0.0, 0.0), 1.0, (cells, cells, cells))
peak = tracemalloc.get_traced_memory()[1]
voxels = np.prod(shape)
print(f"{'x'.join(map(str, shape)):>14} {of:>7} {voxels:>11,} {peak / voxels:10.2f} {(hwm() - before) / voxels:10.2f}")
"""

MEASURE = """
import sys, tracemalloc
import numpy as np, tifffile
from biostudy.inputs import stacks
from biostudy.quantities import stack_measures

def hwm():
    return next(int(l.split()[1]) * 1024 for l in open("/proc/self/status") if l.startswith("VmHWM"))

path, connected = sys.argv[1], sys.argv[2] == "connected"
with tifffile.TiffFile(path) as tif:
    shape = tif.series[0].shape
before = hwm()
tracemalloc.start()
stack_measures.measure(stacks.load(path), threshold=128.0, face="z-", connected=connected)
peak = tracemalloc.get_traced_memory()[1]
voxels = np.prod(shape)
grown = (hwm() - before) / voxels
print(f"{'x'.join(map(str, shape)):>14} {sys.argv[2]:>9} {voxels:>11,} {peak / voxels:10.2f} {grown:10.2f}")
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--slices", type=int, nargs="*", default=[64, 32])
    parser.add_argument("--side", type=int, default=512)
    parser.add_argument("--dtype", default="uint8", help="the stack's values: uint8, uint16, float32")
    parser.add_argument("--measure", action="store_true", help="biostudy measure's peak instead of a region's")
    args = parser.parse_args()
    import numpy as np
    import tifffile

    print(f"{'stack':>14} {'of':>7} {'voxels':>11} {'tracemalloc':>10} {'VmHWM':>10}  (bytes per voxel)")
    with tempfile.TemporaryDirectory() as folder:
        for slices in args.slices:
            path = Path(folder) / f"stack{slices}.tif"
            stack = (np.random.default_rng(0).random((slices, args.side, args.side)) * 255).astype(args.dtype)
            tifffile.imwrite(path, stack, imagej=True, resolution=(4.0, 4.0),
                             metadata={"spacing": 0.5, "unit": "um", "axes": "ZYX"})
            del stack
            if args.measure:
                for connected in ("plain", "connected"):
                    subprocess.run([sys.executable, "-c", MEASURE, str(path), connected], check=True)
                continue
            for of in ("region", "values"):
                subprocess.run([sys.executable, "-c", CHILD, str(path), of, str(args.side // 8)], check=True)


if __name__ == "__main__":
    main()
