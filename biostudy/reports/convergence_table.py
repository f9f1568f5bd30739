"""convergence.md: the levels and their errors at one output time, the reference beside its own error, the observed
orders at that time and over time, and the levels that solve a different model."""
from __future__ import annotations

import numpy as np
import xarray as xr

from ..formatting import number
from .convergence_levels import COSTS, QUANTITIES, SCALARS

OVER_TIME = ("phi_L1", "biofilm_volume", "front_position", "mean_thickness", "height")  # orders tabulated over time


def _cell(value, digits: int = 3, exponent: bool = True, missing: str = "-") -> str:
    return number(value, digits, exponent=exponent) if np.isfinite(float(value)) else missing


def _levels(ds: xr.Dataset, at: int, present: list[str]) -> list[str]:
    head = (["series", "level", "cells", "h µm", "dt", "tolerance", "steps", "set-up s", "loop CPU s", "cost s",
             "wall s", "model"] + [f"err {q}" for q in present])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name in ds.series.values:
        for level in ds.level.values:
            row = ds.sel(series=name, level=level)
            if not np.isfinite(float(row.cells)):
                continue
            cells = [str(name), str(int(level)), number(row.cells, 12), number(row.h), number(row.dt, 3),
                     number(row.tolerance, 1, exponent=True), number(row.steps_taken, 9),
                     *(_cell(row[c], 3, False) for c in (COSTS[0], COSTS[1], "cost")),
                     number(row.wall_time, 3) if np.isfinite(float(row.wall_time)) else "failed",
                     "same" if float(row.resolved) == 1 else "different"]
            cells += [_cell(row[f"error_{q}"].isel(time=at)) for q in present]
            lines.append("| " + " | ".join(cells) + " |")
    return lines


def _reference(ds: xr.Dataset, at: int) -> list[str]:
    names = [q for q in SCALARS if f"reference_{q}" in ds and np.isfinite(float(ds[f"reference_{q}"][at]))]
    if not names:
        return []
    lines = ["| quantity | reference | its estimated error | order used |", "|---|---|---|---|"]
    for q in names:
        value, error = ds[f"reference_{q}"], ds[f"reference_error_{q}"]
        lines.append(f"| {q} | {_cell(value[at], 4)} | {_cell(error[at], 2)} | "
                     f"{number(value.attrs['order'], 3) if 'order' in value.attrs else '-'} |")
    return lines


def _orders_now(ds: xr.Dataset, present: list[str]) -> list[str]:
    lines = ["| series | " + " | ".join(present) + " |", "|---|" + "---|" * len(present)]
    for name in ds.series.values:
        values = [ds.attrs.get(f"order_{name}_{q}", float("nan")) for q in present]
        lines.append(f"| {name} | " + " | ".join(v if isinstance(v, str) else number(v, 3) for v in values) + " |")
    return lines


def _orders_over_time(ds: xr.Dataset) -> list[str]:
    times = ds["time"].values
    lines = ["| series | quantity | " + " | ".join(f"T* = {t:g}" for t in times) + " |",
             "|---|---|" + "---|" * times.size]
    for name in ds.series.values:
        for q in OVER_TIME:
            found = ds[f"order_{q}"].sel(series=name).values
            if np.isfinite(found).any():
                lines.append(f"| {name} | {q} | " + " | ".join(_cell(v, 3, False) for v in found) + " |")
    return lines if len(lines) > 2 else []


def table_text(ds: xr.Dataset) -> str:
    """Markdown: every level at the compared time, the reference, the orders, the different models."""
    times = ds["time"].values
    at = int(np.argmin(np.abs(times - float(ds.attrs.get("compared_time", times[-1])))))
    present = [q for q in QUANTITIES if np.isfinite(ds[f"error_{q}"].values[..., at]).any()]
    lines = [f"Errors at T* = {times[at]:g} against the reference: {ds.attrs.get('reference', '')}.", ""]
    lines += _levels(ds, at, present) + [""]
    lines.append("set-up s: CPU time of the level's operators and initial nutrient; loop CPU s: its time loop (steps "
                 "and mechanics solves, the first of each apart: they load compiled kernels and build the first "
                 "hierarchies, a one-off like the process start and imports in wall s); cost s = set-up + loop. "
                 "model: 'different' where the level's grid does not hold the scene's regions as the study's finest "
                 "does: left out of the reference, and of its series' orders where its series' finest holds them "
                 "otherwise.")
    reference = _reference(ds, at)
    if reference:
        lines += ["", f"The reference at T* = {times[at]:g}:", ""] + reference
    lines += ["", f"Observed orders at T* = {times[at]:g} (slope of log |q_l - q_(l+1)| against log h, dt or "
              "tolerance, resolved levels):", ""] + _orders_now(ds, present)
    over = _orders_over_time(ds)
    if over:
        lines += ["", "Observed orders over time:", ""] + over
    notes = sorted((k, v) for k, v in ds.attrs.items() if k.startswith("different_model_"))
    if notes:
        lines += ["", "Levels solving a different model:", ""]
        lines += [f"- {k.removeprefix('different_model_').replace('_', ' level ')}: {v}" for k, v in notes]
    if "recommendation" in ds.attrs:
        lines += ["", str(ds.attrs["recommendation"]).strip()]
    return "\n".join(lines) + "\n"
