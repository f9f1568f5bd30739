"""TIFF files of a run (`biostudy export RUN.nc DIR --format tiff`): phi and c as ImageJ hyperstacks, at scale.

One file per field, ``phi.tif`` and ``c.tif``: float32, axes TZYX (a 2-D run:
TYX), every output time a frame.  The calibration is ImageJ's: x and y
resolution in pixels per µm (1 / cell size), ``spacing`` the cell size along
z, ``unit`` um, so Fiji (Image > Properties, the scale bar, 3D Viewer) and
BiofilmQ or COMSTAT read lengths and volumes in µm.  Frames: ``finterval``
is the step between outputs in T* (``tunit`` T*) when they are evenly spaced,
in real time when the scene gave ``t_ref`` (``tunit`` its unit: "hour" for
48 h); each frame's label and the ``Info`` text give every output's time.  Axes as
biostudy reads images (`inputs.images`): slice 0 at the bottom (z lowest),
row 0 at y = 0 (ImageJ draws it at the top).  Obstacle cells are NaN.

A file is written to a temporary and renamed (complete or absent); an existing
file there is replaced only if biostudy exported it (its Info says so).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import BadInput
from ..inputs.files import no_directory
from .real_time import clock, shown
from .writing import atomic

FIELDS = ("phi", "c")
SIGNATURE = "biostudy export"


def _mine(path: Path) -> bool:
    """Whether an existing file is a TIFF biostudy exported (so it may be replaced)."""
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            return SIGNATURE in str((tif.imagej_metadata or {}).get("Info", ""))
    except Exception:  # not a TIFF at all
        return False


def _even(times: np.ndarray) -> float | None:
    steps = np.diff(times)
    return float(steps[0]) if steps.size and np.allclose(steps, steps[0], rtol=1e-9, atol=0) else None


def export_tiff(ds: xr.Dataset, directory: str | Path, source: str = "") -> list[Path]:
    """Write DIR/phi.tif and DIR/c.tif (module docstring); returns the paths."""
    import tifffile

    if "phi" not in ds or "time" not in ds["phi"].dims or "x" not in ds.dims:
        raise ValueError("export needs a run's dataset with cell fields (phi on time, [z,] y, x)")
    directory = Path(directory)
    if no_directory(directory):
        raise ValueError(f"{directory} {no_directory(directory)}: the TIFF files need a directory")
    cells = [d for d in ("z", "y", "x") if d in ds.dims]
    h = float(ds.attrs.get("grid_spacing", ds["x"].values[1] - ds["x"].values[0]))
    times = ds["time"].values.astype(float)
    found = clock(ds)
    frame_times, tunit = (found.real(times), found.cf[:-1]) if found else (times, "T*")
    labels = [shown(ds, t, 6) if found else f"T* = {t:.6g}" for t in times]
    frames = ", ".join(labels) if found else "T* = " + ", ".join(f"{t:.6g}" for t in times)
    targets = [directory / f"{name}.tif" for name in FIELDS if name in ds]
    for target in targets:
        if target.exists() and not _mine(target):
            raise BadInput("exists and is not a TIFF biostudy exported; refusing to overwrite it (choose another "
                           "directory, or remove the file first)", target)
    written = []
    for name, target in zip([n for n in FIELDS if n in ds], targets):
        values = ds[name].transpose("time", *cells).values.astype(np.float32)
        if len(cells) == 3:
            values = values[:, :, None]  # TZCYX with one channel: ImageJ's hyperstack order
        meta = {"axes": "TZCYX" if len(cells) == 3 else "TYX", "unit": "um", "tunit": tunit,
                "Labels": [label for label in labels for _ in range(values.shape[1] if len(cells) == 3 else 1)],
                "Info": f"{SIGNATURE} of {source or 'a run'}: {name} ({ds[name].attrs.get('long_name', name)}), "
                        f"units {ds[name].attrs.get('units', '1')}; frames at {frames}"}
        if len(cells) == 3:
            meta["spacing"] = h
        interval = _even(frame_times)
        if interval:
            meta["finterval"] = interval
        written.append(atomic(target, lambda path, values=values, meta=meta: tifffile.imwrite(
            path, values, imagej=True, resolution=(1.0 / h, 1.0 / h), metadata=meta)))
    return written
