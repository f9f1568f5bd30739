"""Microscopy images in (image regions: TIFF stacks, PNG pictures) and out (export --format tiff)."""
import textwrap

import numpy as np
import pytest
import tifffile
from PIL import Image as Picture
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.data import writing
from biostudy.inputs import images
from biostudy.inputs.scene import load_scene

cli = CliRunner()

# A 3-D grid of 8 x 6 x 4 cells of 1 µm (x, y, z) and a stack with anisotropic voxels dz = 0.5, dy = 0.25,
# dx = 0.5 µm covering it: 8 slices of 24 rows of 16 columns.
BASE = """\
name = "img"
[grid]
shape = [8, 6, 4]
[time]
t_end = 0.1
steps = 2
[[nutrient]]
shape = "face"
face = "z+"
"""
VOXEL = (0.5, 0.25, 0.5)  # dz, dy, dx


def scene(folder, region: str, name: str = "s.toml"):
    path = folder / name
    path.write_text(BASE + textwrap.dedent(region))
    return path


def stack_with_box() -> np.ndarray:
    """Foreground in the voxels of cells x 2..4, y 1..2, z 0..1 (µm 2-5, 1-3, 0-2), z-y-x order."""
    stack = np.zeros((8, 24, 16), np.uint8)
    stack[0:4, 4:12, 4:10] = 255
    return stack


def test_a_stack_with_imagej_or_ome_voxels_lands_where_a_hand_made_mask_puts_it(tmp_path):
    stack = stack_with_box()
    dz, dy, dx = VOXEL
    tifffile.imwrite(tmp_path / "ij.tif", stack, imagej=True, resolution=(1 / dx, 1 / dy),
                     metadata={"spacing": dz, "unit": "um", "axes": "ZYX"})
    tifffile.imwrite(tmp_path / "ome.tif", stack, ome=True, metadata={
        "axes": "ZYX", "PhysicalSizeX": dx * 1000, "PhysicalSizeXUnit": "nm", "PhysicalSizeY": dy, "PhysicalSizeZ": dz})
    tifffile.imwrite(tmp_path / "plain.tif", stack, photometric="minisblack")
    mask = np.zeros((8, 6, 4), bool)  # scene order [x, y, z]
    mask[2:5, 1:3, 0:2] = True
    np.save(tmp_path / "mask.npy", mask)
    expected = load_scene(scene(tmp_path, '[[biofilm]]\nshape = "mask"\npath = "mask.npy"\n', "m.toml")).problem().phi0
    assert expected.sum() == 12
    for region in ('path = "ij.tif"', 'path = "ome.tif"', 'path = "plain.tif"\nvoxel = [0.5, 0.25, 0.5]'):
        phi0 = load_scene(scene(tmp_path, f'[[biofilm]]\nshape = "image"\n{region}\n')).problem().phi0
        np.testing.assert_array_equal(phi0, expected, err_msg=region)
    # z-y-x against the grid's x-y-z: a stack moved by origin = [x, y, z] moves the region the same way
    moved = load_scene(scene(tmp_path, '[[obstacle]]\nshape = "image"\npath = "ij.tif"\norigin = [2.0, 0.0, 1.0]\n'))
    np.testing.assert_array_equal(moved.problem().obstacle, np.roll(np.roll(expected, 2, axis=2), 1, axis=0) > 0)


def test_cells_take_the_image_average_over_their_volume():
    """Voxels of 0.75 µm over cells of 1 µm: a cell's average weights each voxel by the length inside it."""
    values = np.array([[1.0, 2.0, 3.0, 4.0]])  # one row of four voxels, 0..3 µm along x
    average = images.cell_average(values, (1.0, 0.75), (0.0, 0.0), 1.0, (1, 3))
    # cell 0 (0-1 µm): voxel 0 whole, 1/4 of voxel 1 -> (0.75 * 1 + 0.25 * 2) / 1; cell 1: 0.5 * 2 + 0.5 * 3;
    # cell 2: 0.25 * 3 + 0.75 * 4
    np.testing.assert_allclose(average, [[1.25, 2.5, 3.75]])
    assert images.cell_average(np.ones((4, 4)), (0.5, 0.5), (0.0, 0.0), 1.0, (3, 3)).sum() == pytest.approx(4.0)


def test_a_stack_averaged_a_slab_at_a_time_gives_the_whole_stack_s_average(monkeypatch):
    """Issue 39.8: the averaging went over the whole stack at once (14 bytes a voxel: 1.9 GB for a 128 MB stack);
    in slabs of a few slices it holds a slab's worth and gives the same cell averages (sums in the same order:
    per row along x, then y, then z)."""
    stack = np.random.default_rng(3).random((13, 24, 20)) * 255
    args = ((0.4, 0.3, 0.35), (0.2, -0.1, 0.3), 1.0, (6, 8, 8))
    whole = images.cell_average(stack, *args, of=lambda block: block >= 100)
    monkeypatch.setattr(images, "SLAB_VOXELS", 24 * 20 * 3)  # three slices at a time: 5 slabs, the last of one
    slabs = images.cell_average(stack, *args, of=lambda block: block >= 100)
    np.testing.assert_allclose(slabs, whole, rtol=1e-14, atol=1e-15)
    assert whole.shape == (6, 8, 8) and 0 < whole.max() <= 1


def test_greyscale_pictures_by_threshold_or_as_phi(tmp_path):
    grey = np.zeros((12, 16), np.uint8)  # a 2-D picture, y-x, 0.5 µm pixels over a 8 x 6 grid of 1 µm
    grey[2:6, 4:8] = 200  # cells x 2..3, y 1..2
    grey[2:6, 8:12] = 50  # cells x 4..5, y 1..2
    Picture.fromarray(grey).save(tmp_path / "grey.png")
    base = BASE.replace("shape = [8, 6, 4]", "shape = [8, 6]").replace('face = "z+"', 'face = "y+"')
    path = tmp_path / "g.toml"
    path.write_text(base + '[[biofilm]]\nshape = "image"\npath = "grey.png"\nvoxel = [0.5, 0.5]\nthreshold = 100\n')
    phi0 = load_scene(path).problem().phi0
    assert phi0.sum() == 4 and phi0[1:3, 2:4].all()
    path.write_text(base + '[[biofilm]]\nshape = "image"\npath = "grey.png"\nvoxel = [0.5, 0.5]\nscale = 0.004\n')
    phi0 = load_scene(path).problem().phi0
    np.testing.assert_allclose(phi0[1:3, 2:4], 0.8)  # 0.004 x 200
    np.testing.assert_allclose(phi0[1:3, 4:6], 0.2)
    assert phi0.sum() == pytest.approx(4 * 0.8 + 4 * 0.2)


def test_bad_images_are_one_line_exit_2(tmp_path):
    tifffile.imwrite(tmp_path / "plain.tif", stack_with_box(), photometric="minisblack")
    tifffile.imwrite(tmp_path / "flat.tif", stack_with_box()[0], photometric="minisblack")
    tifffile.imwrite(tmp_path / "grey.tif", np.arange(8 * 24 * 16, dtype=np.uint16).reshape(8, 24, 16) % 7,
                     imagej=True, resolution=(2, 4), metadata={"spacing": 0.5, "unit": "um", "axes": "ZYX"})
    tifffile.imwrite(tmp_path / "rgb.tif", np.zeros((24, 16, 3), np.uint8), photometric="rgb")
    (tmp_path / "text.tif").write_text("not an image")
    cases = {
        'path = "flat.tif"\nvoxel = [0.25, 0.5]': "flat.tif is a 2-D y-x picture (shape [24, 16]); the grid is 3-D",
        'path = "plain.tif"': "biofilm[0].voxel: ",
        'path = "plain.tif"\nvoxel = [0.25, 0.5]': "biofilm[0].voxel: has 2 entries",
        'path = "grey.tif"': "biofilm[0].threshold: ",
        'path = "rgb.tif"\nvoxel = [0.25, 0.5]': "biofilm[0].path: ",
        'path = "text.tif"': "cannot read",
        'path = "../x.tif"': "lies outside the scene's folder",
        'path = "grey.tif"\nscale = 1.0': "biofilm[0].scale: phi = 1 × the brightest voxel 6 = 6 > 1",
        'path = "grey.tif"\nscale = 0.1\nthreshold = 3': "give threshold (segment the image) or scale",
    }
    for region, expected in cases.items():
        path = scene(tmp_path, f'[[biofilm]]\nshape = "image"\n{region}\n')
        result = cli.invoke(app, ["run", str(path), "-o", str(tmp_path / "o.nc")])
        lines = result.stderr.strip().splitlines()
        assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), (region, result.output)
        assert expected in lines[0], (region, lines[0])
    assert "voxel = [dz, dy, dx]" in cli.invoke(app, ["run", str(scene(tmp_path, '[[biofilm]]\nshape = "image"\n'
                                                                      'path = "plain.tif"\n'))]).stderr
    obstacle = scene(tmp_path, '[[obstacle]]\nshape = "image"\npath = "grey.tif"\nscale = 0.1\n')
    result = cli.invoke(app, ["run", str(obstacle)])
    assert result.exit_code == 2 and "obstacle[0].scale: only a biofilm region takes phi" in result.stderr


def test_export_tiff_is_read_back_at_scale(tiny_run, tmp_path):
    for shape, spacing in (((6, 5, 4), 2.0), ((8, 6), 0.5)):
        ds = tiny_run(shape, spacing)
        written = writing.write_atomic(ds.assign_attrs(biostudy_version="0"), tmp_path / "run.nc")
        out = tmp_path / f"tiff{len(shape)}"
        result = cli.invoke(app, ["export", str(written), str(out), "--format", "tiff"])
        assert result.exit_code == 0, result.output
        with tifffile.TiffFile(out / "phi.tif") as tif:
            meta = tif.imagej_metadata
            series = tif.series[0]
            x_per_um = tif.pages[0].tags["XResolution"].value
            y_per_um = tif.pages[0].tags["YResolution"].value
            phi = series.asarray()
        assert x_per_um[0] / x_per_um[1] == pytest.approx(1 / spacing) == y_per_um[0] / y_per_um[1]
        assert meta["unit"] == "um" and meta["finterval"] == pytest.approx(0.01) and meta["tunit"] == "T*"
        if len(shape) == 3:
            assert series.axes == "TZYX" and series.shape == (3, 4, 5, 6) and meta["spacing"] == spacing
            expected = ds.phi.transpose("time", "z", "y", "x").values
        else:
            assert series.axes == "TYX" and series.shape == (3, 6, 8) and "spacing" not in meta
            expected = ds.phi.transpose("time", "y", "x").values
        np.testing.assert_array_equal(phi, expected.astype(np.float32))  # NaN in the obstacle cells too
        assert "T* = 0.01" in meta["Labels"][len(meta["Labels"]) // 3]
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "phi.tif").write_text("a user's file")
    result = cli.invoke(app, ["export", str(written), str(tmp_path / "mine"), "--format", "tiff"])
    assert result.exit_code == 2 and "not a TIFF biostudy exported" in result.stderr
    assert (tmp_path / "mine" / "phi.tif").read_text() == "a user's file"
