"""Observables (`biostudy.quantities.observables`) against values computed by hand on small fields, and a run's own
series."""
import numpy as np
import pytest
import xarray as xr

from biostudy.quantities import observables

H = 0.5  # µm: a spacing other than 1 so that index and coordinate mix-ups show


def sphere_dataset(n=9, radius_cells=1.5):
    """3-D, n³ cells of H: t = 0 empty; t = 1 a ball of phi = 1 (centres within radius_cells of the middle
    cell), its centre cell 0.9... no: its centre cell phi = 1 and the 6 face neighbours 0.85, the rest 0.6."""
    x = (np.arange(n) + 0.5) * H
    middle = x[n // 2]
    Z, Y, X = np.meshgrid(x, x, x, indexing="ij")
    d2 = ((X - middle) ** 2 + (Y - middle) ** 2 + (Z - middle) ** 2) / H**2  # in cells²
    ball = np.where(d2 <= radius_cells**2, 0.6, 0.0)
    ball[d2 <= 1.0] = 0.85
    ball[d2 == 0.0] = 1.0
    phi = np.stack([np.zeros_like(ball), ball])
    c = np.ones_like(phi)
    c[1, 0, 0, 0] = 0.25
    coords = {d: x for d in ("z", "y", "x")} | {"time": [0.0, 1.0]}
    return xr.Dataset({"phi": (("time", "z", "y", "x"), phi), "c": (("time", "z", "y", "x"), c)}, coords=coords)


def test_a_known_sphere_volume_height_means():
    ds = sphere_dataset()
    values = observables.variables(ds)
    # by hand: centres within 1.5 cells of the middle: the middle, 6 face and 12 edge neighbours (2 <= 2.25),
    # not the 8 corners (3 > 2.25): 19 cells of H³; phi >= 0.8: the middle and the 6 face neighbours
    np.testing.assert_allclose(values["biofilm_volume"].values, [0.0, 19 * H**3])
    np.testing.assert_allclose(values["dense_volume"].values, [0.0, 7 * H**3])
    np.testing.assert_allclose(values["phi_mean"].values, [0.0, (1.0 + 6 * 0.85 + 12 * 0.6) / 9**3])
    np.testing.assert_allclose(values["phi_max"].values, [0.0, 1.0])
    # the top along z: the highest cell with phi >= 0.5 is one above the middle (0.85), the one above it 0:
    # the crossing of 0.5 lies (0.85 - 0.5) / 0.85 of a cell above its centre
    top = (4 + 1 + 0.5) * H + 0.35 / 0.85 * H
    assert np.isnan(values["height"].values[0]) and values["height"].values[1] == pytest.approx(top)
    assert observables.evaluate(ds, "height_x").values[1] == pytest.approx(top)  # a ball: the same along x
    np.testing.assert_allclose(values["c_mean"].values, [1.0, 1.0 - 0.75 / 9**3])
    np.testing.assert_allclose(values["nutrient_minimum"].values, [1.0, 0.25])
    assert "front_advance" not in values and "compression_max" not in values  # no source mask, no p
    assert values["biofilm_volume"].attrs == {"units": "um^3", "long_name": "volume of cells with phi >= 0.5"}


def test_front_advance_and_obstacles_in_2d():
    """A slab growing two cells toward a source column on the right; an obstacle cell (NaN) not in the means."""
    ny, nx = 4, 10
    phi = np.zeros((2, ny, nx))
    phi[0, :, :3] = 1.0
    phi[1, :, :5] = 1.0
    phi[:, 0, 8] = np.nan  # an obstacle cell
    source = np.zeros((ny, nx), np.int8)
    source[:, 9] = 1
    coords = {"y": (np.arange(ny) + 0.5) * H, "x": (np.arange(nx) + 0.5) * H, "time": [0.0, 0.5]}
    ds = xr.Dataset({"phi": (("time", "y", "x"), phi), "nutrient_source": (("y", "x"), source)}, coords=coords)
    # the front is the face between the last phi = 1 cell and the next: it moved by two cells
    np.testing.assert_allclose(observables.evaluate(ds, "front_advance").values, [0.0, 2 * H])
    np.testing.assert_allclose(observables.evaluate(ds, "phi_mean").values, [12 / 39, 20 / 39])
    volume = observables.evaluate(ds, "biofilm_volume")
    np.testing.assert_allclose(volume.values, [12 * H**2, 20 * H**2])
    assert "per µm of thickness" in volume.attrs["long_name"]
    assert observables.evaluate(ds, "height").values[1] == pytest.approx(4 * H)  # y: the whole column


def test_compression_and_tension_of_p_and_unsolved_outputs():
    p = np.array([[[0.0, 0.0], [0.0, 0.0]], [[-3.0, 1.5], [np.nan, 0.2]], [[np.nan] * 2] * 2])
    coords = {"y": [0.5, 1.5], "x": [0.5, 1.5], "time": [0.0, 0.5, 1.0]}
    ds = xr.Dataset({"p": (("time", "y", "x"), p)}, coords=coords)
    np.testing.assert_allclose(observables.evaluate(ds, "compression_max").values, [0.0, 3.0, np.nan])
    np.testing.assert_allclose(observables.evaluate(ds, "tension_max").values, [0.0, 1.5, np.nan])


def test_registry_names_units_and_bad_names():
    for name, observable in observables.REGISTRY.items():
        assert observable.units and observable.long_name, name
    assert set(observables.SUMMARY) <= set(observables.REGISTRY)
    assert observables.get("height_z").long_name == "top of phi >= 0.5 along z"
    with pytest.raises(ValueError, match="unknown observable 'volume'"):
        observables.get("volume")
    with pytest.raises(ValueError, match="has no axis z"):
        observables.evaluate(sphere_dataset().isel(z=0), "height_z")
    with pytest.raises(ValueError, match="needs p"):
        observables.evaluate(sphere_dataset(), "compression_max")


def test_a_runs_own_series_agree_and_a_study_is_evaluated_case_by_case(tiny_run, with_mechanics):
    """The run's own phi_mean, c_mean and biofilm_volume (measured on its fields as it goes, `solver.series`) and the
    registry's (the same definitions, measured on the dataset's fields, obstacles NaN) agree to the last bit, units
    and long names too."""
    ds = with_mechanics(tiny_run((16, 12)))
    values = observables.variables(ds)
    for name in ("phi_mean", "c_mean", "biofilm_volume"):
        np.testing.assert_array_equal(values[name].values, ds[name].values, err_msg=name)
        assert values[name].attrs == ds[name].attrs, name
    # a solver's dataset records no substratum: the COMSTAT observables are left out, not guessed; nor has this
    # run dead ends off its route (open space beside it): the dead-end observables are left out too
    assert set(values) == {n for n, o in observables.REGISTRY.items() if not o.needs_attrs and o.applies is None}
    assert values["compression_max"].values[-1] == pytest.approx(-float(ds.p.isel(time_mechanics=-1).min()))
    study = xr.concat([ds, ds.assign(phi=ds.phi * 0.5)], dim="case")
    both = observables.evaluate(study, "biofilm_volume")
    assert both.dims == ("case", "time")
    np.testing.assert_allclose(both.values[0], values["biofilm_volume"].values)
    np.testing.assert_allclose(both.values[1], observables.evaluate(ds.assign(phi=ds.phi * 0.5), "biofilm_volume"))


def test_a_height_at_the_top_of_the_box_is_marked_saturated(tmp_path):
    """A column of dense biofilm reaching the top cell: its height is the box's top (9 H), a lower bound."""
    from typer.testing import CliRunner

    from biostudy.cli import app
    from biostudy.data import netcdf, writing
    from biostudy.quantities.saturation import SATURATION, saturated

    ds = sphere_dataset()
    ds["phi"][1, :, 4, 4] = 1.0  # the middle column, bottom to top
    height = observables.variables(ds)["height"]
    assert height.attrs[SATURATION] == 9 * H and height.values[1] == 9 * H
    assert saturated(height.values, height.attrs[SATURATION]).tolist() == [False, True]  # t = 0: no biofilm (NaN)
    assert not saturated([9 * H - 0.01 * H], 9 * H).any() and not saturated([1.0], None).any()
    run = ds.assign(nutrient_source=(("z", "y", "x"), np.zeros((9, 9, 9), np.int8)))
    run.attrs.update(biostudy_version="0", grid_spacing=H, grid_shape=[9, 9, 9], scene='name = "column"')
    path = writing.write_atomic(netcdf.with_observables(run), tmp_path / "column.nc")
    shown = CliRunner().invoke(app, ["show", str(path)], env={"COLUMNS": "200"})
    row = next(line for line in shown.stdout.splitlines() if line.strip().startswith("height "))
    assert shown.exit_code == 0 and "4.5 (top: saturated)" in row


def test_substratum_observables_from_a_dataset_alone_on_its_recorded_face():
    """A slab on the x- face whose phi (falling 0.25 per cell, linear between the centres around the crossing)
    crosses 0.5 at 2.3 cells (then 3.3): the registry computes the COMSTAT
    observables from the dataset's recorded face and threshold; a dataset without them says what it lacks."""
    ny, nx = 6, 8
    x = (np.arange(nx) + 0.5) * H
    slabs = [np.clip(0.5 + (t * H - x) / (4 * H), 0, 1) * np.ones((ny, 1)) for t in (2.3, 3.3)]
    ds = xr.Dataset({"phi": (("time", "y", "x"), np.stack(slabs))},
                    coords={"y": (np.arange(ny) + 0.5) * H, "x": x, "time": [0.0, 1.0]})
    with pytest.raises(ValueError, match="needs the attribute substratum_face"):
        observables.evaluate(ds, "biomass")
    ds.attrs.update(substratum_face="x-", substratum_threshold=0.5, grid_spacing=H)
    values = observables.variables(ds)
    np.testing.assert_allclose(values["biomass"].values, [2.3 * H, 3.3 * H], rtol=1e-12)
    np.testing.assert_allclose(values["max_thickness"].values, [2.3 * H, 3.3 * H], rtol=1e-12)
    np.testing.assert_allclose(values["coverage"].values, [1.0, 1.0])
    assert values["surface_to_biovolume"].attrs == {"units": "um^-1", "long_name": observables.get(
        "surface_to_biovolume").long_name}
    ds.attrs["substratum_threshold"] = 0.25  # phi falls by 0.25 per cell: 0.25 lies one cell beyond 0.5
    np.testing.assert_allclose(observables.evaluate(ds, "biomass").values, [3.3 * H, 4.3 * H], rtol=1e-12)
