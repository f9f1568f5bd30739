"""A file complete or absent: atomic writes, and the temporaries a killed writer leaves.

Every dataset, report and picture is written to a hidden temporary file in
the target directory, flushed to disk (fsync, for a dataset), then renamed
over the final name (`os.replace` is atomic within a filesystem).  A run
killed mid-write leaves only a ``.NAME.PID.XXXXXXXX.tmp`` file (the writer's
process id and a random token: unique per writer), which the next sweep in
that directory removes once that process is gone (`remove_temporaries`);
other files, and the temporaries of processes still running, are never
touched.  A write that fails is a `NotWritten` naming the file and why, a
full disk by its file system.  netCDF files are written through `netcdf_io`,
which an interruption cannot leave waiting on a lock, with the compression
and checksums of `netcdf.encoding`.
"""
from __future__ import annotations

import errno
import os
import re
import secrets
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterable

if TYPE_CHECKING:
    import xarray as xr  # imported where a dataset is written: `show` of a run's file needs none

from ..errors import Failed, first_line
from ..inputs.resources import size
from . import netcdf

TMP_GLOB = ".*.tmp"
TEMPORARY = re.compile(r"^\..+\.(?P<pid>\d+)\.[0-9a-f]{8}\.tmp$")  # .NAME.PID.TOKEN.tmp, see `temporary_name`
FULL_BELOW = 1 << 20  # bytes free on a file system that failed a write: it is full


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


def not_written(path: Path, error: OSError | RuntimeError) -> NotWritten:
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
        raise not_written(path, error) from None
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
        raise not_written(path, error) from None
    finally:
        temporary.unlink(missing_ok=True)
    if fsync:
        _fsync_directory(path.parent)
    return path


def write_text(path: str | Path, text: str) -> Path:
    """A text file (a report beside a dataset), written atomically."""
    return atomic(path, lambda temporary: temporary.write_text(text, encoding="utf-8"))


def write_atomic(ds: xr.Dataset, path: str | Path, temporary: Path | None = None,
                 rename: Callable[[], None] | None = None, deferred=None) -> Path:
    """Write `ds` to `path` as netCDF4, compressed and with checksums (`netcdf.encoding`): temporary file
    beside it, fsync, rename (`atomic`); nothing else on failure (`NotWritten`).  `deferred`: lazy variables
    written by a function of their own (`netcdf_io.write`)."""
    from . import netcdf_io  # lazily: xarray only where a dataset is read or written (`show` of a run needs none)

    return atomic(path, lambda into: netcdf_io.write(ds, into, netcdf.encoding(ds), deferred), True, temporary,
                  rename)


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
