"""What a calibration costs, and how often its 95 % intervals hold the truth (issue 18, "Cost" and "Verified by").

    .venv/bin/python benchmarks/calibration.py                  # both parts
    .venv/bin/python benchmarks/calibration.py --only cost      # the bundled example, 4 ways
    .venv/bin/python benchmarks/calibration.py --only coverage --seeds 20
    .venv/bin/python benchmarks/calibration.py --only noise     # the observables' resolution
    .venv/bin/python benchmarks/calibration.py --only posterior # the bundled posterior example, serial and 2 workers
    .venv/bin/python benchmarks/calibration.py --only posterior-coverage --seeds 10
    .venv/bin/python benchmarks/calibration.py --only posterior-grid  # the bundled twin's posterior by brute force

cost: the bundled two-parameter twin (`studies/calibrate-agar.toml`: the 2-D agar colony on 20 x 40 cells,
150 steps, g and r from biomass and max_thickness at six times) without and with profiles, serially and on 2
local workers, each into a fresh directory: simulations, rounds, wall time and where it went (the rounds'
simulations, reading the observables back, the rest: fitting, writing, pictures), the mean simulation's own
wall time, and the speed-up of 2 workers.

coverage: the tiny twin of tests/test_calibration.py (12 x 16 cells, 40 steps, g = 1e9, r = 100, 8 measurements
of 5 % noise) calibrated with profiles for each of `--seeds` noise draws: how often each parameter's 95 % profile
interval, and the Jacobian's estimate ± 1.96 standard errors, hold the truth.  Reported as measured.

posterior: `studies/calibrate-agar-posterior.toml` (the same twin, method "posterior") serially and on 2 local
workers, each into a fresh directory: the simulations (the fit's, the surrogate's design, the held-out ones),
wall time and where it went (the rounds, reading the case files, the surrogate and the sampler, the rest), what
it found (median and 95 % credible interval), the sampler's acceptance and autocorrelation times, the
surrogate's held-out error.

posterior-coverage: the tiny twin of tests/test_calibration.py, method "posterior" (2 starts, design 16, 4 held
out, 1500 steps: the test's settings) for each of `--seeds` noise draws: how often each 95 % credible interval
holds the truth.  Reported as measured.

posterior-grid: the bundled twin's posterior without a surrogate, as a reference for the surrogate's: the
simulator itself on a grid of log10 g = 7.00, 7.05 ... 8.50 by log10 r = 1.85, 1.87 ... 2.15 (496 simulations,
~100 s on 2 workers), the likelihood exp(-chi²/2) summed over the grid with the prior of the calibration (flat
in log g and log r): each parameter's marginal median and 2.5 % / 97.5 % quantiles (the grid's cells taken as
steps of the cumulative distribution), and the share of the mass on the r grid's edges (it must be negligible).

noise: how smoothly the sub-cell observables follow a parameter (what the finite-difference steps are chosen
against): the bundled example's scene at g = 1e8 (1 + i eps), i = 1..4, for eps = 1e-8 ... 1e-2: the relative
change of biomass and max_thickness at T* = 0.2, 0.4, 0.6 divided by i eps (constant where the observable is
smooth; scattered where the solver's discrete events, a cell joining the front band, make it jump).
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("FIPY_SOLVERS", "scipy")
os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from biostudy.calibration import twin  # noqa: E402
from biostudy.commands import calibrate  # noqa: E402
from biostudy.execution.jobs import Execution  # noqa: E402
from biostudy.inputs import bundled  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def load_average() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


def run(path: Path, out: Path, workers: int | None, profiles: bool) -> xr.Dataset:
    job = calibrate.load(path, directory=out)
    job.plan.spec.method.profiles = profiles
    job.run(Execution(workers=workers))
    return xr.load_dataset(out / "calibration.nc")


def cost() -> None:
    source = bundled.resolve("calibrate-agar")
    print(f"## cost: {source.name} (load average at the start: {load_average()})\n")
    print("| profiles | workers | simulations | rounds | wall s | in rounds s | reading s | rest s | mean run s | "
          "g | r |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    walls = {}
    for profiles in (False, True):
        for workers in (None, 2):
            with tempfile.TemporaryDirectory() as scratch:
                out = Path(scratch) / "out"
                began = time.perf_counter()
                ds = run(source, out, workers, profiles)
                wall = time.perf_counter() - began
                runs = [float(xr.open_dataset(p).attrs["wall_time"]) for p in (out / "cases").glob("*.nc")]
            walls[(profiles, workers)] = wall
            a = ds.attrs
            rest = wall - a["wall_time_simulations"] - a["wall_time_reading"]
            interval = [f"{ds.estimate.values[j]:.4g} [{ds.lower.values[j]:.4g}, {ds.upper.values[j]:.4g}]"
                        if profiles else f"{ds.estimate.values[j]:.4g} ± {ds.standard_error.values[j]:.2g}"
                        for j in range(2)]
            print(f"| {'yes' if profiles else 'no'} | {workers or 'serial'} | {a['simulations']} | {a['rounds']} | "
                  f"{wall:.1f} | {a['wall_time_simulations']:.1f} | {a['wall_time_reading']:.1f} | {rest:.1f} | "
                  f"{np.mean(runs):.2f} | {interval[0]} | {interval[1]} |", flush=True)
    for profiles in (False, True):
        print(f"\nspeed-up on 2 workers, {'with' if profiles else 'without'} profiles: "
              f"{walls[(profiles, None)] / walls[(profiles, 2)]:.2f}x")
    print(f"\nload average at the end: {load_average()}\n")


def coverage(seeds: int, workers: int | None) -> None:
    from test_calibration import CALIBRATION, HOURS, SCENE, TRUTH

    print(f"## coverage: tiny twin, {seeds} noise seeds (load average at the start: {load_average()})\n")
    hits = {name: [0, 0] for name in TRUTH}  # profile, Jacobian
    closed = {name: 0 for name in TRUTH}
    simulations, began = 0, time.perf_counter()
    with tempfile.TemporaryDirectory() as scratch:
        here = Path(scratch)
        (here / "agar.toml").write_text(SCENE)
        (here / "cal.toml").write_text(CALIBRATION)
        for seed in range(seeds):
            (here / "twin.tsv").write_text(twin.table(here / "agar.toml", truth=TRUTH, observables_measured=[
                "biomass", "max_thickness"], times=HOURS, time_factor=1 / 20, noise=0.05, seed=1000 + seed))
            shutil.rmtree(here / "out", ignore_errors=True)
            ds = run(here / "cal.toml", here / "out", workers, True)
            simulations += ds.attrs["simulations"]
            row = []
            for j, name in enumerate(ds.parameter.values):
                truth = TRUTH[str(name)]
                inside = ds.lower.values[j] <= truth <= ds.upper.values[j]
                scaled, error = float(ds.estimate_scaled.values[j]), float(ds.standard_error_scaled.values[j])
                jacobian = abs(math.log10(truth) - scaled) <= 1.96 * error
                hits[str(name)][0] += inside
                hits[str(name)][1] += jacobian
                closed[str(name)] += bool(ds.identifiable.values[j])
                row.append(f"{name} {ds.estimate.values[j]:.3g} [{ds.lower.values[j]:.3g}, {ds.upper.values[j]:.3g}]"
                           f"{'' if inside else ' MISSED'}")
            print(f"seed {seed}: chi² {ds.attrs['chi2']:.2f}, " + "; ".join(row), flush=True)
    wall = time.perf_counter() - began
    print("\n| parameter | profile interval holds the truth | estimate ± 1.96 SE holds it | interval closed "
          "(identifiable) |")
    print("|---|---|---|---|")
    for name in TRUTH:
        print(f"| {name} | {hits[name][0]}/{seeds} | {hits[name][1]}/{seeds} | {closed[name]}/{seeds} |")
    print(f"\n{simulations} simulations, {wall:.0f} s; load average at the end: {load_average()}")


def posterior_cost() -> None:
    source = bundled.resolve("calibrate-agar-posterior")
    print(f"## posterior: {source.name} (load average at the start: {load_average()})\n")
    print("| workers | simulations (fit + design + held out) | wall s | in rounds s | reading s | surrogate and "
          "sampler s | rest s | g median [95 %] | r median [95 %] | acceptance | tau (steps) | surrogate error "
          "max (sigma) | box widened |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for workers in (None, 2):
        with tempfile.TemporaryDirectory() as scratch:
            out = Path(scratch) / "out"
            began = time.perf_counter()
            calibrate.load(source, directory=out).run(Execution(workers=workers))
            wall = time.perf_counter() - began
            ds = xr.load_dataset(out / "calibration.nc")
        a = ds.attrs
        fit = a["simulations"] - a["surrogate_design_runs"] - a["surrogate_held_out_runs"]
        rest = wall - a["wall_time_simulations"] - a["wall_time_reading"] - a["wall_time_sampling"]
        found = [f"{ds.posterior_median.values[j]:.4g} [{ds.posterior_lower.values[j]:.4g}, "
                 f"{ds.posterior_upper.values[j]:.4g}]" for j in range(2)]
        print(f"| {workers or 'serial'} | {a['simulations']} ({fit} + {a['surrogate_design_runs']} + "
              f"{a['surrogate_held_out_runs']}) | {wall:.1f} | {a['wall_time_simulations']:.1f} | "
              f"{a['wall_time_reading']:.1f} | {a['wall_time_sampling']:.1f} | {rest:.1f} | {found[0]} | {found[1]} | "
              f"{a['acceptance_fraction']:.2f} | {', '.join(f'{t:.3g}' for t in ds.autocorrelation_time.values)} | "
              f"{a['surrogate_error_max']:.2g} | {a['surrogate_box_widened']} |", flush=True)
        for said in filter(None, str(a["posterior_statements"]).split("; ")):
            print(f"\n{workers or 'serial'}: {said}")
    print(f"\nload average at the end: {load_average()}\n")


def posterior_coverage(seeds: int, workers: int | None) -> None:
    from test_calibration import CALIBRATION, HOURS, POSTERIOR, SCENE, TRUTH

    print(f"## posterior coverage: tiny twin, {seeds} noise seeds (load average at the start: {load_average()})\n")
    hits = {name: 0 for name in TRUTH}
    simulations, began, warned = 0, time.perf_counter(), 0
    with tempfile.TemporaryDirectory() as scratch:
        here = Path(scratch)
        (here / "agar.toml").write_text(SCENE)
        (here / "post.toml").write_text(CALIBRATION[:CALIBRATION.index("[method]")] + POSTERIOR)
        for seed in range(seeds):
            (here / "twin.tsv").write_text(twin.table(here / "agar.toml", truth=TRUTH, observables_measured=[
                "biomass", "max_thickness"], times=HOURS, time_factor=1 / 20, noise=0.05, seed=1000 + seed))
            shutil.rmtree(here / "out", ignore_errors=True)
            calibrate.load(here / "post.toml", directory=here / "out").run(Execution(workers=workers))
            ds = xr.load_dataset(here / "out" / "calibration.nc")
            simulations += ds.attrs["simulations"]
            warned += bool(ds.attrs["posterior_statements"])
            row = []
            for j, name in enumerate(ds.parameter.values):
                low, high = ds.posterior_lower.values[j], ds.posterior_upper.values[j]
                inside = low <= TRUTH[str(name)] <= high
                hits[str(name)] += inside
                row.append(f"{name} {ds.posterior_median.values[j]:.3g} [{low:.3g}, {high:.3g}]"
                           f"{'' if inside else ' MISSED'}")
            print(f"seed {seed}: " + "; ".join(row) + f"; surrogate error max {ds.attrs['surrogate_error_max']:.2g} "
                  f"sigma, tau {', '.join(f'{t:.3g}' for t in ds.autocorrelation_time.values)}"
                  + (f"; said: {ds.attrs['posterior_statements']}" if ds.attrs["posterior_statements"] else ""),
                  flush=True)
    wall = time.perf_counter() - began
    print("\n| parameter | 95 % credible interval holds the truth |\n|---|---|")
    for name in TRUTH:
        print(f"| {name} | {hits[name]}/{seeds} |")
    print(f"\n{simulations} simulations, {wall:.0f} s, {warned} of {seeds} with a warning; load average at the end: "
          f"{load_average()}")


def noise() -> None:
    import solver
    from biostudy.inputs.scene import load_scene
    from biostudy.quantities import substratum

    print(f"## noise: relative change per relative change of g (load average at the start: {load_average()})\n")
    given = ["grid.shape=[20,40]", "time.steps=150", "time.t_end=0.6", 'numerics.growth_velocity="front"',
             "time.output_times=[0.2,0.4,0.6]"]
    scene = bundled.resolve("agar2d")

    def measure(g: float) -> np.ndarray:
        ds = solver.simulate(load_scene(scene, [*given, f"g={g!r}"]).problem())
        phi = ds.phi.values  # the outputs at T* = 0.2, 0.4, 0.6 (explicit output times: no T* = 0)
        return np.array([substratum.biomass(f, 1.0, "y-") for f in phi] +
                        [substratum.max_thickness(f, 1.0, "y-") for f in phi])

    base = measure(1e8)
    names = [f"{q} T*={t}" for q in ("biomass", "max_thickness") for t in (0.2, 0.4, 0.6)]
    print("| eps | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for eps in (1e-8, 1e-6, 1e-4, 1e-3, 1e-2):
        slopes = np.array([(measure(1e8 * (1 + i * eps)) - base) / base / (i * eps) for i in range(1, 5)])
        print(f"| {eps:g} | " + " | ".join(" ".join(f"{v:.3f}" for v in column) for column in slopes.T) + " |",
              flush=True)
    print(f"\nload average at the end: {load_average()}\n")


def posterior_grid(workers: int | None) -> None:
    from biostudy.calibration.evaluator import Evaluator
    from biostudy.calibration.problem import load_calibration

    plan = load_calibration(bundled.resolve("calibrate-agar"))
    low, high = np.log10([1e7, 20.0]), np.log10([1e10, 400.0])  # the calibration's [estimate] ranges
    log_g, log_r = np.arange(7.0, 8.5001, 0.05), np.arange(1.85, 2.1501, 0.02)
    points = [(np.array([a, b]) - low) / (high - low) for a in log_g for b in log_r]
    print(f"## posterior on a grid: the bundled twin, {len(points)} simulations (load average at the start: "
          f"{load_average()})\n")
    with tempfile.TemporaryDirectory() as folder:
        began = time.perf_counter()
        results = Evaluator(plan, Path(folder), Execution(workers=workers)).evaluate(points)
        seconds = time.perf_counter() - began
    failed = sum(r is None for r in results)
    chi2 = np.array([np.inf if r is None else float(np.sum(np.square(r))) for r in results]).reshape(len(log_g), -1)
    weight = np.exp(-0.5 * (chi2 - chi2.min()))
    print(f"{seconds:.0f} s, {failed} failed; least chi² on the grid {chi2.min():.3f}; mass on the r grid's edges "
          f"{weight[:, [0, -1]].sum() / weight.sum():.1e}\n")
    print("| parameter | median | 95 % interval (2.5-97.5 %) |\n|---|---|---|")
    for name, axis, marginal in (("g", log_g, weight.sum(axis=1)), ("r", log_r, weight.sum(axis=0))):
        step = axis[1] - axis[0]
        edges = np.concatenate([[axis[0] - step / 2], axis + step / 2])
        cumulative = np.concatenate([[0.0], np.cumsum(marginal) / marginal.sum()])
        median, lower, upper = (10 ** np.interp(q, cumulative, edges) for q in (0.5, 0.025, 0.975))
        print(f"| {name} | {median:.4g} | [{lower:.4g}, {upper:.4g}] |")
    print(f"\nload average at the end: {load_average()}\n")


def main() -> None:
    parser = argparse.ArgumentParser(description="calibration cost and interval coverage")
    parser.add_argument("--only", choices=("cost", "coverage", "noise", "posterior", "posterior-coverage",
                                           "posterior-grid"))
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--workers", type=int, default=2, help="coverage: local workers per calibration")
    args = parser.parse_args()
    if args.only in (None, "cost"):
        cost()
    if args.only in (None, "coverage"):
        coverage(args.seeds, args.workers if args.workers > 1 else None)
    if args.only in (None, "noise"):
        noise()
    if args.only in (None, "posterior"):
        posterior_cost()
    if args.only in (None, "posterior-coverage"):
        posterior_coverage(args.seeds, args.workers if args.workers > 1 else None)
    if args.only in (None, "posterior-grid"):
        posterior_grid(args.workers if args.workers > 1 else None)


if __name__ == "__main__":
    main()
