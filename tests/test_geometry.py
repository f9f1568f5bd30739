"""Shapes -> cell masks: centre-inside rule, 2-D and 3-D, mask files in [x, y(, z)] order."""
import numpy as np
import pytest

from biostudy.errors import InvalidAt
from biostudy.inputs.geometry import Box, Cylinder, Mask, Sphere
from solver import Grid


def test_box_takes_cells_whose_centre_is_inside_boundaries_included():
    grid = Grid((10, 8, 6), 1.0)
    cells = Box(shape="box", lower=[2, 0, 0], upper=[4.5, 8, 1]).cells(grid)
    assert cells.shape == (6, 8, 10)  # solver order (z, y, x)
    # x centres 2.5, 3.5 (4.5 is a centre and on the boundary: included), all 8 y, z centre 0.5 only
    assert cells.sum() == 3 * 8 * 1
    assert cells[0, :, 2:5].all() and not cells[1:].any() and not cells[:, :, :2].any()


def test_sphere_is_a_ball_in_3d_and_a_disc_in_2d():
    ball = Sphere(shape="sphere", center=[5, 5, 5], radius=1.0).cells(Grid((10, 10, 10)))
    assert ball.sum() == 8  # the 8 centres at distance sqrt(3)/2 from (5, 5, 5)
    disc = Sphere(shape="sphere", center=[5, 5], radius=2.0).cells(Grid((10, 10)))
    x, y = Grid((10, 10)).cell_coordinates()
    assert np.array_equal(disc, (x - 5) ** 2 + (y - 5) ** 2 <= 4)
    assert disc.sum() == 12


def test_cylinder_along_an_axis_with_length_and_unbounded():
    grid = Grid((8, 8, 8))
    x, y, z = grid.cell_coordinates()
    rod = Cylinder(shape="cylinder", center=[4, 4, 4], radius=1.0, axis="x", length=4).cells(grid)
    assert np.array_equal(rod, ((y - 4) ** 2 + (z - 4) ** 2 <= 1) & (np.abs(x - 4) <= 2))
    assert rod.sum() == 4 * 4
    through = Cylinder(shape="cylinder", center=[4, 4, 4], radius=1.0, axis="z").cells(grid)
    assert through.sum() == 4 * 8
    # 2-D: along z the plane cuts a disc, along y a band
    flat = Grid((8, 8))
    assert Cylinder(shape="cylinder", center=[4, 4], radius=1.0).cells(flat).sum() == 4
    assert Cylinder(shape="cylinder", center=[4, 4], radius=1.0, axis="y", length=2).cells(flat).sum() == 4


def test_mask_file_is_read_in_x_y_z_order_and_transposed(tmp_path):
    grid = Grid((5, 4, 3))
    array = np.zeros((5, 4, 3), bool)  # [x, y, z]
    array[4, 1, 2] = True
    np.save(tmp_path / "m.npy", array)
    mask = Mask.model_validate({"shape": "mask", "path": "m.npy"}, context={"base": tmp_path})
    cells = mask.cells(grid)
    assert cells.shape == (3, 4, 5) and cells[2, 1, 4] and cells.sum() == 1
    mask.check(grid)
    with pytest.raises(InvalidAt, match=r"shape \[5, 4, 3\]; the grid is \[3, 4, 5\]"):
        mask.check(Grid((3, 4, 5)))


def test_shape_checks_against_the_grid():
    grid = Grid((10, 10))
    with pytest.raises(InvalidAt, match="outside the grid") as error:
        Sphere(shape="sphere", center=[11, 5], radius=1).check(grid)
    assert error.value.key == "center"
    with pytest.raises(InvalidAt, match="2 coordinates|3 coordinates"):
        Sphere(shape="sphere", center=[5, 5, 5], radius=1).check(grid)
    with pytest.raises(InvalidAt, match="no cell centre"):
        Sphere(shape="sphere", center=[5, 5], radius=0.2).check(grid)
    Box(shape="box", lower=[0, 0], upper=[10, 10]).check(grid)  # the whole grid is fine


def test_mask_values_must_be_boolean_or_0_1(tmp_path):
    np.save(tmp_path / "ints.npy", np.array([[0, 1], [1, 0]]))
    ints = Mask.model_validate({"shape": "mask", "path": "ints.npy"}, context={"base": tmp_path})
    assert ints.cells(Grid((2, 2))).tolist() == [[False, True], [True, False]]
    np.save(tmp_path / "floats.npy", np.full((2, 2), 0.5))
    with pytest.raises(ValueError, match="holds float64 values; a mask is boolean"):
        Mask.model_validate({"shape": "mask", "path": "floats.npy"}, context={"base": tmp_path})
    (tmp_path / "text.npy").write_text("not an array")
    with pytest.raises(ValueError, match="cannot read .* as a .npy array: not a .npy file"):
        Mask.model_validate({"shape": "mask", "path": "text.npy"}, context={"base": tmp_path})
