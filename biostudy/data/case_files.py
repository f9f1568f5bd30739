"""A sweep's case files, ``DIR/cases/<case id>.nc``: where each lies, what it records, a failure's record, its
place in the study.

A case file holds the dataset of a finished run (``status = "done"``) or,
for a run that failed, a record with no fields (``status = "failed"``,
``message`` says why).  Each carries a fingerprint of the compiled problem
(`execution.identity`), so re-running a study skips exactly the cases whose
inputs have not changed.  A study's case file is written in the layout it has
in the study (`CaseLayout`): its swept values as coordinates along the study's
dimensions, of length 1, its status, message, wall time and steps as
variables, so that ``xr.open_mfdataset("DIR/cases/*.nc")`` rebuilds the study
without a ``preprocess`` (docs/results.md).  The worker that ran a case writes
its file (`execution.worker.perform`), so everything here is light to send.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from solver.counters import MEANINGS

if TYPE_CHECKING:
    import xarray as xr

from .netcdf import CASE_DIMENSIONS
from .provenance import stamp
from .reading import attributes

CASE_VARIABLES = ("status", "message", "wall_time", "steps_taken", "case_id")  # per case, in study.nc and case files
CASE_ATTRS = {"long_name": "case id (file under cases/)", "units": "1"}

CASE_NAME_BYTES = 150  # a case file's name stays well within the 255 bytes of a file name, temporary suffix included


def _bounded(name: str) -> str:
    """A case id as a file name: as it is if short enough, else its beginning and a hash of the whole."""
    if len(name.encode()) <= CASE_NAME_BYTES:
        return name
    digest = hashlib.sha256(name.encode()).hexdigest()[:16]
    head = name.encode()[:CASE_NAME_BYTES - 17].decode(errors="ignore")
    return f"{head}-{digest}"


def case_file(out_dir: str | Path, case_id: str) -> Path:
    """DIR/cases/<case id>.nc; a case id too long for a file name is shortened with a hash of it (the full id
    is the file's `case_id` attribute)."""
    return Path(out_dir) / "cases" / f"{_bounded(case_id)}.nc"


def recorded(path: str | Path) -> dict | None:
    """The status attributes of a case file (and the software versions that made it), or None if there is
    none or it cannot be read; with what `quantities.alerts` said of it."""
    from ..quantities.alerts import ATTRIBUTES  # lazily: scipy and xarray only where cases are read back

    if not Path(path).is_file():
        return None
    attrs = attributes(Path(path))
    if attrs is None:
        return None
    return {name: value for name, value in attrs.items()
            if name in ("status", "message", "error", "fingerprint", "wall_time", "biostudy_version", *ATTRIBUTES)
            or name.startswith("version_")}


def failure_record(message: str, seconds: float, name: str, scene: str, scene_file: str | Path, overrides: str,
                   **extra: Any) -> xr.Dataset:
    """A failed case on disk: no variables, the reason in the attributes (`scene`: its TOML text)."""
    import xarray as xr

    ds = xr.Dataset(attrs={"Conventions": "CF-1.10", "title": f"failed run: {name}", "wall_time": seconds})
    return stamp(ds, scene, scene_file, overrides, status="failed", message=message, **extra)


def static(var: xr.DataArray) -> bool:
    """Not a function of time: masks, parameters."""
    return not {"time", "time_mechanics"} & set(var.dims)


def case_scalars(status: str, message: str, attrs: dict) -> dict:
    """A case's status, message, wall time and steps as variables (from its attributes)."""
    def number(key):
        return float(attrs.get(key, np.nan))

    return {
        "status": ((), np.array(status, dtype=object), {"long_name": "outcome of the case: done, failed "
                                                                    "or missing (not run)", "units": "1"}),
        "message": ((), np.array(message, dtype=object), {"long_name": "why the case failed", "units": "1"}),
        "wall_time": ((), number("wall_time"), {"long_name": "wall time of the simulation", "units": "s"}),
        "steps_taken": ((), number("steps_taken"), {"long_name": MEANINGS["steps_taken"], "units": "1"}),
    }


@dataclass(frozen=True)
class CaseLayout:
    """A case's place in its study, as its case file records it: the study's coordinates at this case (length
    1 along each study dimension) and whether the static variables are shared by every case."""

    dims: tuple[str, ...]
    coords: dict  # name -> (dims, values of length 1, attrs)
    statics_shared: bool

    def apply(self, ds: xr.Dataset) -> xr.Dataset:
        """A run's dataset (or a failure record) in this layout: every variable that varies between cases,
        and the case's status, message, wall time, steps and id, gain the study dimensions; a swept
        parameter is a coordinate instead of a variable."""
        attrs = ds.attrs
        ds = ds.drop_vars([n for n in self.coords if n in ds.data_vars])
        scalars = case_scalars(str(attrs.get("status", "done")), str(attrs.get("message", "")), attrs)
        scalars["case_id"] = ((), np.array(str(attrs.get("case_id", "")), dtype=object), CASE_ATTRS)
        ds = ds.assign(scalars)
        kept = [n for n in ds.data_vars if static(ds[n]) and n not in scalars and self.statics_shared]
        ds = ds.assign({n: ds[n].expand_dims(list(self.dims)) for n in ds.data_vars if n not in kept})
        ds = ds.assign_coords(self.coords)
        ds.attrs = {**attrs, CASE_DIMENSIONS: ", ".join(self.dims)}
        return ds
