"""Where the mechanics' memory per node goes: what it holds and what each phase adds, by grid size.

    python benchmarks/mechanics_memory.py                          # 24^3, 32^3, 48^3
    python benchmarks/mechanics_memory.py --sizes 32 --baseline /tmp/old   # another version's tree beside
    python benchmarks/mechanics_memory.py --ndim 2 --sizes 200 400           # a disc in a square, 2-D
    python benchmarks/mechanics_memory.py --sizes 24 --linear-solver amg     # another preconditioner

The static case of benchmarks/mechanics.py (a cube of 20 µm in n^3 cells, phi = 1 in a sphere of radius
5 µm smoothed over a cell, alpha = k phi, Table 2 parameters, no clamp; in 2-D a disc in a square of n^2
cells), two snapshots (alpha = k phi, then 1.1 k phi, warm-started), each size in a fresh process.  Per case,
in bytes per grid node (tracemalloc, which sees numpy's and scipy's arrays; SuperLU's factors of the coarsest
level are not seen):

- held after the two solves, by part (the arrays reachable from it): mesh (numbering, connectivity),
  assembler (pattern, index arrays), preconditioner (the tangent it was built from, the operators of the
  coarser levels, transfers, smoother data), pressure recovery, state (u, phi, alpha, constraints);
- what each phase adds above what was held when it began, at its worst: the assembly of a tangent, of a
  residual, a preconditioner build, a Krylov solve, the pressure recovery;
- the peak over the whole case (tracemalloc) and the process's VmHWM less its VmHWM before the mechanics
  was built (imports and the scene's fields not counted).

Asserts nothing: the table says which part to cut (docs/mechanics.md, "Memory").
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import time

from fresh import header, run_case

PHASES = ("tangent", "residual", "build", "krylov", "recover")


def vm_hwm() -> int:
    with open("/proc/self/status") as status:
        return int(re.search(r"VmHWM:\s+(\d+) kB", status.read()).group(1)) * 1024


def nbytes(root, seen: set[int]) -> int:
    """Bytes of the numpy arrays and scipy matrices reachable from `root` (each counted once in `seen`)."""
    import numpy as np
    import scipy.sparse as sp

    total, stack = 0, [root]
    while stack:
        item = stack.pop()
        if id(item) in seen or item is None or isinstance(item, (int, float, str, bool, type)):
            continue
        seen.add(id(item))
        if isinstance(item, np.ndarray):
            base = item
            while isinstance(base.base, np.ndarray):
                base = base.base
            if id(base) not in seen or base is item:
                seen.add(id(base))
                total += base.nbytes
        elif sp.issparse(item):
            stack.extend(getattr(item, name) for name in ("data", "indices", "indptr", "row", "col", "offsets")
                         if hasattr(item, name))
        elif isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, (list, tuple, set)):
            stack.extend(item)
        elif hasattr(item, "__dict__") and type(item).__module__.split(".")[0] in ("solver", "scipy"):
            stack.extend(vars(item).values())
        elif hasattr(item, "__slots__"):
            stack.extend(getattr(item, name, None) for name in item.__slots__)
    return total


class Phases:
    """Worst extra memory of each instrumented call above what was traced when it began (nested calls fine)."""

    def __init__(self):
        self.stack: list[list[int]] = []  # [traced at entry, peak seen so far]
        self.worst = {name: 0 for name in PHASES}
        self.entry = {name: 0 for name in PHASES}
        self.peak = 0  # the most traced at once

    def _propagate(self):
        import tracemalloc

        peak = tracemalloc.get_traced_memory()[1]
        self.peak = max(self.peak, peak)
        for frame in self.stack:
            frame[1] = max(frame[1], peak)
        tracemalloc.reset_peak()

    def wrap(self, owner, attribute: str, name, pick=None):
        original = getattr(owner, attribute)

        def wrapped(*args, **kwargs):
            import tracemalloc

            phase = name if pick is None else pick(args, kwargs)
            self._propagate()
            current = tracemalloc.get_traced_memory()[0]
            self.stack.append([current, current])
            try:
                return original(*args, **kwargs)
            finally:
                self._propagate()
                entry, peak = self.stack.pop()
                self.worst[phase] = max(self.worst[phase], peak - entry)
                self.entry[phase] = max(self.entry[phase], entry)
        setattr(owner, attribute, wrapped)


def disc(n: int):
    """The 2-D counterpart of `mechanics.scene`: a disc of radius 5 µm at the centre of a 20 µm square."""
    import numpy as np

    from solver import Grid

    grid = Grid((n, n), 20.0 / n)
    x, y = grid.cell_coordinates()
    return grid, np.clip(0.5 - (np.hypot(x - 10, y - 10) - 5.0) / grid.spacing, 0.0, 1.0)


def case(n: int, k: float, ndim: int, method: str, chunk: int) -> dict:
    import tracemalloc

    import numpy as np

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
    from mechanics import scene

    from solver import MechanicsSetup, Parameters
    from solver.mechanics import GrowthMechanics, Settings, assembly, linear, pressure

    grid, phi = scene(n) if ndim == 3 else disc(n)
    phases = Phases()

    def tangent_or_residual(args, kwargs):
        wanted = kwargs.get("tangent", args[6] if len(args) > 6 else True)
        return "tangent" if wanted else "residual"

    phases.wrap(assembly.Assembler, "evaluate", None, tangent_or_residual)
    phases.wrap(linear.TangentSolver, "_krylov", "krylov")
    phases.wrap(linear.TangentSolver, "_build", "build")
    phases.wrap(pressure.PressureRecovery, "recover", "recover")
    before = vm_hwm()
    tracemalloc.start()
    began = time.perf_counter()
    mechanics = GrowthMechanics(grid, Parameters(), MechanicsSetup(linear_solver=method), None,
                                settings=Settings(chunk=chunk))
    setup = tracemalloc.get_traced_memory()[0]
    result = None
    seconds = []
    for t in (1.0, 1.1):
        clock = time.perf_counter()
        result = mechanics.solve(phi, k * t * phi, t)
        seconds.append(time.perf_counter() - clock)
    phases._propagate()
    held_total = tracemalloc.get_traced_memory()[0]
    peak = phases.peak
    seen: set[int] = set()
    preconditioner = mechanics.linear.preconditioner
    held = {
        "mesh": nbytes(mechanics.mesh, seen),
        "assembler": nbytes(mechanics.assembler, seen),
        "preconditioner": nbytes(preconditioner, seen),
        "pressure": nbytes(mechanics.pressure, seen),
        "state": nbytes([mechanics.u, mechanics.phi, mechanics.alpha, mechanics.held, mechanics.constrained,
                         mechanics.pieces], seen),
    }
    nodes = int(np.prod(grid.nodes_shape))
    return {"n": n, "nodes": nodes, "dofs": mechanics.mesh.n_dofs, "setup": setup, "held": held,
            "held_total": held_total, "phases": phases.worst, "entry": phases.entry, "peak_traced": peak,
            "vm_hwm": vm_hwm() - before, "seconds": seconds, "setup_s": clock - began,
            "newton": result.newton_iterations, "krylov": result.info["krylov_iterations"],
            "u_max": float(np.nanmax(np.abs(result.u))), "p_min": float(np.nanmin(result.p))}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="*", default=[24, 32, 48])
    parser.add_argument("--k", type=float, default=1e-2, help="alpha = k phi (then 1.1 k phi)")
    parser.add_argument("--ndim", type=int, default=3, choices=(2, 3))
    parser.add_argument("--linear-solver", default="auto", choices=("auto", "direct", "multigrid", "amg"))
    parser.add_argument("--chunk", type=int, default=2048, help="cells assembled at once (Settings.chunk)")
    parser.add_argument("--baseline", default=None, help="another version's tree, run beside this one")
    parser.add_argument("--case", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case is not None:
        print(json.dumps(case(args.case, args.k, args.ndim, args.linear_solver, args.chunk)))
        return
    versions = [("this", None)] + ([("baseline", args.baseline)] if args.baseline else [])
    header(f"{'n^' + str(args.ndim):>5} {'version':>8} {'B/node:':>7} " + " ".join(f"{p:>8}" for p in
           ("mesh", "assembl.", "precond.", "pressure", "state")) + " | "
           + " ".join(f"{p:>8}" for p in PHASES) + f" | {'traced':>7} {'VmHWM':>7} {'load':>5} {'s':>6}")
    for n in args.sizes:
        for name, tree in versions:
            found = run_case(__file__, ["--case", str(n), "--k", str(args.k), "--ndim", str(args.ndim),
                                        "--linear-solver", args.linear_solver, "--chunk", str(args.chunk)], tree)
            if "error" in found:
                print(f"{n:>5} {name:>8} {found['error']}")
                continue
            per = found["nodes"]
            held = " ".join(f"{found['held'][p] / per:>8.0f}" for p in ("mesh", "assembler", "preconditioner",
                                                                          "pressure", "state"))
            phases = " ".join(f"{found['phases'][p] / per:>8.0f}" for p in PHASES)
            print(f"{n:>5} {name:>8} {'':>7} {held} | {phases} | {found['peak_traced'] / per:>7.0f} "
                  f"{found['vm_hwm'] / per:>7.0f} {found['load']:>5.1f} {sum(found['seconds']):>6.1f}"
                  f"   (Newton {found['newton']}, Krylov {found['krylov']}, |u| {found['u_max']:.6g}, "
                  f"min p {found['p_min']:.6g})", flush=True)


if __name__ == "__main__":
    main()
