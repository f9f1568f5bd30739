"""What ``biostudy measure`` reports: one row per frame of every stack, as a table, as JSON, and as the PEtab
measurement table a calibration reads (docs/comstat.md, "A lab's stacks").

A row holds the file, the frame, its time (given; `None` without), the six COMSTAT observables in their units
(`quantities.substratum.QUANTITIES`) and how they were measured (substratum face, threshold, the filter, voxel
sizes, the file's sha256).  The PEtab table has one row per frame and observable: ``observableId`` the
observable, ``simulationConditionId`` the condition given, ``time`` the frame's time (in the unit the calibration
will name as its ``time_unit``), ``measurement`` the value, ``noiseParameters`` σ: a number given per observable,
or by default a noise parameter per observable (``sigma_biomass``, ...) that the calibration estimates, and
``datasetId`` the stack's file name without its suffix (a PEtab id).  A value that is not a number (roughness
of a frame without biofilm) has no row: PEtab measures numbers.
"""
from __future__ import annotations

import math
import re
from typing import Any

from ..formatting import number, units_text
from ..quantities.stack_measures import OBSERVABLES, Measured
from ..quantities.substratum import QUANTITIES

COLUMNS = ("observableId", "simulationConditionId", "time", "measurement", "noiseParameters", "datasetId")


def records(measured: list[Measured], times: list[float] | None) -> list[dict[str, Any]]:
    """One record per frame of every file, in order; `times` one per frame of all files together (or None)."""
    rows = []
    for found in measured:
        for frame, values in enumerate(found.rows):
            rows.append({"file": str(found.frames.path), "frame": frame,
                         "time": None if times is None else float(times[len(rows)]),
                         **{name: float(values[name]) for name in OBSERVABLES},
                         "substratum": found.face, "threshold": found.threshold, "connected": found.connected,
                         "voxel": list(found.frames.voxel), "shape": list(found.frames.shape),
                         "sha256": found.frames.sha256})
    return rows


def table_text(rows: list[dict[str, Any]]) -> str:
    """The rows as a Markdown table people read: file, frame, time, the observables with their units."""
    head = ["file", "frame", "time", *(f"{n} ({units_text(QUANTITIES[n].units) or '1'})" for n in OBSERVABLES)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        cells = [row["file"], str(row["frame"]), "-" if row["time"] is None else number(row["time"]),
                 *(number(row[n]) for n in OBSERVABLES)]
        lines.append("| " + " | ".join(cells) + " |")
    first = rows[0] if rows else {}
    said = (f"substratum {first.get('substratum')}, biofilm: values >= {number(first.get('threshold'))}"
            if first.get("threshold") is not None else f"substratum {first.get('substratum')}, segmented stack")
    return "\n".join([*lines, "", said + (", connected to the substratum" if first.get("connected") else "")])


def dataset_id(path: str) -> str:
    """A file's name without its suffix, as a PEtab id (other characters as _)."""
    stem = re.sub(r"\.(ome\.)?(tiff?|png)$", "", path.rsplit("/", 1)[-1], flags=re.IGNORECASE)
    found = re.sub(r"\W", "_", stem)
    return found if re.match(r"[A-Za-z_]", found) else f"_{found}"


def petab_text(rows: list[dict[str, Any]], condition: str = "", noise: dict[str, float] | None = None,
               observables: tuple[str, ...] = OBSERVABLES) -> str:
    """The PEtab measurement table of the rows (module docstring): every row has its time."""
    noise = noise or {}
    lines = ["\t".join(COLUMNS)]
    for row in rows:
        for name in observables:
            value = row[name]
            if not math.isfinite(value):
                continue
            sigma = repr(float(noise[name])) if name in noise else f"sigma_{name}"
            lines.append("\t".join([name, condition, repr(float(row["time"])), repr(value), sigma,
                                    dataset_id(row["file"])]))
    return "\n".join(lines) + "\n"
