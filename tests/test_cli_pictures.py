"""`biostudy plot` and `biostudy export` through the command line."""
import meshio

from test_cli import invoke


def test_plot_and_export_a_run(tiny_scene, tmp_path):
    run = tmp_path / "tiny.nc"
    assert invoke("run", tiny_scene, "-o", run, "-q").exit_code == 0
    result = invoke("plot", run, "-o", tmp_path / "fig.png")
    assert result.exit_code == 0, result.output
    pictures = sorted(p.name for p in tmp_path.glob("fig_*.png"))
    assert pictures == ["fig_maps.png", "fig_series.png"]
    assert all((tmp_path / p).stat().st_size > 10_000 for p in pictures)

    result = invoke("export", run, tmp_path / "vtk")
    assert result.exit_code == 0, result.output
    snapshots = sorted((tmp_path / "vtk").glob("snapshot_*.vtu"))
    assert len(snapshots) == 3 and (tmp_path / "vtk" / "series.pvd").is_file()
    assert "phi" in meshio.read(snapshots[-1]).cell_data


def test_plot_bad_option_is_one_line_exit_2(tiny_scene, tmp_path):
    run = tmp_path / "tiny.nc"
    invoke("run", tiny_scene, "-o", run, "-q")
    for option in (["--variable", "u"], ["--time", "5"], ["--cut", "x=3"]):
        result = invoke("plot", run, *option)
        assert result.exit_code == 2, option
        assert result.stderr.startswith(f"error: {run}: ") and result.stderr.count("\n") == 1, result.stderr
        assert "Traceback" not in result.output


def test_plot_a_sweep_directory(tiny_study, tmp_path):
    assert invoke("sweep", tiny_study, "-o", tmp_path / "sweep", "-q").exit_code == 0
    result = invoke("plot", tmp_path / "sweep", "-o", tmp_path / "sweep.png")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "sweep_sweep.png").is_file() and (tmp_path / "sweep_series.png").is_file()
