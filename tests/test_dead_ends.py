"""Dead ends off the route (`biostudy.quantities.dead_ends`) found in a geometry drawn by hand, their observables
against cells counted by hand, and the bundled scenes that show paper 4.4's dead ends."""
import numpy as np
import pytest
import xarray as xr

from biostudy.inputs import bundled
from biostudy.inputs.scene import load_scene
from biostudy.quantities import dead_ends, observables
from solver import simulate

H = 0.5  # µm: not 1, so that cells and µm cannot be mixed up unseen


def corridor(phi_late: np.ndarray | None = None) -> xr.Dataset:
    """A corridor 7 cells wide (rows 10-16) along x (60 cells) from a colony (x < 4 cells) to a held nutrient
    (x >= 56 cells), and one dead end 4 cells wide (columns 28-31) and 12 deep (rows 17-28) off its upper wall;
    t = 0 the colony, t = 1 `phi_late`."""
    ny, nx = 30, 60
    obstacle = np.ones((ny, nx), bool)
    obstacle[10:17, :] = False
    obstacle[17:29, 28:32] = False
    source = np.zeros((ny, nx), bool)
    source[10:17, 56:] = True
    colony = np.zeros((ny, nx))
    colony[10:17, :4] = 1.0
    late = colony if phi_late is None else phi_late
    phi = np.where(obstacle, np.nan, np.stack([colony, late]))
    coords = {"y": (np.arange(ny) + 0.5) * H, "x": (np.arange(nx) + 0.5) * H, "time": [0.0, 1.0]}
    return xr.Dataset({"phi": (("time", "y", "x"), phi), "obstacle": (("y", "x"), obstacle.astype(np.int8)),
                       "nutrient_source": (("y", "x"), source.astype(np.int8))}, coords=coords)


def test_the_dead_end_off_a_corridor_is_found_where_it_was_drawn():
    found = dead_ends.of(corridor())
    assert found.area.size == 1  # the corridor's own cells are the route's
    cells = found.label == 1
    rows, columns = np.nonzero(cells)
    assert set(columns) == {28, 29, 30, 31} and rows.max() == 28
    assert found.route[13, 10:50].all()  # the route runs along the corridor's middle row
    # the corridor: within its half-width (from row 13's centre to the wall row 9's: 4 cells) and a cell of the
    # route, rows 9-18 (row 18: 5 cells); the dead end beyond it: rows 19-28, 40 cells
    assert rows.min() == 19 and found.area[0] == 40 * H**2


def test_a_second_way_is_no_dead_end():
    """A channel that leaves the corridor and comes back to it (a loop, as between a grate's bars) opens onto it
    twice: no dead end; the dead end beside it still is one."""
    ds = corridor()
    obstacle = ds.obstacle.values.copy()
    obstacle[2:6, 8:50] = 0  # a channel below the corridor (rows 2-5) joined to it by two shafts (rows 6-9)
    obstacle[6:10, 8:12] = 0
    obstacle[6:10, 46:50] = 0
    found = dead_ends.of(ds.assign(obstacle=(("y", "x"), obstacle), phi=ds.phi.where(obstacle == 0)))
    assert found.area.size == 1 and set(np.nonzero(found.label)[1]) == {28, 29, 30, 31}


def test_biofilm_in_a_dead_end_and_its_reach_are_counted_by_hand():
    """phi = 1 in the dead end's 5 deepest rows (rows 24-28: 20 cells) and in the whole corridor (not counted):
    20 cells of H², reaching to the dead end's bottom row, 28 - 13 = 15 cells from the route's row less the
    corridor's half-width (4 cells) and one cell: 10 cells."""
    late = np.zeros((30, 60))
    late[10:17, :] = 1.0
    late[24:29, 28:32] = 1.0
    ds = corridor(late)
    np.testing.assert_allclose(observables.evaluate(ds, "dead_end_biofilm").values, [0.0, 20 * H**2])
    np.testing.assert_allclose(observables.evaluate(ds, "dead_end_reach").values, [0.0, 10 * H])
    late[24:29, 28:32] = 0.49  # below the biofilm's threshold
    assert observables.evaluate(corridor(late), "dead_end_biofilm").values[1] == 0.0


def test_runs_without_dead_ends_leave_the_observables_out():
    open_box = corridor().assign(obstacle=lambda ds: ds.obstacle * 0)
    block = np.zeros((30, 60), np.int8)
    block[22:30, :8] = 1  # open space beside the route, one block of wall in a corner (the tiny scene's kind)
    boxed = corridor().assign(obstacle=(("y", "x"), block))
    boxed = boxed.assign(phi=boxed.phi.fillna(0.0).where(block == 0))
    no_source = corridor().assign(nutrient_source=lambda ds: ds.nutrient_source * 0)
    for ds in (open_box, boxed, no_source):
        assert not dead_ends.applies(ds)
        assert "dead_end_biofilm" not in observables.variables(ds)
        with pytest.raises(ValueError, match="dead_end_biofilm: the run has none to measure"):
            observables.evaluate(ds, "dead_end_biofilm")
    assert {"dead_end_biofilm", "dead_end_reach"} <= set(observables.variables(corridor()))


def test_the_dead_end_scene_s_front_invades_the_wider_dead_end_further_and_retracts_from_it():
    """Paper 4.4 on the bundled corridor (2 µm cells, 300 steps to T* = 3): "the biofilm first grows ... even if
    [it] grows into a dead-end.  The bigger the dead-end is, ... the more biofilm grows into the dead-end.  Once
    nutrients are depleted in the dead-end, the biofilm either stays at the level that was before, or it
    retracts": biofilm enters both dead ends, more of it the wider one (32 µm against 16 µm), and the wider one
    holds less at the end than at its most."""
    scene = load_scene(bundled.resolve("dead-end"), ["time.t_end=3.0", "time.steps=300", "time.outputs=31"])
    ds = simulate(scene.problem())
    found = dead_ends.of(ds)
    assert found.area.size == 2
    narrow, wide = np.argsort(found.area)
    invaded = dead_ends.per_dead_end(ds)
    assert invaded[narrow].max() > 0 and invaded[wide].max() > invaded[narrow].max()
    assert invaded[wide][-1] < 0.9 * invaded[wide].max(), invaded[wide]
