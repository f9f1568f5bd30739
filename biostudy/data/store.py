"""Datasets on disk: atomic netCDF writes, reading them back, provenance, case records.

Plain dataset I/O: nothing here knows what a scene or a study is.

A file is complete or absent: every dataset is written to a hidden
temporary file in the target directory, flushed to disk (fsync), then
renamed over the final name (`os.replace` is atomic within a filesystem).
A run killed mid-write leaves only a ``.NAME.PID.XXXXXXXX.tmp`` file (the
writer's process id and a random token: unique per writer), which the next
sweep in that directory removes once that process is gone; other files,
and the temporaries of processes still running, are never touched.

Every numeric variable of more than one value carries a fletcher32 checksum
per chunk (netCDF4/HDF5; `netcdf.encoding`, beside the compression), so
`intact` tells a damaged file from a good one even when the damage keeps its
size.  `writable` and `replaceable` check a
target before anything is computed: a result is never lost to an unwritable
path afterwards, and never overwrites an input or a file biostudy did not
write.

A sweep keeps one file per case, ``DIR/cases/<case id>.nc``: the dataset of
a finished run (``status = "done"``) or, for a run that failed, a record
with no variables (``status = "failed"``, ``message`` says why).  Each
carries a fingerprint of the compiled problem (`execution.jobs.fingerprint`), so
re-running a study skips exactly the cases whose inputs have not changed.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import importlib.metadata
import math
import os
import re
import secrets
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np
import xarray as xr

from ..errors import BadInput, first_line
from . import netcdf

TMP_GLOB = ".*.tmp"
TEMPORARY = re.compile(r"^\..+\.(?P<pid>\d+)\.[0-9a-f]{8}\.tmp$")  # .NAME.PID.TOKEN.tmp, see `temporary_name`
CASE_NAME_BYTES = 150  # a case file's name stays well within the 255 bytes of a file name, temporary suffix included


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


def temporary_name(path: Path) -> Path:
    """Where `path` is written before it is renamed: hidden, beside it, unique to this process and call."""
    return path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"


def atomic(path: str | Path, write: Callable[[Path], object], fsync: bool = False) -> Path:
    """write(temporary) beside `path` (unique to this writer), then renamed to it: the file is complete or
    absent, and nothing else is left on failure.  `fsync`: the data and the rename reach the disk first."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = temporary_name(path)
    try:
        write(temporary)
        if fsync:
            with open(temporary, "rb+") as handle:
                os.fsync(handle.fileno())
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)
    if fsync:
        _fsync_directory(path.parent)
    return path


def write_text(path: str | Path, text: str) -> Path:
    """A text file (a report beside a dataset), written atomically."""
    return atomic(path, lambda temporary: temporary.write_text(text, encoding="utf-8"))


def write_atomic(ds: xr.Dataset, path: str | Path) -> Path:
    """Write `ds` to `path` as netCDF4, compressed and with checksums (`netcdf.encoding`): temporary file
    beside it, fsync, rename; nothing else on failure."""
    return atomic(path, lambda temporary: ds.to_netcdf(temporary, engine="netcdf4", format="NETCDF4",
                                                       encoding=netcdf.encoding(ds)), fsync=True)


def _fsync_directory(directory: Path) -> None:
    try:
        handle = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(handle)
        finally:
            os.close(handle)
    except OSError:
        pass  # directories cannot be fsynced on every platform; the rename itself is done


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process
    return True


def remove_temporaries(directory: str | Path) -> list[Path]:
    """Delete the temporary files (`temporary_name`) that writers no longer running left behind: never a
    file under a final name, nor one of another name pattern (a user's .draft.tmp), nor the temporary of a
    process still running (another sweep's file in flight)."""
    removed = []
    for leftover in Path(directory).glob(TMP_GLOB):
        match = TEMPORARY.match(leftover.name)
        if not match or int(match["pid"]) == os.getpid() or _alive(int(match["pid"])):
            continue
        leftover.unlink(missing_ok=True)
        removed.append(leftover)
    return removed


def writable(path: str | Path) -> None:
    """`BadInput` unless a dataset can be written to `path` (checked before anything is computed): not a
    directory, under a directory (or where one can be made), whose file system takes the file's temporary."""
    path = Path(path)
    try:
        if path.is_dir():
            raise BadInput("is a directory; give a file name for the dataset", path)
        existing = path.parent
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        if not existing.is_dir():
            raise BadInput(f"cannot write here: {existing} is a file, not a directory", path)
        probe = temporary_name(existing / path.name)
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        probe.unlink()
    except OSError as error:
        raise BadInput(f"cannot write here ({error.strerror or error})", path) from None


def _attributes(path: Path) -> dict | None:
    """The global attributes of a netCDF file, or None if it is not one (or cannot be read)."""
    import netCDF4

    try:
        with netCDF4.Dataset(path) as nc:
            return {name: nc.getncattr(name) for name in nc.ncattrs()}
    except (OSError, RuntimeError, ValueError):
        return None


def replaceable(path: str | Path, inputs: Iterable[str | Path] = ()) -> dict | None:
    """Whether a new dataset may replace `path`: None if there is nothing there, the old file's attributes if
    it is a dataset biostudy wrote; `BadInput` if it is one of `inputs` or any other file."""
    path = Path(path)
    if not path.exists():
        return None
    for given in inputs:
        if Path(given).exists() and os.path.samefile(path, given):
            raise BadInput(f"is an input of this run ({given}); choose another output", path)
    attrs = _attributes(path) if path.is_file() else None
    if attrs is None and path.is_file():
        with open(path, "rb") as handle:
            if handle.read(8) == b"\x89HDF\r\n\x1a\n":
                return {}  # a netCDF4 file too damaged to read: nothing in it is left to keep
    if attrs is None or "biostudy_version" not in attrs:
        raise BadInput("exists and is not a dataset biostudy wrote; refusing to overwrite it (choose another "
                       "output, or remove the file first)", path)
    return attrs


def _bounded(name: str) -> str:
    """A case id as a file name: as it is if short enough, else its beginning and a hash of the whole."""
    if len(name.encode()) <= CASE_NAME_BYTES:
        return name
    digest = hashlib.sha256(name.encode()).hexdigest()[:16]
    head = name.encode()[:CASE_NAME_BYTES - 17].decode(errors="ignore")
    return f"{head}-{digest}"


def open_dataset(path: str | Path) -> xr.Dataset:
    """A result file, loaded into memory and closed (a sweep's case file as one run: `netcdf.as_run`);
    an unreadable or damaged file is `BadInput`."""
    path = Path(path)
    if not path.is_file():
        raise BadInput("no such file", path)
    try:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            return netcdf.as_run(ds.load())
    except (OSError, ValueError) as error:
        raise BadInput(f"not a netCDF dataset ({first_line(error)})", path) from None
    except RuntimeError as error:  # netCDF4/HDF5 while reading data: a checksum that does not match
        raise BadInput(f"damaged: its data cannot be read ({first_line(error)})", path) from None


def kind(ds: xr.Dataset) -> str:
    """What a dataset is: "study" (a sweep's study.nc), "run" (a run or a finished case), "failed" (a failed
    case's record), "empty" (no variables), "summary" (convergence.nc, stability.nc), or "" (not written by
    biostudy)."""
    if "biostudy_version" not in ds.attrs:
        return ""
    if "sweep_mode" in ds.attrs:
        return "study"
    if ds.attrs.get("status") == "failed":
        return "failed"
    if not ds.data_vars:
        return "empty"
    return "run" if "phi" in ds and "time" in ds.dims else "summary"


def open_result(path: str | Path, wanted: tuple[str, ...] = ("run", "study", "failed"), doing: str = "") -> xr.Dataset:
    """`open_dataset` for a command that reads results (show, plot, export): `BadInput` in one line for a
    file that is not of the kinds it takes (`kind`), e.g. a netCDF file biostudy did not write."""
    ds = open_dataset(path)
    found = kind(ds)
    if found in wanted:
        return ds
    reason = {
        "": "not a dataset biostudy wrote (it lacks biostudy's attributes)",
        "failed": f"a failed case's record ({str(ds.attrs.get('message', ''))[:200]}): it holds no fields",
        "empty": "a dataset with no variables",
        "study": "a sweep's study.nc, not one run (use a case file from its cases/ directory)",
        "summary": f"a summary ({ds.attrs.get('title', 'convergence or stability')}), not a run",
        "run": "one run, not a sweep",
    }[found]
    raise BadInput(f"{reason}; {doing or 'nothing to do with it'}", path)


def intact(path: str | Path, slab_bytes: int = 1 << 26) -> bool:
    """Whether every numeric variable of a netCDF file reads back (checksums verified where it has them),
    read in slabs of at most `slab_bytes`; False for a file that cannot be opened.

    Variable-length strings (in files written before text became characters, `netcdf.encoding`) carry no
    checksum and are not read: read through a second handle of a file that is open elsewhere in this
    process, they leave HDF5 in a state that crashes a later open (HDFGroup/hdf5#5359)."""
    import netCDF4

    try:
        with netCDF4.Dataset(path) as nc:
            nc.set_auto_mask(False)
            for var in nc.variables.values():
                if not isinstance(var.dtype, np.dtype):
                    continue  # a variable-length string: no checksum to verify
                if not var.ndim or not var.shape[0]:
                    var[...]  # a scalar or an empty variable
                    continue
                row = math.prod(var.shape[1:]) * var.dtype.itemsize
                step = max(1, slab_bytes // max(row, 1))
                for start in range(0, var.shape[0], step):
                    var[start:start + step]
    except (OSError, RuntimeError, ValueError, IndexError):
        return False
    return True


# ---------------------------------------------------------------------------------------------
# Case records of a sweep


def case_file(out_dir: str | Path, case_id: str) -> Path:
    """DIR/cases/<case id>.nc; a case id too long for a file name is shortened with a hash of it (the full id
    is the file's `case_id` attribute)."""
    return Path(out_dir) / "cases" / f"{_bounded(case_id)}.nc"


def recorded(path: str | Path) -> dict | None:
    """The status attributes of a case file (and the software versions that made it), or None if there is
    none or it cannot be read."""
    if not Path(path).is_file():
        return None
    attrs = _attributes(Path(path))
    if attrs is None:
        return None
    return {name: value for name, value in attrs.items()
            if name in ("status", "message", "error", "fingerprint", "wall_time", "biostudy_version",
                        "dense_biofilm_vanished")
            or name.startswith("version_")}


def failure_record(message: str, seconds: float, name: str, scene: str, scene_file: Path, overrides: str,
                   **extra: Any) -> xr.Dataset:
    """A failed case on disk: no variables, the reason in the attributes (`scene`: its TOML text)."""
    ds = xr.Dataset(attrs={"Conventions": "CF-1.10", "title": f"failed run: {name}", "wall_time": seconds})
    return stamp(ds, scene, scene_file, overrides, status="failed", message=message, **extra)
