"""`biostudy measure STACK...`: COMSTAT's observables of a lab's confocal stacks, by the code that measures a run.

Every stack (or hyperstack of frames) is read by the image-input rules (`inputs.stacks`) and measured frame by
frame (`quantities.stack_measures`); the rows come back as records (`reports.measured`), a table people read, and
with `petab` the PEtab measurement table a calibration reads, one row per frame and observable at the `time`
given for each frame.  The table is a new file: one that is there is never replaced (a TSV has no place for
biostudy's mark, so biostudy cannot prove it wrote one), and one that appears while the stacks are measured is
not replaced either (it is linked into place, never renamed over).  Bad input is `BadInput`, one line each.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from ..data.writing import atomic, temporary_name
from ..errors import BadInput
from ..inputs.files import link_loop
from ..inputs.stacks import load
from ..quantities.stack_measures import OBSERVABLES
from ..quantities.stack_measures import measure as measured_frames
from ..reports import measured


@dataclass(frozen=True)
class Measured:
    """What `measure` found: one record per frame (`reports.measured.records`), the table it prints, and the PEtab
    table written (None without `petab`)."""

    records: list[dict[str, Any]]
    table: str
    written: Path | None = None


def _petab_target(path: Path) -> Path:
    if link_loop(path) or os.path.lexists(path):
        raise BadInput("exists; the measurement table is written as a new file (choose another name, or remove "
                       "it first)", path, "petab")
    if not path.parent.is_dir():
        raise BadInput(f"its folder {path.parent} does not exist", path, "petab")
    return path


def _times(time: Sequence[float] | None, frames: int, petab: Path | None) -> list[float] | None:
    if time is None:
        if petab is not None:
            raise BadInput("the measurement table needs the time of every frame: give time (T1,T2,..., in the unit "
                           "the calibration names as its time_unit)", None, "time")
        return None
    found = [float(t) for t in time]
    if len(found) != frames:
        raise BadInput(f"gives {len(found)} times for {frames} frames (one per frame, in the order of the stacks)",
                       None, "time")
    if not all(math.isfinite(t) and t >= 0 for t in found):
        raise BadInput("times are numbers >= 0", None, "time")
    return found


def _link(temporary: Path, path: Path) -> None:
    """Put the table in place only if nothing is there (a hard link fails on an existing name)."""
    try:
        os.link(temporary, path)
    except FileExistsError:
        raise BadInput("appeared while the stacks were measured; it is kept (nothing written)", path,
                       "petab") from None


def measure(stacks: Sequence[str | Path], *, voxel: Sequence[float] | None = None, threshold: float | None = None,
            substratum: str | None = None, connected: bool = False, petab: str | Path | None = None,
            time: Sequence[float] | None = None, condition: str = "",
            noise: dict[str, float] | None = None) -> Measured:
    """Measure every stack (module docstring; the options: `declared.MEASURE`); `petab`: also write the measurement
    table there, `time` one per frame, `condition` its simulationConditionId, `noise` σ per observable (default: a
    noise parameter each)."""
    if not stacks:
        raise BadInput("no stack given: biostudy measure STACK.tif [STACK.tif ...]")
    target = _petab_target(Path(petab)) if petab is not None else None
    sigmas = dict(noise or {})
    unknown = sorted(set(sigmas) - set(OBSERVABLES))
    if unknown:
        raise BadInput(f"{unknown[0]} is not measured here ({', '.join(OBSERVABLES)})", None, "noise")
    bad = [name for name, sigma in sigmas.items() if not 0 < sigma < math.inf]
    if bad:
        raise BadInput(f"σ of {bad[0]} must be > 0 (got {sigmas[bad[0]]:g})", None, "noise")
    found = [measured_frames(load(path, None if voxel is None else list(voxel)), threshold, substratum, connected)
             for path in stacks]
    times = _times(time, sum(len(m.rows) for m in found), target)
    records = measured.records(found, times)
    written = None
    if target is not None:
        text = measured.petab_text(records, condition, sigmas)
        temporary = temporary_name(target)
        written = atomic(target, lambda into: into.write_text(text, encoding="utf-8"), temporary=temporary,
                         rename=lambda: _link(temporary, target))
    return Measured(records, measured.table_text(records), written)
