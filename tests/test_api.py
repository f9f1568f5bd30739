"""The Python API (`biostudy.run`, `sweep`, `open`) and the notebook in docs/examples that uses it."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import TINY_SCENE
from typer.testing import CliRunner

import biostudy
from biostudy.cli import app

NOTEBOOK = Path(__file__).resolve().parents[1] / "docs" / "examples" / "notebook.ipynb"
# differ between two runs
PER_RUN = {"created", "history", "wall_time", "host", "cpu_time_loop", "cpu_time_first", "cpu_time_setup"}


def test_run_returns_the_dataset_the_command_writes(tiny_scene, tmp_path):
    given = ["params.g=1e9", "mechanics.enabled=false"]
    result = CliRunner().invoke(app, ["run", str(tiny_scene), "-o", str(tmp_path / "cli.nc"), "-q",
                                      *(a for s in given for a in ("--set", s))])
    assert result.exit_code == 0, result.output
    ds = biostudy.run(tiny_scene, set={"g": 1e9, "mechanics.enabled": False}, output=tmp_path / "api.nc")
    written = biostudy.open(tmp_path / "cli.nc")
    assert set(ds.variables) == set(written.variables) and "front_advance" in ds and "dense_volume" in ds
    for name in ("phi", "c", "alpha", "phi_mean", "height"):
        np.testing.assert_array_equal(ds[name].values, written[name].values)
    differ = {k for k in set(ds.attrs) | set(written.attrs) if k not in PER_RUN and not k.startswith("wall_time")
              and str(ds.attrs.get(k)) != str(written.attrs.get(k))}
    assert not differ, differ
    assert float(ds.g) == 1e9  # an overridden key is a scalar coordinate (in the file too)
    history = xr.open_dataset(tmp_path / "api.nc").attrs["history"]
    call = history.split(": ", 1)[1]  # what made the file: the call, not the test runner's command line
    assert call.startswith(f"biostudy.run('{tiny_scene}', set={{'g': 1000000000.0, ") and "api.nc" in call


def test_run_takes_a_scene_as_data_and_raises_bad_input(tmp_path):
    import tomllib

    scene = tomllib.loads(TINY_SCENE)
    scene.pop("obstacle")
    ds = biostudy.run(scene, set=["time.steps=10"])
    assert ds.attrs["steps_nominal"] == 10 and ds.attrs["scene_file"] == "" and "tiny" in ds.attrs["title"]
    with pytest.raises(biostudy.BadInput, match=r"params\.d: must be > 0"):
        biostudy.run(scene, set={"d": -1.0})
    with pytest.raises(biostudy.BadInput, match="did you mean 'directional'"):
        biostudy.run("directonal")


def test_sweep_and_open_of_cases_and_studies(tiny_study, tmp_path):
    study = biostudy.sweep(tiny_study, tmp_path / "out", set={"mechanics.enabled": False, "time.steps": 10})
    assert study.phi_mean.dims == ("g", "r", "time") and (study.status.values == "done").all()
    case = biostudy.open(tmp_path / "out" / "cases" / "g=1e+09_r=50.nc")  # one run: its place squeezed away
    np.testing.assert_array_equal(case.phi_mean.values, study.phi_mean.sel(g=1e9, r=50).values)
    assert biostudy.open(tmp_path / "out").attrs["cases_done"] == 4
    assert "biostudy.sweep(" in study.attrs["history"]
    with pytest.raises(biostudy.BadInput, match="not a dataset biostudy wrote"):
        xr.Dataset({"a": ("x", [1.0, 2.0])}).to_netcdf(tmp_path / "foreign.nc")
        biostudy.open(tmp_path / "foreign.nc")


def test_import_is_cheap_and_calibrate_is_there(tmp_path):
    probe = ("import sys, biostudy, biostudy.cli; heavy = [m for m in ('xarray', 'pydantic', 'fipy', 'dask', "
             "'matplotlib', 'skimage', 'scipy', 'rich') if m in sys.modules]; print(heavy)")
    shown = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert shown.stdout.strip() == "[]", shown.stdout
    assert {"run", "sweep", "open", "calibrate"} <= set(dir(biostudy))
    (tmp_path / "fit.toml").write_text('scene = "nowhere.toml"\n')
    with pytest.raises(biostudy.BadInput, match="fit.toml"):  # the command's own validation, one line
        biostudy.calibrate(tmp_path / "fit.toml", tmp_path / "fit")


def test_the_notebook_runs_and_records_the_api_call(tmp_path, monkeypatch):
    monkeypatch.delenv("MPLBACKEND", raising=False)  # the kernel's own (inline) backend: figures as outputs
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    text = "\n".join(str(o.get("text", "")) + str(o.get("data", {}).get("text/plain", "")) for o in outputs)
    assert "biostudy.run('directional2d'" in text and "ipykernel" not in text
    assert any("image/png" in o.get("data", {}) for o in outputs)  # the plot was drawn
    ds = xr.open_dataset(tmp_path / "directional2d-g1e8.nc")
    assert "biostudy.run(" in ds.attrs["history"] and ds.sizes["time"] == 3


@pytest.mark.parametrize("call, said", [
    (lambda: biostudy.sweep("s.toml", "out", workers=-1), "workers: give a whole number of processes"),
    (lambda: biostudy.sweep("s.toml", "out", workers="2"), "workers: give a whole number .* \\(got '2'\\)"),
    (lambda: biostudy.calibrate("c.toml", "out", workers=True), "workers: give a whole number"),
    (lambda: biostudy.sweep("s.toml", "out", set=5), "set: give a dict .* \\(got 5\\)"),
    (lambda: biostudy.run("tiny.toml", set=5), "set: give a dict"),
    (lambda: biostudy.run("tiny.toml", progress=5), "progress: give a function"),
])
def test_arguments_of_the_wrong_kind_are_one_line_before_anything_is_read(call, said, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no such files: the arguments are refused before any is looked for
    with pytest.raises(biostudy.BadInput, match=said) as refused:
        call()
    assert len(refused.value.lines()) == 1 and not list(tmp_path.iterdir())


def test_an_interrupted_run_gives_its_output_back_from_python_too(tiny_scene, tmp_path, monkeypatch):
    """The output's claim is the command's (issue 38.3): interrupted between the checks and the computing, a
    call of `biostudy.run` leaves no temporary behind while the interruption is still held, and the output can
    be claimed again at once."""
    from biostudy.commands import run as command

    def interrupted(loaded, **kwargs):
        raise KeyboardInterrupt

    with monkeypatch.context() as patched:
        patched.setattr(command, "compute", interrupted)
        with pytest.raises(KeyboardInterrupt) as caught:
            biostudy.run(tiny_scene, output=tmp_path / "t.nc")
        assert [p.name for p in tmp_path.iterdir()] == ["tiny.toml"], caught  # the traceback holds the frames
    biostudy.run(tiny_scene, output=tmp_path / "t.nc")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.nc", "tiny.toml"]
