"""Every observable on fields the solver can accept (issue 33.3): huge, zero, one cell, everything biofilm, in 2-D and
3-D.  None may raise (0.4.0 crashed in COMSTAT's marching cubes on phi = 6e55: skimage works in float32, whose range
ends at 3.4e38, and a NaN vertex became index -9223372036854775808); each is finite, or NaN where its definition
has no value (a roughness without biofilm, a height with none)."""
from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from biostudy.quantities import observables

H = 1.5
NAN_ALLOWED = {"height", "roughness", "surface_to_biovolume", "front_advance"}  # no biofilm: no value


def dataset(phi: np.ndarray, c: np.ndarray | None = None) -> xr.Dataset:
    """A run's dataset of two outputs (the field given and a copy) with everything an observable reads: c, alpha,
    p with the mechanics solved at both, the nutrient source in a corner, the substratum on the first axis."""
    dims = ("z", "y", "x")[-phi.ndim:]
    coords = {d: (np.arange(n) + 0.5) * H for d, n in zip(dims, phi.shape)} | {"time": [0.0, 1.0],
                                                                                "time_mechanics": [0.0, 1.0]}
    fields = np.stack([phi, phi])
    c = np.ones_like(fields) if c is None else np.stack([c, c])
    source = np.zeros(phi.shape, np.int8)
    source[(-1,) * phi.ndim] = 1
    ds = xr.Dataset({"phi": (("time", *dims), fields), "c": (("time", *dims), c),
                     "alpha": (("time", *dims), fields), "p": (("time_mechanics", *dims), -fields),
                     "nutrient_source": (dims, source)}, coords=coords)
    return ds.assign_attrs(substratum_face="y-" if phi.ndim == 2 else "z-", substratum_threshold=0.5,
                           grid_spacing=H)


def single(shape) -> np.ndarray:
    phi = np.zeros(shape)
    phi[tuple(n // 2 for n in shape)] = 1.0
    return phi


FIELDS = {
    "zero": lambda shape: np.zeros(shape),
    "one cell": single,
    "everything biofilm": lambda shape: np.ones(shape),
    "huge": lambda shape: np.where(single(shape) > 0, 1e300, 1e-3),
    "huge everywhere": lambda shape: np.full(shape, 1e300),
    "beyond float32": lambda shape: 6e55 * np.linspace(0.0, 1.0, int(np.prod(shape))).reshape(shape),
    "a corner cell": lambda shape: np.pad(np.ones((1,) * len(shape)), [(0, n - 1) for n in shape]),
}


@pytest.mark.parametrize("shape", [(6, 5, 4), (7, 5)], ids=["3-D", "2-D"])
@pytest.mark.parametrize("kind", list(FIELDS))
def test_every_observable_takes_an_extreme_field(kind, shape):
    ds = dataset(FIELDS[kind](shape))
    values = observables.variables(ds)
    applying = {name for name, o in observables.REGISTRY.items() if o.applies is None or o.applies(ds)}
    assert applying >= set(observables.REGISTRY) - {"dead_end_biofilm", "dead_end_reach"}  # (no obstacles here)
    assert set(values) == applying, "an observable was left out of a dataset that has its needs"
    for name, series in values.items():
        finite = np.isfinite(series.values)
        assert finite.all() or (name in NAN_ALLOWED and kind in ("zero",)), (name, series.values)


def test_a_huge_field_is_measured_where_it_crosses_the_threshold():
    """phi of 1e300 in one cell beside 1e-3: the level set phi = 1/2 crosses each edge from that cell right beside
    the small neighbour, so the biofilm is the cell and nearly all of its six half-edges: at least the cell."""
    ds = dataset(FIELDS["huge"]((6, 5, 4)))
    assert observables.value(ds, "biomass") * 5 * 4 * H**2 >= H**3 * (1 - 1e-9)
    assert observables.value(ds, "biofilm_volume") == pytest.approx(H**3)
    assert observables.value(ds, "phi_max") == 1e300
