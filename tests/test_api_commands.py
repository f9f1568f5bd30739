"""Every command from Python (issue 28.2): each `biostudy.<command>` returns what the command line makes of the
same input (the numbers of its ``--json``, the same files byte for byte, the same text), raises `BadInput` in
one line for bad input, and prints nothing.

The job commands (convergence, stability, calibrate) run from Python first; the command line then runs the
same into the same directory, reuses every simulation, and must report the same numbers.
"""
from __future__ import annotations

import filecmp
import json
import textwrap
import tomllib
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import TINY_SCENE
from typer.testing import CliRunner

import biostudy
from biostudy.cli import app
from biostudy.reports.records import dataset_record, text

cli = CliRunner()
STUDY = """\
scene = "tiny.toml"
[set]
"time.steps" = 10
[sweep]
mode = "grid"
g = [1e8, 1e9]
r = [50.0, 100.0]
"""
CATALOGUE = """\
name = "tiny-stability"
scene = "tiny.toml"
[set]
"time.steps" = 10
[[case]]
name = "paper"
[[case]]
name = "g=1e10"
set = { "params.g" = 1e10 }
"""


def invoke(*args) -> str:
    """The command's stdout; it must succeed."""
    result = cli.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result.stdout


def as_json(record):
    """A record as `--json` prints it and `json.loads` reads it (NaN as None, arrays as lists)."""
    return json.loads(text(record))


def numbers_of(record: dict) -> dict:
    """A summary dataset's record without what says when and how it was made (`created`, `history`)."""
    return {"coordinates": record["coordinates"], "variables": record["variables"]}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """Two runs of the tiny scene (g = 1e8 by the command line, g = 1e9 from Python) and a 2 x 2 sweep of it."""
    here = tmp_path_factory.mktemp("api")
    (here / "tiny.toml").write_text(textwrap.dedent(TINY_SCENE))
    (here / "study.toml").write_text(STUDY)
    (here / "catalogue.toml").write_text(CATALOGUE)
    invoke("run", here / "tiny.toml", "-o", here / "a.nc", "-q")
    biostudy.run(here / "tiny.toml", set={"g": 1e9}, output=here / "b.nc")
    biostudy.sweep(here / "study.toml", here / "sweep")
    return here


def test_every_command_of_the_command_line_is_a_function():
    commands = {command.name or command.callback.__name__ for command in app.registered_commands}
    assert commands == {"run", "sweep", "calibrate", "convergence", "stability", "analyze", "plot", "export",
                        "measure", "show", "scenes"}
    assert all(callable(getattr(biostudy, name)) for name in commands) and callable(biostudy.open)


@pytest.mark.parametrize("names", [["a.nc"], ["a.nc", "b.nc"], ["sweep"], ["tiny.toml"]])
def test_show_returns_what_the_command_prints_and_its_json(made, names):
    paths = [made / name for name in names]
    shown = biostudy.show(*paths)
    assert str(shown) == invoke("show", *paths)
    if names == ["tiny.toml"]:
        assert shown.record is None and shown.text().startswith("tiny: 16 × 16 cells, 20 steps")
    else:
        assert as_json(shown.record) == json.loads(invoke("show", "--json", *paths))
    assert (shown.comparison is None) == (len(names) == 1)
    if names == ["a.nc"]:  # the numbers are the file's
        ds = xr.load_dataset(made / "a.nc")
        observables = shown.record["observables"]
        assert shown.record["kind"] == "run" and list(observables) == ds.attrs["observables"].split(", ")
        assert all(np.array_equal(v["values"], ds[k].values, equal_nan=True) for k, v in observables.items())
    if names == ["a.nc", "b.nc"]:  # one record per run
        assert as_json(shown.record) == [as_json(biostudy.show(p).record) for p in paths]
    if names == ["sweep"]:
        study = xr.load_dataset(made / "sweep" / "study.nc")
        assert shown.record["kind"] == "study"
        assert [c["case_id"] for c in shown.record["cases"]] == study.case_id.values.ravel().tolist()


def test_show_of_two_runs_gives_how_they_differ(made):
    compared = biostudy.show([made / "a.nc", made / "b.nc"]).comparison
    assert compared.scenes == {"params.g": [1e8, 1e9]}
    assert compared.times.tolist() == [0.0, 0.1, 0.2]
    a, b = xr.load_dataset(made / "a.nc"), xr.load_dataset(made / "b.nc").squeeze()
    gap = np.abs(a.phi - b.phi)
    phi = next(d for d in compared.fields if d.field == "phi")
    assert phi.largest == float(gap.max()) and phi.run == 1
    where = gap.where(gap == gap.max(), drop=True)
    assert (phi.time, phi.cell) == (float(where.time[0]), {"y": float(where.y[0]), "x": float(where.x[0])})


def test_scenes_is_the_commands_json_of_the_bundled_files():
    listed = biostudy.scenes()
    assert listed == json.loads(invoke("scenes", "--json"))
    files = sorted(Path(listed["directory"]).glob("*.toml"))
    assert {e["file"]: e["description"] for e in listed["entries"]} == {
        f.name: tomllib.loads(f.read_text(encoding="utf-8")).get("description", "") for f in files}


def test_plot_and_export_write_the_files_the_command_writes_and_print_nothing(made, capfd):
    pictures = biostudy.plot(made / "a.nc", output=made / "api.png", variable="phi", time=0.1)
    vti = biostudy.export(made / "a.nc", made / "vti-api")
    tiff = biostudy.export(made / "a.nc", made / "tiff-api", format="tiff")
    assert capfd.readouterr() == ("", "")
    said = invoke("plot", made / "a.nc", "-o", made / "cli.png", "--variable", "phi", "--time", "0.1")
    assert [p.name for p in pictures] == ["api_series.png", "api_maps.png"]
    assert said.splitlines() == [f"wrote {p.with_name(p.name.replace('api', 'cli'))}" for p in pictures]
    invoke("export", made / "a.nc", made / "vti-cli")
    invoke("export", made / "a.nc", made / "tiff-cli", "--format", "tiff")
    assert [p.name for p in vti] == ["snapshot_0000.vti", "snapshot_0001.vti", "snapshot_0002.vti", "series.pvd"]
    assert [p.name for p in tiff] == ["phi.tif", "c.tif"]
    for written, other in ((pictures, lambda p: p.with_name(p.name.replace("api", "cli"))),
                           (vti, lambda p: made / "vti-cli" / p.name), (tiff, lambda p: made / "tiff-cli" / p.name)):
        assert all(filecmp.cmp(p, other(p), shallow=False) for p in written)


def test_analyze_returns_the_analysis_the_command_writes(made):
    record = json.loads(invoke("analyze", made / "sweep", "--output", "biofilm_volume", "--output", "height",
                               "--json"))
    ds = biostudy.analyze(made / "sweep", outputs=["biofilm_volume", "height"], times=0.2)
    assert numbers_of(as_json(dataset_record(ds))) == numbers_of(record)
    assert list(ds.output.values) == ["biofilm_volume", "height"] and ds.sizes["parameter"] == 2
    assert "biostudy.analyze(" in ds.attrs["history"]


def test_convergence_and_stability_return_what_the_command_reports(made):
    # 20 steps: the coarsest the tiny scene's front allows (its Courant number 0.91); fewer would be split
    conv = biostudy.convergence(made / "tiny.toml", made / "conv", levels=2, series="time", set={"time.steps": 20})
    assert conv.steps_taken.sel(series="time").values.tolist() == [20, 40]
    again = invoke("convergence", made / "tiny.toml", "-o", made / "conv", "--levels", "2", "--series", "time",
                   "--set", "time.steps=20", "--json", "-q")
    assert numbers_of(as_json(dataset_record(conv))) == numbers_of(json.loads(again))
    verdicts = biostudy.stability(made / "catalogue.toml", made / "stab")
    assert verdicts.case.values.tolist() == ["paper", "g=1e10"] and verdicts.ok.all()
    again = invoke("stability", made / "catalogue.toml", "-o", made / "stab", "--json", "-q")
    assert numbers_of(as_json(dataset_record(verdicts))) == numbers_of(json.loads(again))


@pytest.mark.filterwarnings("ignore:1 of its simulations lost")  # the tiny colony retreats where it starves
def test_calibrate_returns_what_the_command_reports(made):
    from biostudy.calibration import twin

    (made / "twin.tsv").write_text(twin.table(made / "tiny.toml", truth={"r": 80.0}, observables_measured=["biomass"],
                                              times=[0.1, 0.2], noise=0.05, seed=3))
    (made / "fit.toml").write_text('scene = "tiny.toml"\n[data]\nmeasurements = "twin.tsv"\n'
                                   '[estimate]\nr = [50.0, 150.0]\n[method]\nstarts = 1\nprofiles = false\n')
    fit = biostudy.calibrate(made / "fit.toml", made / "fit")
    again = invoke("calibrate", made / "fit.toml", "-o", made / "fit", "--json", "-q")
    assert numbers_of(as_json(dataset_record(fit))) == numbers_of(json.loads(again))
    assert 50.0 <= float(fit.estimate.sel(parameter="r")) <= 150.0


@pytest.mark.parametrize("call, said", [
    (lambda here: biostudy.show(here / "foreign.nc"), "foreign.nc: not a dataset biostudy wrote"),
    (lambda here: biostudy.show(), "paths: give a file to show"),
    (lambda here: biostudy.plot(here / "a.nc", cut="x=3"), "a.nc: cut 'x=3' needs a 3-D run"),
    (lambda here: biostudy.plot(here / "a.nc", warp="big"), "warp: give a number"),
    (lambda here: biostudy.export(here / "a.nc", here / "out", format="obj"), "unknown format 'obj'"),
    (lambda here: biostudy.export(here / "sweep" / "study.nc", here / "out"), "a sweep's study.nc, not one run"),
    (lambda here: biostudy.analyze(here / "a.nc"), "a.nc: not a study's combined dataset"),
    (lambda here: biostudy.analyze(here / "sweep", outputs=[1]), "outputs: give a name or a list of names"),
    (lambda here: biostudy.convergence(here / "tiny.toml", levels=1), "levels: give a whole number, 2 or more"),
    (lambda here: biostudy.stability(here / "nowhere.toml"), "nowhere.toml: no such file"),
    (lambda here: biostudy.run(here / "tiny.toml", threads=0), "threads: give a whole number of threads, 1 or more"),
])
def test_bad_input_is_one_line_and_writes_nothing(made, call, said):
    xr.Dataset({"a": ("x", [1.0, 2.0])}).to_netcdf(made / "foreign.nc")
    before = sorted(made.rglob("*"))
    with pytest.raises(biostudy.BadInput, match=said.replace("(", r"\(")) as refused:
        call(made)
    assert len(refused.value.lines()) == 1 and sorted(made.rglob("*")) == before
