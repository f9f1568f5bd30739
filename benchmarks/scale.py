"""How far one machine goes (issue 29.4): time per step and peak memory of the directional scene by grid size.

    python benchmarks/scale.py --quick                        # 32^3 with and without mechanics (~1 min)
    python benchmarks/scale.py                                # 32^3 ... 128^3 with mechanics, ... 200^3 without
    python benchmarks/scale.py --sizes 64 --outputs 5 81 --steps 80 --no-mechanics   # streamed outputs (29.1)
    python benchmarks/scale.py --sizes 32 --outputs 5 81 --steps 80 --no-mechanics --baseline /tmp/old
    python benchmarks/scale.py --sizes 48 96 --set params.k_alpha=5     # fast growth: a harder mechanics solve
    python benchmarks/scale.py --2d --sizes 400 800 --no-mechanics      # studies/directional2d.toml at n^2

The scene: `studies/directional.toml` (paper 4.1, a 20 µm cube) at n^3 cells of 20/n µm, the time step of the
scene (dt = 1e-3), `--steps` steps, `--outputs` outputs, mechanics as the scene has it (every 4th output and the
last) or off.  Each case is a fresh process that runs and writes the dataset as `biostudy run -o` does (fields
streamed to disk as they are made, `data.spool`), so its peak resident memory (VmHWM) is a run's.  Per case:
transport ms per step (the wall time of the loop's parts, `wall_time_*` less the mechanics, over the steps),
seconds per mechanics solve, the rest of the process's wall time (start, imports, operators, writing: "other s"),
the peak memory, the estimate `biostudy show` gives (`inputs.resources`) and peak / estimate.  Then the largest
n^3 whose estimate fits in --memory (24 GB: this machine) with and without mechanics, by the estimate alone.
Asserts nothing: tables for docs/transport.md and docs/mechanics.md.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "studies" / "directional.toml"
WITH_MECHANICS = (32, 48, 64, 96, 128)
WITHOUT_MECHANICS = (32, 48, 64, 96, 128, 160, 200)
QUICK = (32,)

CHILD = """\
import json, re, sys, time
began = time.perf_counter()
from pathlib import Path
from biostudy.execution.worker import pin_solvers
pin_solvers()
from biostudy.commands import run as command
from biostudy.inputs import resources
target, overrides = Path(sys.argv[1]), sys.argv[2:]
loaded = command.load(Path(SCENE), set=overrides, output=target)
result = command.compute(loaded)
attrs = result.dataset.attrs
peak = int(re.search(r"VmHWM:\\s+(\\d+) kB", open("/proc/self/status").read()).group(1)) * 1024
solves = int(result.dataset.sizes.get("time_mechanics", 0))
newton = [int(v) for v in result.dataset["newton_iterations"].values if v >= 0] if solves else []
try:
    estimate = resources.estimate(loaded.scene, streamed=True).memory
except TypeError:  # a version before outputs streamed (--baseline)
    estimate = resources.estimate(loaded.scene).memory
loop = sum(float(v) for k, v in attrs.items() if k.startswith("wall_time_"))  # the time loop's own parts
print(json.dumps({"wall": time.perf_counter() - began, "run": loop,
                  "mechanics": float(attrs.get("wall_time_mechanics", 0.0)), "steps": int(attrs["steps_taken"]),
                  "solves": solves, "newton": newton, "peak": peak, "estimate": estimate}))
"""


NDIM = 3  # --2d: 2


def overrides(n: int, steps: int, outputs: int, mechanics: bool, extra: tuple[str, ...] = ()) -> list[str]:
    return [f"grid.shape=[{','.join([str(n)] * NDIM)}]", f"grid.spacing={20.0 / n!r}", f"time.steps={steps}",
            f"time.t_end={steps * 1e-3!r}", f"time.outputs={outputs}", f"mechanics.enabled={str(mechanics).lower()}",
            *extra]


def case(n: int, steps: int, outputs: int, mechanics: bool, extra: tuple[str, ...] = ()) -> dict:
    """One run in a fresh process, its dataset written to a temporary directory (removed after)."""
    with tempfile.TemporaryDirectory() as directory:
        child = CHILD.replace("SCENE", repr(str(SCENE)))
        done = subprocess.run([sys.executable, "-c", child, str(Path(directory) / "run.nc"),
                               *overrides(n, steps, outputs, mechanics, extra)],
                              capture_output=True, text=True, env={"BIOSTUDY_MEMORY": "1 TB", **_env()},
                              cwd=directory)  # not this tree: `python -c` puts the working directory first
    if done.returncode:
        raise SystemExit(f"{n}^3 failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _env() -> dict:
    import os

    return {**os.environ, "PYTHONPATH": BASELINE or str(ROOT)}


BASELINE = ""  # --baseline DIR: another version's tree, run instead of this one


def largest_fitting(memory: float, mechanics: bool, outputs: int) -> int:
    """The largest n whose n^3 directional run the estimate puts within `memory` bytes."""
    from biostudy.inputs import resources
    from biostudy.inputs.scene import load_scene

    def need(n: int) -> float:
        scene = load_scene(SCENE, [f"grid.shape=[{','.join([str(n)] * NDIM)}]", f"grid.spacing={20.0 / n!r}",
                                   f"time.outputs={outputs}", f"mechanics.enabled={str(mechanics).lower()}"])
        return resources.estimate(scene, streamed=True).memory

    low, high = 8, 16
    while need(high) <= memory:
        low, high = high, 2 * high
    while high - low > 1:
        middle = (low + high) // 2
        low, high = (middle, high) if need(middle) <= memory else (low, middle)
    return low


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="32^3 only, with and without mechanics")
    parser.add_argument("--sizes", type=int, nargs="*", help="n of n^3 (default: all, by mechanics)")
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--outputs", type=int, nargs="*", default=[5])
    parser.add_argument("--no-mechanics", action="store_true", help="only runs without mechanics")
    parser.add_argument("--memory", type=float, default=24e9, help="bytes of memory for the largest fitting n")
    parser.add_argument("--set", dest="extra", action="append", default=[], metavar="KEY=VALUE",
                        help="another override of the scene, e.g. params.k_alpha=5 (fast growth)")
    parser.add_argument("--baseline", default="", help="run another version's tree instead (e.g. before streaming: "
                                                       "git archive 55c9f28 | tar -x -C /tmp/old)")
    parser.add_argument("--2d", dest="two", action="store_true", help="studies/directional2d.toml on n^2 cells")
    args = parser.parse_args()
    if args.two:
        global SCENE, NDIM
        SCENE, NDIM = ROOT / "studies" / "directional2d.toml", 2
    import os

    global BASELINE
    BASELINE = args.baseline

    os.environ.setdefault("BIOSTUDY_MEMORY", "1 TB")  # the estimate is reported, not enforced
    sys.path.insert(0, str(ROOT))
    plans = [(False, args.sizes or (QUICK if args.quick else WITHOUT_MECHANICS))]
    if not args.no_mechanics:
        plans.insert(0, (True, args.sizes or (QUICK if args.quick else WITH_MECHANICS)))
    print(f"{'n^3':>6} {'mech':>4} {'outputs':>7} {'ms/step':>8} {'s/solve':>8} {'other s':>8} {'peak GB':>8} "
          f"{'estimate GB':>11} {'peak/est':>8}")
    for mechanics, sizes in plans:
        for n in sizes:
            for outputs in args.outputs:
                began = time.perf_counter()
                found = case(n, args.steps, outputs, mechanics, tuple(args.extra))
                transport = (found["run"] - found["mechanics"]) / max(found["steps"], 1)
                per_solve = found["mechanics"] / found["solves"] if found["solves"] else float("nan")
                start = found["wall"] - found["run"]
                print(f"{n:>6} {'on' if mechanics else 'off':>4} {outputs:>7} {1e3 * transport:>8.1f} "
                      f"{per_solve:>8.2f} {start:>8.1f} {found['peak'] / 1e9:>8.2f} {found['estimate'] / 1e9:>11.2f} "
                      f"{found['peak'] / found['estimate']:>8.2f}   ({time.perf_counter() - began:.0f} s"
                      f"{', Newton steps ' + str(found['newton']) if found.get('newton') else ''})",
                      flush=True)
    for mechanics in (True, False):
        n = largest_fitting(args.memory, mechanics, max(args.outputs))
        print(f"largest n^3 within {args.memory / 1e9:g} GB by the estimate, mechanics {'on' if mechanics else 'off'}"
              f": {n}^3")


if __name__ == "__main__":
    main()
