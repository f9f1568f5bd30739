"""A sweep's case files, ``DIR/cases/<case id>.nc``: where each lies, what it records, a failure's record.

A case file holds the dataset of a finished run (``status = "done"``) or,
for a run that failed, a record with no variables (``status = "failed"``,
``message`` says why).  Each carries a fingerprint of the compiled problem
(`execution.identity`), so re-running a study skips exactly the cases whose
inputs have not changed.
"""
from __future__ import annotations

import hashlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import xarray as xr

from .provenance import stamp
from .reading import attributes

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


def failure_record(message: str, seconds: float, name: str, scene: str, scene_file: Path, overrides: str,
                   **extra: Any) -> xr.Dataset:
    """A failed case on disk: no variables, the reason in the attributes (`scene`: its TOML text)."""
    import xarray as xr

    ds = xr.Dataset(attrs={"Conventions": "CF-1.10", "title": f"failed run: {name}", "wall_time": seconds})
    return stamp(ds, scene, scene_file, overrides, status="failed", message=message, **extra)
