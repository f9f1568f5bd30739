"""Accuracy per second on the directional scene: fixed against error-controlled steps.

    python benchmarks/accuracy.py                      # the bundled scene's advection scheme
    python benchmarks/accuracy.py --advection upwind

Runs the bundled directional scene (20^3, T* = 1) with fixed steps (the paper
used 1000) and with step doubling under a range of tolerances, and measures
each run's error at T* = 1 against a reference with 8000 fixed steps (the
same grid: this is the time-discretisation error; `biostudy convergence`
measures the grid's).  Prints a table and the least wall time after which
every more expensive run of the same kind stays within 1 % in
biofilm_volume — the volume counts cells with phi >= 0.5, so its error
jumps by whole cells and a single lucky run is not enough.
Asserts nothing: a table for docs/accuracy.md.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("FIPY_SOLVERS", "scipy")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from biostudy.inputs.scene import load_scene  # noqa: E402
from solver import simulate  # noqa: E402

SCENE = Path(__file__).resolve().parents[1] / "studies" / "directional.toml"


def run(overrides: list[str]):
    problem = load_scene(SCENE, overrides).problem()
    began = time.perf_counter()
    ds = simulate(problem)
    return ds, time.perf_counter() - began


def errors(ds, reference) -> dict:
    last, ref = ds.isel(time=-1), reference.isel(time=-1)
    phi = last.phi.values - ref.phi.values
    return {"volume": abs(float(last.biofilm_volume) / float(ref.biofilm_volume) - 1),
            "phi_L1": float(np.nanmean(np.abs(phi))), "c_mean": abs(float(last.c_mean - ref.c_mean))}


def reliable_time(rows: list[dict], limit: float = 0.01) -> float:
    """Least wall time from which on every (costlier) run is within `limit` in volume."""
    best = float("nan")
    for row in sorted(rows, key=lambda r: -r["wall"]):
        if row["volume"] > limit:
            break
        best = row["wall"]
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--advection", choices=["upwind", "tvd"], help="default: the scene's")
    parser.add_argument("--reference-steps", type=int, default=8000)
    args = parser.parse_args()
    common = ["time.outputs=11", "mechanics.enabled=false"]
    common += [f"numerics.advection=\"{args.advection}\""] if args.advection else []
    reference, seconds = run(common + [f"time.steps={args.reference_steps}"])
    scheme = reference.attrs["advection"]
    print(f"directional scene 20^3, T* = 1, advection = {scheme}; reference: {args.reference_steps} fixed steps "
          f"({seconds:.0f} s), biofilm_volume {float(reference.biofilm_volume[-1]):.0f} µm³")
    rows = []
    for steps in (50, 100, 200, 400, 1000, 2000):
        ds, wall = run(common + [f"time.steps={steps}"])
        rows.append({"kind": "fixed", "setting": f"{steps} steps", "steps": steps, "wall": wall,
                     **errors(ds, reference)})
    for tolerance in (3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4):
        ds, wall = run(common + ["time.steps=20", f"numerics.time_tolerance={tolerance}"])
        rows.append({"kind": "adaptive", "setting": f"tol {tolerance:g}", "steps": int(ds.attrs["steps_taken"]),
                     "rejected": int(ds.attrs["steps_rejected"]), "wall": wall, **errors(ds, reference)})
    print("| steps | setting | accepted steps | wall s | error biofilm_volume | error phi (L1) | error c_mean |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        extra = f" ({r['rejected']} rejected)" if "rejected" in r else ""
        print(f"| {r['kind']} | {r['setting']} | {r['steps']}{extra} | {r['wall']:.2f} | {100 * r['volume']:.2f} % | "
              f"{r['phi_L1']:.2e} | {r['c_mean']:.2e} |")
    for kind in ("fixed", "adaptive"):
        mine = [r for r in rows if r["kind"] == kind]
        print(f"\n{kind}: within 1 % in biofilm_volume from {reliable_time(mine):.2f} s of wall time on "
              f"(every costlier {kind} run stays within 1 %)")


if __name__ == "__main__":
    main()
