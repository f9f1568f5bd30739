"""ParaView files of a run (`biostudy export`): one file per snapshot and a PVD that lists them in time.

Formats: ``vti`` (the default), VTK image data, the regular grid as it is
(`vtk_image`: origin, spacing, every cell; obstacle cells NaN in the fields
and 1 in the int8 cell array `obstacle`); ``vtu``, an unstructured grid of
the open cells only (`vtk_unstructured`: hexahedra, quadrilaterals in 2-D;
obstacles are holes).  Each output time becomes `snapshot_NNNN.vti` (or
`.vtu`), with
- cell data phi, c, alpha and p (where the run has the mechanics) and the int8
  mask `nutrient_source` (1 where c is held); phi is the active scalar;
- point data u, the displacement (µm) as a 3-vector (2-D: z component 0), the
  active vector, so ParaView's "Warp By Vector" shows the deformed body;
- field data `TimeValue` (the snapshot's T*, VTK's name for a file's time) and,
  with the mechanics, `mechanics_time` (the T* at which the p and u shown were
  solved) and `mechanics_solved` (1 where the mechanics was solved at this
  output, 0 where p and u are the latest solve's).  A run whose scene gave
  ``t_ref``: times in real time, in t_ref's unit (48 h: hours, so ParaView's
  time slider reads hours), and `T_star` the snapshot's T*.
Every file has the same arrays.  The mechanics is solved at some outputs only
(`[mechanics] every`); at the others a file shows p and u of the latest output
where it was solved (`mechanics_solved` 0, `mechanics_time` < `TimeValue`), so
a warped animation holds the last deformed state instead of jumping back to
the undeformed body; before the first solve p is NaN and u 0.
`series.pvd` lists the snapshots with their times (T*, or real time as
`TimeValue`): opening it in ParaView loads the whole series with a working time
slider.  Every file carries biostudy's mark in a comment: a file of these names
that does not is never replaced, and the extra snapshots of an earlier, longer
export of the same format into the same directory are removed.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import xarray as xr

from solver import Grid
from solver.problem import AXES

from ..inputs.files import no_directory
from .claims import foreign, mark, marked
from .real_time import clock
from .vtk_image import ImageGrid
from .vtk_unstructured import OpenCells
from .writing import atomic

CELL_FIELDS = ("phi", "c", "alpha", "p")
MECHANICS_TIME = "time_mechanics"
SNAPSHOT = "snapshot_{:04d}"
COLLECTION = "series.pvd"
FORMATS = ("vti", "vtu")  # the first is the default


def _grid(ds: xr.Dataset) -> Grid:
    """The run's solver grid (cubic cells, origin at 0): shape from the fields, spacing as recorded."""
    axes = [a for a in AXES if a in ds.dims]
    x = np.asarray(ds["x"].values, dtype=float)
    spacing = ds.attrs.get("grid_spacing", x[1] - x[0] if x.size > 1 else 1.0)
    return Grid(tuple(ds.sizes[a] for a in axes), float(spacing))


def _check(ds: xr.Dataset):
    """Refuse, with a one-line reason, what is not one run's fields (a sweep, a time series only)."""
    if "phi" not in ds or "x" not in ds.dims:
        raise ValueError("export needs a run's dataset with cell fields (phi on time, [z,] y, x)")
    extra = set(ds["phi"].dims) - {"time", "z", "y", "x"}
    if extra:
        raise ValueError(f"export takes one run, not a sweep (dimensions {', '.join(sorted(extra))}); "
                         "export a case file from the sweep's cases/ directory")


def export(ds: xr.Dataset, directory: Path, format: str = FORMATS[0]) -> list[Path]:  # noqa: A002
    """Write one file per snapshot in `format` (`FORMATS`) and `series.pvd` into `directory`; return the paths (PVD
    last)."""
    _check(ds)
    if format not in FORMATS:
        raise ValueError(f"unknown format {format!r}; ParaView formats are {', '.join(FORMATS)}")
    ds = _on_mechanics_time(ds)
    directory = Path(directory)
    if no_directory(directory):
        raise ValueError(f"{directory} {no_directory(directory)}: the snapshots need a directory")
    writer = _writer(ds, format)
    names = [directory / (SNAPSHOT.format(t) + writer.suffix) for t in range(ds.sizes["time"])]
    foreign(names + [directory / COLLECTION], "a ParaView file")  # before anything is written
    created = not directory.exists()
    directory.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    try:
        written = _write_series(ds, writer, names, written)
    except BaseException:  # nothing half-written: this call's files go, and the directory if it made it
        for path in written:
            path.unlink(missing_ok=True)
        if created and not any(directory.iterdir()):
            directory.rmdir()
        raise
    for stale in directory.glob(f"snapshot_*{writer.suffix}"):  # of an earlier, longer export: biostudy's own go
        if stale not in written and marked(stale):
            stale.unlink()
    return written


def _writer(ds: xr.Dataset, format: str) -> ImageGrid | OpenCells:  # noqa: A002
    grid = _grid(ds)
    cell_dims = tuple(reversed(grid.axes))
    obstacle = ds["obstacle"].transpose(*cell_dims).values.astype(bool).ravel() if "obstacle" in ds else None
    if format == "vtu":
        return OpenCells(grid, np.ones(grid.n_cells, bool) if obstacle is None else ~obstacle)
    origin = tuple(float(grid.nodes(a)[0]) for a in grid.axes)  # x, y[, z]
    return ImageGrid(grid.cells_shape, grid.spacing, origin, obstacle)


def _write_series(ds: xr.Dataset, writer: ImageGrid | OpenCells, names: list[Path], written: list[Path]) -> list[Path]:
    """The snapshots and the PVD, each written to a temporary and renamed; `written` lists them as they come."""
    grid = _grid(ds)
    cell_dims = tuple(reversed(grid.axes))
    static = {}
    if "nutrient_source" in ds:
        static["nutrient_source"] = ds["nutrient_source"].transpose(*cell_dims).values.astype(np.int8).ravel()
    fields = {n: ds[n].transpose("time", *cell_dims).values.reshape(ds.sizes["time"], -1)
              for n in CELL_FIELDS if n in ds and n != "p"}
    found = clock(ds)
    real = found.real if found is not None else (lambda t: t)  # what TimeValue and the PVD's timesteps are in
    times = real(ds["time"].values.astype(float))
    shown = _mechanics_shown(ds)  # output index -> index into the mechanics' outputs (-1: none yet)
    p = u = None
    if "p" in ds:
        p = ds["p"].transpose(MECHANICS_TIME, *cell_dims).values.reshape(ds.sizes[MECHANICS_TIME], -1)
    if "u" in ds:
        u = ds["u"].transpose(MECHANICS_TIME, *(f"{d}_node" for d in cell_dims), "component").values
        u = np.pad(u.reshape(u.shape[0], -1, u.shape[-1]), ((0, 0), (0, 0), (0, 3 - u.shape[-1])))

    for t, name in enumerate(names):
        cell_data = {**static, **{n: values[t].astype(float) for n, values in fields.items()}}
        point_data, field_data = {}, {"TimeValue": float(times[t])}
        if found is not None:
            field_data["T_star"] = float(ds["time"].values[t])
        if shown is not None:
            m = shown[t]
            if p is not None:
                cell_data["p"] = p[m].astype(float) if m >= 0 else np.full(grid.n_cells, np.nan)
            if u is not None:
                point_data["u"] = u[m].astype(float) if m >= 0 else np.zeros((int(np.prod(grid.nodes_shape)), 3))
            solved = m >= 0 and ds[MECHANICS_TIME].values[m] == ds["time"].values[t]
            field_data["mechanics_time"] = float(real(ds[MECHANICS_TIME].values[m])) if m >= 0 else float("nan")
            field_data["mechanics_solved"] = float(solved)
        written.append(atomic(name, lambda path: writer.write(path, cell_data, point_data, field_data,  # noqa: B023
                                                               mark(), time_text)))  # (called at once)
    written.append(atomic(names[0].parent / COLLECTION, lambda path: _write_collection(path, written, times)))
    return written


def time_text(value: float) -> str:
    """A time as ParaView reads it, to 15 significant digits: 0.15 for the float64 0.15000000000000002 that
    an output clock of np.linspace makes (the two are one double apart, far below any time step)."""
    return f"{float(value):.15g}"


def _mechanics_shown(ds: xr.Dataset) -> np.ndarray | None:
    """For every output, the index (along `time_mechanics`) of the latest output at or before it where the
    mechanics was solved; -1 before the first; None without mechanics."""
    if MECHANICS_TIME not in ds.dims:
        return None
    return np.searchsorted(ds[MECHANICS_TIME].values, ds["time"].values, side="right") - 1


def _on_mechanics_time(ds: xr.Dataset) -> xr.Dataset:
    """A dataset written before `time_mechanics` existed (p and u on `time`, NaN where the mechanics was not
    solved) in today's layout: p and u at the solved outputs only."""
    if MECHANICS_TIME in ds.dims or "p" not in ds or "time" not in ds["p"].dims:
        return ds
    solved = ds["p"].notnull().any([d for d in ds["p"].dims if d != "time"]).values
    moved = {n: ds[n].isel(time=solved).rename(time=MECHANICS_TIME) for n in ("p", "u") if n in ds}
    return ds.drop_vars(list(moved)).assign(moved)


def _write_collection(path: Path, files: list[Path], times: np.ndarray) -> Path:
    """The PVD file: every snapshot with its time, file names relative to the PVD."""
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    root.append(ET.Comment(f" {mark()} "))
    collection = ET.SubElement(root, "Collection")
    for file, when in zip(files, times):
        ET.SubElement(collection, "DataSet", timestep=time_text(when), group="", part="0", file=file.name)
    ET.indent(root)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
    return path
