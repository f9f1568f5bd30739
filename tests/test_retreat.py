"""A run that loses its biofilm says so (issue 26): the model's retreat from where the nutrient is not (Eq. 34).

The bottom-fed layer is the case the model does not describe: a 10 µm layer on agar, fed only from below,
is eaten away from its free top (the interface moves toward the nutrient) — biomass 10 → 6.0 → 1.2 → 0 µm at
T* = 0, 0.1, 0.2, 0.3 — while with g = 1e10 the nutrient is used up inside it and it stays as it started.
"""
import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.quantities import retreat

LAYER = """\
name = "layer"
[grid]
shape = [6, 60]
spacing = 1.0
[params]
g = 1e8
r = 100
[time]
t_end = 0.3
steps = 60
outputs = 4
[[nutrient]]
shape = "face"
face = "y-"
[[biofilm]]
shape = "box"
lower = [0.0, 0.0]
upper = [6.0, 10.0]
[numerics]
growth_velocity = "front"
"""


def _volumes(cells):
    """A 2-D dataset of 1 µm cells in which phi >= 0.5 covers the given numbers of cells per output."""
    phi = np.zeros((len(cells), 10, 10))
    for t, n in enumerate(cells):
        phi[t].reshape(-1)[:n] = 0.7
    coords = {"time": np.linspace(0, 0.3, len(cells)), "y": np.arange(10) + 0.5, "x": np.arange(10) + 0.5}
    return xr.Dataset({"phi": (("time", "y", "x"), phi)}, coords=coords)


def test_a_fall_by_a_quarter_of_the_largest_volume_before_is_told_with_times_and_volumes():
    said = retreat.lost(_volumes([60, 36, 7, 0]))
    assert said.startswith("the biofilm (phi >= 0.5) shrank by 40 % from 60 µm² at T* = 0 to 36 µm² by T* = 0.1 "
                           "and vanished by T* = 0.3: the model moves every interface toward the nutrient (Eq. 34)")
    assert "(docs/model.md)" in said
    kept = retreat.lost(_volumes([40, 80, 50, 45]))  # fell by 44 % after growing: measured from the peak
    assert "shrank by 38 % from 80 µm² at T* = 0.1 to 50 µm² by T* = 0.2 (45 µm² at T* = 0.3, the last" in kept
    assert retreat.lost(_volumes([60, 46, 70, 90])) == ""  # 23 %: within the stated fraction
    assert retreat.lost(_volumes([10, 20, 30, 40])) == ""
    assert retreat.lost(_volumes([0, 0, 0, 0])) == ""  # never any biofilm: nothing lost


def test_the_bottom_fed_layer_warns_and_records_the_loss_and_a_starved_one_does_not(write_toml, tmp_path):
    scene = write_toml("layer.toml", LAYER)
    result = CliRunner().invoke(app, ["run", str(scene), "-o", str(tmp_path / "lost.nc"), "-q"])
    assert result.exit_code == 0, result.output
    warning = [line for line in result.stderr.splitlines() if line.startswith("warning: the biofilm")]
    assert len(warning) == 1, result.stderr
    ds = xr.open_dataset(tmp_path / "lost.nc")
    assert ds.attrs[retreat.ATTRIBUTE] == warning[0].removeprefix("warning: ")
    volume = ds.biofilm_volume.values.ravel()  # the warning tells what the dataset holds
    assert (f"shrank by {100 * (1 - volume[1] / volume[0]):.0f} % from {volume[0]:.3g} µm² at T* = 0 to "
            f"{volume[1]:.3g} µm² by T* = 0.1 and vanished by T* = 0.3") in warning[0]
    # Eq. 34: the free top moves toward the nutrient at r c/(k + c), c between its starting minimum c0 and 1 (first-
    # order consumption keeps c <= 1), so the layer thins by at most r/2 and at least r c0/(k + c0) per T* (one cell
    # of slack for the discrete front), and 10 µm are gone by T* = 0.3
    biomass, dt = ds.biomass.values.ravel(), 0.1
    c0 = float(ds.nutrient_minimum.values.ravel()[0])
    thinned = -np.diff(biomass)
    assert np.all(thinned <= 100 / 2 * dt + 1e-9), thinned
    assert thinned[0] >= 100 * c0 / (1 + c0) * dt - 1.0 and biomass[0] == pytest.approx(10) and biomass[-1] == 0

    kept = CliRunner().invoke(app, ["run", str(scene), "-o", str(tmp_path / "kept.nc"), "-q", "--set", "g=1e10"])
    assert kept.exit_code == 0 and "warning" not in kept.stderr, kept.stderr
    ds = xr.open_dataset(tmp_path / "kept.nc")
    assert retreat.ATTRIBUTE not in ds.attrs
    np.testing.assert_allclose(ds.biomass.values.ravel(), 10, atol=1e-3)


def test_a_sweep_lists_the_cases_that_lost_their_biofilm(write_toml, tmp_path):
    scene = write_toml("layer.toml", LAYER)
    study = write_toml("study.toml", f'name = "layers"\nscene = "{scene}"\n[sweep]\ng = [1e8, 1e10]\n')
    result = CliRunner().invoke(app, ["sweep", str(study), "-o", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 0, result.output
    listed = [line for line in result.stderr.splitlines() if "lost a quarter or more of their biofilm" in line]
    assert len(listed) == 1 and listed[0].startswith("warning: 1 cases lost") and "g=1e+08" in listed[0] \
        and "g=1e+10" not in listed[0], result.stderr
    again = CliRunner().invoke(app, ["sweep", str(study), "-o", str(tmp_path / "out"), "-q"])
    assert "1 cases lost a quarter or more" in again.stderr  # read back from the finished case files
    # a case file is finished as a run's dataset is (`data.finish`): the same observables, alert and attributes
    import biostudy
    from biostudy.data.netcdf import as_run

    with pytest.warns(UserWarning, match="the biofilm"):
        run = biostudy.run(scene)
    case = as_run(xr.load_dataset(tmp_path / "out" / "cases" / "g=1e+08.nc"))
    assert case.attrs["observables"] == run.attrs["observables"]
    for name in run.attrs["observables"].split(", "):
        np.testing.assert_array_equal(case[name].values, run[name].values, err_msg=name)
    for name in (retreat.ATTRIBUTE, "substratum_face", "substratum_estimator", "scene"):
        assert case.attrs[name] == run.attrs[name], name
