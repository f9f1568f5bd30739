"""What one level of a convergence study contributes: its quantities at every output time, on the common grid.

A level's run is read once: the observables compared (`COMPARED`: their units
and long names from where each is declared), the front position, and phi and
p restricted by cell averaging to the study's coarsest grid (`measures.restrict`),
at every output time; its costs (`COSTS`, the set-up included: the operators a
level builds are part of what it costs).  A reference run given by the user
(`--reference`) is read the same way, on the scene's output times.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from solver.output import FIELDS, on_output_times

from ..data import case_files, reading
from ..errors import BadInput
from ..inputs.scene import Scene
from ..quantities import measures, observables

# observables compared (biomass and mean_thickness: the COMSTAT ones a calibration fits, on the recorded substratum)
OBSERVED = ("biofilm_volume", "dense_volume", "phi_max", "height", "c_mean", "biomass", "mean_thickness")
RELATIVE = ("biofilm_volume", "dense_volume")  # compared relative to the reference's value
SCALARS = (*OBSERVED, "front_position")
FIELD_NORMS = ("phi_L1", "phi_L2", "p_L2")
COSTS = ("cpu_time_setup", "cpu_time_loop", "cpu_time_first")  # `solver.timeloop.Simulation.report`


@dataclass(frozen=True)
class Compared:
    """One quantity whose error a convergence run reports, with the units and long name of its error."""

    name: str
    units: str
    long_name: str


def _compared() -> tuple[Compared, ...]:
    """The compared quantities, their units and long names from where each quantity is declared: the fields'
    in `solver.output.FIELDS`, the observables' in their registry."""
    fields = [Compared(f"{name}_{norm}", FIELDS[name][0], f"{what} of {name} - {name}_ref over open cells "
                       "(common grid)") for name, norm, what in (("phi", "L1", "mean |.|"),
                                                               ("phi", "L2", "root mean square"))]
    scalars = []
    for name in OBSERVED:
        observable = observables.get(name)
        relative = name in RELATIVE
        scalars.append(Compared(name, "1" if relative else observable.units,
                                f"{'relative ' if relative else ''}error of the {observable.long_name}"))
    scalars.append(Compared("front_position", "um", "error of the front position toward the nutrient"))
    return (*fields, *scalars, Compared("p_L2", FIELDS["p"][0], "root mean square of p - p_ref over open cells "
                                                                "(common grid)"))


COMPARED = _compared()
QUANTITIES = tuple(c.name for c in COMPARED)
UNITS = {**{name: observables.get(name).units for name in OBSERVED}, "front_position": "um"}


@dataclass
class Level:
    """A finished run's quantities at every output time: scalars (time,), phi and p (time, cells of the common
    grid; p NaN where the mechanics was not solved), its costs and the times."""

    times: np.ndarray
    scalars: dict[str, np.ndarray]
    phi: np.ndarray
    p: np.ndarray | None
    costs: dict[str, float]


def _scalar(ds: xr.Dataset, name: str) -> np.ndarray:
    if name in ds and ds[name].dims == ("time",):
        return np.asarray(ds[name].values, float)
    if observables.available(ds, observables.get(name)):
        return np.asarray(observables.evaluate(ds, name).values, float)
    return np.full(ds.sizes["time"], np.nan)


def level_of(ds: xr.Dataset, factor: int | None) -> Level:
    """A run's `Level`; `factor`: cells of the run along each axis of a common-grid cell (None: the run's grid is
    not a refinement of the common grid, so no field norms)."""
    moved = on_output_times(ds)
    n = ds.sizes["time"]
    scalars = {name: _scalar(ds, name) for name in OBSERVED}
    scalars["front_position"] = np.array([measures.front_position(ds, i) for i in range(n)])
    phi = p = None
    if factor is not None:
        phi = np.stack([measures.restrict(moved["phi"].values[i], factor) for i in range(n)])
        if "p" in moved:
            p = np.stack([measures.restrict(moved["p"].values[i], factor) for i in range(n)])
    costs = {"wall_time": float(ds.attrs.get("wall_time", np.nan)),
             "steps_taken": float(ds.attrs.get("steps_taken", np.nan)),
             **{name: float(ds.attrs.get(name, np.nan)) for name in COSTS}}
    return Level(np.asarray(ds["time"].values, float), scalars, phi, p, costs)  # type: ignore[arg-type]


def finished(path: Path, factor: int | None) -> Level | None:
    """The `Level` of a case file, or None if that level did not finish."""
    record = case_files.recorded(path)
    if not record or record.get("status") != "done":
        return None
    return level_of(reading.open_dataset(path), factor)


def factor_of(ds: xr.Dataset, coarse_h: float) -> int | None:
    """How many of the run's cells span a cell of size `coarse_h` along each axis, if a whole number."""
    ratio = coarse_h / measures.spacing(ds)
    return int(round(ratio)) if abs(ratio - round(ratio)) < 1e-6 and round(ratio) >= 1 else None


def given_reference(path: Path, base: Scene) -> Level:
    """A reference run for every level (`--reference`): the same domain as the scene and an output at each of the
    scene's output times (the reference's other outputs are left out)."""
    ds = reading.open_dataset(path)
    if "phi" not in ds:
        raise BadInput("is not a run's dataset (no phi)", path, "--reference")
    dimensions = sum(axis in ds["phi"].dims for axis in ("x", "y", "z"))
    if dimensions != len(base.grid.shape):
        raise BadInput(f"is a {dimensions}-D run; the scene is {len(base.grid.shape)}-D", path, "--reference")
    h = measures.spacing(ds)
    found = tuple(float(ds[a].values[-1]) + 0.5 * h for a in ("x", "y", "z") if a in ds.dims)
    extent = tuple(float(e) for e in base.grid.solver_grid().extent)
    if not np.allclose(found, extent, rtol=1e-9):
        raise BadInput(f"covers {found} µm; the scene covers {extent} µm", path, "--reference")
    wanted = np.asarray(base.time.times(), float)
    have = np.asarray(ds["time"].values, float)
    index = [int(np.argmin(np.abs(have - t))) for t in wanted]
    missing = [t for t, i in zip(wanted, index) if abs(have[i] - t) > 1e-9 * max(1.0, t)]
    if missing:
        outputs = ", ".join(f"{t:g}" for t in wanted)
        raise BadInput(f"has no output at T* = {missing[0]:g} (the scene's outputs are {outputs})", path,
                       "--reference")
    return level_of(ds.isel(time=index), factor_of(ds, base.grid.spacing))
