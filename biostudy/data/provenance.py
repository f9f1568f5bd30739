"""What every file biostudy writes says about itself: the version that made it, when, and how (its `history`),
in attributes netCDF can store; a run's dataset with the scene that produced it (`stamp`)."""
from __future__ import annotations

import datetime as _dt
import functools
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import netcdf

if TYPE_CHECKING:
    import xarray as xr  # imported where a dataset is made: `show` of a run's file needs none


@functools.lru_cache(maxsize=None)
def version() -> str:
    """biostudy's installed version, read once per process (every dataset records it)."""
    import importlib.metadata  # lazily: it imports email and more, which `show` of a run's file never needs

    try:
        return importlib.metadata.version("biostudy")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def with_provenance(attrs: dict) -> dict:
    """`attrs` as netCDF can store them, with the biostudy version and the time of writing: every file
    biostudy writes says which version made it and when."""
    return legal_attrs({**attrs, "biostudy_version": version(), "created": now(), "history": netcdf.history()})


def legal_attrs(attrs: dict) -> dict:
    """Attributes netCDF can store: no None, booleans as 0/1, nested dicts flattened to 'a_b' names."""
    legal = {}
    for name, value in attrs.items():
        if value is None:
            continue
        if isinstance(value, dict):
            legal.update(legal_attrs({f"{name}_{k}": v for k, v in value.items()}))
        elif isinstance(value, (bool, np.bool_)):
            legal[name] = int(value)
        elif isinstance(value, (list, tuple)):
            legal[name] = ", ".join(map(str, value)) if any(isinstance(v, str) for v in value) else np.asarray(value)
        elif isinstance(value, Path):
            legal[name] = str(value)
        else:
            legal[name] = value
    return legal


def stamp(ds: xr.Dataset, scene: str, scene_file: str | Path, overrides: str, **extra: Any) -> xr.Dataset:
    """The run's dataset with what produced it: the scene as TOML text, its file, the overrides (a ``t_ref``
    among `extra`: the real-time coordinates, `real_time`)."""
    from . import real_time  # lazily, as xarray

    ds = ds.copy()
    ds.attrs = with_provenance({**ds.attrs, "scene": scene, "scene_file": str(Path(scene_file).resolve())
                                if scene_file else "",
                                "overrides": overrides, **extra})
    return real_time.with_real_time(ds)  # a scene's t_ref: the real-time coordinates
