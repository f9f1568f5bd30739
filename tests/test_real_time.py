"""Real time (issue 26.1): a scene's ``[time] t_ref`` gives datasets a real-time coordinate that pint reads as a
time, and exports, tables and calibrations speak it.  Tiny 16² scene, 10 steps."""
from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from conftest import TINY_SCENE
from typer.testing import CliRunner

from biostudy.cli import app

REAL = TINY_SCENE.replace("t_end = 0.2\nsteps = 20\n", 't_end = 0.5\nsteps = 10\nt_ref = "48 h"\n')


@pytest.fixture(scope="module")
def real_run(tmp_path_factory):
    """A run of the tiny scene with t_ref = 48 h and outputs at T* = 0, 0.25, 0.5."""
    root = tmp_path_factory.mktemp("real")
    (root / "real.toml").write_text(REAL)
    result = CliRunner().invoke(app, ["run", str(root / "real.toml"), "-o", str(root / "real.nc"), "-q"])
    assert result.exit_code == 0, result.output
    return root


def test_a_run_with_t_ref_has_a_real_time_coordinate_pint_reads_as_hours(real_run):
    import cf_xarray.units
    import pint_xarray  # noqa: F401  (the .pint accessor)

    with xr.open_dataset(real_run / "real.nc") as ds:
        ds = ds.load()
    np.testing.assert_allclose(ds["time"].values, [0.0, 0.25, 0.5])
    assert ds["time_real"].dims == ("time",)
    np.testing.assert_allclose(ds["time_real"].values, [0.0, 12.0, 24.0])
    assert "standard_name" not in ds["time_real"].attrs  # CF would want an epoch (docs/time.md)
    registry = cf_xarray.units.units
    quantified = ds.pint.quantify(unit_registry=registry)
    hours = quantified["time_real"].pint.units
    assert hours.dimensionality == registry.second.dimensionality
    np.testing.assert_allclose(quantified["time_real"].pint.to("s").pint.magnitude, [0.0, 12 * 3600, 24 * 3600])
    assert str(quantified["time"].pint.units) == "dimensionless"  # T* stays


def test_a_scene_without_t_ref_has_no_real_time(tiny_scene, tmp_path):
    result = CliRunner().invoke(app, ["run", str(tiny_scene), "-o", str(tmp_path / "t.nc"), "-q",
                                      "--set", "time.steps=4"])
    assert result.exit_code == 0, result.output
    with xr.open_dataset(tmp_path / "t.nc") as ds:
        assert "time_real" not in ds.coords and "t_ref" not in ds.attrs


@pytest.mark.parametrize("given, said", [
    ('"48 m"', "time.t_ref: '48 m' is not a time"),
    ('"-2 h"', "time.t_ref: must be a positive time"),
    ('"soon"', "time.t_ref: 'soon' is not a time pint reads"),
    ('"1 T*"', "time.t_ref: '1 T*' is not a time pint reads"),  # pint's parser fails an assertion on it
])
def test_a_t_ref_that_is_not_a_positive_time_is_one_line(write_toml, given, said):
    path = write_toml("bad.toml", REAL.replace('"48 h"', given))
    result = CliRunner().invoke(app, ["run", str(path), "-q"])
    assert result.exit_code == 2 and said in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.output


def test_the_tiff_export_steps_frames_in_hours(real_run, tmp_path):
    import tifffile

    result = CliRunner().invoke(app, ["export", str(real_run / "real.nc"), str(tmp_path / "tif"),
                                      "--format", "tiff"])
    assert result.exit_code == 0, result.output
    with tifffile.TiffFile(tmp_path / "tif" / "phi.tif") as tif:
        meta = tif.imagej_metadata
    assert meta["finterval"] == pytest.approx(12.0) and meta["tunit"] == "hour"
    assert meta["Labels"][1] == "12 h (T* = 0.25)"


def calibration_folder(root, scene_t_ref: str, data_t_ref: str = "20 h"):
    """The tiny agar scene of test_calibration with `scene_t_ref`, its two-row table, and a calibration of r
    alone with `data_t_ref`."""
    from test_calibration import SCENE, TABLE

    (root / "agar.toml").write_text(SCENE.replace("steps = 40\n", f'steps = 40\nt_ref = "{scene_t_ref}"\n'))
    (root / "t.tsv").write_text(TABLE)
    (root / "c.toml").write_text(f'scene = "agar.toml"\n[set]\n"params.g" = 1e9\n[data]\nmeasurements = '
                                 f'"t.tsv"\ntime_unit = "h"\nt_ref = "{data_t_ref}"\n[estimate]\n'
                                 'r = [80.0, 120.0]\n[method]\nstarts = 1\nprofiles = false\n')
    return root / "c.toml"


def test_a_calibration_whose_t_ref_is_not_the_scenes_is_one_line(tmp_path):
    from biostudy.calibration.problem import load_calibration

    path = calibration_folder(tmp_path, scene_t_ref="48 h")
    result = CliRunner().invoke(app, ["calibrate", str(path), "-o", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output, result.stderr
    assert "c.toml: data.t_ref: '20 h' is not the scene's time.t_ref = '48 h'" in lines[0], lines[0]
    assert not (tmp_path / "out").exists()
    calibration_folder(tmp_path, scene_t_ref="1200 min")  # the same time in other units agrees
    assert load_calibration(path).spec.data.t_ref == "20 h"


@pytest.mark.filterwarnings("ignore:The ioos_sos checker is deprecated:DeprecationWarning")
def test_the_cf_checker_accepts_the_real_time_coordinate(real_run, tmp_path):
    from test_cf import ACCEPTED, high_priority_failures

    failures = high_priority_failures(real_run / "real.nc", tmp_path)
    assert failures <= ACCEPTED, failures - ACCEPTED


def test_paraview_times_are_real_times_with_t_star_beside(real_run, tmp_path):
    import meshio
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLImageDataReader

    for form in ("vti", "vtu"):
        result = CliRunner().invoke(app, ["export", str(real_run / "real.nc"), str(tmp_path / form), "--format", form])
        assert result.exit_code == 0, result.output
        pvd = (tmp_path / form / "series.pvd").read_text()
        assert [line.split('timestep="')[1].split('"')[0] for line in pvd.splitlines() if "timestep" in line] == \
            ["0", "12", "24"]
    mesh = meshio.read(tmp_path / "vtu" / "snapshot_0001.vtu")
    assert "phi" in mesh.cell_data
    text = (tmp_path / "vtu" / "snapshot_0001.vtu").read_text(errors="replace")
    assert 'Name="TimeValue" NumberOfTuples="1" format="ascii">12<' in text
    assert 'Name="T_star" NumberOfTuples="1" format="ascii">0.25<' in text
    reader = vtkXMLImageDataReader()
    reader.SetFileName(str(tmp_path / "vti" / "snapshot_0001.vti"))
    reader.Update()
    fields = reader.GetOutput().GetFieldData()
    assert vtk_to_numpy(fields.GetArray("TimeValue")).tolist() == [12.0]
    assert vtk_to_numpy(fields.GetArray("T_star")).tolist() == [0.25]


def test_show_heads_its_columns_with_real_time(real_run):
    result = CliRunner().invoke(app, ["show", str(real_run / "real.nc")])
    assert result.exit_code == 0, result.output
    assert "0 h (T* = 0)" in result.stdout and "24 h (T* = 0.5)" in result.stdout


def test_plots_draw_time_in_hours_and_take_a_real_time(real_run, tmp_path):
    from biostudy.plots.style import time_axis, time_title

    with xr.open_dataset(real_run / "real.nc") as ds:
        values, label, on_axis = time_axis(ds)
        np.testing.assert_allclose(values, [0.0, 12.0, 24.0])
        assert label == "time (h; T* = t / 48 h)" and on_axis(0.5) == 24.0
        assert time_title(ds, 1) == "12 h (T* = 0.25)"
    result = CliRunner().invoke(app, ["plot", str(real_run / "real.nc"), "--time", "12 h", "-o",
                                      str(tmp_path / "p.png")])
    assert result.exit_code == 0, result.output


def test_a_real_time_asked_of_a_run_in_t_star_alone_is_one_line(tiny_scene, tmp_path):
    cli = CliRunner()
    assert cli.invoke(app, ["run", str(tiny_scene), "-o", str(tmp_path / "t.nc"), "-q",
                            "--set", "time.steps=4"]).exit_code == 0
    result = cli.invoke(app, ["plot", str(tmp_path / "t.nc"), "--time", "12 h"])
    assert result.exit_code == 2 and "--time '12 h': the dataset is in T* alone" in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_analyze_takes_a_real_time(real_run, tmp_path):
    (tmp_path / "real.toml").write_text(REAL)
    (tmp_path / "g.toml").write_text('scene = "real.toml"\n[set]\n"time.steps" = 4\n[sweep]\ng = [1e8, 1e9]\n')
    cli = CliRunner()
    result = cli.invoke(app, ["sweep", str(tmp_path / "g.toml"), "-o", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 0, result.output
    study = xr.load_dataset(tmp_path / "out" / "study.nc")
    np.testing.assert_allclose(study["time_real"].values, [0.0, 12.0, 24.0])  # study.nc keeps it
    result = cli.invoke(app, ["analyze", str(tmp_path / "out"), "--time", "12 h", "--output", "biofilm_volume"])
    assert result.exit_code == 0, result.output
    assert float(xr.load_dataset(tmp_path / "out" / "analysis.nc")["time"]) == 0.25


def test_show_of_a_scene_says_where_its_run_ends_in_real_time(write_toml):
    result = CliRunner().invoke(app, ["show", str(write_toml("real.toml", REAL))])
    assert result.exit_code == 0, result.output
    assert "3 outputs, mechanics off, to 24 h (T* = 0.5)" in result.stdout


def test_a_sweep_over_t_ref_is_one_line(write_toml, tmp_path):
    """Every case would be the same simulation, and study.nc would stack 24 h and 2 d under one unit."""
    write_toml("real.toml", REAL)
    path = write_toml("tr.toml", 'scene = "real.toml"\n[sweep]\n"time.t_ref" = ["24 h", "2 d"]\n')
    result = CliRunner().invoke(app, ["sweep", str(path), "-o", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 2 and "tr.toml: sweep.time.t_ref: is the real time of T* = 1" in result.stderr, \
        result.stderr
    assert not (tmp_path / "out").exists()


def test_the_mechanics_outputs_get_their_real_time_in_t_refs_own_unit(tiny_run, with_mechanics):
    from biostudy.data.real_time import with_real_time

    ds = with_mechanics(tiny_run((6, 5)), unsolved=1)  # outputs at T* = 0, 0.01, 0.02; mechanics at 0, 0.02
    assert with_real_time(ds) is ds  # no t_ref: unchanged
    ds.attrs["t_ref"] = "30 min"
    real = with_real_time(ds)
    np.testing.assert_allclose(real["time_real"].values, [0.0, 0.3, 0.6])
    np.testing.assert_allclose(real["time_mechanics_real"].values, [0.0, 0.6])
    assert real["time_real"].attrs["units"] == real["time_mechanics_real"].attrs["units"] == "minutes"


def test_a_warning_gives_its_times_in_real_time_too(real_run):
    """The tiny scene's biofilm is dissolved by T* = 0.5 (quantities/retreat.py): said in hours as well."""
    from biostudy.quantities import alerts

    with xr.open_dataset(real_run / "real.nc") as ds:
        said = alerts.said(ds.attrs)
    assert any("vanished by 24 h (T* = 0.5)" in sentence for sentence in said), said
