"""Do two versions of the solver give the same answers?  Every bundled scene run by both, compared field by field.

    git archive <commit> | tar -x -C /tmp/old
    python benchmarks/same_answers.py --baseline /tmp/old                 # every scene below
    python benchmarks/same_answers.py --baseline /tmp/old --scenes grate maze

Each scene is run by `biostudy run` in a fresh process, once with this version and once with the
baseline's `solver`/`biostudy` first on the path (mechanics off except where the list says, the maze
shortened to T* = 2: the scenes of docs/transport.md, "The same answers"; agar2d with the paper's other laws,
Table 1's expansion and the transient nutrient, and the dead ends (a baseline without them fails there: leave
them out with --scenes); then three scenes again with the mechanics on, as bundled, for its clamps, obstacles
and plane strain).  The two datasets are then
compared at every output: the largest |difference| of phi, c and alpha over cells and outputs (and of
every other field, the mechanics' where they were computed), and of every observable (a variable over time alone).
Printed as a markdown table with the CG iterations of both runs.  Asserts nothing: the sizes of the
differences are to be set beside the solver tolerances (1e-10 relative for c, 1e-12 for phi).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

MECHANICS_OFF = ["mechanics.enabled=false"]
SCENES = {  # name: (bundled scene, overrides)
    "directional": ("directional", []),
    "agar-g1e8": ("agar-g1e8", MECHANICS_OFF),
    "agar-g1e10": ("agar-g1e10", MECHANICS_OFF),
    "agar-g1e8-zero-order": ("agar-g1e8", MECHANICS_OFF + ['model.consumption="zero-order"']),
    "obstacles": ("obstacles", MECHANICS_OFF),
    "maze": ("maze", MECHANICS_OFF + ["time.t_end=2.0", "time.steps=400", "time.outputs=11"]),
    "agar2d": ("agar2d", MECHANICS_OFF),
    "agar2d-g1e10": ("agar2d-g1e10", MECHANICS_OFF),
    "agar2d-thin": ("agar2d-thin", MECHANICS_OFF),
    "directional2d": ("directional2d", MECHANICS_OFF),
    "grate": ("grate", MECHANICS_OFF),
    # the paper's other laws (docs/model.md) and its dead ends
    "agar2d-table1": ("agar2d", MECHANICS_OFF + ['model.expansion="table1"']),
    "agar2d-transient": ("agar2d", MECHANICS_OFF + ['model.nutrient="transient"']),
    "dead-end": ("dead-end", []),
    # the mechanics where it meets clamps, obstacles and plane strain (run with it on, as bundled)
    "agar-g1e8-mechanics": ("agar-g1e8", []),
    "obstacles-mechanics": ("obstacles", []),
    "grate-mechanics": ("grate", []),
}


def run(scene: str, overrides: list[str], out: str, baseline: str | None) -> float:
    """`biostudy run` of the scene into `out` by this version or the baseline's; wall seconds."""
    command = [sys.executable, "-c", "from biostudy.cli import app; app()", "run", scene, "-o", out, "-q", "--force"]
    for override in overrides:
        command += ["--set", override]
    path = [os.path.abspath(baseline)] if baseline else []
    began = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, text=True, cwd=os.path.dirname(out),  # not this tree
                   env={**os.environ, "PYTHONPATH": os.pathsep.join(path + sys.path)})
    return time.perf_counter() - began


def largest(a, b) -> float:
    """max |a - b| over every value (NaN where both are NaN, e.g. obstacles, is no difference)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    both = np.isnan(a) & np.isnan(b)
    if np.any(np.isnan(a) != np.isnan(b)):
        return np.inf
    return float(np.max(np.abs(np.where(both, 0.0, a - b)), initial=0.0))


def compare(this: str, old: str) -> dict:
    import xarray as xr

    with xr.open_dataset(this) as a, xr.open_dataset(old) as b:
        if not np.array_equal(a["time"].values, b["time"].values):
            raise SystemExit(f"{this} and {old}: different output times")
        timed = [k for k in a.data_vars if k in b.data_vars and {"time", "time_mechanics"} & set(a[k].dims)
                 and np.issubdtype(a[k].dtype, np.number)]  # the mechanics' fields at their own times
        fields = {k: largest(a[k], b[k]) for k in timed if {"x", "x_node"} & set(a[k].dims)}
        observables = {k: largest(a[k], b[k]) for k in timed if k not in fields and k != "elapsed"}
        iterations = tuple(int(d.attrs.get("nutrient_cg_iterations", -1)) for d in (a, b))
    worst = max(observables, key=observables.get) if observables else None
    return {"fields": fields, "observables": observables, "worst": worst, "iterations": iterations}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--baseline", required=True, help="directory holding the other version's solver/ and biostudy/")
    parser.add_argument("--scenes", nargs="*", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--keep", help="directory to keep the datasets in (default: a temporary one)")
    args = parser.parse_args()
    folder = os.path.abspath(args.keep or tempfile.mkdtemp(prefix="same-answers-"))
    os.makedirs(folder, exist_ok=True)
    rows = []
    for name in args.scenes:
        scene, overrides = SCENES[name]
        this, old = os.path.join(folder, f"{name}-this.nc"), os.path.join(folder, f"{name}-baseline.nc")
        load = os.getloadavg()[0]
        seconds = (run(scene, overrides, this, None), run(scene, overrides, old, args.baseline))
        result = compare(this, old)
        rows.append((name, load, seconds, result))
        print(f"# {name}: phi {result['fields'].get('phi', np.nan):.1e} (load {load:.1f})", file=sys.stderr, flush=True)
    print(f"this version against {args.baseline}: largest |difference| over cells and outputs")
    print("| scene | load | s, this / baseline | CG its, this / baseline | phi | c | alpha | other fields "
          "| observables: largest (which) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, load, seconds, r in rows:
        f = r["fields"]
        mech = ", ".join(f"{k} {v:.1e}" for k, v in f.items() if k not in ("phi", "c", "alpha")) or "–"
        worst = f"{r['observables'][r['worst']]:.1e} ({r['worst']})" if r["worst"] else "–"
        print(f"| {name} | {load:.1f} | {seconds[0]:.1f} / {seconds[1]:.1f} | {r['iterations'][0]} / "
              f"{r['iterations'][1]} | {f.get('phi', np.nan):.1e} | {f.get('c', np.nan):.1e} | "
              f"{f.get('alpha', np.nan):.1e} | {mech} | {worst} |")
    print(f"\ndatasets in {folder}")


if __name__ == "__main__":
    main()
