"""`biostudy export FILE.nc DIR`: one run's fields as files other programs open.

``vti`` (the default): VTK image data, one file per snapshot, and ``series.pvd``
for ParaView; ``vtu``: the same as unstructured grids of the open cells
(`data.export`); ``tiff``: ``phi.tif`` and ``c.tif``, ImageJ hyperstacks at scale for Fiji
(`data.tiff`).  What the dataset cannot give is `BadInput` naming the file.
"""
from __future__ import annotations

from pathlib import Path

from ..data.reading import open_result
from ..errors import BadInput
from .declared import FORMATS


def export(result: str | Path, directory: str | Path, *, format: str = FORMATS[0]) -> list[Path]:  # noqa: A002
    """Write a run's fields (a run or one case of a sweep) into `directory` in `format` (one of
    `declared.FORMATS`); returns the files written."""
    path, directory = Path(result), Path(directory)
    ds = open_result(path, ("run",), "export writes one run's fields")
    try:
        if format == "tiff":
            from ..data.tiff import export_tiff  # lazily: tifffile only for TIFF

            return export_tiff(ds, directory, str(path))
        from ..data.export import export as write  # lazily: VTK's writers only for VTK files

        return write(ds, directory, format)
    except ValueError as error:
        raise BadInput(str(error), path) from None


def said(written: list[Path], directory: str | Path, format: str = FORMATS[0]) -> str:  # noqa: A002
    """The line the command prints: how many files, where, and what opens them."""
    opened = "in Fiji (File > Open: at scale, in µm)" if format == "tiff" else \
        f"{Path(directory) / 'series.pvd'} in ParaView"
    return f"wrote {len(written)} files to {directory} (open {opened})"
