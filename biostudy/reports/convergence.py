"""How accurate is a scene's result, and what does accuracy cost: the measurements of `biostudy convergence`.

The levels are planned by `biostudy.plans.refinement`.  Every series is
measured against one reference (docs/accuracy.md, "How biostudy convergence
measures"): the Richardson extrapolation of the two finest levels of the
series refined in both h and dt,

    Q_ref = Q_L + (Q_L - Q_(L-1)) / (2^r - 1),

r the order of that series (first: backward Euler's; a smaller one if three
levels observe it, `richardson.believed`), with its own error beside it: with three levels the
change of the extrapolation from one level to the next, |Q_ref - Q_ref(L-1)|,
or its root mean square over the outputs where that is larger (at one output
the change can vanish by chance, as a front crosses cells); with two levels the
correction itself.  Or a given run
(`reference`): a refined run of the same scene, perhaps with another scheme.
Errors at every output time (dimension ``time``), fields restricted to the
series' common coarsest grid (`convergence_levels`); observed orders at every
output time from the differences of successive levels (unbiased by the
reference), |Q_l - Q_(l+1)| ~ size^p.  A level whose grid does not hold the
scene's regions as the study's finest grid does (`resolution.differences`: a
region that covers another volume on its cells, or a colony one cell thick)
solves a different model: flagged in the ``resolved`` variable, said in
``different_model_<series>_<level>``, and left out of the reference and, where
it differs from its own series' finest level, of the series' orders (a time
series on such a grid is one model throughout).  Quantities a series
reproduces to round-off get no order: they are reported as exact.
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np
import xarray as xr

from solver.counters import MEANINGS

from ..data import case_files, provenance
from ..inputs.scene import Scene
from ..plans import resolution
from ..plans.refinement import Refinement
from ..quantities import richardson
from .convergence_levels import COMPARED, COSTS, QUANTITIES, RELATIVE, SCALARS, UNITS, Level, finished

REFERENCE = "both"  # the series whose two finest levels make the reference
EXACT = 1e-9  # differences below this (relative to the quantity, absolute for field norms) are round-off


def _field_norms(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(L1, L2) of a - b per output time over the cells where both are finite (NaN where there are none)."""
    diff = a - b
    axes = tuple(range(1, diff.ndim))
    ok = np.isfinite(diff)
    count = ok.sum(axis=axes)
    with np.errstate(invalid="ignore", divide="ignore"):
        l1 = np.where(ok, np.abs(diff), 0.0).sum(axis=axes) / count
        l2 = np.sqrt(np.where(ok, diff**2, 0.0).sum(axis=axes) / count)
    return np.where(count > 0, l1, np.nan), np.where(count > 0, l2, np.nan)


def _norms(level: Level, reference: Mapping) -> dict[str, np.ndarray]:
    """phi L1, L2 and p L2 of level - reference per output time (NaN where either has no field)."""
    out = {name: np.full(level.times.size, np.nan) for name in ("phi_L1", "phi_L2", "p_L2")}
    if level.phi is not None and reference.get("phi") is not None:
        out["phi_L1"], out["phi_L2"] = _field_norms(level.phi, reference["phi"])
    if level.p is not None and reference.get("p") is not None:
        out["p_L2"] = _field_norms(level.p, reference["p"])[1]
    return out


def _errors(level: Level, reference: dict) -> dict[str, np.ndarray]:
    """Every compared quantity's error of `level` against `reference` at each output time."""
    out = _norms(level, reference)
    for q in SCALARS:
        difference = np.abs(level.scalars[q] - reference[q])
        if q in RELATIVE:  # a volume the reference does not have at all: infinitely wrong, unless absent too
            with np.errstate(invalid="ignore", divide="ignore"):
                scale = np.abs(reference[q])
                difference = np.where(scale > 0, difference / np.where(scale > 0, scale, 1.0),
                                      np.where(difference > 0, np.inf, 0.0))
        out[q] = difference
    return out


def _order_of(values: list[np.ndarray]) -> float:
    """The order observed over three levels (coarse to fine) of one series refined by 2, pooled over time."""
    if len(values) < 3:
        return float("nan")
    return richardson.space_order(values[-1] - values[-2], values[-3], values[-2])


def extrapolated(chain: list[Level]) -> tuple[dict, dict, dict]:
    """(reference, its estimated error, the order used) per quantity from the finished, resolved levels of the
    reference series, coarse to fine (at least two)."""
    formal = richardson.TIME_ORDER  # refined in h and dt together: backward Euler's first order bounds it
    reference, error, orders = {}, {}, {}
    for q in SCALARS:
        values = [level.scalars[q] for level in chain]
        r, _ = richardson.believed(_order_of(values), formal)
        value, correction = richardson.richardson(values[-1], values[-2], 2.0, r)
        if len(values) >= 3:  # the extrapolation's change; at one output it can vanish as a front crosses cells
            before, _ = richardson.richardson(values[-2], values[-3], 2.0, r)
            change = np.abs(value - before)
            finite = change[np.isfinite(change)]
            correction = np.fmax(change, np.sqrt(np.mean(finite**2))) if finite.size else change
        reference[q], error[q], orders[q] = value, correction, r
    for field in ("phi", "p"):
        fields = [getattr(level, field) for level in chain]
        if any(f is None for f in fields):
            continue
        norms = [_field_norms(coarse, fine)[0] for coarse, fine in zip(fields, fields[1:])]
        sums = [float(np.nansum(n)) for n in norms[-2:]]
        observed = float(np.log2(sums[0] / sums[1])) if len(sums) == 2 and min(sums) > 0 else np.nan
        r, _ = richardson.believed(observed, formal)
        reference[field] = richardson.richardson(fields[-1], fields[-2], 2.0, r)[0]
        orders[field] = r
    return reference, error, orders


def _successive(chain: list[Level]) -> dict[str, np.ndarray]:
    """|Q_l - Q_(l+1)| per quantity, (level - 1, time), over the levels of one series (coarse to fine)."""
    out = {q: np.abs(np.diff(np.stack([level.scalars[q] for level in chain]), axis=0)) for q in SCALARS}
    for a, b in ((a, b) for a, b in zip(chain, chain[1:])):
        found = _norms(a, {"phi": b.phi, "p": b.p})
        for name, value in found.items():
            out.setdefault(name, []).append(value)  # type: ignore[union-attr]
    for name in ("phi_L1", "phi_L2", "p_L2"):
        out[name] = np.stack(out[name]) if len(chain) > 1 else np.zeros((0, chain[0].times.size))
    return out


def measure(wanted: list[Refinement], out_dir: Path, levels: int, series: tuple[str, ...], base: Scene,
            given: Level | None = None, time: float | None = None,
            scenes: Mapping[str, Scene] | None = None) -> xr.Dataset:
    """convergence.nc from the finished levels: dimensions (series, level, time).  `given`: a reference run every
    level is measured against instead of the extrapolation; `time`: the output the attributes and the table speak
    of (default the last); `scenes`: each level's scene (job id -> Scene), to flag a level solving another model."""
    coarse_h = base.grid.spacing  # level 0 of every series is the scene as given: the common grid
    results = {lv.job_id: finished(case_files.case_file(out_dir, lv.job_id), lv.refine) for lv in wanted}
    times = next((r.times for r in results.values() if r is not None), np.asarray(base.time.times(), float))
    shape, full = (len(series), levels), (len(series), levels, times.size)
    table = {name: np.full(shape, np.nan) for name in ("cells", "h", "dt", "tolerance", "wall_time", "steps_taken",
                                                      "resolved", *COSTS)}
    errors = {q: np.full(full, np.nan) for q in QUANTITIES}
    values = {q: np.full(full, np.nan) for q in SCALARS}
    orders = {q: np.full((len(series), times.size), np.nan) for q in QUANTITIES}
    attrs: dict = {}
    ndim = len(base.grid.shape)
    flags, within = _flags(wanted, scenes, within=False), _flags(wanted, scenes, within=True)
    chain = [results[lv.job_id] for lv in wanted if lv.series == REFERENCE and not flags[(lv.series, lv.index)]]
    chain = [level for level in chain if level is not None]
    if given is not None:
        reference, reference_error, used = ({**given.scalars, "phi": given.phi, "p": given.p},
                                            {q: np.full(times.size, np.nan) for q in SCALARS}, {})
    elif len(chain) >= 2:
        reference, reference_error, used = extrapolated(chain)
    else:
        reference, reference_error, used = {}, {}, {}
    compared = int(np.argmin(np.abs(times - time))) if time is not None else times.size - 1
    for s, name in enumerate(series):
        mine = [lv for lv in wanted if lv.series == name]
        kept_sizes, kept = [], []
        for level in mine:
            i, result = level.index, results[level.job_id]
            table["cells"][s, i] = int(np.prod(base.grid.shape)) * level.refine**ndim
            table["h"][s, i] = coarse_h / level.refine
            table["tolerance"][s, i] = level.tolerance if level.tolerance is not None else np.nan
            different = flags[(name, i)]
            table["resolved"][s, i] = 0 if different else 1
            if different:
                attrs[f"different_model_{name}_{i}"] = "; ".join(different)
            if result is None:
                continue
            table["steps_taken"][s, i] = result.costs["steps_taken"]
            for cost in ("wall_time", *COSTS):
                table[cost][s, i] = result.costs[cost]
            table["dt"][s, i] = times[-1] / result.costs["steps_taken"]
            for q in SCALARS:
                values[q][s, i] = result.scalars[q]
            if reference:
                for q, value in _errors(result, reference).items():
                    errors[q][s, i] = value
            if not within[(name, i)]:
                size = {"adaptive": level.tolerance, "time": table["dt"][s, i]}.get(name, table["h"][s, i])
                kept_sizes.append(size)
                kept.append(result)
        if len(kept) < 2:
            continue
        differences = _successive(kept)
        for q in QUANTITIES:
            found = differences[q]
            exact = np.array([np.isfinite(found[:, t]).all() and bool(np.all(found[:, t] <= EXACT * _scale(kept, q, t)))
                              for t in range(times.size)])
            orders[q][s] = np.where(exact, np.nan,
                                    richardson.order_of_differences(np.array(kept_sizes, float)[:-1], found))
            if exact[compared]:
                attrs[f"order_{name}_{q}"] = "exact"
            elif np.isfinite(orders[q][s, compared]):
                attrs[f"order_{name}_{q}"] = float(orders[q][s, compared])
    return _dataset(series, levels, times, table, errors, values, orders, reference, reference_error, used,
                    attrs, base, given is not None, compared)


def _flags(wanted: list[Refinement], scenes: Mapping[str, Scene] | None, within: bool) -> dict:
    """(series, level) -> the regions a level's grid does not hold as the finest grid does ([] if none): the finest
    of the study, or (`within`) of the level's own series."""
    if not scenes:
        return {(lv.series, lv.index): [] for lv in wanted}
    out = {}
    finest_of_all = scenes[max(wanted, key=lambda lv: lv.refine).job_id]
    for level in wanted:
        mine = [lv for lv in wanted if lv.series == level.series]
        finest = scenes[max(mine, key=lambda lv: lv.refine).job_id] if within else finest_of_all
        out[(level.series, level.index)] = resolution.differences(scenes[level.job_id], finest)
    return out


def _scale(kept: list[Level], q: str, index: int) -> float:
    """The size of a scalar quantity at an output (1 for field norms): what round-off is measured against."""
    if q not in SCALARS:
        return 1.0
    return max(1.0, float(np.nanmax(np.abs([level.scalars[q][index] for level in kept]), initial=0.0)))


def _dataset(series, levels, times, table, errors, values, orders, reference, reference_error, used, attrs, base,
             given: bool, compared: int) -> xr.Dataset:
    """convergence.nc: the levels' sizes and costs, errors and values over time, orders over time, the reference."""
    sl, slt, st = ("series", "level"), ("series", "level", "time"), ("series", "time")
    data = {
        "cells": (sl, table["cells"], {"units": "1", "long_name": "number of grid cells"}),
        "h": (sl, table["h"], {"units": "um", "long_name": "cell size"}),
        "dt": (sl, table["dt"], {"units": "1", "long_name": "mean time step (T*)"}),
        "tolerance": (sl, table["tolerance"],
                      {"units": "1", "long_name": "time_tolerance of the error-controlled steps"}),
        "wall_time": (sl, table["wall_time"], {"units": "s", "long_name": "wall time of the run"}),
        "steps_taken": (sl, table["steps_taken"], {"units": "1", "long_name": MEANINGS["steps_taken"]}),
        "cell_steps": (sl, table["cells"] * table["steps_taken"],
                       {"units": "1", "long_name": "cells times accepted steps: the work, whatever the machine"}),
        **{name: (sl, table[name], {"units": "s", "long_name": MEANINGS[name]}) for name in COSTS},
        "cost": (sl, table["cpu_time_setup"] + table["cpu_time_loop"],
                 {"units": "s", "long_name": "CPU seconds of the level's set-up and time loop (its first step apart)"}),
        "resolved": (sl, table["resolved"], {"units": "1", "long_name": "1: the level's grid resolves the scene's "
                                             "regions as the study's finest does; 0: a different model (left out "
                                             "of the reference)"}),
        **{f"error_{c.name}": (slt, errors[c.name], {"units": c.units, "long_name": c.long_name}) for c in COMPARED},
        **{f"value_{q}": (slt, values[q], {"units": UNITS[q], "long_name": f"{q} of the level's run"})
           for q in SCALARS},
        **{f"order_{q}": (st, orders[q], {"units": "1", "long_name": f"observed order of {q} (successive levels)"})
           for q in QUANTITIES},
    }
    for q in SCALARS:
        if q in reference:
            data[f"reference_{q}"] = ("time", np.asarray(reference[q], float),
                                      {"units": UNITS[q], "long_name": f"reference value of {q}",
                                       **({"order": used[q]} if q in used else {})})
            data[f"reference_error_{q}"] = ("time", np.asarray(reference_error[q], float),
                                            {"units": UNITS[q], "long_name": f"estimated error of the reference {q}"})
    coords = {"series": ("series", np.array(series, dtype=object), {"units": "1", "long_name": "refinement series"}),
              "level": ("level", np.arange(levels), {"units": "1", "long_name": "refinement level (0 = as given)"}),
              "time": ("time", times, {"units": "1", "long_name": "normalised time T*"})}
    how = ("a given run" if given else
           f"Richardson extrapolation of the two finest levels of the series '{REFERENCE}' (h and dt refined "
           "together), order per reference_<q> variable, its error reference_error_<q> (three levels: the "
           "extrapolation's change from one level to the next, at least its root mean square over the outputs; two: "
           "the correction itself)")
    attrs.update({
        "Conventions": "CF-1.10", "title": f"convergence of {base.name}", "reference": how,
        "levels": levels, "series": ", ".join(series), "compared_time": float(times[compared]),
        "orders": "observed order per output time from the differences of successive resolved levels; "
                  "order_<series>_<q> attributes at compared_time",
    })
    return xr.Dataset(data, coords=coords, attrs=provenance.legal_attrs(attrs))
