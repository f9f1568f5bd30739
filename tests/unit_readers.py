"""Every units string of a dataset as the ecosystem's unit libraries read it (issue 36.3): UDUNITS-2 (cf-units,
what the CF checker and netCDF tools use), plain pint (a registry as pint makes it: pint-xarray's default in a
session that never imported cf_xarray) and cf_xarray's pint registry; all three must read the same quantity.  A
helper of the tests that make files.

Importing ``cf_xarray.units`` makes its registry pint's application registry (and so pint-xarray's default), so
plain pint is a registry of its own here (`plain`), never ``pint.get_application_registry()``."""
from __future__ import annotations

import functools
import math

import xarray as xr


@functools.lru_cache(maxsize=1)
def plain():
    """pint's own registry, untouched by cf_xarray."""
    import pint

    return pint.UnitRegistry(force_ndarray_like=True)  # as pint-xarray wants a registry


def units_of(ds: xr.Dataset) -> dict[str, str]:
    """Variable (or coordinate) name -> its units attribute."""
    return {str(name): str(var.attrs["units"]) for name, var in ds.variables.items() if "units" in var.attrs}


def in_si(units: str) -> tuple[float, str]:
    """One `units` in SI base units with plain pint: (factor, base units as udunits reads them, 'm**3')."""
    quantity = (1.0 * plain().parse_units(units)).to_base_units()
    return float(quantity.magnitude), f"{quantity.units:~C}" or "1"


def assert_read_alike(units: str, where: str = "") -> None:
    """`units` parses in plain pint, cf_xarray's registry and UDUNITS-2, to the same quantity in SI."""
    import cf_units
    import cf_xarray.units

    factor, base = in_si(units)  # plain pint: raises on 'um3' (unknown unit) and 'um-1' (a subtraction)
    cf = (1.0 * cf_xarray.units.units.parse_units(units)).to_base_units()
    assert math.isclose(float(cf.magnitude), factor, rel_tol=1e-12), (where, units, cf, factor)
    udunits = cf_units.Unit(units).convert(1.0, cf_units.Unit(base))
    assert math.isclose(udunits, factor, rel_tol=1e-12), (where, units, udunits, factor)


def assert_every_unit_read_alike(ds: xr.Dataset, where: str = "") -> None:
    """Every units attribute of `ds` read alike by the three (`assert_read_alike`), and the dataset quantified by
    pint-xarray with plain pint's registry."""
    import pint_xarray  # noqa: F401  (the .pint accessor)

    for name, units in units_of(ds).items():
        assert_read_alike(units, f"{where}: {name}")
    ds.pint.quantify(unit_registry=plain())
