"""study.nc's fields filled case by case (`combine.write_study`): each case's compressed chunks copied as they are.

A case file's fields and study.nc's are laid out alike by `netcdf.encoding`: one snapshot per chunk, the same
filters (fletcher32 checksum, shuffle, zlib) and type.  Reading a case's fields only to compress them again into
study.nc cost most of the time of combining a study (6 ms a case of 40 x 40 cells and 11 outputs, zlib on data
that compress to ~0.7 of their size), and opening each case file a second time through netCDF4, which reads every
variable's metadata, 3.4 ms more.  Here study.nc, once netCDF4 has written and closed it, is opened with h5py, and
so is each case file (0.13 ms: h5py reads only what is asked); a field whose chunks and filters are study.nc's
(`copyable`) has its chunks written into study.nc as they are (`copy_chunks`): the same bytes, so the same values.
Each chunk's zlib stream is decompressed before it is written, which checks its own checksum (Adler-32; the
fletcher32 checksum, the first filter, covers the data before compression and is checked when data are read): a
damaged chunk sends its field the other way, where HDF5 reads it, finds the damage and stops the write, as when
every field was read to be compressed again.  Any other field
(another layout, type or filters; packed or with a fill value that is not NaN) is read as before
(`study_cases.read_fields`) and written through h5py, compressed by study.nc's own filters.  A case that did not
finish is NaN.

Two HDF5 libraries are then in the process, netCDF4's and h5py's, each with its own state and neither
thread-safe: every call into either is made under `netcdf_io.HDF5` (`opened` holds it for its block).  No case
file stays open past its case, and one case's fields at most are in memory.
"""
from __future__ import annotations

import math
import zlib
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import netcdf_io, study_cases

if TYPE_CHECKING:
    import h5py

DEFLATE = 1  # HDF5's id of the zlib filter


def fill(path: Path, names: list[str], cases: list[tuple[tuple, study_cases.Case]]) -> None:
    """Variables `names` of the study file at `path` (written but for them) filled from `cases` ((index along the
    study's dimensions, Case), every case of the study)."""
    with netcdf_io.opened_hdf5(path, "r+") as study:
        targets = {name: study[name] for name in names}
        layouts = {name: _layout(target) for name, target in targets.items()}
        for at, found in cases:
            if found.path is None:  # failed or missing
                for target in targets.values():
                    target[at] = np.nan
                continue
            with netcdf_io.opened_hdf5(found.path) as file:
                sources = {name: file[stored_name(file, name)] for name in names}
                copied = [name for name in names if found.lazy[name][2]
                          and copyable(sources[name], layouts[name], len(at))
                          and copy_chunks(sources[name], targets[name], at)]
            rest = {name: found.lazy[name] for name in names if name not in copied}
            for name, values in (study_cases.read_fields(found.path, rest) if rest else {}).items():
                targets[name][at] = values


def stored_name(file: h5py.Group, name: str) -> str:
    """A variable's name in `file`: `name`, or the name it had before a rename (`netcdf.OLD_NAMES`)."""
    old = study_cases.SOURCE.get(name)
    return old if old is not None and old in file else name


def _layout(dataset: h5py.Dataset) -> tuple:
    """What a field's chunks are made of: type, shape, chunks and filters (id, flags, parameters), in that order."""
    plist = dataset.id.get_create_plist()
    return (dataset.dtype, dataset.shape, dataset.chunks,
            [plist.get_filter(i)[:3] for i in range(plist.get_nfilters())])


def copyable(source: h5py.Dataset, target: tuple, lead: int) -> bool:
    """Whether `source` (a case's field; its study dimensions, of length 1, lead) can be copied chunk by chunk into
    a field of study.nc of `target` `_layout` whose first `lead` dimensions are the study's: the same type, trailing
    shape, chunks and filters (zlib the last applied, so that each chunk is a zlib stream), every chunk stored."""
    dtype, shape, chunks, filters = _layout(source)
    extra = len(shape) - (len(target[1]) - lead)
    if (extra < 0 or dtype != target[0] or chunks is None or target[2] is None or any(n != 1 for n in shape[:extra])
            or shape[extra:] != target[1][lead:] or chunks[extra:] != target[2][lead:]
            or any(c != 1 for c in target[2][:lead])):
        return False
    if filters != target[3] or not filters or filters[-1][0] != DEFLATE:
        return False
    return source.id.get_num_chunks() == math.prod(math.ceil(n / c) for n, c in zip(shape, chunks))


def copy_chunks(source: h5py.Dataset, target: h5py.Dataset, at: tuple) -> bool:
    """`source`'s chunks written as they are into `target` at `at` (`copyable`), each once it has been checked
    whole: every filter applied to it, and its zlib stream decompressed (its Adler-32 checksum verified; one chunk
    in memory at a time).  False at the first that is not (some may be written: the caller writes the field
    again, or fails)."""
    lead = source.ndim - (target.ndim - len(at))
    sid, tid = source.id, target.id
    for index in range(sid.get_num_chunks()):
        offset = sid.get_chunk_info(index).chunk_offset
        mask, data = sid.read_direct_chunk(offset)
        try:
            if mask:
                return False
            zlib.decompress(data)
        except zlib.error:
            return False
        tid.write_direct_chunk((*at, *offset[lead:]), data, mask)
    return True
