"""What leaving COMSTAT's observables out saves (issue 33.1): their cost on the bundled scenes that have no substratum.

Each scene runs at its bundled size with the mechanics off (the observables are measured on phi alone), in this
process; then the run's observables are computed as `biostudy run` does (`quantities.observables.variables`,
the fields in memory) twice, best of `--repeat`: as the scene is now (no substratum: COMSTAT's six left out) and
measured from the face 0.4.0 chose for it (the bottom for a floating biofilm, z- / y-; the maze from x+, where its
colony touches the domain's edge).  The table: the run's wall time (the simulation, mechanics off), both
observable times, and what leaving them out saves, in seconds and as a share of the run with its mechanics
(the column "run s" of `docs/gallery/runs.md`, when the scene is there) and without.

    python benchmarks/comstat_cost.py [--scene NAME]... [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

import solver
from biostudy.inputs.scene import load_scene
from biostudy.quantities import observables

SCENES = {"directional": "z-", "directional2d": "y-", "obstacles": "z-", "maze": "x+"}  # 0.4.0's face for each


def gallery_seconds() -> dict[str, float]:
    """The bundled runs' wall times with their mechanics, from the column "run s" of docs/gallery/runs.md."""
    path = os.path.join(os.path.dirname(__file__), "..", "docs", "gallery", "runs.md")
    lines = [line.strip("|\n ").split("|") for line in open(path, encoding="utf-8") if line.startswith("|")]
    header = [cell.strip() for cell in lines[0]]
    return {row[0].strip(): float(row[header.index("run s")]) for row in lines[2:]}


def best(function, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        began = time.perf_counter()
        function()
        times.append(time.perf_counter() - began)
    return min(times)


def measure(name: str, face: str, repeat: int) -> dict:
    scene = load_scene(f"studies/{name}.toml", ["mechanics.enabled=false"])
    began = time.perf_counter()
    ds = solver.simulate(scene.problem())
    run = time.perf_counter() - began
    now = ds.assign_attrs(scene.substratum_attrs(), grid_spacing=scene.grid.spacing)
    before = ds.copy().assign_attrs({**scene.substratum_attrs(), "substratum_face": face})
    assert "substratum_face" not in now.attrs, f"{name} has a substratum now: nothing is left out"
    left_out = best(lambda: observables.variables(now), repeat)
    measured = best(lambda: observables.variables(before), repeat)
    return {"scene": name, "cells": int(np.prod(scene.grid.shape)), "outputs": int(ds.sizes["time"]),
            "run": run, "now": left_out, "before": measured}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", action="append", choices=sorted(SCENES))
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    gallery = gallery_seconds()
    print(f"load average before: {' '.join(open('/proc/loadavg').read().split()[:3])}")
    print("| scene | cells | outputs | run s (no mechanics) | observables s, COMSTAT's left out | with COMSTAT's "
          "from 0.4.0's face | saved s | of the run without mechanics | of the bundled run with it |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.scene or SCENES:
        row = measure(name, SCENES[name], args.repeat)
        saved = row["before"] - row["now"]
        full = gallery.get(name)
        share = f"{100 * saved / full:.1f} % of {full:g} s" if full else "-"
        print(f"| {name} | {row['cells']} | {row['outputs']} | {row['run']:.2f} | {row['now']:.3f} | "
              f"{row['before']:.3f} | {saved:.3f} | {100 * saved / (row['run'] + row['before']):.1f} % | {share} |",
              flush=True)
    print(f"load average after: {' '.join(open('/proc/loadavg').read().split()[:3])}")


if __name__ == "__main__":
    main()
