"""The cheapest resolution for a requested accuracy: the error model fitted to a convergence study's levels.

For one observable at one output time, the fixed-step levels that solve the
scene's model (space, time and both series; `resolved`) are fitted by least
squares to

    Q(h, dt) = Q* + a h^p + b dt^q,

p the spatial order observed by the space series (believed up to the scheme's
formal order, `richardson.believed`), q the time series' (up to backward
Euler's 1).  The relative error predicted for a run at (h, dt) is
(|a| h^p + |b| dt^q) / |Q*| (no cancellation between space and time is counted
on), its cost c1 cells steps + c2 cells + c3 steps, fitted (non-negative) to
the levels' cost (set-up and time loop CPU seconds).  Every grid of the scene's
domain with cubic cells from the coarsest level's size down to half the finest
level's, whose regions it resolves as the finest level does
(`plans.resolution`), gets the fewest steps that keep the predicted error
within the target (never longer steps than the coarsest level's); the cheapest
is recommended, ready for ``run --set``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import xarray as xr
from scipy.optimize import nnls

from ..formatting import number
from ..quantities import richardson

FIXED = ("space", "time", "both")


@dataclass(frozen=True)
class Fit:
    """Q(h, dt) = limit + a h^p + b dt^q at one output time, and the cost model."""

    observable: str
    time: float
    limit: float
    a: float
    p: float
    p_observed: bool
    b: float
    q: float
    q_observed: bool
    cost: tuple[float, float, float]  # seconds per cell-step, per cell, per step
    points: int

    def error(self, h: float, dt: float) -> float:
        """The predicted relative error of a run at (h, dt)."""
        return (abs(self.a) * h**self.p + abs(self.b) * dt**self.q) / abs(self.limit)

    def seconds(self, cells: float, steps: float) -> float:
        c1, c2, c3 = self.cost
        return c1 * cells * steps + c2 * cells + c3 * steps


@dataclass(frozen=True)
class Recommendation:
    """The cheapest run predicted to meet the target, or why there is none."""

    target: float
    fit: Fit | None
    settings: dict = field(default_factory=dict)  # grid.shape, grid.spacing, time.steps
    predicted_error: float = float("nan")
    predicted_cost_s: float = float("nan")
    reason: str = ""

    def as_json(self) -> dict:
        if not self.settings:
            return {"recommended": None, "reason": self.reason, "target_error": self.target}
        return {"recommended": {"set": self.settings, "predicted_error": self.predicted_error,
                                "predicted_cost_s": self.predicted_cost_s}}

    def attrs(self, observable: str) -> dict:
        """What convergence.nc records of it (`recorded` reads it back as `as_json`)."""
        out = {"target_error": self.target, "target_observable": observable, "recommendation": self.text()}
        if self.settings:
            out.update({"recommended_grid_shape": np.asarray(self.settings["grid.shape"], dtype=np.int64),
                        "recommended_grid_spacing": float(self.settings["grid.spacing"]),
                        "recommended_time_steps": int(self.settings["time.steps"]),
                        "recommended_predicted_error": self.predicted_error,
                        "recommended_predicted_cost_s": self.predicted_cost_s})
        return out


    def text(self) -> str:
        """The recommendation for convergence.md and the command's summary."""
        if self.fit is None:
            return f"No recommendation for a relative error of {self.target:g}: {self.reason}\n"
        fit = self.fit
        lines = [f"Error model of {fit.observable} at T* = {fit.time:g}, fitted to {fit.points} levels: "
                 f"Q = {number(fit.limit, 4)} + {number(fit.a, 3, exponent=True)} h^{number(fit.p, 3)} "
                 f"({'observed' if fit.p_observed else 'formal'}) + {number(fit.b, 3, exponent=True)} "
                 f"dt^{number(fit.q, 3)} ({'observed' if fit.q_observed else 'formal'}).", ""]
        if not self.settings:
            lines.append(f"No recommendation for a relative error of {self.target:g}: {self.reason}")
            return "\n".join(lines) + "\n"
        sets = " ".join(f"--set {key}={_toml(value)}" for key, value in self.settings.items())
        lines.append(f"Cheapest run predicted to reach a relative error of {self.target:g}: `{sets}` (predicted error "
                     f"{self.predicted_error:.3g}, set-up and time loop {self.predicted_cost_s:.3g} CPU s).")
        return "\n".join(lines) + "\n"


def recorded(attrs: dict) -> dict:
    """{"recommended": {"set": {...}, "predicted_error": ..., "predicted_cost_s": ...}} from convergence.nc's
    attributes (None and the reason where none was found; {} where none was asked for)."""
    if "target_error" not in attrs:
        return {}
    if "recommended_time_steps" not in attrs:
        return {"recommended": None, "reason": str(attrs.get("recommendation", "")).strip()}
    settings = {"grid.shape": [int(n) for n in np.atleast_1d(attrs["recommended_grid_shape"])],
                "grid.spacing": float(attrs["recommended_grid_spacing"]),
                "time.steps": int(attrs["recommended_time_steps"])}
    return {"recommended": {"set": settings, "predicted_error": float(attrs["recommended_predicted_error"]),
                            "predicted_cost_s": float(attrs["recommended_predicted_cost_s"])}}


def _toml(value) -> str:
    return "[" + ",".join(map(str, value)) + "]" if isinstance(value, list) else f"{value:.12g}"


def fit(ds: xr.Dataset, observable: str, time: float | None, scheme: str) -> Fit | str:
    """The error model of `observable` at the output nearest `time` (default: the compared one), or why not."""
    if f"value_{observable}" not in ds:
        return f"the convergence study does not measure {observable}"
    times = ds["time"].values
    at = int(np.argmin(np.abs(times - (float(ds.attrs.get("compared_time", times[-1])) if time is None else time))))
    rows = {}
    for name in (s for s in FIXED if s in ds.series.values):
        part = ds.sel(series=name)
        for level in part.level.values:
            row = part.sel(level=level)
            value = float(row[f"value_{observable}"][at])
            if float(row.resolved) == 1 and np.isfinite(value) and np.isfinite(float(row.dt)):
                rows[(float(row.h), float(row.dt))] = (value, float(row.cells), float(row.steps_taken),
                                                       float(row.cost))
    if len(rows) < 3:
        return f"fewer than 3 levels solving the scene's model finished ({len(rows)})"
    p, p_seen = _order(ds, "space", observable, at, richardson.FORMAL.get(scheme, 1.0))
    q, q_seen = _order(ds, "time", observable, at, richardson.TIME_ORDER)
    h, dt = np.array([k[0] for k in rows]), np.array([k[1] for k in rows])
    values = np.array([v[0] for v in rows.values()])
    design = np.column_stack([np.ones_like(h), h**p, dt**q])
    (limit, a, b), *_ = np.linalg.lstsq(design, values, rcond=None)
    if not limit:
        return f"the fitted limit of {observable} is 0: a relative error has no meaning"
    cells, steps, cost = (np.array([v[i] for v in rows.values()]) for i in (1, 2, 3))
    usable = np.isfinite(cost)
    coefficients = (nnls(np.column_stack([cells * steps, cells, steps])[usable], cost[usable])[0]
                    if usable.sum() >= 3 else np.array([np.nan] * 3))
    return Fit(observable, float(times[at]), float(limit), float(a), p, p_seen, float(b), q, q_seen,
               tuple(float(c) for c in coefficients), len(rows))  # type: ignore[arg-type]


def _order(ds: xr.Dataset, series: str, observable: str, at: int, formal: float) -> tuple[float, bool]:
    if series not in ds.series.values:
        return formal, False
    return richardson.believed(float(ds[f"order_{observable}"].sel(series=series)[at]), formal)


def grids(shape: list[int], spacing: float, coarsest: float, finest: float) -> list[tuple[list[int], float]]:
    """Every grid of the domain (shape x spacing) with cubic cells of size between `finest` and `coarsest`."""
    extent = [n * spacing for n in shape]
    out = []
    smallest = min(extent)
    low, high = math.ceil(smallest / coarsest - 1e-9), math.floor(smallest / finest + 1e-9)
    axis = extent.index(smallest)
    for n in range(max(low, 1), high + 1):
        h = extent[axis] / n
        counts = [e / h for e in extent]
        if all(abs(c - round(c)) < 1e-9 * max(1.0, c) for c in counts):
            out.append(([int(round(c)) for c in counts], h))
    return out


def recommend(model: Fit | str, target: float, ds: xr.Dataset, t_end: float, shape: list[int], spacing: float,
              resolves: Callable[[list[int], float], bool]) -> Recommendation:
    """The cheapest (grid.shape, grid.spacing, time.steps) predicted to keep the relative error within `target`."""
    if isinstance(model, str):
        return Recommendation(target, None, reason=model)
    ok = ds["resolved"].values == 1
    h_run, dt_run = ds["h"].values[ok], ds["dt"].values[ok]
    coarsest, finest = float(np.nanmax(h_run)), float(np.nanmin(h_run)) / 2
    fewest = max(1, math.ceil(t_end / float(np.nanmax(dt_run)) - 1e-9))
    budget = target * abs(model.limit)
    best: tuple | None = None
    for cells_along, h in grids(shape, spacing, coarsest, finest):
        left = budget - abs(model.a) * h**model.p
        if left <= 0:
            continue
        steps = fewest if model.b == 0 else max(fewest, math.ceil(t_end / (left / abs(model.b)) ** (1 / model.q)))
        cells = float(np.prod(cells_along))
        seconds = model.seconds(cells, steps)
        key = seconds if np.isfinite(seconds) else cells * steps
        if best is not None and key >= best[0]:
            continue
        if not resolves(cells_along, h):
            continue
        best = (key, cells_along, h, steps, seconds)
    if best is None:
        return Recommendation(target, model, reason=f"no grid down to {finest:g} µm (half the finest level's cells) "
                                                    "is predicted to reach it; run more levels")
    _, cells_along, h, steps, seconds = best
    settings = {"grid.shape": cells_along, "grid.spacing": h, "time.steps": steps}
    return Recommendation(target, model, settings, model.error(h, t_end / steps), seconds)
