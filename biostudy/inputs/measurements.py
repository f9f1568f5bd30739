"""A measurement table as a lab keeps it: PEtab's measurement-table columns, CSV or TSV (README, "Calibration").

::

    observableId    simulationConditionId   time    measurement     noiseParameters
    biomass         agar                    12      3.41            0.17
    max_thickness   agar                    12      8.02            0.40

One row per measurement: `observableId` names an observable of the registry
(`biostudy.quantities.observables`: biomass, mean_thickness, max_thickness, ...),
`time` is in the calibration file's `time_unit`, `measurement` is in the
observable's units (biomass in µm³/µm² = µm), `noiseParameters` is the
measurement's standard deviation σ (a number > 0: PEtab also allows a
parameter's name there, which is not supported), `simulationConditionId`
names one of the calibration's `[conditions]` (empty or absent without them).
PEtab's `datasetId` and `replicateId` are read and kept; its
`preequilibrationConditionId` and `observableParameters`, and any other
column, are refused rather than ignored.  The delimiter is a tab for `.tsv`
and `.tab` files, a comma for `.csv`, and otherwise whichever the header line
holds.  Every problem of the table is reported at once, one line each, naming
the file, the line and the column (`BadInput`).
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

from ..errors import BadInput

REQUIRED = ("observableId", "time", "measurement", "noiseParameters")
OPTIONAL = ("simulationConditionId", "datasetId", "replicateId")
REFUSED = {"preequilibrationConditionId": "pre-equilibration is not supported",
           "observableParameters": "observable parameters are not supported (the observables have none)"}


@dataclass(frozen=True)
class Measurement:
    """One row of the table: `line` is its line in the file (for messages), `time` in the table's own unit."""

    line: int
    observable: str
    time: float
    value: float
    sigma: float
    condition: str = ""
    dataset: str = ""
    replicate: str = ""


def _delimiter(path: Path, header: str) -> str:
    suffix = path.suffix.lower()
    if suffix in (".tsv", ".tab"):
        return "\t"
    if suffix == ".csv":
        return ","
    return "\t" if "\t" in header else ","


def _number(text: str, column: str, line: int, path: Path, problems: list[BadInput], positive: bool = False):
    where = f"line {line}: {column}"
    if not text:
        what = "the standard deviation sigma of the measurement" if column == "noiseParameters" else "a number"
        problems.append(BadInput(f"missing ({what})", path, where))
        return None
    try:
        value = float(text)
    except ValueError:
        problems.append(BadInput(f"not a number (got {text!r})", path, where))
        return None
    if not math.isfinite(value):
        problems.append(BadInput(f"must be a finite number (got {text!r})", path, where))
        return None
    if positive and value <= 0:
        problems.append(BadInput(f"the standard deviation must be > 0 (got {text})", path, where))
        return None
    return value


def read_measurements(path: str | Path) -> list[Measurement]:
    """Every row of a measurement table; `BadInput` with every problem found (missing or refused columns, an
    empty table, non-numbers, non-finite numbers, sigma <= 0 or missing)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")  # a spreadsheet's byte-order mark is not part of a name
    except FileNotFoundError:
        raise BadInput("no such file", path) from None
    except (OSError, UnicodeDecodeError) as error:
        raise BadInput(f"cannot be read as a text table ({error})", path) from None
    lines = text.splitlines()
    first = next((i for i, line in enumerate(lines) if line.strip()), None)
    if first is None:
        raise BadInput("is empty: a measurement table needs a header line (" + ", ".join(REQUIRED) + ")", path)
    reader = csv.reader(lines[first:], delimiter=_delimiter(path, lines[first]))
    header = [name.strip() for name in next(reader)]
    missing = [name for name in REQUIRED if name not in header]
    problems = [BadInput(f"missing column {name} (PEtab's measurement table: "
                         f"{', '.join(REQUIRED)}, optionally {', '.join(OPTIONAL)})", path) for name in missing]
    for name in header:
        if name in REFUSED:
            problems.append(BadInput(f"column {name}: {REFUSED[name]}", path))
        elif name not in REQUIRED + OPTIONAL:
            problems.append(BadInput(f"unknown column {name!r} (PEtab's measurement table: {', '.join(REQUIRED)}, "
                                     f"optionally {', '.join(OPTIONAL)})", path))
    repeated = sorted({name for name in header if header.count(name) > 1})
    problems += [BadInput(f"column {name} comes twice", path) for name in repeated]
    if problems:
        raise BadInput(problems[0].problem, path, problems[0].key, tuple(problems[1:]))
    rows = []
    for offset, cells in enumerate(reader):
        line = first + 2 + offset
        if not any(cell.strip() for cell in cells):
            continue
        if len(cells) != len(header):
            problems.append(BadInput(f"has {len(cells)} cells, the header {len(header)}", path, f"line {line}"))
            continue
        row = {name: cell.strip() for name, cell in zip(header, cells)}
        if not row["observableId"]:
            problems.append(BadInput("missing (the observable's name)", path, f"line {line}: observableId"))
        time = _number(row["time"], "time", line, path, problems)
        value = _number(row["measurement"], "measurement", line, path, problems)
        sigma = _number(row["noiseParameters"], "noiseParameters", line, path, problems, positive=True)
        if None not in (time, value, sigma) and row["observableId"]:
            rows.append(Measurement(line, row["observableId"], time, value, sigma,
                                    row.get("simulationConditionId", ""), row.get("datasetId", ""),
                                    row.get("replicateId", "")))
    if not problems and not rows:
        problems.append(BadInput("has a header but no measurements", path))
    if problems:
        raise BadInput(problems[0].problem, path, problems[0].key, tuple(problems[1:]))
    return rows
