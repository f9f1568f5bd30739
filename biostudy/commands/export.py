"""`biostudy export FILE.nc DIR`: one run's fields as files other programs open.

``vtu``: one VTU per snapshot and ``series.pvd`` for ParaView (`data.export`);
``tiff``: ``phi.tif`` and ``c.tif``, ImageJ hyperstacks at scale for Fiji
(`data.tiff`).  What the dataset cannot give is `BadInput` naming the file.
"""
from __future__ import annotations

from pathlib import Path

from ..data.reading import open_result
from ..errors import BadInput


def export(result: str | Path, directory: str | Path, *, format: str = "vtu") -> list[Path]:  # noqa: A002
    """Write a run's fields (a run or one case of a sweep) into `directory` in `format` (one of
    `declared.FORMATS`); returns the files written."""
    path, directory = Path(result), Path(directory)
    ds = open_result(path, ("run",), "export writes one run's fields")
    try:
        if format == "tiff":
            from ..data.tiff import export_tiff  # lazily: tifffile only for TIFF

            return export_tiff(ds, directory, str(path))
        from ..data.export import export as write  # lazily: meshio only for VTU

        return write(ds, directory)
    except ValueError as error:
        raise BadInput(str(error), path) from None


def said(written: list[Path], directory: str | Path, format: str = "vtu") -> str:  # noqa: A002
    """The line the command prints: how many files, where, and what opens them."""
    opened = "in Fiji (File > Open: at scale, in µm)" if format == "tiff" else \
        f"{Path(directory) / 'series.pvd'} in ParaView"
    return f"wrote {len(written)} files to {directory} (open {opened})"
