"""Is a loss of dense biofilm the grid's or the model's?  The 2-D yardstick scenes under refinement.

Runs each scene (studies/agar2d*.toml, directional2d.toml; mechanics off) with the pointwise growth
velocity (Eq. 34 as written) at h = 1 ... 1/2^finest µm and with the front velocity at h = 1 ... 1/2^n µm,
the time step proportional to h, and prints per output time: max phi / top of phi >= 0.5 (µm, along y) /
area of phi >= 0.8 (µm² per µm of thickness) / y of the nutrient minimum and phi there, and wall times.
Every finished run is kept as a JSON file in --results (default docs/measured/dense-reference/), so an
interrupted call resumes and a later call only prints.

    python benchmarks/dense_reference.py                    # every scene, pointwise to h = 1/16 (hours on 2 cores)
    python benchmarks/dense_reference.py --scenes agar2d --finest 3 --front-finest 2 --workers 2
    python benchmarks/dense_reference.py --scenes agar2d --finest 4 --t-end 0.4   # h = 1/16 only to T* = 0.4

The finest pointwise run of each scene is the reference that tests/test_dense.py compares the front velocity
with on 1 µm and 1/2 µm cells (tests/data/dense_reference.json, written with --json).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

os.environ.setdefault("FIPY_SOLVERS", "scipy")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from biostudy.inputs.scene import load_scene  # noqa: E402
from biostudy.quantities import measures  # noqa: E402
from solver import simulate  # noqa: E402

SCENES = ("agar2d", "agar2d-g1e10", "agar2d-thin", "directional2d")


def refined(name: str, refine: int, velocity: str, t_end: float | None = None):
    """The scene on cells refine times smaller, steps refine times more (to t_end, default the scene's)."""
    base = load_scene(ROOT / "studies" / f"{name}.toml")
    shape = [n * refine for n in base.grid.shape]
    fraction = 1.0 if t_end is None else t_end / base.time.t_end
    cut = [] if t_end is None else [f"time.t_end={t_end}",
                                    f"time.outputs={int(round((len(base.time.times()) - 1) * fraction)) + 1}"]
    return load_scene(ROOT / "studies" / f"{name}.toml", [
        f"grid.shape={shape}", f"grid.spacing={base.grid.spacing / refine}",
        f"time.steps={int(round(base.time.steps * refine * fraction))}", *cut,
        f"numerics.growth_velocity=\"{velocity}\"", "mechanics.enabled=false"])


def result_file(results: Path, name: str, velocity: str, refine: int, t_end: float | None) -> Path:
    return results / (f"{name}_{velocity}_{refine}" + ("" if t_end is None else f"_to{t_end:g}") + ".json")


def run(name: str, refine: int, velocity: str, results: Path, t_end: float | None = None) -> dict:
    """One level: the dense measures per output time and the wall time, stored in `results`."""
    scene = refined(name, refine, velocity, t_end)
    began = time.perf_counter()
    ds = simulate(scene.problem())
    minimum = measures.nutrient_minimum(ds)
    result = {
        "scene": name, "velocity": velocity, "h": scene.grid.spacing, "wall_time": time.perf_counter() - began,
        "time": ds["time"].values.tolist(), "phi_max": measures.phi_max(ds).tolist(),
        "height": measures.height(ds, "y").tolist(), "dense_area": measures.volume(ds).tolist(),
        "reach": measures.reach(ds, "y").tolist(), "c_min_y": minimum["y"].tolist(),
        "phi_at_c_min": minimum["phi"].tolist(), "c_mean": ds["c_mean"].values.tolist(),
    }
    result_file(results, name, velocity, refine, t_end).write_text(json.dumps(result) + "\n")
    return result


def row(result: dict, times: list[float], brief: bool) -> str:
    cells = [f"{m:.2f}/{t:.1f}/{a:.0f}" + ("" if brief else f"/{y:.1f}:{p:.2f}") for m, t, a, y, p in
             zip(result["phi_max"], result["height"], result["dense_area"], result["c_min_y"], result["phi_at_c_min"])]
    cells = [c.replace("nan", "–") for c in cells] + ["–"] * (len(result["time"]) - len(cells))
    at = {round(t, 9): c for t, c in zip(result["time"], cells)}
    cells = [at.get(round(t, 9), "–") for t in times]  # a run cut short (--t-end) has no later columns
    return f"| {result['velocity']} | {result['h']:g} | " + " | ".join(cells) + f" | {result['wall_time']:.0f} |"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--finest", type=int, default=4, help="finest pointwise level: h = 1/2^finest µm")
    parser.add_argument("--front-finest", type=int, default=3, help="finest front level: h = 1/2^n µm")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--results", type=Path, default=ROOT / "docs" / "measured" / "dense-reference")
    parser.add_argument("--json", type=Path, help="store the finest pointwise run of each scene here")
    parser.add_argument("--t-end", type=float, help="run only to this T* (the finest pointwise level only)")
    parser.add_argument("--times", type=float, nargs="+", help="print only these output times")
    parser.add_argument("--brief", action="store_true", help="print max phi / top / dense area only")
    args = parser.parse_args()
    args.results.mkdir(parents=True, exist_ok=True)
    finest = 2**args.finest
    cut = lambda refine, velocity: args.t_end if (velocity, refine) == ("pointwise", finest) else None
    jobs = [(s, 2**n, "pointwise") for s in args.scenes for n in range(args.finest + 1)]
    jobs += [(s, 2**n, "front") for s in args.scenes for n in range(args.front_finest + 1)]
    file = lambda s, r, v: result_file(args.results, s, v, r, cut(r, v))
    todo = sorted((j for j in jobs if not file(*j).exists()), key=lambda j: -j[1])
    with ProcessPoolExecutor(args.workers) as pool:
        for done in as_completed([pool.submit(run, *job, args.results, cut(job[1], job[2])) for job in todo]):
            result = done.result()
            print(f"done: {result['scene']} {result['velocity']} h = {result['h']:g} ({result['wall_time']:.0f} s)",
                  flush=True)
    results = [json.loads(file(s, r, v).read_text()) for s, r, v in jobs]
    reference = {}
    for name in args.scenes:
        mine = sorted((r for r in results if r["scene"] == name), key=lambda r: (r["velocity"] != "pointwise", -r["h"]))
        print(f"\n### {name}\n")
        print("max phi / top of phi >= 0.5 (µm) / area of phi >= 0.8 (µm²)"
              + ("" if args.brief else " / y of the nutrient minimum : phi there") + "; – where there is none")
        print()
        times = args.times or max((r["time"] for r in mine), key=len)
        print("| growth velocity | h µm | " + " | ".join(f"T* = {t:g}" for t in times) + " | wall s |")
        print("|---|---|" + "---|" * len(times) + "---|")
        for result in mine:
            print(row(result, times, args.brief))
        reference[name] = min((r for r in mine if r["velocity"] == "pointwise"), key=lambda r: r["h"])
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(reference, indent=1) + "\n")
        print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
