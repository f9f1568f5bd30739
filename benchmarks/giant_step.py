"""One giant step against many (issue 33.2): the directional scene over T* = 5 with 1 step and with 500.

The issue's scene (`biostudy run directional --set grid.shape=[12,12,12] --set grid.spacing=1.6667 --set
time.t_end=5 --set time.steps=1 --set time.outputs=3 --set mechanics.enabled=false`) and the same at 10³ cells of
2 µm, with 3 and with 11 outputs: the biofilm volume (phi >= 0.5) at every output with one nominal step and with
500, their relative difference, and what the clock did (steps taken, of them shortened to the scheme's limit,
the largest Courant number, wall time).  Before the limit, one step filled the box (7996 µm³ at T* = 2.5 where
500 steps grow to 2120 µm³).

    python benchmarks/giant_step.py [--sizes 10 12] [--outputs 3 11] [--many 500]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import solver
from biostudy.inputs.scene import load_scene

SPACING = {10: 2.0, 12: 1.6667}  # the 20 µm cube (the 1.6667 µm at 12³)


def run(cells: int, outputs: int, steps: int):
    overrides = [f"grid.shape=[{cells},{cells},{cells}]", f"grid.spacing={SPACING[cells]}", "time.t_end=5",
                 f"time.outputs={outputs}", "mechanics.enabled=false", f"time.steps={steps}"]
    began = time.perf_counter()
    ds = solver.simulate(load_scene("studies/directional.toml", overrides).problem())
    return ds, time.perf_counter() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 12], choices=sorted(SPACING))
    parser.add_argument("--outputs", type=int, nargs="+", default=[3, 11])
    parser.add_argument("--many", type=int, default=500)
    args = parser.parse_args()
    print(f"load average before: {' '.join(open('/proc/loadavg').read().split()[:3])}")
    print(f"| cells | outputs | steps asked | steps taken | substepped | Courant max | wall s | biofilm volume µm³ at "
          f"T* = 0 ... 5 | largest difference from {args.many} steps |")
    print("|---|---|---|---|---|---|---|---|---|")
    for cells in args.sizes:
        for outputs in args.outputs:
            many, many_s = run(cells, outputs, args.many)
            one, one_s = run(cells, outputs, 1)
            reference = many.biofilm_volume.values
            for steps, ds, seconds in ((1, one, one_s), (args.many, many, many_s)):
                volume = ds.biofilm_volume.values
                with np.errstate(invalid="ignore", divide="ignore"):
                    apart = np.where(reference > 0, volume / reference - 1, np.where(volume > 0, np.inf, 0.0))
                worst = int(np.argmax(np.abs(apart)))
                print(f"| {cells}³ | {outputs} | {steps} | {ds.attrs['steps_taken']} | {ds.attrs['steps_substepped']} "
                      f"| {ds.attrs['courant_max']:.3f} | {seconds:.2f} | {', '.join(f'{v:.0f}' for v in volume)} | "
                      f"{100 * apart[worst]:+.1f} % at T* = {ds.time.values[worst]:g} |", flush=True)
    print(f"load average after: {' '.join(open('/proc/loadavg').read().split()[:3])}")


if __name__ == "__main__":
    main()
