"""Did a run's dense biofilm vanish while its biofilm grew?  A grid artefact must not pass silently.

On 1 µm cells the model as written (the pointwise growth velocity) dissolves dense biofilm (phi >= 0.8)
into a cloud of thinner biofilm while the region phi >= 0.5 still grows; refined, the model keeps it dense
(docs/paper.md, "is a loss of dense biofilm the grid's or the model's?").  A fit to such a run fits the
grid.  `vanished` finds the first output where the dense volume is zero after it was positive while the
biofilm's volume (phi >= 0.5) grew at some output between the dense volume's peak and then (it may shrink
again afterwards, as a cloud thinner than 0.5 does), and says so with the check to
make: the same scene at h/2 (twice the cells along every axis, twice the steps).  Commands record the
message as the dataset attribute `dense_biofilm_vanished` (`attrs`) and print it as a warning; a run whose
dense biofilm did not vanish has no such attribute.
"""
from __future__ import annotations

import numpy as np
import xarray as xr

from ..inputs.real_time import stated
from . import measures

ATTRIBUTE = "dense_biofilm_vanished"


def vanished(ds: xr.Dataset) -> str:
    """'' if the dense biofilm did not vanish while the biofilm grew, else what happened and the check to make."""
    if "phi" not in ds or "time" not in ds.dims or ds.sizes["time"] < 2:
        return ""
    dense = measures.kept_volume(ds, measures.DENSE)
    biofilm = measures.kept_volume(ds, measures.THRESHOLD)
    times = ds["time"].values
    for j in range(1, len(dense)):
        if dense[j] > 0 or dense[:j].max() <= 0:
            continue
        peak = int(np.argmax(dense[:j]))
        grown = peak + int(np.argmax(biofilm[peak:j + 1]))
        if biofilm[grown] <= biofilm[peak]:
            continue
        units = "µm³" if "z" in ds.dims else "µm²"
        return (f"dense biofilm (phi >= 0.8) vanished by {stated(ds, times[j])} (it was {dense[peak]:.3g} {units} "
                f"at {stated(ds, times[peak])}) while the biofilm (phi >= 0.5) grew from {biofilm[peak]:.3g} to "
                f"{biofilm[grown]:.3g} {units} ({stated(ds, times[grown])}): on cells this coarse that is likely the "
                f"grid's, not the model's (docs/paper.md); check with the same scene at h/2: {half_spacing(ds)}")
    return ""


def half_spacing(ds: xr.Dataset) -> str:
    """The --set options that run the dataset's scene at h/2 with the step halved too."""
    shape = [int(n) * 2 for n in np.atleast_1d(ds.attrs.get("grid_shape", []))]
    spacing = float(ds.attrs.get("grid_spacing", measures.spacing(ds))) / 2
    steps = int(ds.attrs.get("steps_nominal", 0)) * 2
    shape_text = "[" + ",".join(map(str, shape)) + "]"
    return f"--set grid.shape={shape_text} --set grid.spacing={spacing:g}" + (
        f" --set time.steps={steps}" if steps else "")


def attrs(ds: xr.Dataset) -> dict:
    """{ATTRIBUTE: message} when the dense biofilm vanished, else {}: for the dataset's attributes."""
    message = vanished(ds)
    return {ATTRIBUTE: message} if message else {}
