"""ParaView files of a run (`biostudy export`): one VTU per snapshot and a PVD that lists them in time.

Each output time becomes `snapshot_NNNN.vtu` (meshio, XML unstructured grid,
zlib-compressed): hexahedra in 3-D, quadrilaterals in the z = 0 plane in 2-D,
with
- cell data phi, c, alpha and p (where the run has the mechanics) and the int8
  mask `nutrient_source` (1 where c is held); phi is the active scalar;
- point data u, the displacement (µm) as a 3-vector (2-D: z component 0), the
  active vector, so ParaView's "Warp By Vector" shows the deformed body;
- field data `TimeValue` (the snapshot's T*, VTK's name for a file's time) and,
  with the mechanics, `mechanics_time` (the T* at which the p and u shown were
  solved).  A run whose scene gave ``t_ref``: both in real time, in t_ref's
  unit (48 h: hours, so ParaView's time slider reads hours), and `T_star`
  the snapshot's T*.
Every file has the same arrays.  The mechanics is solved at some outputs only
(`[mechanics] every`); at the others a file shows p and u of the latest output
where it was solved (`mechanics_time` < `TimeValue`), so a warped animation
holds the last deformed state instead of jumping back to the undeformed body.
`series.pvd` lists the snapshots with their times (T*, or real time as
`TimeValue`): opening it in ParaView
loads the whole series with a working time slider.  Every file carries
biostudy's mark in a comment: a file of these names that does not is never
replaced, and the extra snapshots of an earlier, longer export into the same
directory are removed.

Obstacles are left out of the mesh: their cells are removed, and the nodes
that only obstacle cells use with them.  ParaView then shows the obstacles
as holes with real faces instead of NaN cells that break colour ranges and
filters; the cell count of each file is the number of open cells.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import xarray as xr

from solver import Grid
from solver.problem import AXES

from ..inputs.files import no_directory
from .claims import foreign, mark, marked
from .real_time import clock
from .writing import atomic

CELL_FIELDS = ("phi", "c", "alpha", "p")
MECHANICS_TIME = "time_mechanics"
SNAPSHOT = "snapshot_{:04d}.vtu"
COLLECTION = "series.pvd"


def _grid(ds: xr.Dataset) -> Grid:
    """The run's solver grid (cubic cells, origin at 0): shape from the fields, spacing as recorded."""
    axes = [a for a in AXES if a in ds.dims]
    x = np.asarray(ds["x"].values, dtype=float)
    spacing = ds.attrs.get("grid_spacing", x[1] - x[0] if x.size > 1 else 1.0)
    return Grid(tuple(ds.sizes[a] for a in axes), float(spacing))


def _lattice(grid: Grid):
    """All grid nodes (n, 3) and every cell's node indices, cells in the (z, y, x) C order of the fields."""
    nodes = np.meshgrid(*(grid.nodes(a) for a in reversed(grid.axes)), indexing="ij")  # (z, y, x) order
    points = np.zeros((nodes[0].size, 3))
    for k, g in enumerate(reversed(nodes)):  # x, y[, z]
        points[:, k] = g.ravel()
    n = np.arange(points.shape[0]).reshape(grid.nodes_shape)  # node number at (k, j, i)
    if grid.ndim == 3:
        # VTK hexahedron: bottom face counter-clockwise, then the top face
        corners = [n[:-1, :-1, :-1], n[:-1, :-1, 1:], n[:-1, 1:, 1:], n[:-1, 1:, :-1],
                   n[1:, :-1, :-1], n[1:, :-1, 1:], n[1:, 1:, 1:], n[1:, 1:, :-1]]
        kind = "hexahedron"
    else:
        corners = [n[:-1, :-1], n[:-1, 1:], n[1:, 1:], n[1:, :-1]]
        kind = "quad"
    cells = np.stack([c.ravel() for c in corners], axis=1)
    return points, cells, kind


def _check(ds: xr.Dataset):
    """Refuse, with a one-line reason, what is not one run's fields (a sweep, a time series only)."""
    if "phi" not in ds or "x" not in ds.dims:
        raise ValueError("export needs a run's dataset with cell fields (phi on time, [z,] y, x)")
    extra = set(ds["phi"].dims) - {"time", "z", "y", "x"}
    if extra:
        raise ValueError(f"export takes one run, not a sweep (dimensions {', '.join(sorted(extra))}); "
                         "export a case file from the sweep's cases/ directory")


def export(ds: xr.Dataset, directory: Path) -> list[Path]:
    """Write one VTU per snapshot and `series.pvd` into `directory`; return the paths (PVD last)."""
    _check(ds)
    ds = _on_mechanics_time(ds)
    directory = Path(directory)
    if no_directory(directory):
        raise ValueError(f"{directory} {no_directory(directory)}: the snapshots need a directory")
    foreign([directory / SNAPSHOT.format(t) for t in range(ds.sizes["time"])] + [directory / COLLECTION],
            "a ParaView file")  # before anything is written
    created = not directory.exists()
    directory.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    try:
        written = _write_series(ds, directory, written)
    except BaseException:  # nothing half-written: this call's files go, and the directory if it made it
        for path in written:
            path.unlink(missing_ok=True)
        if created and not any(directory.iterdir()):
            directory.rmdir()
        raise
    for stale in directory.glob("snapshot_*.vtu"):  # of an earlier, longer export: biostudy's own go
        if stale not in written and marked(stale):
            stale.unlink()
    return written


def _write_series(ds: xr.Dataset, directory: Path, written: list[Path]) -> list[Path]:
    """The snapshots and the PVD, each written to a temporary and renamed; `written` lists them as they come."""
    grid = _grid(ds)
    cell_dims = tuple(reversed(grid.axes))
    points, cells, kind = _lattice(grid)
    open_cells = (np.ones(cells.shape[0], bool) if "obstacle" not in ds
                  else ~ds["obstacle"].transpose(*cell_dims).values.astype(bool).ravel())
    cells = cells[open_cells]
    used = np.unique(cells)  # nodes of open cells, renumbered compactly
    renumber = np.full(points.shape[0], -1)
    renumber[used] = np.arange(used.size)
    points, cells = points[used], renumber[cells]

    static = {}
    if "nutrient_source" in ds:
        source = ds["nutrient_source"].transpose(*cell_dims).values.astype(np.int8)
        static["nutrient_source"] = source.ravel()[open_cells]
    fields = {n: ds[n].transpose("time", *cell_dims).values.reshape(ds.sizes["time"], -1)[:, open_cells]
              for n in CELL_FIELDS if n in ds and n != "p"}
    found = clock(ds)
    real = found.real if found is not None else (lambda t: t)  # what TimeValue and the PVD's timesteps are in
    times = real(ds["time"].values.astype(float))
    shown = _mechanics_shown(ds)  # output index -> index into the mechanics' outputs (-1: none yet)
    p = u = None
    if "p" in ds:
        p = ds["p"].transpose(MECHANICS_TIME, *cell_dims).values.reshape(-1, open_cells.size)[:, open_cells]
    if "u" in ds:
        u = ds["u"].transpose(MECHANICS_TIME, *(f"{d}_node" for d in cell_dims), "component").values
        u = np.pad(u.reshape(u.shape[0], -1, u.shape[-1])[:, used], ((0, 0), (0, 0), (0, 3 - u.shape[-1])))

    for t in range(ds.sizes["time"]):
        cell_data = {name: [values] for name, values in static.items()}
        for name, values in fields.items():
            cell_data[name] = [values[t].astype(float)]
        point_data, field_data = {}, {"TimeValue": float(times[t])}
        if found is not None:
            field_data["T_star"] = float(ds["time"].values[t])
        if shown is not None:
            m = shown[t]
            if p is not None:
                cell_data["p"] = [p[m].astype(float) if m >= 0 else np.full(len(cells), np.nan)]
            if u is not None:
                point_data["u"] = u[m].astype(float) if m >= 0 else np.zeros((len(points), 3))
            field_data["mechanics_time"] = float(real(ds[MECHANICS_TIME].values[m])) if m >= 0 else float("nan")
        mesh = meshio.Mesh(points, [(kind, cells)], point_data=point_data, cell_data=cell_data)
        vectors = "u" if point_data else None
        written.append(atomic(directory / SNAPSHOT.format(t),
                               lambda path: _write_vtu(path, mesh, field_data, vectors)))  # noqa: B023 (called at once)
    written.append(atomic(directory / COLLECTION, lambda path: _write_collection(path, written, times)))
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


def _write_vtu(path: Path, mesh: meshio.Mesh, field_data: dict, vectors: str | None) -> None:
    meshio.write(path, mesh, file_format="vtu")
    _annotate(path, field_data, scalars="phi", vectors=vectors)


def _annotate(path: Path, field_data: dict, scalars: str, vectors: str | None) -> None:
    """Add what meshio's VTU writer leaves out: field data (one value each, e.g. `TimeValue`) and the
    active scalars and vectors."""
    tree = ET.parse(path)
    tree.getroot().insert(0, ET.Comment(f" {mark()} "))  # tells biostudy's files from others' (`claims.marked`)
    grid = tree.getroot().find("UnstructuredGrid")
    if field_data:
        block = ET.Element("FieldData")
        for name, value in field_data.items():
            array = ET.SubElement(block, "DataArray", type="Float64", Name=name, NumberOfTuples="1", format="ascii")
            array.text = time_text(value)
        grid.insert(0, block)
    piece = grid.find("Piece")
    if piece.find("CellData") is not None:
        piece.find("CellData").set("Scalars", scalars)
    if vectors is not None:
        piece.find("PointData").set("Vectors", vectors)
    tree.write(path)


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
