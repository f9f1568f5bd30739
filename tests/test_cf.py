"""Datasets as the ecosystem's own tools take them (issue 11): the CF checker, udunits spellings through cf_xarray's
pint registry, xarray's open_mfdataset on a study's case files, the netCDF layout (flags, fill values,
compression, history).  Tiny runs: a 10 x 9 x 8 and a 16² scene with mechanics, a 2 x 2 grid study and a zip study."""
from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr
from conftest import CUBE_SCENE, TINY_SCENE
from study_files import both_ways, same_files
from typer.testing import CliRunner
from unit_readers import assert_every_unit_read_alike, assert_read_alike, plain

from biostudy.cli import app

pytestmark = [pytest.mark.filterwarnings("ignore:In a future version of xarray the default value:FutureWarning"),
              pytest.mark.filterwarnings("ignore:The ioos_sos checker is deprecated:DeprecationWarning")]

# The CF checker's one high-priority complaint the docs accept (docs/model.md, "The dataset"): T* is a
# dimensionless normalised time, not a CF time (no unit of time, no epoch), so the dimension named `time`
# carries no standard_name "time"; with one, the checker fails the units instead (§3.1, §4.4).
ACCEPTED = {("§5.1 Independent Latitude, Longitude, Vertical, and Time Axes",
             "Coordinate variable 'time' should have standard_name='time', found: 'None'")}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """The files: runs (3-D, 2-D, both with mechanics), a grid study, a zip study, an analysis."""
    root = tmp_path_factory.mktemp("cf")
    (root / "tiny.toml").write_text(TINY_SCENE + "[mechanics]\nevery = 2\n")
    (root / "cube.toml").write_text(CUBE_SCENE + '[mechanics]\nclamp = ["z-"]\nevery = 2\n')
    (root / "grid.toml").write_text(textwrap.dedent("""\
        scene = "tiny.toml"
        [sweep]
        g = [1e8, 1e9]
        r = [50.0, 100.0]
        """))
    (root / "zip.toml").write_text(textwrap.dedent("""\
        scene = "tiny.toml"
        [set]
        "mechanics.enabled" = false
        [sweep]
        mode = "zip"
        k_alpha = [1e-3, 2e-3, 4e-3]
        beta = [1.0, 2.0, 3.0]
        """))
    cli = CliRunner()
    for args in (["run", root / "cube.toml", "-o", root / "run3d.nc"],
                 ["run", root / "tiny.toml", "-o", root / "run2d.nc"],
                 ["sweep", root / "grid.toml", "-o", root / "grid"], ["sweep", root / "zip.toml", "-o", root / "zip"],
                 ["analyze", root / "grid", "--output", "biofilm_volume"]):
        result = cli.invoke(app, [str(a) for a in args] + (["-q"] if args[0] in ("run", "sweep") else []))
        assert result.exit_code == 0, result.output
    return root


def high_priority_failures(path: Path, tmp_path: Path) -> set[tuple[str, str]]:
    from compliance_checker.runner import CheckSuite, ComplianceChecker

    CheckSuite.load_all_available_checkers()
    report = tmp_path / f"{path.stem}.json"
    ComplianceChecker.run_checker(str(path), ["cf:1.10"], 0, "normal", output_filename=str(report),
                                  output_format="json")
    found = json.loads(report.read_text())["cf:1.10"]
    return {(check["name"], message) for check in found["high_priorities"] if check["value"][0] < check["value"][1]
            for message in check["msgs"]}


@pytest.mark.parametrize("name", ["run3d.nc", "run2d.nc", "grid/study.nc", "zip/study.nc",
                                  "grid/cases/g=1e+08_r=50.nc"])
def test_the_cf_checker_finds_no_high_priority_failure_but_the_accepted_one(made, tmp_path, name):
    failures = high_priority_failures(made / name, tmp_path)
    assert failures <= ACCEPTED, failures - ACCEPTED


def datasets(root: Path) -> dict[str, xr.Dataset]:
    """Every dataset made, loaded and closed (a file left open for the garbage collector to close may close
    under a thread of a later test that reads HDF5)."""
    files = ["run3d.nc", "run2d.nc", "grid/study.nc", "zip/study.nc", "grid/analysis.nc",
             *(str(p.relative_to(root)) for p in sorted(root.glob("*/cases/*.nc")))]
    loaded = {}
    for name in files:
        with xr.open_dataset(root / name) as ds:
            loaded[name] = ds.load()
    return loaded


def test_every_units_string_parses_with_udunits_plain_pint_and_cf_xarray_alike(made):
    """Issue 36.3: pint-xarray's own registry quantifies every file (it failed on um2, um3, um-1), UDUNITS and
    cf_xarray's registry read the same quantities."""
    import cf_xarray.units

    registry = cf_xarray.units.units
    for name, ds in datasets(made).items():
        assert_every_unit_read_alike(ds, name)
        quantified = ds.pint.quantify(unit_registry=registry)
        assert str(quantified["time"].pint.units) == "dimensionless", name
        if "phi" in ds:
            assert quantified["x"].pint.units == registry.micrometer, name
        if "r" in ds:  # a parameter, or a swept coordinate: µm/T* with T* dimensionless
            assert quantified["r"].pint.units == registry.micrometer, name
        if "biofilm_volume" in ds:
            assert quantified["biofilm_volume"].pint.units == registry.micrometer**3, name
        if "surface_to_biovolume" in ds:
            per_mm = ds.pint.quantify(unit_registry=plain())["surface_to_biovolume"].pint.to("1/mm")
            assert per_mm.pint.units == plain().parse_units("1/mm"), name


def test_the_declared_units_of_every_other_dataset_parse_too():
    """stability.nc, convergence.nc, calibration.nc and the observables, whose datasets cost too much to make
    here (a calibration's own file is checked in tests/test_calibration.py)."""
    from biostudy.calibration import units as parameter_units
    from biostudy.inputs.real_time import real_time
    from biostudy.quantities import observables
    from biostudy.reports import convergence, stability
    from solver.output import cf_units
    from solver.problem import parameter_infos

    declared = [u for u, _ in (*stability.NUMBERS.values(), *stability.COORDS.values())]
    declared += [c.units for c in convergence.COMPARED] + [o.units for o in observables.REGISTRY.values()]
    declared += [cf_units(p.units) for p in parameter_infos()]
    clock = real_time("48 h")
    declared += [parameter_units.per_real_time(p.units, clock)[0] for p in parameter_infos() if "/T*" in p.units]
    assert {"um^3", "um^-1", "um^2", "um^2/h", "1/h", "um/h"} <= set(declared)
    for units in declared:
        assert_read_alike(units)


def test_files_of_earlier_versions_with_glued_powers_are_read_with_todays_spellings(made, tmp_path):
    """A run or a case written with 'um3', 'um-1', 'um2' (biostudy 0.4) is read back as 'um^3', ... (show, plot,
    combine, --continue read through `reading`), and shown as µm³."""
    from biostudy.data import reading
    from biostudy.formatting import units_text

    old = xr.load_dataset(made / "run2d.nc")
    spelled = {"biofilm_volume": "um3", "surface_to_biovolume": "um-1", "d": "um2"}
    for name, units in spelled.items():
        old[name].attrs["units"] = units
    old.to_netcdf(tmp_path / "old.nc")
    read = reading.open_dataset(tmp_path / "old.nc")
    assert {n: read[n].attrs["units"] for n in spelled} == {"biofilm_volume": "um^3", "surface_to_biovolume": "um^-1",
                                                            "d": "um^2"}
    assert_every_unit_read_alike(read, "old.nc")
    assert [units_text(u) for u in spelled.values()] == ["µm³", "µm⁻¹", "µm²"]
    result = CliRunner().invoke(app, ["show", str(tmp_path / "old.nc")])
    assert result.exit_code == 0 and "µm³" in result.output and "um3" not in result.output, result.output


def compare(study: xr.Dataset, combined: xr.Dataset, dims: list[str]) -> list[str]:
    """Assert that every variable study.nc shares with the combined case files has the same values there;
    a variable the combination stacked although it is the same in every case is compared case by case."""
    compared = []
    for name in study.data_vars:
        if name not in combined:
            continue
        got, want = combined[name], study[name]
        extra = [d for d in got.dims if d not in want.dims]
        if extra:
            assert (got == got.isel({d: 0 for d in extra})).all(), name
            got = got.isel({d: 0 for d in extra}, drop=True)
        got = got.transpose(*want.dims).load()
        if want.dtype.kind in "OUS":
            assert got.values.astype(str).tolist() == want.values.astype(str).tolist(), name
        else:
            np.testing.assert_array_equal(got.values.astype(float), want.values.astype(float), err_msg=name)
        compared.append(name)
    for dim in dims:
        np.testing.assert_array_equal(combined[dim].values, study[dim].values)
        assert combined[dim].attrs == study[dim].attrs, dim
    return compared


@pytest.mark.parametrize("new_defaults", [False, True])
def test_open_mfdataset_on_a_grid_studys_cases_rebuilds_study_nc(made, new_defaults):
    """`xr.open_mfdataset("cases/*.nc")` without a preprocess, under xarray's present defaults and the coming
    ones (data_vars=None, compat="override"): no case's fields silently replaced by another's."""
    study = xr.load_dataset(made / "grid" / "study.nc")
    with xr.set_options(use_new_combine_kwarg_defaults=new_defaults), \
            xr.open_mfdataset(sorted((made / "grid" / "cases").glob("*.nc")), combine="by_coords") as combined:
        compared = compare(study, combined, ["g", "r"])
    assert {"phi", "c", "alpha", "p", "u", "phi_mean", "steps_bisected", "status", "case_id", "obstacle",
            "mu"} <= set(compared)
    assert study.p.dims == ("g", "r", "time_mechanics", "y", "x")


def test_open_mfdataset_on_a_zip_studys_cases_rebuilds_study_nc(made):
    study = xr.load_dataset(made / "zip" / "study.nc")
    paths = [made / "zip" / "cases" / f"{case}.nc" for case in study.case.values]
    with xr.open_mfdataset(paths, combine="nested", concat_dim="case", data_vars="minimal",
                           combine_attrs="drop_conflicts") as nested:
        compare(study, nested, ["case", "k_alpha", "beta"])
        assert "case_id" not in nested.attrs and "k_alpha" not in nested.attrs  # per case: no silent first
        assert nested.attrs["scene_file"] == study.attrs["scene_file"]
    with xr.open_mfdataset(sorted(paths), combine="by_coords", data_vars="minimal") as combined:
        compare(study, combined.sel(case=study.case), ["case", "k_alpha", "beta"])


def test_masks_keep_their_int8_flags_and_no_study_dimensions(made):
    """obstacle and nutrient_source, the same in every case, are in study.nc once, int8 with their flags."""
    for study in ("grid", "zip"):
        with netCDF4.Dataset(made / study / "study.nc") as nc:
            for name in ("obstacle", "nutrient_source"):
                var = nc[name]
                assert var.dimensions == ("y", "x") and var.dtype == np.int8, (study, name)
                assert var.flag_values.dtype == np.int8 and "_FillValue" not in var.ncattrs()


def test_masks_that_differ_between_cases_are_stacked_with_flags_of_their_type(tmp_path, tiny_scene, monkeypatch):
    (tmp_path / "walls.toml").write_text('scene = "tiny.toml"\n[sweep]\n'
                                         '"obstacle.0.upper" = [[3.0, 16.0], [4.0, 16.0]]\n')
    result = CliRunner().invoke(app, ["sweep", str(tmp_path / "walls.toml"), "-o", str(tmp_path / "out"), "-q",
                                      "--set", "time.steps=4"])
    assert result.exit_code == 0, result.output
    study = xr.load_dataset(tmp_path / "out" / "study.nc")
    assert study.obstacle.dims == ("obstacle_0_upper", "y", "x")
    assert study.obstacle.sum(["y", "x"]).values.tolist() == [12, 16]
    with netCDF4.Dataset(tmp_path / "out" / "study.nc") as nc:
        assert nc["obstacle"].flag_values.dtype == nc["obstacle"].dtype
    from biostudy.plans.study import load_study

    plan = load_study(tmp_path / "walls.toml", ["time.steps=4"])
    same_files(*both_ways(plan, tmp_path / "out", monkeypatch))  # study-wide arrays: as a dataset per case


def test_netcdf_layout_history_no_coordinate_fill_compressed_snapshots(made):
    with netCDF4.Dataset(made / "run3d.nc") as nc:
        assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ: .+", nc.history)  # the command line: test_cli
        assert nc.Conventions == "CF-1.10" and nc["z"].positive == "up" and nc["x"].bounds == "x_bounds"
        for name in ("time", "x", "y", "z", "time_mechanics", "x_node", "x_bounds"):
            assert "_FillValue" not in nc[name].ncattrs(), name
        for name in ("phi", "c", "alpha", "p"):
            assert nc[name].filters()["zlib"] and nc[name].filters()["shuffle"], name
            assert nc[name].chunking() == [1, 8, 9, 10], name
        assert nc["u"].chunking() == [1, 9, 10, 11, 3]
        for name in ("phi", "u", "phi_mean", "time", "x_bounds", "obstacle"):
            assert nc[name].filters()["fletcher32"], name  # checksums (netcdf_io.intact) need chunked storage
        assert nc["phi_mean"].chunking() == [3] and not nc["phi_mean"].filters()["zlib"]  # one chunk, not compressed
    with netCDF4.Dataset(made / "grid" / "study.nc") as nc:
        assert nc["phi"].chunking() == [1, 1, 1, 16, 16] and nc["phi"].filters()["zlib"]
        assert nc["status"].dtype == np.dtype("S1") and nc["case_id"].dtype == np.dtype("S1")  # text: characters
        assert nc.history


def test_files_written_before_read_with_todays_names_and_layout(made, tmp_path):
    """A case file read as one run (show, plot, export) is squeezed; an old run's steps_bisections is
    steps_bisected; combine reads both."""
    from biostudy.data import combine, netcdf, reading, study_cases, writing
    from biostudy.plans.study import load_study

    case = reading.open_dataset(made / "grid" / "cases" / "g=1e+08_r=50.nc")
    assert case.phi.dims == ("time", "y", "x") and float(case.g) == 1e8 and case.status.item() == "done"
    old = xr.load_dataset(made / "run2d.nc").rename(steps_bisected="steps_bisections")
    assert "steps_bisected" in netcdf.as_run(old) and "steps_bisections" not in netcdf.as_run(old)
    plan = load_study(made / "grid.toml")
    for path in (made / "grid" / "cases").glob("*.nc"):  # as a sweep before issue 11 wrote them
        with xr.open_dataset(path) as ds:
            before = study_cases.as_run(ds.load(), {}).rename(steps_bisected="steps_bisections")
        before.attrs.pop(netcdf.CASE_DIMENSIONS)
        writing.write_atomic(before, tmp_path / "cases" / path.name)
    study = combine.combine(plan, tmp_path).load()
    assert study.steps_bisected.dims == ("g", "r", "time") and (study.status == "done").all()
    xr.testing.assert_equal(study.phi, xr.load_dataset(made / "grid" / "study.nc").phi)
