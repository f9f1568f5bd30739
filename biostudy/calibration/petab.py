"""A measurement table's PEtab identifiers in a calibration's outputs, and PEtab's simulation table.

* `id_variables`: calibration.nc's per-measurement text variables `dataset`,
  `replicate`, `datapoint` (PEtab's `datasetId`, `replicateId`, `datapointId`,
  empty where the table has none) and its attribute `measurement_columns` (the
  table's PEtab columns, in its order, comma-separated).
* `datasets_text`: calibration.md's table of the datasets per observable and
  condition, their replicates, and what each adds to chi² (a misfit dataset
  stands out there, not in the total).
* `simulation_table`: PEtab's simulation table (simulation.tsv, docs/calibrate.md):
  PEtab's optional simulation file has the measurement table's format with
  model simulations in it, the value column named `simulation` as PEtab's
  tools read it (libpetab's visualisation; the specification left the name
  open until PEtab issue #628); one row per row of the
  measurement table, in its order, the model at the estimate (calibration.nc's
  `fitted`), times in the table's own unit, the optional columns the measurement
  table had (`preequilibrationConditionId` and `observableParameters` empty, as
  they must be there) in PEtab's order.  Numbers are written as Python's `repr`
  writes them, the shortest text that reads back as the same double.
"""
from __future__ import annotations

import csv
import io
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from ..formatting import number

if TYPE_CHECKING:
    from .problem import CalibrationPlan

IDS = {"dataset": "datasetId", "replicate": "replicateId", "datapoint": "datapointId"}  # variable -> column
ORDER = ("observableId", "preequilibrationConditionId", "simulationConditionId", "time", "simulation",
         "observableParameters", "noiseParameters", "datasetId", "replicateId", "datapointId")  # PEtab's
ALWAYS = ("observableId", "simulationConditionId", "time", "simulation", "noiseParameters")
SHOWN_REPLICATES = 6  # replicate ids a row of calibration.md names; the others are counted


def id_variables(plan: CalibrationPlan) -> tuple[dict, dict]:
    """calibration.nc's `dataset`, `replicate`, `datapoint` per measurement (text, long names the PEtab
    columns), and its attribute `measurement_columns`."""
    rows = plan.measurements
    data = {name: ("measurement", np.array([getattr(m, name) for m in rows], dtype=object),
                   {"units": "1", "long_name": column}) for name, column in IDS.items()}
    return data, {"measurement_columns": ", ".join(rows[0].columns if rows else ())}


def _cell(text: str) -> str:
    return text.replace("|", "\\|") or "-"


def datasets_text(ds: xr.Dataset) -> list[str]:
    """calibration.md's lines on the datasets and replicates (none when the table names neither): per dataset,
    observable and condition, its replicates, measurements and share of chi²."""
    dataset, replicate = ds["dataset"].values.astype(str), ds["replicate"].values.astype(str)
    if not any(dataset) and not any(replicate):
        return []
    keys = list(zip(dataset, ds.observable.values.astype(str), ds.condition.values.astype(str)))
    squares = ds.residual.values ** 2
    lines = ["", "datasets and replicates (PEtab's datasetId, replicateId) and their share of chi²:", "",
             "| dataset | observable | condition | replicates | measurements | chi² |", "|---|---|---|---|---|---|"]
    groups: dict[tuple[str, str, str], list[int]] = {}  # one pass: 16,000 datasets took 10.5 s scanned per dataset
    for i, key in enumerate(keys):
        groups.setdefault(key, []).append(i)
    for key, at in groups.items():
        named = list(dict.fromkeys(replicate[i] for i in at if replicate[i]))
        shown = ", ".join(_cell(r) for r in named[:SHOWN_REPLICATES])
        if len(named) > SHOWN_REPLICATES:
            shown += f", … ({len(named)} in all)"
        lines.append(f"| {' | '.join(_cell(k) for k in key)} | {shown or '-'} | {len(at)} | "
                     f"{number(squares[at].sum(), 4)} |")
    return lines


def _number(value: float) -> str:
    return "NaN" if np.isnan(value) else repr(float(value))


def _noise(ds: xr.Dataset) -> list[str]:
    """noiseParameters as the table gave it: σ, or the name of a σ the calibration estimated."""
    names = ds.noise_name.values.astype(str) if "noise_name" in ds else [""] * ds.sizes["measurement"]
    return [name or _number(s) for name, s in zip(names, ds.sigma.values)]


def simulation_table(ds: xr.Dataset) -> str:
    """PEtab's simulation table of calibration.nc's `ds` (module docstring), as the text of a TSV file."""
    had = set(str(ds.attrs.get("measurement_columns", "")).split(", "))
    columns = [name for name in ORDER if name in ALWAYS or name in had]
    values = {"observableId": ds.observable.values.astype(str),
              "simulationConditionId": ds.condition.values.astype(str),
              "time": [_number(t) for t in ds.time_measured.values],
              "simulation": [_number(v) for v in ds.fitted.values],
              "noiseParameters": _noise(ds),
              **{column: ds[name].values.astype(str) for name, column in IDS.items()}}
    empty = [""] * ds.sizes["measurement"]
    text = io.StringIO()
    writer = csv.writer(text, delimiter="\t", lineterminator="\n")
    writer.writerow(columns)
    writer.writerows(zip(*(values.get(column, empty) for column in columns)))
    return text.getvalue()
