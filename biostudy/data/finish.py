"""A run's dataset finished, one way wherever it was simulated: `biostudy run`, a sweep's case, a convergence
level, a stability case, a calibration's simulation.

The steps read what the ones before wrote, so their order is `finish`'s, not its callers': the stamp records
the scene, its file, its overrides, the substratum and the clock (`provenance.stamp`); the observables
(`netcdf.with_observables`) read the substratum's attributes from it; the alerts (`quantities.alerts`) read the
volumes just measured and the clock (they say their times in real time too).  What the stamp records is a
`Record`, text and numbers known before the run, so that it can travel to a worker beside its problem.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..quantities import alerts
from . import netcdf, provenance

if TYPE_CHECKING:
    import xarray as xr

    from ..inputs.scene import Scene


@dataclass(frozen=True)
class Record:
    """What a run's dataset records of what produced it: the scene as TOML text, its file ('' for a scene given as
    data), the overrides as TOML text, and attributes (the substratum, the clock, a case's own)."""

    scene: str
    scene_file: str
    overrides: str
    attrs: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def of(cls, scene: Scene, scene_file: str | Path | None, overrides: str, **attrs: Any) -> Record:
        """The record of `scene`: with what its observables and alerts read (`Scene.substratum_attrs`,
        `Scene.real_time_attrs`, the images' provenance `Scene.image_attrs`) and `attrs`."""
        return cls(scene.to_toml(), str(scene_file or ""), overrides,
                   {**scene.substratum_attrs(), **scene.real_time_attrs(), **scene.image_attrs(), **attrs})


def finish(ds: xr.Dataset, record: Record, **attrs: Any) -> xr.Dataset:
    """The simulated dataset `ds` as biostudy writes it: stamped with `record` and `attrs`, every observable a
    variable, the alerts' sentences attributes (module docstring: in this order)."""
    ds = provenance.stamp(ds, record.scene, record.scene_file, record.overrides, **record.attrs, **attrs)
    ds = netcdf.with_observables(ds)  # after the stamp: the substratum's observables read its attributes
    ds.attrs.update(alerts.attrs(ds))  # after the observables: from the volumes just measured
    return ds
