"""Datasets on disk: atomic netCDF writes, reading them back, provenance, case records.

Plain dataset I/O: nothing here knows what a scene or a study is.

A file is complete or absent: every dataset is written to a hidden
temporary file in the target directory, flushed to disk (fsync), then
renamed over the final name (`os.replace` is atomic within a filesystem).
A run killed mid-write leaves only a ``.NAME.PID.XXXX.tmp`` file, which the
next sweep in that directory removes.

A sweep keeps one file per case, ``DIR/cases/<case id>.nc``: the dataset of
a finished run (``status = "done"``) or, for a run that failed, a record
with no variables (``status = "failed"``, ``message`` says why).  Each
carries a fingerprint of the compiled problem (`runner.fingerprint`), so
re-running a study skips exactly the cases whose inputs have not changed.
"""
from __future__ import annotations

import datetime as _dt
import importlib.metadata
import os
import secrets
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from . import netcdf
from .errors import BadInput

TMP_GLOB = ".*.tmp"


def version() -> str:
    try:
        return importlib.metadata.version("biostudy")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def with_provenance(attrs: dict) -> dict:
    """`attrs` as netCDF can store them, with the biostudy version and the time of writing: every file
    biostudy writes says which version made it and when."""
    return legal_attrs({**attrs, "biostudy_version": version(), "created": now(), "history": netcdf.history()})


def legal_attrs(attrs: dict) -> dict:
    """Attributes netCDF can store: no None, booleans as 0/1, nested dicts flattened to 'a_b' names."""
    legal = {}
    for name, value in attrs.items():
        if value is None:
            continue
        if isinstance(value, dict):
            legal.update(legal_attrs({f"{name}_{k}": v for k, v in value.items()}))
        elif isinstance(value, (bool, np.bool_)):
            legal[name] = int(value)
        elif isinstance(value, (list, tuple)):
            legal[name] = ", ".join(map(str, value)) if any(isinstance(v, str) for v in value) else np.asarray(value)
        elif isinstance(value, Path):
            legal[name] = str(value)
        else:
            legal[name] = value
    return legal


def stamp(ds: xr.Dataset, scene: str, scene_file: str | Path, overrides: str, **extra: Any) -> xr.Dataset:
    """The run's dataset with what produced it: the scene as TOML text, its file, the overrides."""
    ds = ds.copy()
    ds.attrs = with_provenance({**ds.attrs, "scene": scene, "scene_file": str(Path(scene_file).resolve()),
                                "overrides": overrides, **extra})
    return ds


def write_atomic(ds: xr.Dataset, path: str | Path) -> Path:
    """Write `ds` to `path` as netCDF4: temporary file beside it, fsync, rename; nothing else on failure."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    try:
        ds.to_netcdf(temporary, engine="netcdf4", format="NETCDF4", encoding=netcdf.encoding(ds))
        with open(temporary, "rb+") as handle:
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    try:
        directory = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(directory)
        finally:
            os.close(directory)
    except OSError:
        pass  # directories cannot be fsynced on every platform; the rename itself is done
    return path


def remove_temporaries(directory: str | Path) -> list[Path]:
    """Delete temporary files a killed run left behind (never a file under a final name)."""
    removed = []
    for leftover in Path(directory).glob(TMP_GLOB):
        leftover.unlink(missing_ok=True)
        removed.append(leftover)
    return removed


def open_dataset(path: str | Path) -> xr.Dataset:
    """A result file, loaded into memory and closed (a sweep's case file as one run: `netcdf.as_run`);
    an unreadable file is `BadInput`."""
    path = Path(path)
    if not path.is_file():
        raise BadInput("no such file", path)
    try:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            return netcdf.as_run(ds.load())
    except (OSError, ValueError) as error:
        raise BadInput(f"not a netCDF dataset ({str(error).splitlines()[0]})", path) from None


# ---------------------------------------------------------------------------------------------
# Case records of a sweep


def case_file(out_dir: str | Path, case_id: str) -> Path:
    return Path(out_dir) / "cases" / f"{case_id}.nc"


def recorded(path: str | Path) -> dict | None:
    """The status attributes of a case file, or None if there is none or it cannot be read."""
    import netCDF4

    if not Path(path).is_file():
        return None
    try:
        with netCDF4.Dataset(path) as nc:
            return {name: nc.getncattr(name) for name in ("status", "message", "error", "fingerprint", "wall_time")
                    if name in nc.ncattrs()}
    except OSError:
        return None


def failure_record(message: str, seconds: float, name: str, scene: str, scene_file: Path, overrides: str,
                   **extra: Any) -> xr.Dataset:
    """A failed case on disk: no variables, the reason in the attributes (`scene`: its TOML text)."""
    ds = xr.Dataset(attrs={"Conventions": "CF-1.10", "title": f"failed run: {name}", "wall_time": seconds})
    return stamp(ds, scene, scene_file, overrides, status="failed", message=message, **extra)
