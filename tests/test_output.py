"""Dataset layout (docs/model.md, "The dataset"): dimensions, units and long names, masks, attributes, netCDF
round trip."""
from dataclasses import replace

import numpy as np
import xarray as xr

from solver import Grid, Parameters, Problem, simulate


def small_problem(shape=(6, 5, 4), obstacle=True):
    grid = Grid(shape, 1.5)
    coords = grid.cell_coordinates()
    phi0 = (sum((q - 3.0) ** 2 for q in coords) <= 4).astype(float)
    blocked = np.zeros(grid.cells_shape, bool)
    if obstacle:
        blocked[..., -1, 0] = True
    held = np.zeros(grid.cells_shape, bool)
    held[..., -1, -1] = True
    return Problem(grid=grid, phi0=np.where(blocked, 0, phi0), nutrient_fixed=held, obstacle=blocked, t_end=0.01,
                   steps=4, output_times=[0, 0.005, 0.01], params=Parameters(g=2e8), name="small")


def test_dataset_layout_units_and_round_trip(tmp_path):
    ds = simulate(small_problem())
    assert dict(ds.sizes) == {"time": 3, "z": 4, "y": 5, "x": 6}
    assert "u" not in ds and "p" not in ds and "x_node" not in ds.coords  # no mechanics asked for
    for name in list(ds.data_vars) + list(ds.coords):
        assert ds[name].attrs.get("long_name"), name
        assert "units" in ds[name].attrs, name
    assert ds.x.values.tolist() == [0.75 + 1.5 * i for i in range(6)]
    assert ds.attrs["Conventions"].startswith("CF")
    for key in ("mu", "nu", "d", "beta", "k_alpha", "k", "g", "r"):
        assert key in ds.attrs
    assert ds.attrs["g"] == 2e8 and ds.attrs["steps_taken"] == 4 and ds.attrs["wall_time"] > 0
    obstacle = ds.obstacle.values.astype(bool)
    assert obstacle.sum() == 4
    assert np.isnan(ds.phi.values[:, obstacle]).all() and np.isfinite(ds.phi.values[:, ~obstacle]).all()
    path = tmp_path / "run.nc"
    ds.to_netcdf(path, engine="netcdf4")
    back = xr.open_dataset(path)
    xr.testing.assert_identical(back.load(), ds)


def test_time_series_match_their_definitions():
    ds = simulate(small_problem(obstacle=False))
    phi = ds.phi.values
    assert np.allclose(ds.phi_mean.values, phi.mean(axis=(1, 2, 3)))
    assert np.allclose(ds.biofilm_volume.values, (phi >= 0.5).sum(axis=(1, 2, 3)) * 1.5**3)
    assert np.allclose(ds.c_mean.values, ds.c.values.mean(axis=(1, 2, 3)))
    assert ds.steps_taken.values.tolist() == [0, 2, 4]


def test_two_dimensional_dataset_has_no_z_and_volumes_per_micrometre_of_thickness():
    """A 2-D volume is the area times 1 µm, whatever the cell size (so it compares across refinements)."""
    ds = simulate(small_problem(shape=(6, 5)))
    assert "z" not in ds.dims and ds.phi.dims == ("time", "y", "x")
    phi = ds.phi.values[0]
    assert float(ds.biofilm_volume[0]) == np.sum(phi[np.isfinite(phi)] >= 0.5) * 1.5**2 * 1.0


def test_the_dataset_says_what_the_solver_projected_onto_the_bounds_and_how_c_was_solved():
    """Round-off the solver projected onto 0 <= c <= 1 and 0 <= phi (count, largest correction: far below
    the round-off tolerance), and the zero-order law's active-set iterations."""
    base = small_problem(obstacle=False)
    stiff = simulate(replace(base, params=Parameters(d=1.0, g=1e10)))
    attrs = stiff.attrs
    assert attrs["projected_c_count"] > 0 and 0 < attrs["projected_c_largest"] < 1e-3 * attrs["bounds_roundoff"]
    assert attrs["projected_phi_count"] >= 0 and attrs["projected_phi_largest"] <= attrs["bounds_roundoff"]
    assert attrs["nutrient_active_set_iterations"] == 0  # first-order consumption: no active set
    zero = simulate(replace(base, consumption="zero-order", params=Parameters(g=1e10)))
    assert zero.attrs["nutrient_active_set_iterations"] > zero.attrs["steps_taken"]  # every solve iterates
