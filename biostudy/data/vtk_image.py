"""VTK image data (`.vti`): a run's regular grid as ParaView and VTK read it natively, one file per snapshot.

The grid is what it is: an origin, one spacing h per axis and the cell
counts (``WholeExtent`` counts points, 0..n per axis; a 2-D run is one layer
of points in z = 0, its cells pixels).  Cell data is in VTK's order, x
fastest, then y, then z: the fields' own C order (z, y, x), raveled.  Point
data (u) is on the grid's nodes in the same order, 3 components (2-D: z = 0).

Arrays are appended raw after the XML (``<AppendedData encoding="raw">``),
each zlib-compressed in blocks of `BLOCK` bytes with VTK's UInt64 header
(number of blocks, block size, the last block's size or 0 when full, each
block's compressed size), the layout VTK's XML writers use with
``vtkZLibDataCompressor``; values keep the dataset's dtype (float64: the
file holds the dataset's numbers exactly).  One XML comment carries
biostudy's mark (`claims.mark`) before anything binary.
"""
from __future__ import annotations

import struct
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import numpy as np

BLOCK = 1 << 16  # bytes of one compressed block (VTK's own default is 32 KiB; larger blocks compress better)
LEVEL = 6  # zlib's default level: within 3 % of the smallest file for these fields at a third of level 9's time
VTK_TYPES = {"f8": "Float64", "f4": "Float32", "i1": "Int8", "u1": "UInt8", "i4": "Int32", "i8": "Int64"}


def compressed(values: np.ndarray) -> bytes:
    """An array as VTK's zlib-compressed appended data: the UInt64 header, then the blocks."""
    raw = np.ascontiguousarray(values).astype(values.dtype.newbyteorder("<"), copy=False).tobytes()
    blocks = [zlib.compress(raw[start:start + BLOCK], LEVEL) for start in range(0, len(raw), BLOCK)]
    last = len(raw) % BLOCK
    header = struct.pack(f"<{3 + len(blocks)}Q", len(blocks), BLOCK, last, *(len(b) for b in blocks))
    return header + b"".join(blocks)


def _array(parent: ET.Element, name: str, values: np.ndarray, offset: int) -> None:
    components = values.shape[1] if values.ndim == 2 else 1
    attrs = {"type": VTK_TYPES[values.dtype.str[1:]], "Name": name, "format": "appended", "offset": str(offset)}
    if components > 1:
        attrs["NumberOfComponents"] = str(components)
    ET.SubElement(parent, "DataArray", attrs)


def write_vti(path: Path, cells_shape: tuple[int, ...], spacing: float, origin: tuple[float, ...],
              cell_data: dict[str, np.ndarray], point_data: dict[str, np.ndarray], field_data: dict[str, float],
              mark: str, time_text, scalars: str = "phi", vectors: str | None = None) -> Path:
    """One snapshot as VTK image data.  `cells_shape` ([z,] y, x cell counts), `spacing` (µm), `origin` (x, y[, z]
    of the first node); `cell_data` each raveled in (z, y, x) C order, `point_data` (points, components) in
    the nodes' C order; `field_data` one number each (written as `time_text` spells it); `mark` in a comment."""
    counts = list(reversed(cells_shape)) + [0] * (3 - len(cells_shape))  # cells along x, y, z
    extent = " ".join(f"0 {n}" for n in counts)
    corner = list(origin) + [0.0] * (3 - len(origin))
    root = ET.Element("VTKFile", type="ImageData", version="1.0", byte_order="LittleEndian", header_type="UInt64",
                      compressor="vtkZLibDataCompressor")
    root.append(ET.Comment(f" {mark} "))
    image = ET.SubElement(root, "ImageData", WholeExtent=extent, Origin=" ".join(time_text(c) for c in corner),
                          Spacing=" ".join([time_text(spacing)] * 3), Direction="1 0 0 0 1 0 0 0 1")
    if field_data:
        block = ET.SubElement(image, "FieldData")
        for name, value in field_data.items():
            array = ET.SubElement(block, "DataArray", type="Float64", Name=name, NumberOfTuples="1", format="ascii")
            array.text = time_text(value)
    piece = ET.SubElement(image, "Piece", Extent=extent)
    blobs: list[bytes] = []
    offset = 0
    for kind, data, active in (("PointData", point_data, {"Vectors": vectors} if vectors else {}),
                               ("CellData", cell_data, {"Scalars": scalars})):
        section = ET.SubElement(piece, kind, active if data else {})
        for name, values in data.items():
            _array(section, name, values, offset)
            blobs.append(compressed(values))
            offset += len(blobs[-1])
    ET.indent(root)
    text = ET.tostring(root, encoding="unicode").removesuffix("</VTKFile>")
    with open(path, "wb") as handle:
        handle.write(b'<?xml version="1.0"?>\n' + text.encode())
        handle.write(b'  <AppendedData encoding="raw">\n   _')
        for blob in blobs:
            handle.write(blob)
        handle.write(b"\n  </AppendedData>\n</VTKFile>\n")
    return path


class ImageGrid:
    """Writes the snapshots of one grid as image data: every cell (obstacles kept, NaN in the fields, and the int8
    cell array `obstacle` 1 there, for ParaView's Threshold), every node."""

    suffix = ".vti"

    def __init__(self, cells_shape: tuple[int, ...], spacing: float, origin: tuple[float, ...],
                 obstacle: np.ndarray | None):
        self.cells_shape, self.spacing, self.origin = cells_shape, spacing, origin
        self.static = {} if obstacle is None else {"obstacle": obstacle.astype(np.int8)}

    def write(self, path: Path, cell_data: dict[str, np.ndarray], point_data: dict[str, np.ndarray],
              field_data: dict[str, float], mark: str, time_text) -> Path:
        return write_vti(path, self.cells_shape, self.spacing, self.origin, {**cell_data, **self.static}, point_data,
                         field_data, mark, time_text, vectors="u" if point_data else None)
