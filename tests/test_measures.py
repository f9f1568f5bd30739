"""Dense quantities of a run (`biostudy.quantities.measures`) against values computed by hand on small fields."""
import numpy as np
import xarray as xr

from biostudy.quantities import measures

H = 0.5  # µm: a spacing other than 1 so that index and coordinate mix-ups show


def dataset(*phis, c=None):
    """A 2-D run's dataset (time, y, x) of 8 x 6 cells from the given phi fields."""
    phi = np.stack(phis)
    ny, nx = phi.shape[1:]
    coords = {"y": (np.arange(ny) + 0.5) * H, "x": (np.arange(nx) + 0.5) * H, "time": np.arange(len(phis), dtype=float)}
    c = np.ones_like(phi) if c is None else c
    return xr.Dataset({"phi": (("time", "y", "x"), phi), "c": (("time", "y", "x"), c)}, coords=coords)


def test_dense_volume_counts_cells_at_or_above_the_level():
    phi = np.zeros((8, 6))
    phi[:3, :2] = 0.8  # 6 cells exactly at the level
    phi[3, 0] = 0.79
    ds = dataset(np.zeros((8, 6)), phi)
    assert np.allclose(measures.volume(ds), [0.0, 6 * H * H])
    assert np.allclose(measures.phi_max(ds), [0.0, 0.8])


def test_top_is_the_upper_face_of_a_step_and_the_crossing_of_a_ramp():
    step = np.zeros((8, 6))
    step[:3, 1:4] = 1.0  # rows 0..2 dense: the top face at y = 3 H
    ramp = np.zeros((8, 6))
    ramp[:, 2] = 1.0 - np.arange(8) / 8  # phi = 1 - j/8 along y: 0.5 at j = 4, i.e. y = (4 + 0.5) H
    full = np.ones((8, 6))  # up to the last cell: its upper face
    assert np.allclose(measures.height(dataset(step, ramp, full), "y"), [3 * H, 4.5 * H, 8 * H])
    assert np.isnan(measures.height(dataset(np.full((8, 6), 0.4)), "y")[0])


def test_reach_is_the_farthest_dense_cell_centre_from_the_initial_axis():
    start = np.zeros((8, 6))
    start[:2, 2:4] = 1.0  # cell centres x = 2.5 H, 3.5 H: the axis at x = 3 H
    later = start.copy()
    later[0, 0] = 1.0  # cell centre x = 0.5 H: 2.5 H from the axis
    assert np.allclose(measures.reach(dataset(start, later), "y"), [0.5 * H, 2.5 * H])


def test_nutrient_minimum_gives_place_value_and_phi_there():
    phi = np.zeros((8, 6))
    phi[5, 4] = 0.7
    c = np.ones((1, 8, 6))
    c[0, 5, 4] = 0.2
    found = measures.nutrient_minimum(dataset(phi, c=c))
    assert np.allclose([found["x"][0], found["y"][0], found["c"][0], found["phi"][0]], [4.5 * H, 5.5 * H, 0.2, 0.7])
