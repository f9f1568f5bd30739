"""Pictures (`biostudy.plots`): the files a call makes, the cut sampler and the isosurface, exactly."""
import matplotlib.colors
import matplotlib.image
import numpy as np
import pytest
import xarray as xr
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from biostudy.plots import plot
from biostudy.plots.cuts import axis_plane, cell_axes, diagonal_plane, plane_for, sample
from biostudy.plots.isosurface import isosurface
from biostudy.plots.style import axis_label, colour_scale, on_scale
from biostudy.plots.sweep import cases, roles
from solver.output import on_output_times


@pytest.fixture(scope="module")
def run3d(tiny_run):
    return tiny_run((8, 8, 8))


@pytest.fixture(scope="module")
def run2d(tiny_run):
    return tiny_run((16, 12))


def assert_pictures(paths, tags):
    """The files: one PNG per figure, named by its tag, readable."""
    assert [p.stem.rsplit("_", 1)[1] for p in paths] == tags
    for path in paths:
        assert path.suffix == ".png" and matplotlib.image.imread(path).ndim == 3


def coloured(collection, colour) -> bool:
    """Every face of a shaded surface has `colour`, darkened or not by the light."""
    faces = np.asarray(collection.get_facecolor())[:, :3]
    base = np.array(matplotlib.colors.to_rgb(colour))
    return faces.size > 0 and np.allclose(faces / faces.max(axis=1, keepdims=True), base / base.max(), atol=0.02)


def title_times(axes) -> list[str]:
    return [ax.get_title() for ax in axes]


def check_series(fig, ds, marks=()):
    """Mean phi and mean c over time (top), the biofilm volume (bottom), the chosen time marked."""
    top, bottom = fig.axes[:2]
    lines = {line.get_label(): line for line in top.lines}
    for name in ("phi_mean", "c_mean"):
        line = lines[ds[name].attrs["long_name"]]
        np.testing.assert_array_equal(line.get_xdata(), ds.time.values)
        np.testing.assert_array_equal(line.get_ydata(), ds[name].values)
    np.testing.assert_array_equal(bottom.lines[0].get_ydata(), ds.biofilm_volume.values)
    assert [line.get_xdata()[0] for line in bottom.lines[1:]] == list(marks)


def rows(fig, names, indices, ds):
    """The image panels by field: one row per field, one column per time, titled with the times."""
    panels = [ax for ax in fig.axes if ax.images]
    assert len(panels) == len(names) * len(indices)
    assert title_times(panels[: len(indices)]) == [f"T* = {ds.time.values[i]:.3g}" for i in indices]
    return {name: panels[r * len(indices):(r + 1) * len(indices)] for r, name in enumerate(names)}


def check_scales(by_field):
    """One colour scale per row: phi on [0, 1]; p centred on 0 and reaching the largest |p| shown."""
    for name, panels in by_field.items():
        norms = [ax.images[0].norm for ax in panels]
        assert len({(n.vmin, n.vmax) for n in norms}) == 1, name
        if name == "phi":
            assert (norms[0].vmin, norms[0].vmax) == (0.0, 1.0)
        if name == "p":
            shown = np.concatenate([np.ma.compressed(ax.images[0].get_array()) for ax in panels])
            assert norms[0].vcenter == 0 and norms[0].vmax == -norms[0].vmin == np.abs(shown).max()


@pytest.mark.parametrize("mechanics", [False, True])
def test_three_dimensional_run_gives_series_cut_and_isosurface(run3d, with_mechanics, tmp_path, mechanics, drawn,
                                                                monkeypatch):
    import biostudy.plots.isosurface as iso

    surfaces = []

    def recorded(field, level, centres):
        surfaces.append((field, level, iso_real(field, level, centres)))
        return surfaces[-1][2]

    iso_real = iso.isosurface
    monkeypatch.setattr(iso, "isosurface", recorded)
    ds = with_mechanics(run3d, unsolved=1) if mechanics else run3d
    paths = plot(ds, tmp_path / "run.png")
    assert_pictures(paths, ["series", "cut", "isosurface"])
    check_series(drawn["run_series.png"], ds)
    indices = [0, 1, 2]
    names = ["phi", "c", "p"] if mechanics else ["phi", "c"]
    by_field = rows(drawn["run_cut.png"], names, indices, ds)
    check_scales(by_field)
    if mechanics:  # p was not solved at output 1: the panel says so instead of looking like an obstacle
        notes = [[t.get_text() for t in ax.texts] for ax in by_field["p"]]
        assert notes == [[], ["mechanics not\nsolved at this time"], []]

    # the isosurface panels: phi >= 0.8 at each shown time, closed around every cell that reaches it
    views = [ax for ax in drawn["run_isosurface.png"].axes if ax.name == "3d"]
    assert title_times(views) == [f"T* = {ds.time.values[i]:.3g}" for i in indices]
    biofilm = [(field, mesh) for field, level, mesh in surfaces if level == iso.LEVEL]
    assert len(biofilm) == len(indices)
    h = float(ds.attrs["grid_spacing"])
    for view, index, (field, mesh) in zip(views, indices, biofilm):
        phi = ds.phi.transpose("time", "z", "y", "x").values[index]
        np.testing.assert_array_equal(field, phi)
        dense = np.argwhere(phi >= iso.LEVEL)[:, ::-1] * h + 0.5 * h  # (x, y, z) of the cell centres
        orange = [c for c in view.collections if isinstance(c, Poly3DCollection) and c.get_alpha() in (None, 1)
                  and coloured(c, iso.BIOFILM_COLOUR)]
        texts = [t.get_text() for t in view.texts]
        if dense.size:
            verts, faces = mesh
            assert len(orange) == 1 and len(orange[0].get_paths()) == len(faces)
            low, high = verts.min(axis=0), verts.max(axis=0)  # around every dense cell, within a cell of them
            assert (low <= dense.min(axis=0)).all() and (high >= dense.max(axis=0)).all()
            assert (low >= dense.min(axis=0) - h).all() and (high <= dense.max(axis=0) + h).all()
        else:
            assert mesh is None and not orange and texts == [f"nowhere φ ≥ {iso.LEVEL}"]


@pytest.mark.parametrize("mechanics", [False, True])
def test_two_dimensional_run_gives_series_and_maps(run2d, with_mechanics, tmp_path, mechanics, drawn):
    """A 2-D run's maps are its cells as they are: every pixel is a cell's value, obstacles masked grey."""
    ds = with_mechanics(run2d, unsolved=1) if mechanics else run2d
    assert_pictures(plot(ds, tmp_path / "run"), ["series", "maps"])
    check_series(drawn["run_series.png"], ds)
    indices = [0, 1, 2]
    names = ["phi", "c", "p"] if mechanics else ["phi", "c"]
    by_field = rows(drawn["run_maps.png"], names, indices, ds)
    check_scales(by_field)
    for name, panels in by_field.items():
        for ax, index in zip(panels, indices):
            shown = ax.images[0].get_array()
            field = on_output_times(ds)[name].transpose("time", "y", "x").values[index]
            assert (shown.mask == np.isnan(field)).all() and ds.obstacle.values.any()
            expected = np.maximum(field, ax.images[0].norm.vmin) if name == "c" else field  # c: log scale floor
            np.testing.assert_array_equal(shown.compressed(), expected[~np.isnan(field)])
            assert ax.images[0].get_extent() == [0.0, 16.0, 0.0, 12.0]


def test_options_choose_variable_time_and_cut(run3d, with_mechanics, tmp_path, drawn):
    """--variable p --time 0.02 --cut z=5.5: one panel of p at T* = 0.02 on the plane through the centres of
    the sixth cell layer, so the pixels at cell centres are those cells' values exactly."""
    ds = with_mechanics(run3d, unsolved=1)
    assert_pictures(plot(ds, tmp_path / "p.png", variable="p", time=0.02, cut="z=5.5"), ["series", "cut"])
    check_series(drawn["p_series.png"], ds, marks=[0.02])
    (panel,) = rows(drawn["p_cut.png"], ["p"], [2], ds)["p"]
    shown = panel.images[0].get_array()  # 33 x 33 samples, 4 per cell: a cell centre every 4th from the 2nd
    p = on_output_times(ds).p.transpose("time", "z", "y", "x").values[2, 5]
    centres = shown[2::4, 2::4]
    assert centres.shape == p.shape and (centres.mask == np.isnan(p)).all()
    np.testing.assert_allclose(centres.compressed(), p[~np.isnan(p)], rtol=0, atol=1e-12)
    assert_pictures(plot(ds, tmp_path / "phi.png", variable="phi", time=0.004, cut="x=1"),
                    ["series", "cut", "isosurface"])
    check_series(drawn["phi_series.png"], ds, marks=[0.0])  # the output nearest 0.004
    (panel,) = rows(drawn["phi_cut.png"], ["phi"], [0], ds)["phi"]
    assert panel.get_xlabel() == "y (µm)"


@pytest.mark.parametrize("options, message", [
    (dict(variable="u"), "unknown variable"),
    (dict(variable="pressure"), "unknown variable"),
    (dict(time=0.5), "outside the run"),
    (dict(time=-0.1), "outside the run"),
    (dict(cut="w=3"), "unknown cut"),
    (dict(cut="x=9"), "outside the domain"),
])
def test_bad_options_are_one_line_value_errors(run3d, tmp_path, options, message):
    with pytest.raises(ValueError, match=message) as error:
        plot(run3d, tmp_path / "bad.png", **options)
    assert "\n" not in str(error.value)
    assert not list(tmp_path.iterdir()), "nothing is drawn before the options are checked"


def test_a_cut_of_a_two_dimensional_run_is_refused(run2d, tmp_path):
    with pytest.raises(ValueError, match="3-D"):
        plot(run2d, tmp_path / "bad.png", cut="x=3")


def test_exhausted_nutrient_is_drawn_dark_not_grey_like_an_obstacle():
    c = np.array([[0.0, 0.02], [1.0, np.nan]])
    cmap, norm = colour_scale("c", c)
    shown = on_scale(c, norm)
    assert shown.mask.tolist() == [[False, False], [False, True]]  # only the obstacle is grey
    assert shown[0, 0] == norm.vmin and norm.vmax == 1.0
    cmap, norm = colour_scale("p", np.array([-3.0, 1.0, np.nan]))
    assert norm(0.0) == 0.5 and norm(-3.0) == 0.0 and norm(3.0) == 1.0  # centred: blue < 0 < red


def sweep_dataset(zip_mode=False):
    """A combined dataset as a sweep writes it: dims (g, r, time) or (case, time); one case failed."""
    time = np.linspace(0, 1, 6)
    g, r = np.array([1e8, 1e9, 1e10]), np.array([50.0, 100.0])
    G, R, T = np.meshgrid(g, r, time, indexing="ij")
    phi = 0.1 + 0.3 * (1 - np.exp(-R / 50 * T)) * (1e8 / G) ** 0.1
    c = 0.6 * np.exp(-3 * T) + 0.05 * np.log10(G / 1e7)
    phi[2, 1, 3:] = c[2, 1, 3:] = np.nan
    status = np.array([["ok", "ok"], ["ok", "ok"], ["ok", "failed"]])
    ds = xr.Dataset(
        {"phi_mean": (("g", "r", "time"), phi, {"units": "1", "long_name": "mean biofilm density"}),
         "c_mean": (("g", "r", "time"), c, {"units": "1", "long_name": "mean nutrient concentration"}),
         "biofilm_volume": (("g", "r", "time"), 8000 * phi,
                            {"units": "um^3", "long_name": "volume with phi >= 0.5"}),
         "status": (("g", "r"), status)},
        coords={"g": ("g", g, {"units": "1/T*"}), "r": ("r", r, {"units": "um/T*"}), "time": time})
    if zip_mode:
        ds = ds.stack(case=("g", "r")).reset_index("case").transpose("case", "time")
        ds = ds.assign_coords(case=[f"case-{i}" for i in range(ds.sizes["case"])])
    return ds


@pytest.mark.parametrize("zip_mode", [False, True])
def test_sweep_gives_outputs_against_parameters_and_every_series(tmp_path, zip_mode, drawn):
    """Outputs at one time against g, one line per r, the failed case crossed on the axis; and every
    case's time series."""
    grid = sweep_dataset()
    paths = plot(sweep_dataset(zip_mode), tmp_path / "study.png")
    assert_pictures(paths, ["sweep", "series"])
    one = plot(sweep_dataset(zip_mode), tmp_path / "volume.png", variable="biofilm_volume", time=0.4)
    assert_pictures(one, ["sweep", "series"])
    for figure, names, index in (("study", ["phi_mean", "c_mean", "biofilm_volume"], -1),
                                 ("volume", ["biofilm_volume"], 2)):
        panels = drawn[f"{figure}_sweep.png"].axes
        assert [ax.get_ylabel() for ax in panels] == [axis_label(grid[n]) for n in names]
        for ax, name in zip(panels, names):
            lines = {line.get_label(): line for line in ax.lines}
            assert ax.get_xscale() == "log" and set(lines) == {"r = 50", "r = 100", "failed"}
            for k, r in enumerate((50, 100)):
                np.testing.assert_array_equal(lines[f"r = {r}"].get_xdata(), [1e8, 1e9, 1e10])
                np.testing.assert_array_equal(lines[f"r = {r}"].get_ydata(), grid[name].values[:, k, index])
            assert list(lines["failed"].get_xdata()) == [1e10]
        series = drawn[f"{figure}_series.png"].axes
        for ax, name in zip(series, names):  # every case's points that have a value (the failed case's first 3)
            drawn_series = sorted(tuple(line.get_ydata()) for line in ax.lines)
            values = [grid[name].values[i, k] for i in range(3) for k in range(2)]
            assert drawn_series == sorted(tuple(v[np.isfinite(v)]) for v in values)
    with pytest.raises(ValueError, match="unknown variable"):
        plot(sweep_dataset(zip_mode), tmp_path / "bad.png", variable="phi")
    with pytest.raises(ValueError, match="no fields"):
        plot(sweep_dataset(zip_mode), tmp_path / "bad.png", cut="diagonal")


def test_series_of_an_observable_solved_at_some_outputs_draws_those_points(tmp_path, drawn):
    """compression_max is NaN between the outputs where the mechanics was solved: a plain line through NaN draws
    nothing, so the solved points are drawn, with markers."""
    ds = sweep_dataset()
    pressure = 10.0 * ds.phi_mean.where(xr.DataArray(np.arange(6) % 2 == 0, dims="time"))  # solved every 2nd
    ds["compression_max"] = pressure.assign_attrs(units="Pa", long_name="largest compression")
    plot(ds, tmp_path / "study.png", variable="compression_max")
    (ax,) = drawn["study_series.png"].axes
    assert len(ax.lines) == 6
    for line in ax.lines:
        assert line.get_marker() == "o" and len(line.get_xdata()) in (3, 2)  # t = 0, 0.4, 0.8 (failed: 2 left)
        np.testing.assert_allclose(np.asarray(line.get_xdata()) % 0.4, 0, atol=1e-12)


def test_zip_parameters_that_change_together_are_one_line_not_many():
    found, varying = cases(sweep_dataset(zip_mode=True).isel(case=[0, 3, 5]), ["phi_mean"])
    assert varying == ["g", "r"] and [c.params for c in found][1] == {"g": 1e9, "r": 100.0}
    assert roles(found, varying) == ("g", [], ["r"])  # r follows g: named on the axis
    found, varying = cases(sweep_dataset(zip_mode=True), ["phi_mean"])
    assert roles(found, varying) == ("g", ["r"], [])  # every (g, r): one line per r
    assert [c.ok for c in found] == [True] * 5 + [False]


def linear_field_dataset(shape=(9, 7, 5), h=0.5, source=None):
    """Cell centres of a (nx, ny, nz) grid with f = 1 + 2x - 3y + 0.5z, and a nutrient source mask."""
    x, y, z = ((np.arange(n) + 0.5) * h for n in shape)
    Z, Y, X = np.meshgrid(z, y, x, indexing="ij")
    mask = np.zeros(Z.shape, np.int8) if source is None else source(X, Y, Z).astype(np.int8)
    cells = ("z", "y", "x")
    return xr.Dataset({"f": (cells, 1 + 2 * X - 3 * Y + 0.5 * Z), "nutrient_source": (cells, mask)},
                      coords={"x": x, "y": y, "z": z})


def exact(points):
    return 1 + 2 * points[..., 0] - 3 * points[..., 1] + 0.5 * points[..., 2]


def test_diagonal_cut_points_toward_the_source_and_samples_a_linear_field_exactly():
    ds = linear_field_dataset(source=lambda X, Y, Z: (X > 3.6) & (Y < 0.6) & (Z > 1.9))
    plane = diagonal_plane(ds)
    centre = np.array([2.25, 1.75, 1.25])
    source = np.array([np.mean([3.75, 4.25]), 0.25, 2.25])  # centroid of the source cells
    direction = (source - centre)[:2] / np.linalg.norm((source - centre)[:2])
    assert np.allclose(plane.along[:2], direction) and plane.along[2] == 0 and plane.up.tolist() == [0, 0, 1]
    assert np.allclose(plane.origin[:2], centre[:2])
    assert not plane.flip_up  # the source is above the centre: top right as drawn
    ends = [plane.origin + s * plane.along for s in plane.s_range]  # both ends on the box
    assert all(np.isclose(e[0], 0) or np.isclose(e[0], 4.5) or np.isclose(e[1], 0) or np.isclose(e[1], 3.5)
               for e in ends)
    assert plane.s_range[0] < 0 < plane.s_range[1] and plane.t_range == (0.0, 2.5)

    s, t, points = plane.grid(0.05)
    values = sample(ds["f"].values, cell_axes(ds), points)
    x, y, z = cell_axes(ds)
    inside = ((points[..., 0] >= x[0]) & (points[..., 0] <= x[-1]) & (points[..., 1] >= y[0])
              & (points[..., 1] <= y[-1]) & (points[..., 2] >= z[0]) & (points[..., 2] <= z[-1]))
    assert inside.sum() > 100
    assert np.allclose(values[inside], exact(points[inside]), rtol=0, atol=1e-12)
    # between the outermost centres and the wall the field is held (zero flux): the nearest centre's plane
    clamped = np.stack([np.clip(points[..., k], c[0], c[-1]) for k, c in enumerate((x, y, z))], axis=-1)
    assert np.allclose(values, exact(clamped), rtol=0, atol=1e-12)


def test_cut_falls_back_to_the_xy_diagonal_and_flips_for_a_source_below():
    centred = diagonal_plane(linear_field_dataset(source=lambda X, Y, Z: Z < 0.3))  # a bottom layer
    assert np.allclose(centred.along[:2], np.array([4.5, 3.5]) / np.hypot(4.5, 3.5)) and not centred.flip_up
    low = diagonal_plane(linear_field_dataset(source=lambda X, Y, Z: (X < 0.3) & (Z < 0.3)))
    assert np.allclose(low.along, [-1, 0, 0]) and low.flip_up
    assert np.allclose(plane_for(linear_field_dataset(), "xy-diagonal").along, centred.along)


def test_axis_cut_is_exact_and_obstacles_are_not_interpolated():
    ds = linear_field_dataset()
    plane = axis_plane(ds, "z", 1.1)
    _, _, points = plane.grid(0.25)
    values = sample(ds["f"].values, cell_axes(ds), points)
    assert np.allclose(points[..., 2], 1.1)
    x, y = points[..., 0], points[..., 1]
    inner = (x >= 0.25) & (x <= 4.25) & (y >= 0.25) & (y <= 3.25)  # within the outermost centres
    assert np.allclose(values[inner], exact(points[inner]), atol=1e-12)
    field = ds["f"].values.copy()
    field[:, :, :3] = np.nan  # obstacle cells x < 1.5
    values = sample(field, cell_axes(ds), points)
    assert np.isnan(values[points[..., 0] < 1.2]).all()
    far = points[..., 0] >= 1.75  # weights entirely on open cells: still exact
    assert np.allclose(values[far & inner], exact(points[far & inner]), atol=1e-12)


def surface_area(verts: np.ndarray, faces: np.ndarray) -> float:
    """Sum of the triangle areas (µm²)."""
    a, b, c = (verts[faces[:, i]] for i in range(3))
    return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


def test_isosurface_of_a_sphere_has_its_radius_area_and_centre():
    h, shape, centre, radius = 0.5, (30, 26, 22), np.array([7.3, 6.4, 5.6]), 4.0
    x, y, z = ((np.arange(n) + 0.5) * h for n in shape)
    Z, Y, X = np.meshgrid(z, y, x, indexing="ij")
    r = np.sqrt((X - centre[0]) ** 2 + (Y - centre[1]) ** 2 + (Z - centre[2]) ** 2)
    phi = np.clip(0.8 + (radius - r) / 4, 0, 1)  # phi = 0.8 exactly on the sphere
    verts, faces = isosurface(phi, 0.8, (x, y, z))
    distance = np.linalg.norm(verts - centre, axis=1)
    assert abs(distance.mean() - radius) < 0.01 * radius and distance.std() < 0.01 * radius
    assert abs(verts.mean(axis=0) - centre).max() < 0.05  # an axis mix-up would be off by >= 0.8 µm
    assert surface_area(verts, faces) == pytest.approx(4 * np.pi * radius**2, rel=0.03)


def test_isosurface_of_a_body_on_a_wall_is_closed_on_the_wall():
    x, y, z = ((np.arange(n) + 0.5) for n in (6, 5, 4))
    phi = np.zeros((4, 5, 6))
    phi[:, :, :3] = 1.0  # biofilm fills x < 3 and touches five walls
    verts, faces = isosurface(phi, 0.8, (x, y, z))
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, count = np.unique(edges, axis=0, return_counts=True)
    assert (count == 2).all(), "every edge between exactly two triangles: a closed surface"
    on = dict(abs=1e-6)  # marching cubes works in single precision
    assert verts[:, 0].min() == pytest.approx(0, **on) and verts[:, 0].max() == pytest.approx(2.7, **on)
    assert verts[:, 1].max() == pytest.approx(5, **on) and verts[:, 2].min() == pytest.approx(0, **on)
    assert isosurface(np.full((4, 5, 6), 0.5), 0.8, (x, y, z)) is None


def test_warped_two_dimensional_mesh_is_the_grid_moved_by_factor_u(run2d, with_mechanics):
    """Fig. 13: every corner of a biofilm cell (phi >= 0.5) drawn at node + factor * u (u known exactly here), phi
    as the cell colour; the void's cells left out (at x 500 their soft cells fold into a tangle)."""
    from matplotlib.collections import PolyCollection

    from biostudy.plots import warped

    ds = on_output_times(with_mechanics(run2d, unsolved=1))  # as plot() hands it on: p and u per output
    assert warped.solved_indices(ds, [1]) in ([0], [2])  # not solved at 1: the nearest solved output
    fig = warped.figure(ds, [2], 500.0)
    mesh = next(c for c in fig.axes[0].collections if isinstance(c, PolyCollection))
    u = ds.u.isel(time=2).transpose("y_node", "x_node", "component").values
    x, y = np.meshgrid(ds.x_node.values, ds.y_node.values)
    moved = np.stack([x + 500.0 * u[..., 0], y + 500.0 * u[..., 1]], axis=-1)  # (ny+1, nx+1, 2)
    phi = ds.phi.isel(time=2).transpose("y", "x").values
    biofilm = np.argwhere(np.nan_to_num(phi) >= 0.5)  # (j, i) of each drawn cell, in order
    assert len(mesh.get_paths()) == len(biofilm) > 0
    for path, (j, i) in zip(mesh.get_paths(), biofilm):
        assert np.allclose(path.vertices[:4], [moved[j, i], moved[j, i + 1], moved[j + 1, i + 1], moved[j + 1, i]])
    assert np.allclose(mesh.get_array(), phi[np.nan_to_num(phi) >= 0.5])


def test_warped_panels_share_axes_and_size_and_say_when_cells_fold(run2d, with_mechanics):
    from biostudy.plots import warped

    ds = on_output_times(with_mechanics(run2d))
    fig = warped.figure(ds, [0, 1, 2], 500.0)  # u ~ N(0, 1) µm here: x 500 folds cells of 0.5 µm
    fig.canvas.draw()
    panels = [ax for ax in fig.axes if ax.get_title().startswith("T* =")]
    assert len(panels) == 3
    assert len({ax.get_xlim() for ax in panels}) == 1 and len({ax.get_ylim() for ax in panels}) == 1
    sizes = {(round(ax.get_position().width, 4), round(ax.get_position().height, 4)) for ax in panels}
    assert len(sizes) == 1
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    for ax in panels:  # every label inside the figure
        for label in (ax.xaxis.label, ax.yaxis.label):
            if label.get_text():
                extent = label.get_window_extent(renderer)
                assert extent.x0 >= box.x0 - 1 and extent.x1 <= box.x1 + 1 and extent.y0 >= box.y0 - 1
    assert "cells fold over at this magnification" in " ".join(fig._suptitle.get_text().split())
    assert "fold" not in warped.figure(ds, [0], 1e-6)._suptitle.get_text()


def test_warped_refuses_runs_without_solved_mechanics(run2d, with_mechanics, tmp_path):
    from biostudy.plots import warped

    with pytest.raises(ValueError, match="with mechanics"):
        plot(run2d, tmp_path / "w.png", warp=500)
    every = on_output_times(with_mechanics(run2d))
    every["u"][:, :2, :2] = np.nan  # nodes inside a rigid obstacle have no u: still solved
    assert list(warped.solved_indices(every, [0, 1, 2])) == [0, 1, 2]
    every["u"][:] = np.nan
    with pytest.raises(ValueError, match="not solved at any output"):
        plot(every, tmp_path / "w.png", warp=500)
    with pytest.raises(ValueError, match="positive"):
        plot(with_mechanics(run2d), tmp_path / "w.png", warp=-1)


def test_warped_three_dimensional_surface_moves_with_u(run3d, with_mechanics, tmp_path):
    """u = 0.01 X (linear, so trilinear interpolation is exact) moves every surface vertex to X + factor u(X)."""
    from biostudy.plots import warped

    ds = with_mechanics(run3d)
    # (z, y, x, 3): x, y, z
    nodes = np.stack(np.meshgrid(ds.z_node, ds.y_node, ds.x_node, indexing="ij")[::-1], axis=-1)
    ds["u"][:] = 0.01 * nodes
    vertices = np.array([[0.3, 1.7, 2.2], [5.9, 4.1, 0.0], [8.0, 8.0, 8.0]])
    assert np.allclose(warped.displaced_vertices(on_output_times(ds), 0, vertices, 500.0), vertices * (1 + 500 * 0.01))
    assert [p.name for p in plot(ds, tmp_path / "w.png", warp=500)][-1] == "w_warped.png"
