"""Dataset layout (docs/model.md, "The dataset"): dimensions, units and long names, masks, attributes, netCDF
round trip."""
from dataclasses import replace

import numpy as np
import pytest
import xarray as xr

from solver import Grid, Laws, MechanicsSetup, Parameters, Problem, simulate
from solver.output import cf_units, on_output_times


def small_problem(shape=(6, 5, 4), obstacle=True):
    grid = Grid(shape, 1.5)
    coords = grid.cell_coordinates()
    phi0 = (sum((q - 3.0) ** 2 for q in coords) <= 4).astype(float)
    blocked = np.zeros(grid.cells_shape, bool)
    if obstacle:
        blocked[..., -1, 0] = True
    held = np.zeros(grid.cells_shape, bool)
    held[..., -1, -1] = True
    return Problem(grid=grid, phi0=np.where(blocked, 0, phi0), nutrient_held=held, obstacle=blocked, t_end=0.01,
                   steps=4, output_times=[0, 0.005, 0.01], params=Parameters(g=2e8), name="small")


def test_dataset_layout_units_and_round_trip(tmp_path):
    ds = simulate(small_problem())
    assert dict(ds.sizes) == {"time": 3, "z": 4, "y": 5, "x": 6, "bounds": 2}
    assert "u" not in ds and "p" not in ds and "x_node" not in ds.coords  # no mechanics asked for
    assert "time_mechanics" not in ds.dims
    for name in list(ds.data_vars) + list(ds.coords):
        if name.endswith("_bounds"):  # CF 7.1: bounds carry their cell centre's units and long name
            assert ds[name].attrs == {} and ds[name.removesuffix("_bounds")].attrs["bounds"] == name
            continue
        assert ds[name].attrs.get("long_name"), name
        assert "units" in ds[name].attrs, name
    assert ds.x.values.tolist() == [0.75 + 1.5 * i for i in range(6)]
    assert ds.x_bounds.values.tolist() == [[1.5 * i, 1.5 * (i + 1)] for i in range(6)]
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
    assert (attrs["projected_phi_count"] > 0) == (attrs["projected_phi_largest"] > 0)  # counted where it happened
    assert attrs["projected_phi_largest"] <= attrs["bounds_roundoff"]
    assert attrs["nutrient_active_set_iterations"] == 0  # first-order consumption: no active set
    zero = simulate(replace(base, laws=Laws(consumption="zero-order"), params=Parameters(g=1e10)))
    assert zero.attrs["nutrient_active_set_iterations"] > zero.attrs["steps_taken"]  # every solve iterates


def test_cf_units_are_udunits_spellings_and_parameters_are_variables():
    """T* is dimensionless: a rate per T* has its numerator's units; the model's units stay in the long name."""
    assert [cf_units(u) for u in ("um^2/T*", "um/T*", "1/T*", "um^3", "Pa", "1")] == ["um^2", "um", "1", "um^3", "Pa",
                                                                                    "1"]
    with pytest.raises(ValueError):
        cf_units("T*")
    ds = simulate(small_problem())
    assert float(ds.g) == 2e8 and ds.g.dims == () and ds.g.attrs == {"units": "1", "long_name": "consumption g "
                                                                      "(0: no consumption) [1/T*]"}
    assert ds.d.attrs["units"] == "um^2" and ds.r.attrs["units"] == "um" and ds.mu.attrs["units"] == "Pa"
    assert ds.attrs["g"] == 2e8  # still an attribute too
    assert ds.time.attrs == {"units": "1", "long_name": "normalised time T* = t / t_ref (dimensionless)"}
    assert ds.z.attrs["positive"] == "up" and "positive" not in ds.x.attrs
    assert all(ds[c].encoding.get("_FillValue", "absent") is None for c in ds.coords)  # CF 2.5.1


def test_mechanics_has_its_own_time_coordinate():
    """u and p exist at the outputs where the mechanics was solved (every 2nd and the last), nowhere NaN-filled."""
    base = small_problem(shape=(4, 4, 4), obstacle=False)
    ds = simulate(replace(base, output_times=[0, 0.0025, 0.005, 0.0075, 0.01], mechanics=MechanicsSetup(every=3)))
    assert ds.time_mechanics.values.tolist() == [0.0, 0.0075, 0.01]
    assert ds.p.dims == ("time_mechanics", "z", "y", "x") and ds.u.dims[0] == "time_mechanics"
    assert np.isfinite(ds.u.values).all() and (ds.newton_iterations.values >= 0).all()
    squared = (ds.u**2).sum("component")  # no NaN for xarray's sum to turn into 0
    np.testing.assert_array_equal(squared.values, np.sum(ds.u.values**2, axis=-1))
    on_outputs = on_output_times(ds)
    assert on_outputs.p.dims == ("time", "z", "y", "x") and "time_mechanics" not in on_outputs.dims
    assert np.isnan(on_outputs.p.values[[1, 2]]).all() and np.isnan(on_outputs.newton_iterations.values[1])
    np.testing.assert_array_equal(on_outputs.u.values[3], ds.u.values[1])


def test_the_dataset_says_which_pressure_it_holds(tmp_path):
    """p's attributes and the dataset's name the pressure: recovered by default, the paper's element
    pressure on request; both survive the netCDF file."""
    from biostudy.data import writing

    base = small_problem(shape=(4, 3), obstacle=False)
    uniform = replace(base, phi0=np.ones(base.grid.cells_shape), params=Parameters(k_alpha=0.5),
                      mechanics=MechanicsSetup(clamp=("y-",)))
    recovered = simulate(uniform)
    element = simulate(replace(uniform, mechanics=MechanicsSetup(clamp=("y-",), pressure="element")))
    assert recovered.p.attrs["pressure"] == recovered.attrs["mechanics_pressure"] == "recovered"
    assert element.p.attrs["pressure"] == element.attrs["mechanics_pressure"] == "element"
    assert "checkerboard" in element.p.attrs["comment"]
    assert np.isfinite(recovered.p.values[-1]).all() and np.isfinite(element.p.values[-1]).all()
    assert element.p.dims[0] == "time_mechanics"
    back = xr.open_dataset(writing.write_atomic(element, tmp_path / "element.nc"), engine="netcdf4")
    assert back.p.attrs["pressure"] == back.attrs["mechanics_pressure"] == "element"
    assert back.p.attrs["comment"] == back.attrs["mechanics_pressure_comment"] == element.p.attrs["comment"]
    back.close()
