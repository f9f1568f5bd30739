"""Error bars against true errors: bundled scenes at reduced size, each run's estimate beside its true error.

    python benchmarks/error_estimate.py                 # every case (the references take ~5 minutes on 2 cores)
    python benchmarks/error_estimate.py --case agar2d-h1 --case front

Each case runs a bundled scene at a reduced size with its error estimate (the
companions of `plans.companions`, as ``biostudy run --error-estimate``), and
the same scene at h/4 with dt/4 (the "true" answer: its own error is left out,
so a ratio is only as good as that reference).  Prints one row per observable
at the final output: the value, the estimated error, the true error
|Q - Q(h/4, dt/4)|, their ratio (the issue's bar: within a factor 3), and what
the companions cost against the run (CPU time of this process, set-ups included).
Where the estimate says the companions solve a different model, the row says
so instead of a ratio.  Asserts nothing: the table of docs/accuracy.md.
"""
from __future__ import annotations

import argparse
import os
import time
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("FIPY_SOLVERS", "scipy")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from biostudy.execution.estimate import estimate, measured  # noqa: E402
from biostudy.inputs.scene import load_scene  # noqa: E402

STUDIES = Path(__file__).resolve().parents[1] / "studies"


@dataclass(frozen=True)
class Case:
    name: str
    scene: str
    shape: tuple[int, ...]
    spacing: float
    steps: int
    common: tuple[str, ...]
    observables: tuple[str, ...]

    def overrides(self, refine: int = 1) -> list[str]:
        shape = ",".join(str(n * refine) for n in self.shape)
        return [f"grid.shape=[{shape}]", f"grid.spacing={self.spacing / refine}", f"time.steps={self.steps * refine}",
                *self.common]


FRONT = ('numerics.growth_velocity="front"',)
CASES = (
    Case("front", "front", (160, 4), 0.25, 200, (), ("front_advance", "biofilm_volume")),
    Case("agar2d-h1", "agar2d", (20, 40), 1.0, 300, ("time.t_end=0.3", *FRONT),
         ("biofilm_volume", "mean_thickness", "height", "c_mean")),
    Case("agar2d-h0.5", "agar2d", (40, 80), 0.5, 600, ("time.t_end=0.3", *FRONT),
         ("biofilm_volume", "mean_thickness", "height", "c_mean")),
    Case("directional2d-h0.5", "directional2d", (40, 40), 0.5, 600, ("time.t_end=0.3",),
         ("biofilm_volume", "height", "front_advance", "c_mean")),
    Case("agar-3d-h2", "agar-g1e8", (10, 10, 10), 2.0, 100, ("time.t_end=0.2", "time.outputs=5",
                                                          "mechanics.enabled=false"),
         ("biofilm_volume", "mean_thickness", "height", "c_mean")),
    # the directional scene with a 4 µm corner source (one cell on 4 µm cells, as the 1 µm source on 1 µm cells)
    Case("directional-4um-source-h2", "directional", (10, 10, 10), 2.0, 100,
         ("time.t_end=0.5", "time.outputs=6", "mechanics.enabled=false", "nutrient.0.lower=[16.0,16.0,16.0]"),
         ("biofilm_volume", "height", "front_advance", "c_mean")),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--case", action="append", choices=[c.name for c in CASES], help="default: every case")
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f}")
    print("| case | cells, h | steps | observable | value | estimated error | true error | ratio | "
          "companions / run (CPU) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for case in CASES:
        if args.case and case.name not in args.case:
            continue
        file = STUDIES / f"{case.scene}.toml"
        scene = load_scene(file, case.overrides())
        began = time.process_time()
        run = measured(scene, file)
        assert not isinstance(run, str), run
        seconds = time.process_time() - began
        made = estimate(scene, file, run)
        cost = (time.process_time() - began - seconds) / seconds
        reference = measured(load_scene(file, case.overrides(4)), file)
        assert not isinstance(reference, str), reference
        grid = f"{' x '.join(map(str, case.shape))}, {case.spacing:g} µm"
        for name in case.observables:
            value, fine = float(run[name].values[-1]), float(reference[name].values[-1])
            error = float(made.variables[f"{name}_error"].values[-1])
            true = abs(value - fine)
            ratio = f"{error / true:.2f}" if np.isfinite(error) and true > 0 else (
                "not estimated" if not np.isfinite(error) else "-")
            print(f"| {case.name} | {grid} | {case.steps} | {name} | {value:.4g} | {error:.3g} | {true:.3g} | "
                  f"{ratio} | {cost:.2f} |", flush=True)
        if not made.runs:
            print(f"| {case.name} | | | {made.attrs['error_estimate']} | | | | | |", flush=True)


if __name__ == "__main__":
    main()
