"""Where a result may be written, checked before anything is computed.

A result is never lost to an unwritable path after it was computed (`writable`), and never overwrites an
input or a file biostudy cannot prove it wrote, a damaged one included (`replaceable`).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

from ..errors import BadInput
from ..inputs.files import LOOP, link_loop
from .reading import attributes, looks_like_netcdf
from .writing import temporary_name


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
    if attrs is None and path.is_file() and looks_like_netcdf(path):
        if damaged_ok:
            return {}
        raise BadInput("exists and is a damaged or truncated netCDF file, so biostudy cannot tell whether it wrote "
                       "it; refusing to overwrite it, --force or not (choose another output, or remove the file "
                       "first)", path)
    if attrs is None or "biostudy_version" not in attrs:
        raise BadInput("exists and is not a dataset biostudy wrote; refusing to overwrite it (choose another "
                       "output, or remove the file first)", path)
    return attrs
