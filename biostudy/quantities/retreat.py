"""Did a run lose its biofilm?  The model retreats from where the nutrient is not, and must say so.

Eq. 34 moves every interface of phi toward the nutrient (the growth velocity r c/(k + c) grad(c)/|grad(c)|,
docs/model.md): the side of a colony facing away from the nutrient moves inward, and a biofilm fed from one
side only — a layer on agar fed from below — is eaten away from its free side until nothing is left.  That is
the paper's model, outside what it describes (real colonies on agar grow upward: docs/model.md, "What the
model does not describe"), and a user must be told rather than handed a dataset of zeros.

`lost` compares the biofilm's volume (phi >= 0.5, `measures.THRESHOLD`) at each output with its largest volume
before: a fall below `1 - FRACTION` of it is a loss, said with the times and volumes, and whether it vanished.
Commands record the message as the dataset attribute `biofilm_lost` (`attrs`) and print it as a warning; a
run that kept its biofilm has no such attribute.
"""
from __future__ import annotations

import numpy as np
import xarray as xr

from ..inputs.real_time import stated
from . import measures

ATTRIBUTE = "biofilm_lost"
FRACTION = 0.25  # a quarter of the largest volume before: far above what the bundled scenes' fronts wobble
GRID = ("; with the pointwise growth velocity on cells of ~1 µm the grid dissolves dense biofilm too "
        "(docs/paper.md): growth_velocity = \"front\" tells the two apart")


def lost(ds: xr.Dataset) -> str:
    """'' if the biofilm never fell below 1 - FRACTION of its largest volume before, else when and how much."""
    if "phi" not in ds or "time" not in ds.dims or ds.sizes["time"] < 2:
        return ""
    volume = measures.kept_volume(ds, measures.THRESHOLD)
    peak = np.maximum.accumulate(volume)
    fallen = np.flatnonzero((peak > 0) & (volume < (1 - FRACTION) * peak))
    if fallen.size == 0:
        return ""
    times = ds["time"].values
    j = int(fallen[0])
    before = int(np.argmax(volume[:j + 1]))
    units = "µm³" if "z" in ds.dims else "µm²"
    gone = np.flatnonzero(volume[j:] <= 0)
    end = (f" and vanished by {stated(ds, times[j + gone[0]])}" if gone.size
           else f" ({volume[-1]:.3g} {units} at {stated(ds, times[-1])}, the last output)")
    return (f"the biofilm (phi >= 0.5) shrank by {100 * (1 - volume[j] / volume[before]):.0f} % from "
            f"{volume[before]:.3g} {units} at {stated(ds, times[before])} to {volume[j]:.3g} {units} by "
            f"{stated(ds, times[j])}{end}: the model moves every interface toward the nutrient (Eq. 34), so a "
            f"biofilm retreats on its sides that face away from it; growth away from the nutrient, as of a "
            f"colony on agar fed from below, is outside what the model describes (docs/model.md)"
            + (GRID if ds.attrs.get("growth_velocity") == "pointwise" else ""))


def attrs(ds: xr.Dataset) -> dict:
    """{ATTRIBUTE: message} when the biofilm was lost, else {}: for the dataset's attributes."""
    message = lost(ds)
    return {ATTRIBUTE: message} if message else {}
