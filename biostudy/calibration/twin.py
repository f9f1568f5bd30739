"""A twin experiment's measurement table: the model itself at known parameters, plus noise.

The standard test of a calibration method (docs/calibrate.md): simulate
a scene at the parameter values taken as the truth, measure the observables
at the given times, add normal noise of `noise` times each true value and
write PEtab's measurement table (the sigma column: that standard deviation).
A calibration of that table should find the truth within its intervals about
95 % of the time (`benchmarks/calibration.py` measures how often).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import solver

from ..errors import Failed
from ..inputs.resources import Preflight
from ..inputs.scene import load_scene
from ..quantities import observables


def table(scene: str | Path, *, truth: dict[str, float], observables_measured: list[str], times: list[float],
          time_factor: float = 1.0, noise: float = 0.05, seed: int = 0, overrides: list[str] | tuple[str, ...] = (),
          condition: str = "") -> str:
    """The TSV text of a twin table: `times` in the table's unit (T* = time * time_factor), one row per observable
    and time, measurement = true value + noise * |true value| * N(0, 1), noiseParameters = noise * |true value|."""
    model_times = sorted({t * time_factor for t in times})
    given = [*overrides, *(f"{key}={value!r}" for key, value in truth.items()),
             f"time.output_times=[{', '.join(repr(t) for t in model_times)}]"]
    loaded = load_scene(scene, given, Preflight(runs=True))
    try:
        ds = solver.simulate(loaded.problem())
    except solver.SimulationError as error:
        raise Failed(f"the twin's simulation failed: {error}") from None
    ds.attrs.update(loaded.substratum_attrs())
    rng = np.random.default_rng(seed)
    lines = ["observableId\tsimulationConditionId\ttime\tmeasurement\tnoiseParameters"]
    for name in observables_measured:
        series = observables.evaluate(ds, name).values
        for t in times:
            index = int(np.argmin(np.abs(ds["time"].values - t * time_factor)))
            true = float(series[index])
            sigma = noise * abs(true)
            lines.append(f"{name}\t{condition}\t{t:g}\t{true + sigma * rng.normal():.6g}\t{sigma:.6g}")
    return "\n".join(lines) + "\n"
