"""Observables: named scalar quantities of a run at every output time, defined once.

Each has a name, units and a long_name, and is computed from a run's fields
by `biostudy.measures` (one definition per quantity); the three a run records
itself as it goes (phi_mean, c_mean, biofilm_volume) are defined in
`solver.series`, and measured here by that definition.  `show` prints them,
`plot` draws them against the swept or sampled parameters, `convergence`
measures their errors, `analyze` their sensitivity to the parameters, and
`study.nc` carries them per case and time.

====================  =====  ======================================================
name                  units  what
====================  =====  ======================================================
biofilm_volume        µm³    volume of cells with phi >= 0.5 (2-D: per µm of thickness)
dense_volume          µm³    volume of cells with phi >= 0.8 (the paper's isosurface)
phi_mean              1      mean phi over open cells
phi_max               1      largest phi
c_mean                1      mean c over open cells
nutrient_minimum      1      smallest c
height                µm     top of phi >= 0.5 along the vertical axis (z in 3-D, y in 2-D);
                             height_x, height_y, height_z along another axis
front_advance         µm     how far the phi >= 0.5 front moved toward the nutrient source
compression_max       Pa     largest compression, -min p (with mechanics; NaN where unsolved)
tension_max           Pa     largest tension, max p (with mechanics)
biomass               µm     biovolume per substratum area (COMSTAT), sub-cell
mean_thickness        µm     mean biofilm thickness over the substratum (COMSTAT)
max_thickness         µm     largest biofilm thickness above the substratum (COMSTAT)
roughness             1      roughness coefficient Ra* of the thickness (COMSTAT)
coverage              1      fraction of the substratum's first cell layer that is biofilm
surface_to_biovolume  µm⁻¹   biofilm-liquid interface per biovolume (COMSTAT)
dead_end_biofilm      µm³    phi >= 0.5 in dead ends off the route from colony to nutrient (2-D)
dead_end_reach        µm     how deep phi >= 0.5 reaches into a dead end beyond the route's corridor
====================  =====  ======================================================

The last six are measured on the substratum the run's dataset records (attributes
`substratum_face`, `substratum_threshold`, `substratum_connected`, `substratum_estimator`:
the scene's ``[substratum]``) by `biostudy.quantities.substratum`; a scene without a
substratum (a floating biofilm, one resting on several faces alike) has none of them, and
its dataset says why in `comstat_left_out` (`inputs.substratum_face`); they change
continuously with the parameters (sub-cell level sets), so they are the ones to
fit; with ``estimator = "voxel"`` they are COMSTAT's voxel counts instead
(`biostudy.quantities.comstat`).  A dataset written before they existed lacks
those attributes and has none of them.  The two dead-end observables
(`biostudy.quantities.dead_ends`: paper 4.4's invasion of dead ends and
retraction from them) apply to 2-D runs whose route from the colony to a held
nutrient region passes dead ends; other runs leave them out.
"""
from __future__ import annotations

import re
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Callable

import numpy as np
import xarray as xr

from solver.series import PER_THICKNESS, SERIES, VOLUME, Series, cell_volume

from ..inputs.resources import BLOCK_BYTES
from ..inputs.substratum_face import LEFT_OUT
from . import comstat, dead_ends, measures, substratum
from .saturation import SATURATION

CELL_DIMS = ("z", "y", "x")


@dataclass(frozen=True)
class Observable:
    """One named quantity: compute(run dataset) -> one value per output time."""

    name: str
    units: str
    long_name: str
    compute: Callable[[xr.Dataset], np.ndarray]
    needs: tuple[str, ...] = ("phi",)
    needs_attrs: tuple[str, ...] = ()  # attributes of the dataset it is computed from (the substratum)
    granularity: Callable[[float, int], float] | None = None  # (h, ndim) -> its step: it counts cells; None: sub-cell
    applies: Callable[[xr.Dataset], bool] | None = None  # whether the run has what it measures (None: every run)
    described: Callable[[xr.Dataset], dict] | None = None  # what it says of itself on a dataset (a height's top)

    def attrs(self, ds: xr.Dataset | None = None) -> dict:
        """Its units and long name (a volume of a 2-D run is per µm of thickness), and on a dataset what it says
        there (`described`; ValueError where it cannot be measured)."""
        volume = self.units == VOLUME and ds is not None and "z" not in ds.dims
        said = self.described(ds) if self.described is not None and ds is not None else {}
        return {"units": self.units, "long_name": self.long_name + (PER_THICKNESS if volume else ""), **said}


def _vertical(ds: xr.Dataset) -> str:
    return "z" if "z" in ds.dims else "y"


def _height(axis: str | None) -> Observable:
    """The height along `axis` (None: the vertical one), with the domain's top: a height there is saturated."""
    where = f"along {axis}" if axis else "along the vertical axis (z in 3-D, y in 2-D)"
    name = f"height_{axis}" if axis else "height"

    def top(ds: xr.Dataset) -> dict:
        along = axis or _vertical(ds)
        if along not in ds.dims:
            raise ValueError(f"{name}: the dataset has no axis {along}")
        return {SATURATION: measures.top(ds, along), "comment": f"{SATURATION}: the domain's top along {along}; a "
                "height equal to it is saturated (the biofilm reaches the top: a lower bound)"}

    return Observable(name, "um", f"top of phi >= 0.5 {where}", lambda ds: measures.height(ds, axis or _vertical(ds)),
                      described=top)


SUBSTRATUM_ATTRS = ("substratum_face", "substratum_threshold")


def _recorded(series: Series) -> Observable:
    """A series the run itself records (`solver.series`: one definition), measured the same way on a dataset's
    fields, whose obstacle cells are NaN."""
    def compute(ds: xr.Dataset) -> np.ndarray:
        fields = ds[series.field].transpose("time", *(d for d in CELL_DIMS if d in ds.dims)).values
        volume = cell_volume(measures.spacing(ds), fields.ndim - 1)
        return np.array([series.measure(field, np.isfinite(field), volume) for field in fields])

    counts = series.units == VOLUME  # a volume of cells: it moves by one cell's volume
    return Observable(series.name, series.units, series.long_name, compute, (series.field,),
                      granularity=cell_volume if counts else None)


# While `variables` measures a dataset, its sub-cell substratum quantities are computed together, from two level
# sets per output (`substratum.substratum_observables`) instead of one or two per quantity: [dataset, values].
_TOGETHER: ContextVar[list | None] = ContextVar("substratum_together", default=None)


def _on_substratum(quantity: substratum.Quantity) -> Observable:
    """A COMSTAT observable, per output, on the substratum face, with the threshold, the connected-volume filtering
    and the estimator the dataset records (`comstat`; files written before the last two: sub-cell, unfiltered)."""
    def compute(ds: xr.Dataset) -> np.ndarray:
        face, threshold = str(ds.attrs["substratum_face"]), float(ds.attrs["substratum_threshold"])
        voxel = str(ds.attrs.get("substratum_estimator", "subcell")) == "voxel"
        together = _TOGETHER.get()
        if together is not None and not voxel and together[0] is ds:
            return together[1][quantity.name]
        phi = ds["phi"].transpose("time", *(d for d in CELL_DIMS if d in ds.dims)).values
        if int(ds.attrs.get("substratum_connected", 0)):
            phi = np.array([comstat.connected(field, face, threshold) for field in phi])
        h = measures.spacing(ds)
        if voxel:
            return np.array([comstat.voxel_observables(field, h, face, threshold)[quantity.name] for field in phi])
        if together is None:
            return np.array([quantity.compute(field, h, face, threshold) for field in phi])
        values = [substratum.substratum_observables(field, h, face, threshold) for field in phi]
        together[:] = [ds, {name: np.array([v[name] for v in values]) for name in substratum.QUANTITIES}]
        return together[1][quantity.name]

    return Observable(quantity.name, quantity.units, quantity.long_name, compute, ("phi",), SUBSTRATUM_ATTRS)


RECORDED = {series.name: _recorded(series) for series in SERIES}  # phi_mean, c_mean, biofilm_volume
REGISTRY: dict[str, Observable] = {o.name: o for o in (
    RECORDED["biofilm_volume"],
    Observable("dense_volume", VOLUME, "volume of dense biofilm, phi >= 0.8", measures.volume, granularity=cell_volume),
    RECORDED["phi_mean"],
    Observable("phi_max", "1", "largest biofilm density", measures.phi_max),
    RECORDED["c_mean"],
    Observable("nutrient_minimum", "1", "smallest nutrient concentration",
               lambda ds: measures.nutrient_minimum(ds)["c"], ("c", "phi")),
    _height(None),
    Observable("front_advance", "um", "advance of the phi >= 0.5 front toward the nutrient source since the "
               "first output", measures.front_advance, ("phi", "nutrient_source")),
    Observable("compression_max", "Pa", "largest compression of the biofilm: -min p (hydrostatic stress)",
               lambda ds: measures.stress_extremes(ds)[0], ("p",)),
    Observable("tension_max", "Pa", "largest tension of the biofilm: max p (hydrostatic stress)",
               lambda ds: measures.stress_extremes(ds)[1], ("p",)),
    *(_on_substratum(q) for q in substratum.QUANTITIES.values()),
    Observable("dead_end_biofilm", VOLUME, "biofilm (phi >= 0.5) in dead ends off the route from the colony to the "
               "nutrient", dead_ends.biofilm, ("phi", "obstacle", "nutrient_source"), granularity=cell_volume,
               applies=dead_ends.applies),
    Observable("dead_end_reach", "um", "how deep phi >= 0.5 reaches into a dead end beyond the route's corridor",
               dead_ends.reach, ("phi", "obstacle", "nutrient_source"), granularity=lambda h, ndim: h,
               applies=dead_ends.applies),
)}

# The columns `show` gives each case of a study, and the outputs a sweep's picture draws by default.
SUMMARY = ("biofilm_volume", "dense_volume", "height", "c_mean", "compression_max")


def get(name: str) -> Observable:
    """The observable of that name (height_x, height_y, height_z too); ValueError names the known ones."""
    if name in REGISTRY:
        return REGISTRY[name]
    axis = re.fullmatch(r"height_([xyz])", name)
    if axis:
        return _height(axis.group(1))
    raise ValueError(f"unknown observable {name!r}; observables are {', '.join(REGISTRY)} (height_x, height_y, "
                     f"height_z along an axis)")


def evaluate(ds: xr.Dataset, name: str) -> xr.DataArray:
    """The observable over time (and over a study's case dimensions) from the dataset's fields."""
    observable = get(name)
    attrs = observable.attrs(ds)
    missing = [v for v in observable.needs if v not in ds]
    if missing:
        raise ValueError(f"{name} needs {', '.join(missing)}, which the dataset does not have")
    if observable.applies is not None and not observable.applies(ds):
        raise ValueError(f"{name}: the run has none to measure (see biostudy/quantities/observables.py)")
    unrecorded = [a for a in observable.needs_attrs if a not in ds.attrs]
    if unrecorded and LEFT_OUT in ds.attrs:
        raise ValueError(f"{name}: {ds.attrs[LEFT_OUT]}")
    if unrecorded:
        raise ValueError(f"{name} needs the attribute {', '.join(unrecorded)} (the scene's [substratum]), which "
                         "the dataset does not record (written before substratum observables existed: run it again)")
    extra = [d for d in ds[observable.needs[0]].dims if d not in ("time", "time_mechanics", *CELL_DIMS)]
    if not extra:
        values = observable.compute(ds)
        return xr.DataArray(values, dims=("time",), coords={"time": ds["time"]}, name=name, attrs=attrs)
    stacked = ds.stack(_case=extra)
    parts = [observable.compute(stacked.isel(_case=i)) for i in range(stacked.sizes["_case"])]
    out = xr.DataArray(np.stack(parts), dims=("_case", "time"),
                       coords={"_case": stacked["_case"], "time": ds["time"]}, name=name)
    return out.unstack("_case").transpose(*extra, "time").assign_attrs(attrs)


def variables(ds: xr.Dataset, block_bytes: float = BLOCK_BYTES,
              names: list[str] | None = None) -> dict[str, xr.DataArray]:
    """Every observable this run's fields give (or those of `names`), as time series with units and long_name.
    The fields are read once, at most `block_bytes` of them at a time (`_blocks`): a run whose fields stay
    on disk (`data.spool`) is measured without holding every output."""
    if names is None:
        import dask  # lazily: dask only where fields are measured

        with dask.config.set(scheduler="synchronous"):  # what `applies` reads of the fields is read in this thread
            names = [n for n, o in REGISTRY.items() if available(ds, o)]
    if not names:
        return {}
    token = _TOGETHER.set([None, {}])  # the substratum quantities of each dataset measured below: together
    try:
        return _measured(ds, names, block_bytes)
    finally:
        _TOGETHER.reset(token)


def _measured(ds: xr.Dataset, names: list[str], block_bytes: float) -> dict[str, xr.DataArray]:
    fields = ds[sorted({v for n in names for v in REGISTRY[n].needs if v in ds})]
    # lazy fields (a sweep's case files, a streamed run) are read in this thread: the HDF5 library is not
    # thread-safe, and a dataset a notebook left open may be closed by the garbage collector at any moment
    blocks = _blocks(fields, block_bytes)
    if len(blocks) == 1:
        fields = fields.load(scheduler="synchronous")
        return {n: evaluate(fields, n) for n in names}
    parts: dict[str, list[xr.DataArray]] = {n: [] for n in names}
    for block in blocks:
        chosen = fields.isel(time=[0, *block] if block[0] else block)  # the first output: where fronts start
        if "time_mechanics" in chosen.dims:
            chosen = chosen.sel(time_mechanics=chosen["time_mechanics"].isin(chosen["time"].values))
        chosen = chosen.load(scheduler="synchronous")
        for n in names:
            parts[n].append(evaluate(chosen, n).isel(time=slice(1 if block[0] else 0, None)))
    return {n: xr.concat(p, "time").assign_attrs(p[0].attrs) for n, p in parts.items()}


def _blocks(fields: xr.Dataset, block_bytes: float) -> list[list[int]]:
    """The output indices in consecutive blocks whose fields take at most `block_bytes` (one output at least)."""
    outputs = fields.sizes.get("time", 0)
    per_output = sum(v.nbytes for v in fields.data_vars.values()) / max(outputs, 1)
    size = max(1, int(block_bytes // max(per_output, 1)))
    return [list(range(start, min(start + size, outputs))) for start in range(0, outputs, size)] or [[]]


def available(ds: xr.Dataset, observable: Observable) -> bool:
    """Whether the dataset has what the observable is computed from (and the run what it measures)."""
    return all(v in ds for v in observable.needs) and all(a in ds.attrs for a in observable.needs_attrs) and \
        (observable.applies is None or observable.applies(ds))


def as_measured(ds: xr.Dataset, now: dict) -> xr.Dataset:
    """A run's dataset as a scene measures it now (`now`: its `substratum_attrs`): the substratum's attributes the
    scene gives, those it no longer gives (a face, the reason there is none) removed, and the stored observables
    that depend on them dropped where they changed (computed again from the fields; nothing is simulated again)."""
    if remeasured(ds.attrs, now):
        ds = ds.drop_vars([o.name for o in REGISTRY.values() if o.needs_attrs and o.name in ds])
    ds.attrs = {**{k: v for k, v in ds.attrs.items() if k not in MEASURED_ON}, **now}
    return ds


MEASURED_ON = (*SUBSTRATUM_ATTRS, LEFT_OUT, "substratum_connected", "substratum_estimator")  # a dataset's substratum


def remeasured(attrs: dict, now: dict) -> bool:
    """Whether a dataset of `attrs` was measured on another substratum than `now` says (`as_measured`)."""
    return any(str(attrs.get(name)) != str(now.get(name)) for name in MEASURED_ON if name in attrs or name in now)


def value(ds: xr.Dataset, name: str, index: int = -1) -> float:
    """One observable of one run at one output (default the last)."""
    return float(evaluate(ds, name).values[index])
