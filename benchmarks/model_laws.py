"""The bundled scenes under each form of the model's laws (`[model]`, docs/model.md), side by side.

    python benchmarks/model_laws.py                          # every bundled paper scene, as bundled (~15 min)
    python benchmarks/model_laws.py --scenes grate dead-end  # some of them

Each scene runs three times, as bundled (mechanics as the scene has it) and with one law changed:
the defaults (Eq. 36, quasi-steady nutrient), `model.expansion="table1"` (the local equation of the paper's
Table 1) and `model.nutrient="transient"` (Eq. 35 with dc/dt).  Printed per run: wall time and steps; the
biofilm (phi >= 0.5) and dense (phi >= 0.8) volume and mean c at the end; mean c at the first step's end
(where a transient nutrient still differs); alpha's range at the end, and with mechanics the largest
displacement and the pressure's extremes at the last solved output — where the expansion law shows.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

import numpy as np

os.environ.setdefault("FIPY_SOLVERS", "scipy")

SCENES = ["directional", "agar-g1e8", "agar-g1e10", "obstacles", "maze", "dead-end", "grate"]
LAWS = {"eq36, quasi-steady": [], "table1": ['model.expansion="table1"'], "transient": ['model.nutrient="transient"']}


def measured(name: str, overrides: list[str]) -> list[str]:
    from biostudy.inputs import bundled
    from biostudy.inputs.scene import load_scene
    from biostudy.quantities import measures
    from solver import simulate

    scene = load_scene(bundled.resolve(name), overrides)
    problem = scene.problem()
    first = problem.dt
    problem = dataclasses.replace(problem, output_times=np.unique(np.r_[problem.output_times, first]))
    began = time.perf_counter()
    ds = simulate(problem)
    wall = time.perf_counter() - began
    alpha = ds.alpha.values[-1]
    cells = [f"{wall:.1f}", f"{ds.attrs['steps_taken']} / {ds.attrs['steps_bisected']}",
             f"{measures.volume(ds, measures.THRESHOLD)[-1]:.0f}", f"{measures.volume(ds)[-1]:.0f}",
             f"{float(ds.c_mean.sel(time=first, method='nearest')):.4f}", f"{float(ds.c_mean[-1]):.4f}",
             f"{np.nanmin(alpha):.2g} … {np.nanmax(alpha):.2g}"]
    if "u" in ds:
        u = ds.u.isel(time_mechanics=-1).values
        p = ds.p.isel(time_mechanics=-1).values
        cells += [f"{np.nanmax(np.sqrt((u ** 2).sum(-1))):.3g}", f"{np.nanmin(p):.2g} / {np.nanmax(p):.2g}"]
    else:
        cells += ["–", "–"]
    return cells


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=SCENES)
    args = parser.parse_args(argv)
    print(f"load average before: {open('/proc/loadavg').read().split()[:3]}")
    head = ["scene", "laws", "wall s", "steps / bisected", "biofilm µm³ (2-D µm²) at end", "dense at end",
            "c_mean after one step", "c_mean at end", "alpha at end", "largest |u| µm", "p min / max Pa"]
    print("| " + " | ".join(head) + " |\n|" + "---|" * len(head), flush=True)
    for name in args.scenes:
        for laws, overrides in LAWS.items():
            print("| " + " | ".join([name, laws, *measured(name, overrides)]) + " |", flush=True)
    print(f"load average after: {open('/proc/loadavg').read().split()[:3]}")


if __name__ == "__main__":
    main(sys.argv[1:])
