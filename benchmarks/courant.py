"""How close the bundled scenes' own steps come to the scheme's limit (issue 33.2): their largest Courant number.

Every bundled scene at its own size and steps, mechanics off (the limit is the transport's), in this process: the
largest Courant number a step took (`courant_max`: cells the growth front crossed in one step), the steps taken
and how many of them the clock shortened to the limit (`steps_substepped`: 0 means the scene runs exactly as
before the limit existed), and the wall time.

    python benchmarks/courant.py [--scene NAME]...
"""
from __future__ import annotations

import argparse
import time

import solver
from biostudy.inputs.scene import load_scene

SCENES = ("directional", "directional2d", "agar-g1e8", "agar-g1e10", "agar2d", "agar2d-g1e10", "agar2d-thin", "front",
          "grate", "obstacles", "maze")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", action="append", choices=SCENES)
    args = parser.parse_args()
    print(f"load average before: {' '.join(open('/proc/loadavg').read().split()[:3])}")
    print("| scene | cells | nominal dt | steps taken | substepped | Courant max | wall s |")
    print("|---|---|---|---|---|---|---|")
    for name in args.scene or SCENES:
        scene = load_scene(f"studies/{name}.toml", ["mechanics.enabled=false"])
        began = time.perf_counter()
        ds = solver.simulate(scene.problem())
        cells = " × ".join(map(str, scene.grid.shape))
        print(f"| {name} | {cells} | {scene.time.t_end / scene.time.steps:g} | {ds.attrs['steps_taken']} | "
              f"{ds.attrs['steps_substepped']} | {ds.attrs['courant_max']:.3f} | {time.perf_counter() - began:.1f} |",
              flush=True)
    print(f"load average after: {' '.join(open('/proc/loadavg').read().split()[:3])}")


if __name__ == "__main__":
    main()
