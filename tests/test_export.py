"""ParaView export (`biostudy.data.export`): every VTI read back with VTK's own reader and every VTU with meshio and
VTK, against the dataset; the PVD; `mechanics_solved` where the mechanics was not solved (issue 36.4)."""
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
import xarray as xr

from biostudy.data.export import export
from solver.output import on_output_times

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
    meshes = read_series(export(ds, tmp_path / "vtk", "vtu"))
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
    meshes = read_series(export(ds, tmp_path, "vtu"))
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
    paths = export(run3d, tmp_path, "vtu")
    entries = ET.parse(paths[-1]).getroot().find("Collection").findall("DataSet")
    assert [float(e.get("timestep")) for e in entries] == run3d["time"].values.tolist()
    assert [e.get("file") for e in entries] == [p.name for p in paths[:-1]]
    assert all((tmp_path / e.get("file")).is_file() for e in entries)


def test_times_are_written_as_people_write_them(run3d, tmp_path):
    """0.05 * 3 is the float64 0.15000000000000002: the PVD and the VTU's TimeValue say 0.15."""
    ds = run3d.assign_coords(time=[0.0, 0.05 * 3, 0.3])
    paths = export(ds, tmp_path, "vtu")
    entries = ET.parse(paths[-1]).getroot().find("Collection").findall("DataSet")
    assert [e.get("timestep") for e in entries] == ["0", "0.15", "0.3"]
    value = ET.parse(paths[1]).getroot().find("UnstructuredGrid/FieldData/DataArray[@Name='TimeValue']")
    assert value.text == "0.15"


def vtk_read(path):
    """The dataset VTK's own XML reader (as ParaView's) makes of a .vti or .vtu file."""
    from vtkmodules.vtkIOXML import vtkXMLImageDataReader, vtkXMLUnstructuredGridReader

    reader = vtkXMLImageDataReader() if path.suffix == ".vti" else vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def vtk_arrays(path):
    """What VTK's own reader (as ParaView's) finds in a VTU: cell, point and field arrays, the active ones."""
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    grid = reader.GetOutput()

    def names(data):
        return sorted(data.GetArrayName(i) for i in range(data.GetNumberOfArrays()))

    active = (grid.GetCellData().GetScalars(), grid.GetPointData().GetVectors())
    return {"cells": names(grid.GetCellData()), "points": names(grid.GetPointData()),
            "field": {n: grid.GetFieldData().GetArray(n).GetValue(0) for n in names(grid.GetFieldData())},
            "active": tuple(a.GetName() if a is not None else None for a in active),
            "n_cells": grid.GetNumberOfCells()}


def test_every_file_has_the_same_arrays_its_time_and_u_as_active_vectors(run3d, with_mechanics, tmp_path):
    """A warped animation in ParaView: p and u in every file (where the mechanics was not solved, those of the
    latest output where it was: `mechanics_time` says which), each file's T* as `TimeValue`, u the active
    vectors, phi the active scalars; read with meshio and with VTK's reader."""
    ds = with_mechanics(run3d, unsolved=1)  # solved at outputs 0 and 2
    paths = export(ds, tmp_path, "vtu")
    meshes = read_series(paths)
    times = ds.time.values.tolist()
    for mesh in meshes:
        assert sorted(mesh.cell_data) == ["alpha", "c", "nutrient_source", "p", "phi"]
        assert list(mesh.point_data) == ["u"]
    assert [float(m.field_data["TimeValue"][0]) for m in meshes] == times
    assert [float(m.field_data["mechanics_time"][0]) for m in meshes] == [times[0], times[0], times[2]]
    np.testing.assert_array_equal(meshes[1].point_data["u"], meshes[0].point_data["u"])  # held, not undeformed
    np.testing.assert_array_equal(meshes[1].cell_data["p"][0], meshes[0].cell_data["p"][0])
    assert not np.array_equal(meshes[2].point_data["u"], meshes[0].point_data["u"])
    seen = [vtk_arrays(p) for p in paths[:-1]]
    open_cells = np.count_nonzero(ds.obstacle.values == 0)
    for found, when in zip(seen, times):
        assert found["cells"] == ["alpha", "c", "nutrient_source", "p", "phi"] and found["points"] == ["u"]
        assert found["field"] == {"TimeValue": when, "mechanics_time": found["field"]["mechanics_time"],
                                  "mechanics_solved": found["field"]["mechanics_solved"]}
        assert found["active"] == ("phi", "u") and found["n_cells"] == open_cells
    assert [f["field"]["mechanics_solved"] for f in seen] == [1, 0, 1]  # output 1: p and u are output 0's

    plain = [vtk_arrays(p) for p in export(run3d, tmp_path / "plain", "vtu")[:-1]]  # no mechanics: no p, u
    assert {(tuple(f["cells"]), tuple(f["points"]), f["active"]) for f in plain} == {
        (("alpha", "c", "nutrient_source", "phi"), (), ("phi", None))}
    assert [f["field"] for f in plain] == [{"TimeValue": t} for t in times]


def test_a_dataset_written_before_time_mechanics_is_exported_the_same(run3d, with_mechanics, tmp_path):
    """p and u on `time`, NaN where not solved (datasets written before `time_mechanics`): same files."""
    ds = with_mechanics(run3d, unsolved=1)
    old = on_output_times(ds)
    assert "time_mechanics" not in old.dims and np.isnan(old.p.values[1]).all()
    new, before = read_series(export(ds, tmp_path / "new", "vtu")), read_series(export(old, tmp_path / "old", "vtu"))
    for a, b in zip(new, before):
        np.testing.assert_array_equal(a.point_data["u"], b.point_data["u"])
        np.testing.assert_array_equal(a.cell_data["p"][0], b.cell_data["p"][0])
        assert a.field_data["mechanics_time"] == b.field_data["mechanics_time"]


def test_a_sweep_is_refused(tmp_path):
    ds = xr.Dataset({"phi": (("g", "time", "y", "x"), np.zeros((2, 1, 3, 3)))},
                    coords={"g": [1e8, 1e9], "time": [0.0], "y": [0.5, 1.5, 2.5], "x": [0.5, 1.5, 2.5]})
    with pytest.raises(ValueError, match="not a sweep"):
        export(ds, tmp_path, "vtu")


# ---- VTK image data, the default (issue 36.4) ---------------------------------------------------------------------

def image_arrays(path) -> dict:
    """Every array of a .vti as VTK reads it: cell and point arrays as numpy, field data as numbers, the grid."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    image = vtk_read(path)
    cells, points, field = image.GetCellData(), image.GetPointData(), image.GetFieldData()
    return {"cells": {cells.GetArrayName(i): vtk_to_numpy(cells.GetArray(i)) for i in range(cells.GetNumberOfArrays())},
            "points": {points.GetArrayName(i): vtk_to_numpy(points.GetArray(i))
                       for i in range(points.GetNumberOfArrays())},
            "field": {field.GetArrayName(i): field.GetArray(i).GetValue(0) for i in range(field.GetNumberOfArrays())},
            "dimensions": image.GetDimensions(), "spacing": image.GetSpacing(), "origin": image.GetOrigin(),
            "active": (cells.GetScalars().GetName() if cells.GetScalars() else None,
                       points.GetVectors().GetName() if points.GetVectors() else None)}


@pytest.mark.parametrize("shape", [(6, 5, 4), (7, 5)])
def test_image_data_holds_every_cell_and_node_of_the_dataset_exactly(tiny_run, with_mechanics, shape, tmp_path):
    """Read with VTK's reader: the grid's points (n + 1 per axis; 2-D one layer), spacing H and origin 0; every
    field bit for bit in the dataset's cell order (x fastest), obstacle cells NaN and flagged, u at every node."""
    ds = with_mechanics(tiny_run(shape, H), unsolved=1)
    paths = export(ds, tmp_path)
    assert [p.suffix for p in paths] == [".vti"] * ds.sizes["time"] + [".pvd"]
    solved = {0: 0, 1: 0, 2: 1}  # output -> its mechanics output shown
    for t, path in enumerate(paths[:-1]):
        found = image_arrays(path)
        assert found["dimensions"] == (*(n + 1 for n in shape), *([1] if len(shape) == 2 else []))
        assert found["spacing"] == (H, H, H) and found["origin"] == (0.0, 0.0, 0.0)
        assert sorted(found["cells"]) == ["alpha", "c", "nutrient_source", "obstacle", "p", "phi"]
        for name in ("phi", "c", "alpha"):
            np.testing.assert_array_equal(found["cells"][name], ds[name].values[t].ravel(), err_msg=name)
        np.testing.assert_array_equal(found["cells"]["p"], ds.p.values[solved[t]].ravel())
        np.testing.assert_array_equal(found["cells"]["obstacle"], ds.obstacle.values.ravel())
        np.testing.assert_array_equal(found["cells"]["nutrient_source"], ds.nutrient_source.values.ravel())
        assert np.isnan(found["cells"]["phi"][ds.obstacle.values.ravel() == 1]).all()
        u = ds.u.values[solved[t]].reshape(-1, len(shape))
        np.testing.assert_array_equal(found["points"]["u"][:, :len(shape)], u)
        assert found["points"]["u"].shape[1] == 3 and not found["points"]["u"][:, len(shape):].any()
        assert found["field"] == {"TimeValue": ds.time.values[t], "mechanics_time": ds.time_mechanics.values[solved[t]],
                                  "mechanics_solved": float(t != 1)}
        assert found["active"] == ("phi", "u")


def test_image_data_of_a_cell_is_where_its_coordinates_are(run3d, tmp_path):
    """VTK's own cell lookup: the cell holding a dataset cell's centre has that cell's phi (no axis mix-up)."""
    from vtkmodules.vtkCommonCore import reference

    image = vtk_read(export(run3d, tmp_path)[1])
    phi, values = image.GetCellData().GetArray("phi"), run3d.phi.values[1]
    for k, j, i in [(0, 0, 0), (3, 4, 5), (1, 2, 5), (3, 0, 2), (2, 3, 4)]:
        centre = [float(run3d[a].values[n]) for a, n in zip("xyz", (i, j, k))]
        cell = image.FindCell(centre, None, 0, 1e-9, reference(0), [0.0] * 3, [0.0] * 8)
        assert phi.GetValue(cell) == values[k, j, i] or np.isnan(values[k, j, i]) and np.isnan(phi.GetValue(cell))
    assert len(np.unique(values[np.isfinite(values)])) > 3  # the cells told apart differ


def test_image_data_is_the_default_and_a_run_without_mechanics_has_no_p_u_or_mechanics_fields(run3d, tmp_path):
    paths = export(run3d, tmp_path)
    found = [image_arrays(p) for p in paths[:-1]]
    assert {tuple(sorted(f["cells"])) for f in found} == {("alpha", "c", "nutrient_source", "obstacle", "phi")}
    assert [f["points"] for f in found] == [{}] * 3 and [f["field"] for f in found] == [
        {"TimeValue": t} for t in run3d.time.values]
    entries = ET.parse(paths[-1]).getroot().find("Collection").findall("DataSet")
    assert [e.get("file") for e in entries] == [p.name for p in paths[:-1]]


def test_an_image_larger_than_one_compressed_block_reads_back(tiny_run, tmp_path):
    """40 x 30 x 20 float64 cells: 192 kB, three zlib blocks and a partial one in VTK's header."""
    from biostudy.data import vtk_image

    ds = tiny_run((40, 30, 20), H).isel(time=[0])
    assert ds.phi.values[0].nbytes > 2 * vtk_image.BLOCK and ds.phi.values[0].nbytes % vtk_image.BLOCK
    found = image_arrays(export(ds, tmp_path)[0])
    np.testing.assert_array_equal(found["cells"]["phi"], ds.phi.values[0].ravel())


def test_a_snapshot_larger_than_a_read_whole_file_is_still_known_as_biostudys(run3d, tmp_path):
    """The mark is the first comment of every VTK file: found there however large the file (a 128³ snapshot is
    tens of MB), so a second export replaces the first; a file without it stays foreign."""
    from biostudy.data.claims import marked

    for format in ("vti", "vtu"):  # noqa: A001
        paths = export(run3d, tmp_path / format, format)
        assert all(marked(p, most=10) for p in paths[:-1]), format
    (tmp_path / "other.vti").write_bytes(b"<VTKFile>" + b" " * 5000 + b"<!-- written by biostudy 0.4 -->")
    assert not marked(tmp_path / "other.vti", most=10) and marked(tmp_path / "other.vti")
