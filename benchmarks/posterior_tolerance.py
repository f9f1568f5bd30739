"""How far the bundled posterior moves with the solver's tolerance, and whether it depends on where it runs.

Runs `studies/calibrate-agar-posterior.toml` (issue 26: one posterior per file and seed) as it is, serially and
on two local workers, and serially with the nutrient's linear solves ten and a hundred times tighter
(`[numerics] nutrient_tolerance` 1e-11, 1e-12 against 1e-10: simulations that differ at the solver's
tolerance), and prints each parameter's posterior median and 95 % credible interval, with the largest relative
move of any of those numbers from the first row.

    python benchmarks/posterior_tolerance.py [--out DIR]   # ~4 posteriors of ~1-3 min each
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

import biostudy

RUNS = [("serial", {}, None), ("2 workers", {}, 2),
        ("nutrient_tolerance 1e-11", {"numerics.nutrient_tolerance": 1e-11}, None),
        ("nutrient_tolerance 1e-12", {"numerics.nutrient_tolerance": 1e-12}, None)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=None, help="where the calibrations go (default: a temporary)")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="posterior-tolerance-"))
    rows = []
    for label, overrides, workers in RUNS:
        ds = biostudy.calibrate("calibrate-agar-posterior", out / label.replace(" ", "-"), set=overrides,
                                workers=workers)
        rows.append((label, ds))
    names = [str(p) for p in rows[0][1].parameter.values]
    print("| run | " + " | ".join(f"{n} median [2.5 %, 97.5 %]" for n in names) + " | largest move from the first |")
    print("|---|" + "---|" * (len(names) + 1))
    first = np.concatenate([rows[0][1][v].values for v in ("posterior_median", "posterior_lower", "posterior_upper")])
    for label, ds in rows:
        cells = [f"{ds.posterior_median.values[j]:.4g} [{ds.posterior_lower.values[j]:.4g}, "
                 f"{ds.posterior_upper.values[j]:.4g}]" for j in range(len(names))]
        these = np.concatenate([ds[v].values for v in ("posterior_median", "posterior_lower", "posterior_upper")])
        print(f"| {label} | " + " | ".join(cells) + f" | {np.max(np.abs(these / first - 1)):.2%} |")


if __name__ == "__main__":
    main()
