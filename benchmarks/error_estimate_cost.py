"""What an error estimate costs: every bundled scene run plain and with its error estimate's companions.

    python benchmarks/error_estimate_cost.py                # every bundled scene, a quarter of its T* (~10 min)
    python benchmarks/error_estimate_cost.py --fraction 1 directional maze

Each bundled scene runs on its own grid, with mechanics as bundled, over a
fraction of its time (T* and steps scaled together, so the step is the
scene's own; the cost per step is what counts), first plain, then its
companions (`plans.companions`: (2h, 2dt), (2h, 4dt), (4h, 4dt), as
``biostudy run --error-estimate`` runs them).  Prints per scene: cells, steps,
the run's CPU time (this process: one thread, set-up included; steadier than
wall time on a shared machine), the companions' and its ratio to the run's
(the issue's bar: at most 0.6), the same ratio in wall time, which companions
ran, and why the others did not — most bundled scenes have a feature of one cell (a corner source, a
nutrient layer, a thin obstacle) that coarser cells cannot hold, and then the
estimate says so for nothing.  Asserts nothing: a table of docs/accuracy.md.
"""
from __future__ import annotations

import argparse
import math
import os
import time

os.environ.setdefault("FIPY_SOLVERS", "scipy")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from biostudy.execution.estimate import estimate, measured  # noqa: E402
from biostudy.inputs import bundled  # noqa: E402
from biostudy.inputs.scene import load_scene  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenes", nargs="*", help="bundled scene names (default: every bundled scene)")
    parser.add_argument("--fraction", type=float, default=0.25, help="of each scene's T* and steps (default 0.25)")
    args = parser.parse_args()
    scenes = [e.path for e in bundled.entries() if e.kind == "scene" and (not args.scenes or e.path.stem in
                                                                         args.scenes)]
    print(f"load average {os.getloadavg()[0]:.1f}; each scene over {args.fraction:g} of its T*")
    print("| scene | cells | steps | run CPU s | companions CPU s | companions / run | in wall time | companions run "
          "| not run |")
    print("|---|---|---|---|---|---|---|---|---|")
    for file in scenes:
        full = load_scene(file)
        steps = max(1, math.ceil(full.time.steps * args.fraction))
        overrides = [f"time.t_end={full.time.t_end * args.fraction:g}", f"time.steps={steps}"]
        scene = load_scene(file, overrides)
        began, cpu = time.perf_counter(), time.process_time()
        run = measured(scene, file)
        if isinstance(run, str):
            print(f"| {file.stem} | | | {run} | | | | | |")
            continue
        seconds, cpu = time.perf_counter() - began, time.process_time() - cpu
        spent_cpu = time.process_time()
        made = estimate(scene, file, run)
        spent, spent_cpu = float(made.attrs["error_estimate_wall_time"]), time.process_time() - spent_cpu
        said = str(made.attrs["error_estimate"])
        missing = [note for name, note in made.notes.items() if name not in made.runs]
        if said.startswith("not estimated"):
            missing = [said.removeprefix("not estimated: ")]
        print(f"| {file.stem} | {' x '.join(map(str, scene.grid.shape))} | {steps} | {cpu:.3g} | {spent_cpu:.3g} | "
              f"{spent_cpu / cpu:.2f} | {spent / seconds:.2f} | {', '.join(made.runs) or 'none'} | "
              f"{'; '.join(missing) or '-'} |", flush=True)


if __name__ == "__main__":
    main()
