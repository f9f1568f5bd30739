"""ParaView files of a run (`biostudy export`): one VTU per snapshot and a PVD that lists them in time.

Each output time becomes `snapshot_NNNN.vtu` (meshio, XML unstructured grid,
zlib-compressed): hexahedra in 3-D, quadrilaterals in the z = 0 plane in 2-D,
with
- cell data phi, c, alpha and p (where the run has them) and the int8 mask
  `nutrient_source` (1 where c is held);
- point data u, the displacement (µm) as a 3-vector (2-D: z component 0), so
  ParaView's "Warp By Vector" shows the deformed body.
`series.pvd` lists the snapshots with their times (T*): opening it in ParaView
loads the whole series with a working time slider.  (meshio's VTU writer drops
field data, so the PVD is where the times live.)

Obstacles are left out of the mesh: their cells are removed, and the nodes
that only obstacle cells use with them.  ParaView then shows the obstacles
as holes with real faces instead of NaN cells that break colour ranges and
filters; the cell count of each file is the number of open cells.
p and u are written at the times the mechanics was solved; at other times
(all NaN) they are left out of that file rather than written as NaN.
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import xarray as xr

from solver import Grid
from solver.problem import AXES

from .store import temporary_name

CELL_FIELDS = ("phi", "c", "alpha", "p")
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
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise ValueError(f"{directory} is a file, not a directory for the snapshots")
    created = not directory.exists()
    directory.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    try:
        return _write_series(ds, directory, written)
    except BaseException:  # nothing half-written: this call's files go, and the directory if it made it
        for path in written:
            path.unlink(missing_ok=True)
        if created and not any(directory.iterdir()):
            directory.rmdir()
        raise


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
              for n in CELL_FIELDS if n in ds}
    u = None
    if "u" in ds:
        u = ds["u"].transpose("time", *(f"{d}_node" for d in cell_dims), "component").values
        u = u.reshape(u.shape[0], -1, u.shape[-1])[:, used]

    for t in range(ds.sizes["time"]):
        cell_data = {name: [values] for name, values in static.items()}
        for name, values in ((n, f[t]) for n, f in fields.items()):
            if name == "p" and not np.isfinite(values).any():
                continue  # mechanics not solved at this output
            cell_data[name] = [values.astype(float)]
        point_data = {}
        if u is not None and np.isfinite(u[t]).any():
            point_data["u"] = np.pad(u[t].astype(float), ((0, 0), (0, 3 - u.shape[-1])))
        mesh = meshio.Mesh(points, [(kind, cells)], point_data=point_data, cell_data=cell_data)
        written.append(_atomic(directory / SNAPSHOT.format(t),
                               lambda path: meshio.write(path, mesh, file_format="vtu")))
    written.append(_atomic(directory / COLLECTION, lambda path: _write_collection(path, written, ds["time"].values)))
    return written


def _atomic(path: Path, write) -> Path:
    temporary = temporary_name(path)
    try:
        write(temporary)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)
    return path


def _write_collection(path: Path, files: list[Path], times: np.ndarray) -> Path:
    """The PVD file: every snapshot with its time, file names relative to the PVD."""
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ET.SubElement(root, "Collection")
    for file, when in zip(files, times):
        ET.SubElement(collection, "DataSet", timestep=repr(float(when)), group="", part="0", file=file.name)
    ET.indent(root)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
    return path
