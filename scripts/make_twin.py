"""Write a twin experiment's measurement table: the model at known parameters plus noise (`biostudy.calibration.twin`).

The bundled example's table was made by

    .venv/bin/python scripts/make_twin.py studies/agar2d.toml studies/calibrate-agar.tsv \
        --set grid.shape=[20,40] --set time.t_end=0.6 --set time.steps=150 \
        --set 'numerics.growth_velocity="front"' --truth g=1e8 --truth r=100 \
        --observable biomass --observable max_thickness --times 4.8,9.6,14.4,19.2,24,28.8 --t-ref-hours 48 \
        --noise 0.05 --seed 1
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("FIPY_SOLVERS", "scipy")

from biostudy.calibration.twin import table  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("output")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--truth", action="append", default=[], metavar="KEY=VALUE", help="a parameter's true value")
    parser.add_argument("--observable", action="append", required=True)
    parser.add_argument("--times", required=True, help="comma-separated measurement times (hours with --t-ref-hours)")
    parser.add_argument("--t-ref-hours", type=float, default=None, help="the real time of T* = 1, in hours")
    parser.add_argument("--noise", type=float, default=0.05, help="sigma as a fraction of each true value")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--condition", default="", help="every row's simulationConditionId (a PEtab id)")
    args = parser.parse_args()
    truth = {key: float(value) for key, value in (t.split("=", 1) for t in args.truth)}
    times = [float(t) for t in args.times.split(",")]
    factor = 1.0 / args.t_ref_hours if args.t_ref_hours else 1.0
    text = table(args.scene, truth=truth, observables_measured=args.observable, times=times, time_factor=factor,
                 noise=args.noise, seed=args.seed, overrides=args.overrides, condition=args.condition)
    Path(args.output).write_text(text, encoding="utf-8")
    print(f"wrote {args.output} ({len(text.splitlines()) - 1} measurements)")


if __name__ == "__main__":
    main()
