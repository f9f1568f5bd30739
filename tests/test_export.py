"""ParaView export (`biostudy.export`): every VTU read back with meshio against the dataset, and the PVD."""
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
import xarray as xr

from biostudy.export import export

H = 1.5  # µm: a spacing other than 1 so that index and coordinate mix-ups show


@pytest.fixture(scope="module")
def run3d(tiny_run):
    return tiny_run((6, 5, 4), H)


@pytest.fixture(scope="module")
def run2d(tiny_run):
    return tiny_run((7, 5), H)


def read_series(paths):
    assert paths[-1].name == "series.pvd"
    return [meshio.read(p) for p in paths[:-1]]


def cell_index(mesh, ds):
    """(k, j, i) of every mesh cell, found from the coordinates of its corners (not from the writer's order)."""
    corners = mesh.points[mesh.cells[0].data]
    centre = corners.mean(axis=1)
    ijk = np.floor(centre / H).astype(int)
    return tuple(ijk[:, k] for k in ((2, 1, 0) if "z" in ds.dims else (1, 0)))


def test_three_dimensional_round_trip(run3d, with_mechanics, tmp_path):
    ds = with_mechanics(run3d)
    meshes = read_series(export(ds, tmp_path / "vtk"))
    obstacle = ds["obstacle"].values.astype(bool)
    assert obstacle.any() and len(meshes) == ds.sizes["time"]
    for t, mesh in enumerate(meshes):
        assert [block.type for block in mesh.cells] == ["hexahedron"]
        index = cell_index(mesh, ds)
        assert len(mesh.cells[0].data) == np.count_nonzero(~obstacle)
        assert not obstacle[index].any() and len(set(zip(*index))) == len(index[0])
        for name in ("phi", "c", "alpha", "p"):
            assert np.array_equal(mesh.cell_data[name][0], ds[name].values[t][index]), name
        assert np.array_equal(mesh.cell_data["nutrient_source"][0], ds["nutrient_source"].values[index])
        node = np.round(mesh.points / H).astype(int)
        assert np.array_equal(mesh.point_data["u"], ds["u"].values[t][node[:, 2], node[:, 1], node[:, 0]])
        used = np.unique(mesh.cells[0].data)
        assert used.size == len(mesh.points), "no node without an open cell"
        # positive volume in VTK's corner order: (p1 - p0) x (p3 - p0) . (p4 - p0) > 0
        p = mesh.points[mesh.cells[0].data]
        assert (np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 3] - p[:, 0]), p[:, 4] - p[:, 0]) > 0).all()


def test_two_dimensional_quads_with_u_padded_to_three_components(run2d, with_mechanics, tmp_path):
    ds = with_mechanics(run2d)
    meshes = read_series(export(ds, tmp_path))
    for t, mesh in enumerate(meshes):
        assert [block.type for block in mesh.cells] == ["quad"]
        assert np.all(mesh.points[:, 2] == 0)
        index = cell_index(mesh, ds)
        assert len(mesh.cells[0].data) == np.count_nonzero(ds["obstacle"].values == 0)
        assert np.array_equal(mesh.cell_data["phi"][0], ds["phi"].values[t][index])
        node = np.round(mesh.points / H).astype(int)
        u = mesh.point_data["u"]
        assert u.shape == (len(mesh.points), 3) and np.all(u[:, 2] == 0)
        assert np.array_equal(u[:, :2], ds["u"].values[t][node[:, 1], node[:, 0]])


def test_collection_lists_every_snapshot_with_its_time(run3d, tmp_path):
    paths = export(run3d, tmp_path)
    entries = ET.parse(paths[-1]).getroot().find("Collection").findall("DataSet")
    assert [float(e.get("timestep")) for e in entries] == run3d["time"].values.tolist()
    assert [e.get("file") for e in entries] == [p.name for p in paths[:-1]]
    assert all((tmp_path / e.get("file")).is_file() for e in entries)


def test_without_mechanics_no_u_or_p_and_unsolved_times_are_left_out(run3d, with_mechanics, tmp_path):
    mesh = read_series(export(run3d, tmp_path / "plain"))[0]
    assert "u" not in mesh.point_data and "p" not in mesh.cell_data and "phi" in mesh.cell_data
    meshes = read_series(export(with_mechanics(run3d, unsolved=1), tmp_path / "partial"))
    assert ["p" in m.cell_data for m in meshes] == [True, False, True]
    assert ["u" in m.point_data for m in meshes] == [True, False, True]


def test_a_sweep_is_refused(tmp_path):
    ds = xr.Dataset({"phi": (("g", "time", "y", "x"), np.zeros((2, 1, 3, 3)))},
                    coords={"g": [1e8, 1e9], "time": [0.0], "y": [0.5, 1.5, 2.5], "x": [0.5, 1.5, 2.5]})
    with pytest.raises(ValueError, match="not a sweep"):
        export(ds, tmp_path)
