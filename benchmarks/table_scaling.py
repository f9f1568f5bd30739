"""How a calibration's checks and reports grow with its measurement table (issue 39.11): both must be linear.

* `--only sigma`: validating a calibration (`calibration.problem.load_calibration`, what `show` and
  `calibrate` do before anything runs) whose table of n rows names n/2 σs (two rows each), beside the same table
  with σ given as numbers.  0.4.0 scanned the whole table per name: 64,000 rows took 97 s against 2.8 s.
* `--only datasets`: calibration.md's table of datasets (`calibration.petab.datasets_text`) for n measurements in
  n distinct datasetIds, and the fit's picture (`calibration.pictures.fit_figure`, drawn and saved as PNG).
  0.4.0 scanned every measurement per dataset (16,000: 10.5 s for the table) and drew an error-bar series per
  dataset (~30 ms each).

One row per n: seconds, and seconds per 1,000 rows (flat when linear).  Before/after: run it on the tree before
the change with that tree first on the path (`git archive lead | tar -x -C /tmp/old`, then
`PYTHONPATH=/tmp/old .venv/bin/python benchmarks/table_scaling.py`).

    .venv/bin/python benchmarks/table_scaling.py [--rows 2000,8000,32000] [--only sigma|datasets]
    PYTHONPATH=/tmp/old .venv/bin/python benchmarks/table_scaling.py --only datasets --rows 200,800  # before: slow
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")  # before matplotlib: no window

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

import biostudy  # noqa: E402
from biostudy.calibration.petab import datasets_text  # noqa: E402
from biostudy.calibration.pictures import fit_figure  # noqa: E402
from biostudy.calibration.problem import load_calibration  # noqa: E402

SCENE = Path(__file__).resolve().parents[1] / "studies" / "agar2d.toml"  # validated, never run
TIMES = (0.25, 0.5, 0.75, 1.0)  # h, t_ref 1 h (the scene ends at T* = 1): few times, few outputs


def table(rows: int, named: bool) -> str:
    """A measurement table of `rows` biomass rows; σ named (a name per two rows) or given."""
    lines = ["observableId\tsimulationConditionId\ttime\tmeasurement\tnoiseParameters"]
    lines += [f"biomass\t\t{TIMES[i % len(TIMES)]}\t{2.0 + 0.001 * i}\t{f'sigma_{i // 2}' if named else 0.1}"
              for i in range(rows)]
    return "\n".join(lines) + "\n"


def validating(folder: Path, rows: int, named: bool) -> float:
    (folder / "t.tsv").write_text(table(rows, named))
    path = folder / "c.toml"
    path.write_text(f'scene = "{SCENE}"\n[data]\nmeasurements = "t.tsv"\ntime_unit = "h"\nt_ref = "1 h"\n'
                    '[estimate]\nr = [50.0, 150.0]\n[method]\nstarts = 1\nprofiles = false\n')
    began = time.perf_counter()
    plan = load_calibration(path)
    assert len(plan.noise) == (rows // 2 if named else 0)
    return time.perf_counter() - began


def calibration_like(rows: int) -> xr.Dataset:
    """calibration.nc's per-measurement variables that calibration.md's dataset table reads, one dataset each."""
    text = lambda values: ("measurement", np.array(values, dtype=object))  # noqa: E731
    t = np.linspace(0.0, 1.0, rows)
    return xr.Dataset({"dataset": text([f"d{i}" for i in range(rows)]),
                       "replicate": text([f"r{i % 3}" for i in range(rows)]),
                       "observable": text(["biomass"] * rows), "condition": text([""] * rows),
                       "residual": ("measurement", np.linspace(-1.0, 1.0, rows)), "time_measured": ("measurement", t),
                       "measured": ("measurement", 2 + t), "fitted": ("measurement", 2 + t),
                       "sigma": ("measurement", np.full(rows, 0.1)), "band_lower": ("measurement", 1.9 + t),
                       "band_upper": ("measurement", 2.1 + t), "measurement_units": text(["um"] * rows)},
                      attrs={"chi2": 1.0, "dof": rows - 2})


def tabling(rows: int) -> tuple[float, float]:
    """Seconds for calibration.md's dataset table, and for the fit's picture (drawn and saved)."""
    ds = calibration_like(rows)
    began = time.perf_counter()
    lines = datasets_text(ds)
    assert len(lines) == rows + 5
    table = time.perf_counter() - began
    with tempfile.TemporaryDirectory() as folder:
        began = time.perf_counter()
        figure = fit_figure(ds)
        figure.savefig(Path(folder) / "fit.png")
        drawn = time.perf_counter() - began
    matplotlib.pyplot.close(figure)
    return table, drawn


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", default="2000,8000,32000", help="table sizes, comma-separated")
    parser.add_argument("--only", choices=("sigma", "datasets"))
    args = parser.parse_args()
    sizes = [int(n) for n in args.rows.split(",")]
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"biostudy from {Path(biostudy.__file__).parent}; load average {load}")
    print()
    if args.only in (None, "sigma"):
        with tempfile.TemporaryDirectory() as warm:
            validating(Path(warm), 4, True)  # the first validation pays for imports and caches: not in the table
        print("| rows | σ names | validating, σ named (s) | per 1,000 rows | σ as numbers (s) | per 1,000 rows |")
        print("|---|---|---|---|---|---|")
        for n in sizes:
            with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b:
                named, numbers = validating(Path(a), n, True), validating(Path(b), n, False)
            print(f"| {n:,} | {n // 2:,} | {named:.2f} | {1000 * named / n:.3f} | {numbers:.2f} | "
                  f"{1000 * numbers / n:.3f} |", flush=True)
        print()
    if args.only in (None, "datasets"):
        tabling(4)  # imports matplotlib's fonts: not in the table
        print("| measurements | datasets | calibration.md's dataset table (s) | per 1,000 datasets | fit picture (s) |")
        print("|---|---|---|---|---|")
        for n in sizes:
            table, drawn = tabling(n)
            print(f"| {n:,} | {n:,} | {table:.2f} | {1000 * table / n:.3f} | {drawn:.2f} |", flush=True)


if __name__ == "__main__":
    main()
