"""The paper's section-4 scenes, shortened: each statement of the paper as a measured dense quantity.

Every scene is loaded from `studies/` with overrides that cut the cost (steps, grid or mechanics), so what is
tested is the bundled file itself.  "Dense" is the paper's own isosurface level phi >= 0.8 (Figs. 3, 10); the
biofilm's extent is phi >= 0.5 (the dataset's biofilm_volume).  Thresholds are the paper's orderings and the
physics' bounds (a front moves at most r c/(k+c) < r/2 per unit T*), never this code's output.
docs/paper.md has the full-length measurements beside the paper's statements.
"""
import numpy as np
import pytest
from scipy import ndimage

from biostudy.inputs import bundled
from biostudy.inputs.scene import load_scene
from biostudy.quantities import dead_ends, measures
from solver import simulate

DENSE, EXTENT = measures.DENSE, measures.THRESHOLD


def run(name, *overrides):
    scene = load_scene(bundled.resolve(name), ["mechanics.enabled=false", *overrides])
    return scene, simulate(scene.problem())


def advance(ds, direction, level, centre):
    """How far the region phi >= level reaches along `direction` (x, y, z) from `centre`, minus at T* = 0."""
    z, y, x = np.meshgrid(ds.z.values, ds.y.values, ds.x.values, indexing="ij")
    along = (x - centre[0]) * direction[0] + (y - centre[1]) * direction[1] + (z - centre[2]) * direction[2]
    along /= np.linalg.norm(direction)
    reach = np.array([along[phi >= level].max() for phi in ds.phi.values])
    return reach - reach[0]


def test_directional_biofilm_stays_dense_and_grows_toward_the_corner_then_backward_then_sideways():
    """4.1: dense biofilm throughout (the paper's phi >= 0.8 renders at every time) whose volume increases;
    it "evolves toward the corner with nutrient source", grows "also ... in this direction", the opposite one
    ("a slight egg-like shape"), and least on the sides; "the whole domain would fill up if continued": phi's
    mean still rises at T* = 1.  No part of it outruns the front-speed bound r/2."""
    scene, ds = run("directional", "time.steps=250")
    assert np.all(measures.phi_max(ds) >= DENSE)
    dense = measures.volume(ds)
    assert dense[-1] > dense[0] and np.all(measures.volume(ds, EXTENT) >= dense[0])
    centre, time = (10.0, 10.0, 10.0), ds.time.values
    toward, back = advance(ds, (1, 1, 1), EXTENT, centre), advance(ds, (-1, -1, -1), EXTENT, centre)
    side = advance(ds, (1, -1, 0), EXTENT, centre)
    assert toward[-1] > back[-1] > side[-1] > 0, (toward[-1], back[-1], side[-1])
    speed = scene.params.r / (scene.params.k + 1)  # r c/(k+c) at its largest, c <= 1
    assert np.all(toward <= speed * time + np.sqrt(3) * scene.grid.spacing)
    assert ds.phi_mean.values[-1] > ds.phi_mean.values[-2]


@pytest.fixture(scope="module")
def agar():
    """Both agar scenes (g = 1e8 and 1e10) to T* = 1 with 250 steps."""
    return {g: run(f"agar-g{g}", "time.steps=250") for g in ("1e8", "1e10")}


def test_agar_low_consumption_grows_a_dense_colony_to_the_lid(agar):
    """4.2, g = 1e8: the colony "grows much higher, filling the entire discretized cube": dense biofilm
    (phi >= 0.8) reaches the lid, and stays dense; not faster than the front-speed bound r/2 allows."""
    scene, ds = agar["1e8"]
    top = measures.height(ds, "z", DENSE)
    height = scene.grid.solver_grid().extent[2]
    assert top[-1] >= height - scene.grid.spacing and np.all(measures.phi_max(ds) >= DENSE), top
    rise = measures.height(ds, "z", EXTENT) - measures.height(ds, "z", EXTENT)[0]
    speed = scene.params.r / (scene.params.k + 1)  # r c/(k+c) at its largest, c <= 1
    assert np.all(rise <= speed * ds.time.values + scene.grid.spacing), rise


def test_agar_high_consumption_stays_low_and_spreads_into_a_layer(agar):
    """4.2, g = 1e10: "grows only to a certain height, after which the biofilm fills out the edges ... forming
    a biofilm layer at the bottom": lower than the g = 1e8 colony at every output, no higher at the end than
    at T* = 0.5 (within a cell), wider than tall, and dense; its nutrient plateau "significantly" below."""
    (_, tall), (scene, low) = agar["1e8"], agar["1e10"]
    top, tall_top = measures.height(low, "z", EXTENT), measures.height(tall, "z", EXTENT)
    assert np.all(top[1:] < tall_top[1:]), (top, tall_top)
    half = int(np.argmin(np.abs(low.time.values - 0.5)))
    assert top[-1] - top[half] < scene.grid.spacing, top
    assert 2 * measures.reach(low, "z", EXTENT)[-1] > top[-1]
    assert measures.phi_max(low)[-1] >= DENSE
    assert np.all(low.c_mean.values[1:] < tall.c_mean.values[1:])


def test_obstacles_hold_no_biofilm_and_the_dense_biofilm_closes_behind_the_column():
    """4.3: obstacle cells are NaN at every output (never biofilm); "the biofilm then quickly grows around the
    rigid columns and reconnects": dense biofilm reaches the shadow of the column that blocks the straight way
    to the nutrient side, and there it is one connected body with the colony."""
    scene, ds = run("obstacles", "time.t_end=0.5", "time.steps=125", "time.outputs=3")
    problem = scene.problem()
    phi = ds.phi.values
    assert np.all(np.isnan(phi[:, problem.obstacle])) and np.all(np.isfinite(phi[:, ~problem.obstacle]))
    x, y, z = problem.grid.cell_coordinates()
    behind = (x > 25.5) & (np.abs(y - 15) < 2.5)  # in the shadow of the column at x = 23 +- 2.5
    dense = np.nan_to_num(phi) >= DENSE
    assert not dense[0][behind].any() and dense[-1][behind].any()
    bodies, count = ndimage.label(dense[-1])
    assert len(set(bodies[behind & dense[-1]]) | {bodies[15, 15, 15]}) == 1, count  # the centre's body


def test_grate_splits_the_front_and_it_recombines():
    """4.5: "the biofilm is not strictly following just one path but rather splits up and recombines": in the
    open rows between the bars the front arrives as several fingers (separate runs of phi >= 0.5 along a row)
    and later fills the row (one run)."""
    scene, ds = run("grate", "time.steps=800")
    phi = ds.phi.values
    grate = scene.obstacle[0]
    y = scene.grid.solver_grid().cell_coordinates()[1][:, 0]
    rows = np.flatnonzero(~np.isnan(phi[0]).any(axis=1) & (y > grate.lower[1]) & (y < grate.upper[1]))
    assert rows.size >= 3

    def runs(row):
        inside = row >= EXTENT
        return int(inside[0]) + int(np.count_nonzero(inside[1:] & ~inside[:-1]))

    counts = np.array([[runs(phi[t, j]) for j in rows] for t in range(ds.sizes["time"])])
    assert counts.max() >= 3, counts  # split into fingers between the bars
    assert np.all(counts[-1] == 1) and np.all(phi[-1][rows] >= EXTENT), counts[-1]  # recombined


def test_maze_biofilm_finds_its_way_in_and_grows_into_the_dead_ends_it_passes():
    """4.4 (4 µm cells, to T* = 8 of the bundled 20): the biofilm (phi >= 0.5) nearest the centre gets closer,
    never faster than a front moves (r/2 per T*, a cell's slack), and is two rings in by T* = 8; "the biofilm first
    grows from the entrance in all directions ... even if the biofilm grows into a dead-end": biofilm enters
    dead ends off its way (found in the walls: `quantities.dead_ends`).  Reaching the core and settling take the
    full run (docs/paper.md)."""
    scene, ds = run("maze", "grid.shape=[140,140]", "grid.spacing=4.0", "time.t_end=8.0", "time.steps=400",
                    "time.outputs=9")
    maze = scene.obstacle[0].layout()
    x, y = scene.grid.solver_grid().cell_coordinates()
    radius = np.hypot(x - maze.center[0], y - maze.center[1])
    nearest = np.array([radius[p >= EXTENT].min() for p in np.nan_to_num(ds.phi.values)])
    speed = scene.params.r / 2 * np.diff(ds.time.values)
    assert np.all(np.diff(nearest) <= scene.grid.spacing) and np.all(-np.diff(nearest) <= speed + 2 * 4.0)
    assert nearest[-1] < maze.radii[2], (nearest, maze.radii)
    invaded = dead_ends.per_dead_end(ds)
    assert invaded[:, 0].sum() == 0 and np.count_nonzero(invaded[:, -1]) >= 2, invaded


@pytest.mark.parametrize("name", ["directional", "agar-g1e8", "agar-g1e10", "obstacles", "maze", "dead-end", "grate"])
def test_paper_scenes_use_the_papers_parameters(name):
    """Table 2, or the maze's Table 6 (and its dead-end corridor's); 2-D where the paper is semi-2-D; mechanics where
    the paper shows stresses (not in the corridor, which shows the maze's transport alone)."""
    scene = load_scene(bundled.resolve(name))
    params = scene.params
    maze = name in ("maze", "dead-end")
    if maze:  # Table 6
        assert (params.d, params.beta, params.k_alpha, params.r) == (1e13, 10.0, 1e-6, 200.0)
    else:  # Table 2
        assert (params.d, params.beta, params.k_alpha, params.r, params.mu, params.nu) == (1e10, 2.0, 1e-3, 100.0,
                                                                                           3.3557, 0.49)
    assert scene.grid.solver_grid().ndim == (2 if name in ("maze", "dead-end", "grate") else 3)
    assert scene.numerics.advection == "tvd"
    assert scene.numerics.growth_velocity == ("pointwise" if maze else "front")
    assert (scene.mechanics is not None and scene.mechanics.enabled) == (name != "dead-end")


def test_agar_scenes_differ_only_in_consumption():
    a, b = (load_scene(bundled.resolve(n)).model_dump() for n in ("agar-g1e8", "agar-g1e10"))
    assert (a["params"]["g"], b["params"]["g"]) == (1e8, 1e10)
    for scene in (a, b):
        del scene["params"]["g"], scene["name"], scene["description"]
    assert a == b
