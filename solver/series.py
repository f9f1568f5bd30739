"""The numbers a run measures on every output as it goes (phi_mean, c_mean, biofilm_volume), defined once.

The solver's dataset holds them as time series (`output.Record`: measured on the fields before they go to a
sink, so a run whose fields stay on disk keeps them without reading its fields back); the study service's
observables catalogue (`biostudy.quantities.observables`) takes these same definitions and measures them on a
dataset's fields, where obstacle cells are NaN.  Name, units and long name travel with each.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

BIOFILM_THRESHOLD = 0.5  # biofilm is phi >= 0.5
SLAB_THICKNESS = 1.0  # µm: a 2-D scene's volumes are per µm of thickness, whatever the cell size
PER_THICKNESS = " (2-D: per µm of thickness)"  # what a volume's long name says in 2-D
VOLUME = "um^3"  # a volume's units: udunits and plain pint both read this spelling (not "um3")


def cell_volume(h: float, ndim: int) -> float:
    """The volume of one cubic cell of edge `h` (µm³; 2-D: µm² times `SLAB_THICKNESS`)."""
    return h**ndim * (SLAB_THICKNESS if ndim == 2 else 1.0)


@dataclass(frozen=True)
class Series:
    """One number per output: measure(one output's `field`, its open cells, the cell volume) -> value."""

    name: str
    units: str
    long_name: str
    field: str
    measure: Callable[[np.ndarray, np.ndarray, float], float]

    def attrs(self, ndim: int) -> dict:
        """Its units and long name in a dataset of an `ndim`-D run (a 2-D volume is per µm of thickness)."""
        thin = self.units == VOLUME and ndim == 2
        return {"units": self.units, "long_name": self.long_name + (PER_THICKNESS if thin else "")}


def open_mean(field: np.ndarray, open_cells: np.ndarray, volume: float) -> float:
    """The field's mean over the open (non-obstacle) cells."""
    return float(field[open_cells].mean())


def biofilm_volume(phi: np.ndarray, open_cells: np.ndarray, volume: float) -> float:
    """The volume of the open cells where phi >= `BIOFILM_THRESHOLD`."""
    return float(np.count_nonzero(phi[open_cells] >= BIOFILM_THRESHOLD) * volume)


SERIES = (
    Series("phi_mean", "1", "mean biofilm density over non-obstacle cells", "phi", open_mean),
    Series("c_mean", "1", "mean nutrient concentration over non-obstacle cells", "c", open_mean),
    Series("biofilm_volume", VOLUME, f"volume of cells with phi >= {BIOFILM_THRESHOLD:g}", "phi", biofilm_volume),
)
