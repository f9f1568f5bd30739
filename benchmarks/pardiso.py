"""What PARDISO (pypardiso, MKL: the `pardiso` extra, ~1 GB installed) gains over scipy's SuperLU on bundled scenes.

    python benchmarks/pardiso.py                 # each case with and without pypardiso, twice, alternating
    python benchmarks/pardiso.py --repeats 1

Each run in a fresh process (peak memory from /usr/bin/time -v); "without" hides pypardiso behind a module that
fails to import, as on a machine where it is not installed.  Printed: the run's mechanics wall time (the dataset's
wall_time_mechanics), the whole run's, the linear solver the run used, the peak, and the load average before
the case (the machine is shared).  Cases, each shortened: grate (2-D, 5 002 dofs: "auto" factorises), the
directional scene as it runs by default (3-D 20³, 27 783 dofs: multigrid, whose coarsest grid SuperLU
factorises either way) and the same with linear_solver = "direct" (the factorisation PARDISO exists for).
Results: docs/install.md.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile

from fresh import header, run_case

CASES = {
    "grate": ["grate", "time.t_end=0.4", "time.steps=400", "time.outputs=5", "mechanics.every=1"],
    "directional": ["directional", "time.t_end=0.1", "time.steps=100", "time.outputs=3", "mechanics.every=1"],
    "directional direct": ["directional", "mechanics.linear_solver=\"direct\"", "time.t_end=0.02", "time.steps=4",
                           "time.outputs=2", "mechanics.every=1"],
}


def measure(scene: str, overrides: list[str]) -> dict:
    """Run `scene` with `overrides` through the command line's code; its dataset's timings."""
    import netCDF4

    from biostudy.cli import app

    with tempfile.TemporaryDirectory() as folder:
        out = os.path.join(folder, "run.nc")
        arguments = ["run", scene, "-o", out, "-q"] + [item for o in overrides for item in ("--set", o)]
        try:
            app(arguments)
        except SystemExit as stop:
            if stop.code:
                raise
        with netCDF4.Dataset(out) as ds:
            return {"mechanics_s": float(ds.wall_time_mechanics), "run_s": float(ds.wall_time),
                    "solver": str(ds.mechanics_linear_solver)}


def hidden_pardiso() -> str:
    """A directory whose pypardiso.py fails to import, to put first on PYTHONPATH."""
    folder = tempfile.mkdtemp(prefix="no-pardiso-")
    with open(os.path.join(folder, "pypardiso.py"), "w") as stub:
        stub.write('raise ImportError("pypardiso hidden by benchmarks/pardiso.py")\n')
    return folder


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--case", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        os.environ.setdefault("FIPY_SOLVERS", "scipy")
        print(json.dumps(measure(args.case[0], args.case[1:])))
        return
    without = hidden_pardiso()
    header(f"{'case':20s} {'backend':8s} {'load':>5s} {'mechanics s':>11s} {'run s':>6s} {'peak GB':>7s}  solver")
    for _ in range(args.repeats):
        for name, (scene, *overrides) in CASES.items():
            for backend, baseline in (("pardiso", None), ("superlu", without)):
                r = run_case(__file__, ["--case", scene, *overrides], baseline=baseline)
                if "error" in r:
                    print(f"{name:20s} {backend:8s} {r['load']:5.1f} failed: {r['error']}")
                    continue
                print(f"{name:20s} {backend:8s} {r['load']:5.1f} {r['mechanics_s']:11.2f} {r['run_s']:6.2f} "
                      f"{r['peak_gb']:7.2f}  {r['solver']}")
                sys.stdout.flush()


if __name__ == "__main__":
    main()
