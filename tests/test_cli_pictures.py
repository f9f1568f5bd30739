"""`biostudy plot` and `biostudy export` through the command line: what is drawn and written is the run's."""
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import xarray as xr
from test_cli import invoke
from test_plot import check_series, rows


def test_plot_and_export_a_run(tiny_scene, tmp_path, drawn):
    run = tmp_path / "tiny.nc"
    assert invoke("run", tiny_scene, "-o", run, "-q").exit_code == 0
    result = invoke("plot", run, "-o", tmp_path / "fig.png")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.glob("fig_*.png")) == ["fig_maps.png", "fig_series.png"]
    ds = xr.open_dataset(run)
    check_series(drawn["fig_series.png"], ds)
    maps = rows(drawn["fig_maps.png"], ["phi", "c"], [0, 1, 2], ds)
    for ax, index in zip(maps["phi"], [0, 1, 2]):  # every cell as it is in the file, obstacles masked
        shown, phi = ax.images[0].get_array(), ds.phi.values[index]
        assert (shown.mask == np.isnan(phi)).all()
        np.testing.assert_array_equal(shown.compressed(), phi[~np.isnan(phi)])

    result = invoke("export", run, tmp_path / "vti")  # the default: VTK image data
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "vti").iterdir()) == ["series.pvd", *(f"snapshot_000{t}.vti" for t in
                                                                                    range(3))]
    result = invoke("export", run, tmp_path / "vtk", "--format", "vtu")
    assert result.exit_code == 0, result.output
    snapshots = sorted((tmp_path / "vtk").glob("snapshot_*.vtu"))
    assert len(snapshots) == 3
    collection = ET.parse(tmp_path / "vtk" / "series.pvd").getroot().find("Collection")
    assert [float(d.get("timestep")) for d in collection] == ds.time.values.tolist()
    assert [d.get("file") for d in collection] == [p.name for p in snapshots]
    last = meshio.read(snapshots[-1])
    open_cells = ~ds.obstacle.values.astype(bool)
    assert last.cells[0].data.shape == (open_cells.sum(), 4)  # quadrilaterals of the open cells only
    np.testing.assert_array_equal(last.cell_data["phi"][0], ds.phi.values[-1][open_cells])
    np.testing.assert_array_equal(last.cell_data["nutrient_source"][0], ds.nutrient_source.values[open_cells])


def test_plot_bad_option_is_one_line_exit_2(tiny_scene, tmp_path):
    run = tmp_path / "tiny.nc"
    invoke("run", tiny_scene, "-o", run, "-q")
    for option in (["--variable", "u"], ["--time", "5"], ["--cut", "x=3"]):
        result = invoke("plot", run, *option)
        assert result.exit_code == 2, option
        assert result.stderr.startswith(f"error: {run}: ") and result.stderr.count("\n") == 1, result.stderr
        assert "Traceback" not in result.output


def test_plot_a_sweep_directory(tiny_study, tmp_path, drawn):
    assert invoke("sweep", tiny_study, "-o", tmp_path / "sweep", "-q").exit_code == 0
    result = invoke("plot", tmp_path / "sweep", "-o", tmp_path / "sweep.png")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "sweep_sweep.png").is_file() and (tmp_path / "sweep_series.png").is_file()
    study = xr.open_dataset(tmp_path / "sweep" / "study.nc")
    phi_panel = drawn["sweep_sweep.png"].axes[0]  # final mean phi against g, one line per r
    lines = {line.get_label(): line for line in phi_panel.lines}
    for r in (50, 100):
        np.testing.assert_array_equal(lines[f"r = {r}"].get_xdata(), [1e8, 1e9])
        np.testing.assert_array_equal(lines[f"r = {r}"].get_ydata(), study.phi_mean.sel(r=r).isel(time=-1).values)
