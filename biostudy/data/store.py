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
per chunk (netCDF4/HDF5; `netcdf.encoding`, beside the compression), and
HDF5 checksums its headers, so `netcdf_io.intact` tells a damaged file from a good one
even when the damage keeps its size: a file that cannot be read whole
(header, attributes or data) is damaged.  `writable` and `replaceable` check
a target before anything is computed: a result is never lost to an
unwritable path afterwards, and never overwrites an input or a file biostudy
cannot prove it wrote (a damaged file included).  A write that fails is a
`NotWritten` naming the file and why, a full disk by its file system.
netCDF files are read and written through `netcdf_io`, which an interruption
cannot leave waiting on a lock.  `claims`: an output reserved for one run, and
files told apart as biostudy's by a mark.

A sweep keeps one file per case, ``DIR/cases/<case id>.nc``: the dataset of
a finished run (``status = "done"``) or, for a run that failed, a record
with no variables (``status = "failed"``, ``message`` says why).  Each
carries a fingerprint of the compiled problem (`execution.jobs.fingerprint`), so
re-running a study skips exactly the cases whose inputs have not changed.
"""
from __future__ import annotations

import errno
import hashlib
import os
import re
import secrets
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable

if TYPE_CHECKING:
    import xarray as xr  # imported where a dataset is read or made: `show` of a run's file needs none

from ..errors import BadInput, Failed, first_line
from ..inputs.files import LOOP, link_loop
from ..inputs.resources import size
from . import netcdf
from .provenance import with_provenance

TMP_GLOB = ".*.tmp"
TEMPORARY = re.compile(r"^\..+\.(?P<pid>\d+)\.[0-9a-f]{8}\.tmp$")  # .NAME.PID.TOKEN.tmp, see `temporary_name`
CASE_NAME_BYTES = 150  # a case file's name stays well within the 255 bytes of a file name, temporary suffix included
FULL_BELOW = 1 << 20  # bytes free on a file system that failed a write: it is full
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def stamp(ds: xr.Dataset, scene: str, scene_file: str | Path, overrides: str, **extra: Any) -> xr.Dataset:
    """The run's dataset with what produced it: the scene as TOML text, its file, the overrides (a ``t_ref``
    among `extra`: the real-time coordinates, `real_time`)."""
    from . import real_time  # lazily, as xarray

    ds = ds.copy()
    ds.attrs = with_provenance({**ds.attrs, "scene": scene, "scene_file": str(Path(scene_file).resolve())
                                if scene_file else "",
                                "overrides": overrides, **extra})
    return real_time.with_real_time(ds)  # a scene's t_ref: the real-time coordinates


def with_observables(ds: xr.Dataset) -> xr.Dataset:
    """A run's dataset with every observable its fields give as a variable (those it has are kept), listed in
    its ``observables`` attribute in the registry's order (`quantities.observables`): the file says what it
    holds, and `show` reads them without computing anything (`reports.glance`)."""
    from ..quantities import observables  # lazily: scipy and xarray only where a run's dataset is made

    found = observables.variables(ds)
    ds = ds.assign({name: values for name, values in found.items() if name not in ds})
    ds.attrs[netcdf.OBSERVABLES] = ", ".join(found)
    return ds


def temporary_name(path: Path) -> Path:
    """Where `path` is written before it is renamed: hidden, beside it, unique to this process and call."""
    return path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"


class NotWritten(OSError, Failed):
    """A file that could not be written; str() is one line: the file and why (a full disk: which one, and what
    is free on it).  Nothing of it is left behind.  A `Failed` (exit status 1) where no caller says more."""

    def __str__(self) -> str:
        return str(self.strerror)


def mount_point(path: str | Path) -> Path:
    """The directory a file system holding `path` (or its nearest existing ancestor) is mounted at."""
    path = Path(path).absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    device = path.stat().st_dev
    while path != path.parent and path.parent.stat().st_dev == device:
        path = path.parent
    return path


def _not_written(path: Path, error: OSError | RuntimeError) -> NotWritten:
    """What a failed write is told as: a full disk (ENOSPC, or almost nothing left, as HDF5's errors do not
    say), or the system's (or netCDF's) reason."""
    code = getattr(error, "errno", None)
    try:
        free = shutil.disk_usage(path.parent).free
    except OSError:
        free = None
    if code in (errno.ENOSPC, errno.EDQUOT) or (free is not None and free < FULL_BELOW):
        return NotWritten(errno.ENOSPC, f"cannot write {path}: the disk is full (the file system at "
                                        f"{mount_point(path)}, {size(free or 0).lstrip('~')} free)")
    reason = getattr(error, "strerror", None) or first_line(error)
    return NotWritten(code or errno.EIO, f"cannot write {path} ({reason})")


def atomic(path: str | Path, write: Callable[[Path], object], fsync: bool = False, temporary: Path | None = None,
           rename: Callable[[], None] | None = None) -> Path:
    """write(temporary) beside `path` (unique to this writer, or the `temporary` given: a `claims.Claim`'s), then
    renamed to it (by `rename`, if given): the file is complete or absent, and nothing else is left on failure,
    which is a `NotWritten`.  `fsync`: the data and the rename reach the disk first."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise _not_written(path, error) from None
    temporary = temporary or temporary_name(path)
    try:
        write(temporary)
        if fsync:
            with open(temporary, "rb+") as handle:
                os.fsync(handle.fileno())
        if rename:
            rename()
        else:
            os.replace(temporary, path)
    except (OSError, RuntimeError) as error:  # RuntimeError: netCDF4's, e.g. "HDF error" on a full disk
        raise _not_written(path, error) from None
    finally:
        temporary.unlink(missing_ok=True)
    if fsync:
        _fsync_directory(path.parent)
    return path


def write_text(path: str | Path, text: str) -> Path:
    """A text file (a report beside a dataset), written atomically."""
    return atomic(path, lambda temporary: temporary.write_text(text, encoding="utf-8"))


def write_atomic(ds: xr.Dataset, path: str | Path, temporary: Path | None = None,
                 rename: Callable[[], None] | None = None) -> Path:
    """Write `ds` to `path` as netCDF4, compressed and with checksums (`netcdf.encoding`): temporary file
    beside it, fsync, rename (`atomic`); nothing else on failure (`NotWritten`)."""
    from . import netcdf_io  # lazily: xarray only where a dataset is read or written (`show` of a run needs none)

    return atomic(path, lambda into: netcdf_io.write(ds, into, netcdf.encoding(ds)), True, temporary, rename)


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


def temporaries(directory: Path, of: str | None = None) -> Iterable[tuple[Path, int]]:
    """(file, writer's pid) of the temporaries in `directory` (`temporary_name`), of the file named `of` only if
    given."""
    for leftover in Path(directory).glob(TMP_GLOB):
        match = TEMPORARY.match(leftover.name)
        if match and (of is None or leftover.name.startswith(f".{of}.") and
                      leftover.name.count(".") == of.count(".") + 4):
            yield leftover, int(match["pid"])


def remove_temporaries(directory: str | Path, of: str | None = None) -> list[Path]:
    """Delete the temporary files (`temporary_name`; of the file named `of` only, if given) that writers no
    longer running left behind: never a file under a final name, nor one of another name pattern (a user's
    .draft.tmp), nor the temporary of a process still running (another sweep's file in flight)."""
    removed = []
    for leftover, pid in temporaries(Path(directory), of):
        if pid == os.getpid() or _alive(pid):
            continue
        leftover.unlink(missing_ok=True)
        removed.append(leftover)
    return removed


def writable(path: str | Path) -> None:
    """`BadInput` unless a dataset can be written to `path` (checked before anything is computed): not a
    directory, under a directory (or where one can be made), whose file system takes the file's temporary."""
    path = Path(path)
    if link_loop(path):
        raise BadInput(LOOP, path)
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


def attributes(path: Path) -> dict | None:
    """The global attributes of a netCDF file, or None if it is not one or cannot be read whole (a damaged
    header: HDF5 raises AttributeError, KeyError, ... as well as OSError)."""
    from .netcdf_io import opened  # lazily, as in `write_atomic`

    try:
        with opened(path) as nc:
            return {name: nc.getncattr(name) for name in nc.ncattrs()}
    except Exception:
        return None


def _looks_like_netcdf(path: Path) -> bool:
    """Whether a file begins as a netCDF file does (HDF5's signature, or netCDF-3's 'CDF')."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(8)
    except OSError:
        return False
    return head == HDF5_SIGNATURE or head[:3] == b"CDF"


def replaceable(path: str | Path, inputs: Iterable[str | Path] = (), damaged_ok: bool = False) -> dict | None:
    """Whether a new dataset may replace `path`: None if there is nothing there, the old file's attributes if
    it is a dataset biostudy wrote; `BadInput` if it is one of `inputs` or any other file, a netCDF file too
    damaged to tell who wrote it included (unless `damaged_ok`: it lies where only biostudy writes, e.g. in a
    directory a study owned before; then {})."""
    path = Path(path)
    if not path.exists():
        return None
    for given in inputs:
        if Path(given).exists() and os.path.samefile(path, given):
            raise BadInput(f"is an input of this run ({given}); choose another output", path)
    attrs = attributes(path) if path.is_file() else None
    if attrs is None and path.is_file() and _looks_like_netcdf(path):
        if damaged_ok:
            return {}
        raise BadInput("exists and is a damaged or truncated netCDF file, so biostudy cannot tell whether it wrote "
                       "it; refusing to overwrite it, --force or not (choose another output, or remove the file "
                       "first)", path)
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
    a file that is not netCDF, or one that cannot be read whole (damaged), is `BadInput` in one line."""
    path = Path(path)
    if not path.is_file():
        raise BadInput(LOOP if link_loop(path) else "no such file" if not path.exists() else "is not a regular file",
                       path)
    from . import netcdf_io  # lazily, as in `write_atomic`

    try:
        with netcdf_io.HDF5:  # read whole and closed before another thread calls HDF5
            ds = netcdf_io.open_dataset(path)
            try:
                return netcdf.as_run(ds.load())
            finally:
                ds.close()
    except Exception as error:  # netCDF4/HDF5: OSError, RuntimeError (a checksum), AttributeError (a header), ...
        if not _looks_like_netcdf(path):
            raise BadInput(f"not a netCDF dataset ({first_line(error)})", path) from None
        raise BadInput(f"damaged: it cannot be read whole ({first_line(error)}); a sweep computes a damaged case "
                       "again when run again", path) from None


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
    if found == "study":
        dims = [d.strip() for d in str(ds.attrs.get("sweep_dimensions", "")).split(",") if d.strip()]
        missing = [v for v in ("case_id", "status") if v not in ds] + [d for d in dims if d not in ds.dims]
        if missing or not dims:
            raise BadInput(f"a study.nc without {', '.join(missing) or 'sweep_dimensions'}: not as biostudy writes "
                           "one (damaged or edited); running its sweep again writes it anew from cases/", path)
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


# ---------------------------------------------------------------------------------------------
# Case records of a sweep


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
