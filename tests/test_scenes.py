"""The paper's section-4 scenes, shortened: each qualitative finding as a measured quantity.

Every scene is loaded from `studies/` with overrides that cut the cost (time,
grid or mechanics), so what is tested is the bundled file itself.
"""
import numpy as np
import pytest

from biostudy import catalog
from biostudy.scene import load_scene
from solver import simulate


def run(name, *overrides):
    scene = load_scene(catalog.resolve(name), overrides)
    return scene, simulate(scene.problem())


def test_directional_growth_moves_toward_the_nutrient_corner():
    """4.1: along the diagonal toward the source corner, the dense biofilm (phi >= 0.5) advances
    at least 1.5 times as far at the front as at the back."""
    scene, ds = run("directional", "time.t_end=0.3", "time.steps=75", "time.outputs=2", "mechanics.enabled=false")
    x, y, z = scene.grid.solver_grid().cell_coordinates()
    diagonal = (x + y + z - 30) / np.sqrt(3)  # µm from the centre toward the corner
    start, end = ds.phi.values[0], ds.phi.values[-1]
    toward = diagonal[end >= 0.5].max() - diagonal[start >= 0.5].max()
    back = diagonal[start >= 0.5].min() - diagonal[end >= 0.5].min()
    assert toward > 1.5 * back > 0, (toward, back)


def test_agar_higher_consumption_grows_a_lower_wider_layer():
    """4.2: g = 1e10 keeps the biofilm lower and flatter than g = 1e8 (phi-weighted height above the
    agar and the ratio of lateral spread to height), at every output after the start."""
    shape = []
    for name in ("agar-g1e8", "agar-g1e10"):
        scene, ds = run(name, "time.t_end=0.4", "time.steps=100", "time.outputs=5", "mechanics.enabled=false")
        x, y, z = scene.grid.solver_grid().cell_coordinates()
        heights, aspects = [], []
        for phi in ds.phi.values[1:]:
            w = phi / phi.sum()
            height = (w * (z - 1.0)).sum()  # above the agar layer
            lateral = np.sqrt((w * ((x - 10) ** 2 + (y - 10) ** 2)).sum())
            heights.append(height)
            aspects.append(lateral / height)
        shape.append((np.array(heights), np.array(aspects)))
    (tall_h, tall_a), (flat_h, flat_a) = shape
    assert np.all(flat_h < 0.8 * tall_h), (flat_h, tall_h)
    assert np.all(flat_a > 1.15 * tall_a), (flat_a, tall_a)


def test_obstacles_hold_no_biofilm_and_the_biofilm_passes_around_them():
    """4.3: obstacle cells are NaN at every output (never biofilm); biofilm arrives behind the column
    that blocks the straight way to the nutrient side, which it can only reach around the column."""
    scene, ds = run("obstacles", "time.t_end=0.3", "time.steps=75", "time.outputs=4", "mechanics.enabled=false")
    problem = scene.problem()
    phi = ds.phi.values
    assert np.all(np.isnan(phi[:, problem.obstacle])) and np.all(np.isfinite(phi[:, ~problem.obstacle]))
    x, y, z = problem.grid.cell_coordinates()
    behind = (x > 25.5) & (np.abs(y - 15) < 2.5)  # in the shadow of the column at x = 23 +- 2.5
    dense = phi >= 0.5
    assert not dense[0][behind].any()
    assert dense[-1][behind].sum() > 50, dense[-1][behind].sum()


def test_grate_splits_the_front_and_it_recombines():
    """4.5: in the obstacle-free rows between the bars the front arrives as several fingers
    (two or more separate runs of phi >= 0.5 in a row) and later fills the row (one run)."""
    scene, ds = run("grate", "grid.shape=[50,75]", "grid.spacing=4.0", "time.steps=200", "mechanics.enabled=false")
    phi = ds.phi.values
    grate = scene.obstacle[0]
    y = scene.grid.solver_grid().cell_coordinates()[1][:, 0]
    rows = np.flatnonzero(~np.isnan(phi[0]).any(axis=1) & (y > grate.lower[1]) & (y < grate.upper[1]))
    assert rows.size >= 5

    def runs(row):
        dense = row >= 0.5
        return int(dense[0]) + int(np.count_nonzero(dense[1:] & ~dense[:-1]))

    counts = np.array([[runs(phi[t, j]) for j in rows] for t in range(ds.sizes["time"])])
    assert counts.max() >= 3, counts  # split into fingers between the bars
    assert np.all(counts[-1] == 1) and np.all(phi[-1][rows] >= 0.5), counts[-1]  # recombined


def test_maze_biofilm_finds_the_way_to_the_centre():
    """4.4 (4 µm cells): the biofilm nearest the centre gets closer, reaching the innermost ring;
    it stays out of the sectors off the way in; and where it passed and exhausted the nutrient
    (the entrance) it recedes."""
    scene, ds = run("maze", "grid.shape=[140,140]", "grid.spacing=4.0", "time.steps=300", "time.outputs=9",
                    "mechanics.enabled=false")
    maze = scene.obstacle[0].layout()
    x, y = scene.grid.solver_grid().cell_coordinates()
    radius = np.hypot(x - maze.center[0], y - maze.center[1])
    phi, c = ds.phi.values, ds.c.values
    nearest = np.array([radius[p >= 0.5].min() for p in phi])
    assert nearest[0] > 250 and np.all(np.diff(nearest) < 5), nearest
    assert nearest[-1] < maze.radii[1], (nearest[-1], maze.radii)  # in the innermost ring corridor

    sector, names, way = maze.sector(x, y), maze.sectors(), maze.path()
    off_way = np.isin(sector, [names.index(s) for s in names if s not in way])
    stray = np.nansum(phi[:, off_way], axis=1) / np.nansum(phi, axis=(1, 2))
    assert stray.max() < 0.1, stray  # measured: none until the last tenth, then 3 % near the core
    entrance = sector == names.index(way[0])
    dense = np.count_nonzero(phi[:, entrance] >= 0.5, axis=1)
    assert dense[0] > 10 and dense[-1] == 0, dense
    assert np.nanmean(c[-1][entrance]) < 0.7 * np.nanmean(c[0][entrance])


@pytest.mark.parametrize("name", ["directional", "agar-g1e8", "agar-g1e10", "obstacles", "maze", "grate"])
def test_paper_scenes_use_the_papers_parameters(name):
    scene = load_scene(catalog.resolve(name))
    params = scene.params
    if name in ("maze", "grate"):  # Table 6
        assert (params.d, params.beta, params.k_alpha, params.r) == (1e13, 10.0, 1e-6, 200.0)
        assert scene.grid.solver_grid().ndim == 2
    else:  # Table 2
        assert (params.d, params.beta, params.k_alpha, params.r, params.mu, params.nu) == (1e10, 2.0, 1e-3, 100.0,
                                                                                           3.3557, 0.49)
    assert scene.numerics.advection == "tvd"
    assert scene.mechanics is not None and scene.mechanics.enabled


def test_agar_scenes_differ_only_in_consumption():
    a, b = (load_scene(catalog.resolve(n)).model_dump() for n in ("agar-g1e8", "agar-g1e10"))
    assert (a["params"]["g"], b["params"]["g"]) == (1e8, 1e10)
    for scene in (a, b):
        del scene["params"]["g"], scene["name"], scene["description"]
    assert a == b
