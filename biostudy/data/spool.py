"""A run's fields written to disk as they are made: the output sink of a run that writes a file.

`solver.simulate` hands every output's fields to its sink at once
(`solver.sink`); `Spool` appends them to a hidden netCDF file beside the
target (`writing.temporary_name`: a killed run's spool is a temporary like
any other, removed by the next run into that output or sweep there) and gives them back at the
end as lazy arrays, read a few hundred kB at a time (`CHUNK_BYTES`: one output of a large grid, a
block of a small one's).  The dataset is then made,
measured (`quantities.observables` in blocks of outputs) and written to the
target's own temporary chunk by chunk (`netcdf_io.write`), so a run's
memory does not grow with its number of outputs (issue 29; measured in
docs/transport.md, "How far one machine goes").  The spool is lightly
compressed: it lives for one run, and its disk is the dataset's again.
"""
from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any

from solver.sink import CELL_FIELDS, MECHANICS_FIELDS

from ..inputs.resources import SPOOL_CHUNK_BYTES as CHUNK_BYTES
from . import netcdf_io
from .writing import not_written, temporary_name

SPOOL_COMPRESSION = {"zlib": True, "complevel": 1, "shuffle": True}
# a field is read back at most CHUNK_BYTES at a time (one output at least): small outputs in blocks, not one dask
# chunk each (a few kB of bookkeeping each: 6001 outputs of 32² peaked 60 MB above their estimate, issue 39.7)


def outputs_per_chunk(output_bytes: float) -> int:
    """How many outputs of a field of `output_bytes` bytes are read back at once (`CHUNK_BYTES`)."""
    return max(1, int(CHUNK_BYTES // max(output_bytes, 1.0)))


class Spool:
    """An `solver.sink.OutputSink` on a file beside `target`, made at the first output; `close` removes it (after
    the dataset is written, or whatever stopped the run: an interruption included)."""

    def __init__(self, target: Path):
        self.target = Path(target)
        self.path = temporary_name(self.target)
        self.file: netcdf_io.Growing | None = None
        self.opened: Any = None
        self.read = False
        self.output_bytes: dict[str, int] = {}  # per field, one output's

    def add(self, snapshot) -> None:
        """One output's fields, appended; a write that fails (a full disk) is a `writing.NotWritten` naming the
        target's file system."""
        assert not self.read, "a spool takes no outputs after its fields were read"
        try:
            if self.file is None:
                self.file = netcdf_io.Growing(self.path, SPOOL_COMPRESSION)
            for name in (*CELL_FIELDS, *MECHANICS_FIELDS):
                value = getattr(snapshot, name)
                if value is not None:
                    self.file.append(name, value)
                    self.output_bytes[name] = value.nbytes
        except (OSError, RuntimeError) as error:  # RuntimeError: netCDF4's "HDF error" on a full disk
            raise not_written(self.target, error) from None

    def fields(self) -> dict[str, Any]:
        """Every field kept, as a dask array of chunks of `outputs_per_chunk` outputs."""
        assert self.file is not None, "a spool gives fields only after outputs were added"
        try:
            self.file.close()  # flushes: a disk that fills up here is a `writing.NotWritten` too
        except (OSError, RuntimeError) as error:
            raise not_written(self.target, error) from None
        self.read = True
        names = (*CELL_FIELDS, *MECHANICS_FIELDS)
        chunks = {f"{name}_output": outputs_per_chunk(size) for name, size in self.output_bytes.items()}
        self.opened = netcdf_io.open_dataset(self.path, chunks, one_chunk_cached=True)
        return {name: self.opened[name].data for name in names if name in self.opened}

    def close(self) -> None:
        """Close and remove the spool (whatever was written of it)."""
        try:
            with contextlib.suppress(Exception):
                if self.file is not None:
                    self.file.close()
                if self.opened is not None:
                    self.opened.close()
        finally:
            Path(self.path).unlink(missing_ok=True)
