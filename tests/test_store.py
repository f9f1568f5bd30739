"""Datasets on disk: netCDF-legal attributes, atomic writes, the dataset layout after a round trip."""
import os
import subprocess
import tomllib

import numpy as np
import pytest
import xarray as xr
from conftest import CUBE_SCENE

from biostudy.data import provenance, writing
from biostudy.inputs.scene import load_scene
from solver import simulate


def test_legal_attrs_has_no_none_bool_or_nested_dict():
    legal = provenance.legal_attrs({"a": None, "b": True, "c": {"x": 1, "y": {"z": False}}, "d": ["u", "v"],
                               "e": [1, 2], "f": "text"})
    assert legal == {"b": 1, "c_x": 1, "c_y_z": 0, "d": "u, v", "e": legal["e"], "f": "text"}
    assert list(legal["e"]) == [1, 2]


def test_write_atomic_replaces_the_file_and_leaves_nothing_else(tmp_path):
    path = tmp_path / "out.nc"
    writing.write_atomic(xr.Dataset({"v": ("t", [1.0, 2.0])}), path)
    writing.write_atomic(xr.Dataset({"v": ("t", [3.0])}), path)
    assert xr.open_dataset(path).v.values.tolist() == [3.0]
    assert os.listdir(tmp_path) == ["out.nc"]


@pytest.mark.parametrize("interruption", [KeyboardInterrupt, OSError])
def test_an_interrupted_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch, interruption):
    path = tmp_path / "out.nc"
    writing.write_atomic(xr.Dataset({"v": ("t", [1.0])}), path)

    def fail(fd):
        raise interruption("stopped while writing")

    monkeypatch.setattr(writing.os, "fsync", fail)  # the temporary is fully written, not yet renamed
    with pytest.raises(interruption):
        writing.write_atomic(xr.Dataset({"v": ("t", [9.0, 9.0])}), path)
    assert os.listdir(tmp_path) == ["out.nc"]
    assert xr.open_dataset(path).v.values.tolist() == [1.0]
    monkeypatch.undo()
    with pytest.raises(interruption):
        monkeypatch.setattr(writing.os, "fsync", fail)
        writing.write_atomic(xr.Dataset({"v": ("t", [9.0])}), tmp_path / "new.nc")
    assert not (tmp_path / "new.nc").exists()


def test_remove_temporaries_touches_only_temporaries_of_writers_that_are_gone(tmp_path):
    dead = subprocess.Popen(["true"])
    dead.wait()
    (tmp_path / f".a.nc.{dead.pid}.0123abcd.tmp").write_text("half")
    (tmp_path / f".b.nc.{os.getppid()}.0123abcd.tmp").write_text("in flight")  # its writer is running
    (tmp_path / ".draft.tmp").write_text("a user's")
    (tmp_path / "a.nc").write_text("kept")
    removed = writing.remove_temporaries(tmp_path)
    assert [p.name for p in removed] == [f".a.nc.{dead.pid}.0123abcd.tmp"]
    assert sorted(os.listdir(tmp_path)) == [f".b.nc.{os.getppid()}.0123abcd.tmp", ".draft.tmp", "a.nc"]


def test_dataset_layout_after_a_netcdf_round_trip(write_toml, tmp_path):
    """docs/model.md, "The dataset": dims, units and long_name everywhere, obstacles NaN, the scene and its
    provenance in attrs."""
    path = write_toml("cube.toml", CUBE_SCENE)
    scene = load_scene(path, ["params.g=2e8"])
    ds = simulate(scene.problem())
    out = tmp_path / "cube.nc"
    writing.write_atomic(provenance.stamp(ds, scene.to_toml(), path, '"params.g" = 2e+08'), out)
    back = xr.open_dataset(out, engine="netcdf4")

    assert dict(back.sizes) == {"time": 3, "z": 8, "y": 9, "x": 10, "bounds": 2}
    assert back.x.values[0] == 1.0 and back.x.values[-1] == 19.0
    assert back.x_bounds.values[0].tolist() == [0.0, 2.0] and back.x_bounds.values[-1].tolist() == [18.0, 20.0]
    for name in list(back.data_vars) + list(back.coords):
        if name.endswith("_bounds"):  # CF 7.1: a bounds variable has its cell centre's units and long name
            continue
        assert back[name].attrs.get("long_name"), name
        assert "units" in back[name].attrs, name
    for name in ("phi", "c", "alpha"):
        assert back[name].dims == ("time", "z", "y", "x")
    assert {"phi_mean", "c_mean", "biofilm_volume"} <= set(back.data_vars)
    assert "u" not in back and "p" not in back  # mechanics off: neither computed nor stored
    blocked = back.obstacle.values.astype(bool)
    assert blocked.any() and np.isnan(back.phi.values[:, blocked]).all()

    attrs = back.attrs
    assert attrs["Conventions"].startswith("CF")
    for key in ("mu", "nu", "d", "beta", "k_alpha", "k", "g", "r"):
        assert key in attrs
    assert attrs["g"] == 2e8
    assert attrs["steps_taken"] == 10 and attrs["steps_bisected"] == 0 and attrs["wall_time"] > 0
    assert attrs["version_fipy"] and attrs["biostudy_version"] and attrs["created"]
    assert attrs["scene_file"] == str(path.resolve()) and attrs["overrides"] == '"params.g" = 2e+08'
    recorded = tomllib.loads(attrs["scene"])
    assert recorded["params"]["g"] == 2e8 and recorded["grid"]["shape"] == [10, 9, 8]
    assert load_scene(path, ["params.g=2e8"]).to_toml() == attrs["scene"]
    xr.testing.assert_allclose(back.phi, ds.phi)


def test_first_line_of_an_error_never_fails_on_an_empty_message():
    from biostudy.errors import first_line

    assert first_line(OSError("bad header\nmore detail")) == "bad header"
    assert first_line(OSError()) == "OSError"  # str(error).splitlines()[0] raised IndexError here
