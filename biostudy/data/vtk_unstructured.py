"""VTK unstructured grids (`.vtu`, ``biostudy export --format vtu``): the open cells of a run as hexahedra (3-D) or
quadrilaterals in the z = 0 plane (2-D), written by meshio (XML, zlib-compressed).

Obstacles are left out of the mesh: their cells are removed, and the nodes
that only obstacle cells use with them.  ParaView then shows the obstacles
as holes with real faces instead of NaN cells that break colour ranges and
filters; the cell count of each file is the number of open cells.  meshio's
writer leaves out field data and the active arrays; they are added to its
XML afterwards (`_annotate`), with biostudy's mark in a comment.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from solver import Grid


def lattice(grid: Grid):
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


class OpenCells:
    """The mesh of a grid's open cells (`open_cells`: raveled in (z, y, x) order), nodes renumbered compactly."""

    suffix = ".vtu"

    def __init__(self, grid: Grid, open_cells: np.ndarray):
        points, cells, self.kind = lattice(grid)
        self.open_cells = open_cells
        cells = cells[open_cells]
        self.used = np.unique(cells)  # nodes of open cells
        renumber = np.full(points.shape[0], -1)
        renumber[self.used] = np.arange(self.used.size)
        self.points, self.cells = points[self.used], renumber[cells]

    def write(self, path: Path, cell_data: dict[str, np.ndarray], point_data: dict[str, np.ndarray],
              field_data: dict[str, float], mark: str, time_text) -> Path:
        """One snapshot: `cell_data` over the whole grid (raveled) and `point_data` over all its nodes, of which
        the open cells' and their nodes' are written."""
        import meshio  # lazily: only for this format

        mesh = meshio.Mesh(self.points, [(self.kind, self.cells)],
                           point_data={n: v[self.used].astype(float) for n, v in point_data.items()},
                           cell_data={n: [v[self.open_cells]] for n, v in cell_data.items()})
        meshio.write(path, mesh, file_format="vtu")
        _annotate(path, field_data, mark, time_text, scalars="phi", vectors="u" if point_data else None)
        return path


def _annotate(path: Path, field_data: dict, mark: str, time_text, scalars: str, vectors: str | None) -> None:
    """Add what meshio's VTU writer leaves out: field data (one value each, e.g. `TimeValue`) and the
    active scalars and vectors."""
    tree = ET.parse(path)
    tree.getroot().insert(0, ET.Comment(f" {mark} "))  # tells biostudy's files from others' (`claims.marked`)
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
