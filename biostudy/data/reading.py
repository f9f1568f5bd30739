"""Datasets read back: a result file loaded whole, told apart by what it is (a run, a study, a summary).

Plain dataset reading: nothing here knows what a scene or a study is.  Every
numeric variable of more than one value carries a fletcher32 checksum per
chunk (`netcdf.encoding`) and HDF5 checksums its headers, so a file that
cannot be read whole (header, attributes or data) is damaged, even when the
damage keeps its size, and is refused in one line (`open_dataset`).  Files
are read through `netcdf_io`, under its lock.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import xarray as xr  # imported where a dataset is read: `show` of a run's file needs none

from ..errors import BadInput, first_line
from ..inputs.files import LOOP, link_loop
from . import netcdf

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def attributes(path: Path) -> dict | None:
    """The global attributes of a netCDF file, or None if it is not one or cannot be read whole (a damaged
    header: HDF5 raises AttributeError, KeyError, ... as well as OSError)."""
    from .netcdf_io import opened  # lazily: xarray only where a dataset is read (`show` of a run needs none)

    try:
        with opened(path) as nc:
            return {name: nc.getncattr(name) for name in nc.ncattrs()}
    except Exception:
        return None


def looks_like_netcdf(path: Path) -> bool:
    """Whether a file begins as a netCDF file does (HDF5's signature, or netCDF-3's 'CDF')."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(8)
    except OSError:
        return False
    return head == HDF5_SIGNATURE or head[:3] == b"CDF"


LAZY_CHUNKS: dict = {}  # a dataset read lazily: in the chunks it was written in (netcdf.encoding: an output each)
LAZY_SLAB = 1 << 22  # bytes read at once to check such a dataset whole (the check's own default: 64 MiB)


def open_dataset(path: str | Path, lazy: bool = False) -> xr.Dataset:
    """A result file, loaded into memory and closed (a sweep's case file as one run: `netcdf.as_run`);
    a file that is not netCDF, or one that cannot be read whole (damaged), is `BadInput` in one line.
    `lazy`: checked whole (`netcdf_io.intact`, a slab at a time) and left open, its outputs read one at a time
    as they are used (a run continued, whose history is written again: its memory does not grow with it);
    close() it when done."""
    path = Path(path)
    if not path.is_file():
        raise BadInput(LOOP if link_loop(path) else "no such file" if not path.exists() else "is not a regular file",
                       path)
    from . import netcdf_io  # lazily, as in `attributes`

    try:
        if lazy:
            if not netcdf_io.intact(path, LAZY_SLAB):
                raise RuntimeError("a header, an attribute or a checksum failed")
            return netcdf.as_run(netcdf_io.open_dataset(path, LAZY_CHUNKS, one_chunk_cached=True))
        with netcdf_io.HDF5:  # read whole and closed before another thread calls HDF5
            ds = netcdf_io.open_dataset(path)
            try:
                return netcdf.as_run(ds.load())
            finally:
                ds.close()
    except Exception as error:  # netCDF4/HDF5: OSError, RuntimeError (a checksum), AttributeError (a header), ...
        if not looks_like_netcdf(path):
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


def open_result(path: str | Path, wanted: tuple[str, ...] = ("run", "study", "failed"), doing: str = "",
                lazy: bool = False) -> xr.Dataset:
    """`open_dataset` for a command that reads results (show, plot, export): `BadInput` in one line for a
    file that is not of the kinds it takes (`kind`), e.g. a netCDF file biostudy did not write."""
    ds = open_dataset(path, lazy)
    try:
        return _of_kind(ds, path, wanted, doing)
    except BadInput:
        ds.close()
        raise


def _of_kind(ds: xr.Dataset, path: str | Path, wanted: tuple[str, ...], doing: str) -> xr.Dataset:
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
