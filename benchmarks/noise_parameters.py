"""σ estimated from the residuals (issue 26.6): how often its 95 % intervals hold the truth, and the bundled twin
with its σ named instead of given.

`--only coverage`: a model linear in its 2 parameters (`tests/test_noise_parameters.py`'s), n rows sharing one
unknown σ, seeded Gaussian noise; the fit is `fitting.estimate.least_squares` with profiles, exactly as a
calibration runs it (on an analytic model instead of simulations).  For such a model the coverage is known:
the parameter's profile interval is |t| <= sqrt((n - 2)(exp(3.84 / n) - 1)) with t Student's of n - 2 degrees
of freedom, σ's n (σ̂²/σ² - log(σ̂²/σ²) - 1) <= 3.84 with n σ̂²/σ² chi² of n - 2 degrees of freedom (computed
here on its own, not by `likelihood.coverage`).  One row per n: the draws' coverage beside the theory.

`--only agar`: `studies/calibrate-agar.toml` (twin of g = 1e8, r = 100, 5 % noise) with its table's σ replaced
by two names, `sigma_biomass` and `sigma_thickness` (one σ per observable, estimated), beside the same
calibration with the table's σ.  Prints estimates, profile intervals and the σ̂s with theirs.

    python benchmarks/noise_parameters.py --only coverage [--draws 400] > docs/measured/noise-coverage.txt
    python benchmarks/noise_parameters.py --only agar > docs/measured/noise-agar.txt     # ~2 calibrations
"""
from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import stats
from scipy.optimize import brentq

import biostudy
from biostudy.fitting.estimate import least_squares
from biostudy.fitting.likelihood import THRESHOLD, Likelihood
from biostudy.fitting.objective import Objective

ROWS = (4, 6, 12, 40)
TRUTH = np.array([0.4, 0.5])
SIGMA = 0.05
PARAMETERS = 2
STUDIES = Path(__file__).resolve().parents[1] / "studies"
NAMES = {"biomass": "sigma_biomass", "max_thickness": "sigma_thickness"}


def theory(n: int) -> tuple[float, float]:
    """(the parameters', σ's) exact coverage of the 95 % profile intervals with n rows."""
    dof = n - PARAMETERS
    t = math.sqrt(dof * (math.exp(THRESHOLD / n) - 1))
    parameter = 1 - 2 * stats.t.sf(t, dof)
    rise = lambda v: n * (v - math.log(v) - 1) - THRESHOLD  # noqa: E731 -- v = σ̂² / σ²
    low, high = brentq(rise, 1e-9, 1.0), brentq(rise, 1.0, 1e9)
    return parameter, stats.chi2.cdf(n * high, dof) - stats.chi2.cdf(n * low, dof)


def draw(n: int, seed: int) -> tuple[bool, bool, bool]:
    """Whether each parameter's and σ's interval holds the truth in one seeded draw."""
    t = np.linspace(0.1, 1.0, n)
    x = np.stack([2 * t, 3 * t**2], axis=1)
    data = 1 + x @ TRUTH + SIGMA * np.random.default_rng(seed).normal(size=n)
    objective = Objective(lambda points: [1 + x @ np.asarray(p) - data for p in points], n, np.full(n, 1e-9),
                          ("a", "b"), likelihood=Likelihood((np.arange(n),), (1.0,)))
    found = least_squares(np.array([[0.05, 0.95], [0.95, 0.05]]), objective)
    held = [p.lower <= u <= p.upper for p, u in zip(found.profiles, TRUTH)]
    sigma = found.sigmas[0]
    return held[0], held[1], sigma.lower <= SIGMA <= sigma.upper


def coverage(draws: int) -> None:
    began = time.perf_counter()
    print(f"## 95 % profile intervals with σ estimated: {draws} draws per row count, linear model of 2 "
          f"parameters, σ = {SIGMA} (load average at the start: {', '.join(f'{v:.2f}' for v in os.getloadavg())})")
    print()
    print("| rows | a held | b held | theory (a, b) | σ held | theory (σ) |")
    print("|---|---|---|---|---|---|")
    for n in ROWS:
        held = np.array([draw(n, seed) for seed in range(draws)])
        parameter, sigma = theory(n)
        print(f"| {n} | {held[:, 0].mean():.3f} | {held[:, 1].mean():.3f} | {parameter:.3f} | {held[:, 2].mean():.3f} "
              f"| {sigma:.3f} |", flush=True)
    print()
    print(f"({time.perf_counter() - began:.0f} s; a fraction of {draws} draws scatters by "
          f"~{math.sqrt(0.95 * 0.05 / draws):.3f} around its expectation)")


def agar(out: Path) -> None:
    """The bundled twin, σ given and σ named."""
    named = out / "inputs"
    named.mkdir(parents=True, exist_ok=True)
    lines = (STUDIES / "calibrate-agar.tsv").read_text().splitlines()
    rows = [line.split("\t") for line in lines[1:] if line.strip()]
    (named / "calibrate-agar.tsv").write_text("\n".join([lines[0], *("\t".join([*row[:4], NAMES[row[0]]])
                                                                     for row in rows)]) + "\n")
    text = (STUDIES / "calibrate-agar.toml").read_text().replace('scene = "agar2d.toml"',
                                                                 f'scene = "{STUDIES / "agar2d.toml"}"')
    (named / "calibrate-agar-named.toml").write_text(text)
    print(f"## the bundled twin (g = 1e8, r = 100, 5 % noise), σ given and σ named (load average at the start: "
          f"{', '.join(f'{v:.2f}' for v in os.getloadavg())})")
    print()
    print("| σ | simulations | wall s | g [95 %] | r [95 %] | noise parameters: σ̂ [95 %] |")
    print("|---|---|---|---|---|---|")
    for label, calibration in (("given", "calibrate-agar"), ("named", named / "calibrate-agar-named.toml")):
        began = time.perf_counter()
        ds = biostudy.calibrate(calibration, out / label)
        found = [f"{p} {float(ds.estimate[j]):.4g} [{float(ds.lower[j]):.4g}, {float(ds.upper[j]):.4g}]"
                 for j, p in enumerate(ds.parameter.values)]
        sigmas = [f"{n} {float(ds.noise_estimate[j]):.4g} [{float(ds.noise_lower[j]):.4g}, "
                  f"{float(ds.noise_upper[j]):.4g}] {ds.noise_units.values[j]}"
                  for j, n in enumerate(ds.noise_parameter.values)] if "noise_parameter" in ds.coords else ["-"]
        print(f"| {label} | {ds.attrs['simulations']} | {time.perf_counter() - began:.0f} | {found[0]} | "
              f"{found[1]} | {'; '.join(sigmas)} |", flush=True)
    rms = {name: math.sqrt(np.mean([float(row[4]) ** 2 for row in rows if row[0] == observable]))
           for observable, name in NAMES.items()}
    print()
    print("the table's σ, root mean square per observable: " + ", ".join(f"{n} {v:.4g}" for n, v in rms.items()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", choices=("coverage", "agar"), required=True)
    parser.add_argument("--draws", type=int, default=400)
    parser.add_argument("--out", type=Path, default=None, help="where the calibrations go (default: a temporary)")
    args = parser.parse_args()
    if args.only == "coverage":
        coverage(args.draws)
    else:
        agar(args.out or Path(tempfile.mkdtemp(prefix="noise-agar-")))


if __name__ == "__main__":
    main()
