"""Image files a hostile or unlucky user hands in: sizes declared huge, memory limits, truncated stacks, axes of
one pixel or one slice, voxel sizes in metadata, palette pictures."""
import struct
import zlib

import numpy as np
import pytest
import tifffile
from PIL import Image as Picture
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.errors import BadInput
from biostudy.inputs.scene import load_scene
from tests.test_images import BASE, VOXEL, scene, stack_with_box

cli = CliRunner()
PLANE = BASE.replace("shape = [8, 6, 4]", "shape = [8, 6]").replace('face = "z+"', 'face = "y+"')


def one_line_error(path, expected: str) -> None:
    result = cli.invoke(app, ["run", str(path), "-o", str(path.parent / "o.nc")])
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert expected in lines[0], lines[0]


def plane(folder, region: str):
    """A 2-D scene (8 x 6 cells of 1 µm) whose biofilm is the image region `region`."""
    path = folder / "p.toml"
    path.write_text(PLANE + f'[[biofilm]]\nshape = "image"\n{region}\n')
    return path


def imagej(path, stack, spacing=VOXEL[0], resolution=(1 / VOXEL[2], 1 / VOXEL[1])):
    tifffile.imwrite(path, stack, imagej=True, resolution=resolution,
                     metadata={"spacing": spacing, "unit": "um", "axes": "ZYX"})


def huge_tiff(path, monkeypatch):
    """A 284-byte tiled, compressed TIFF whose header says 20000 x 20000 pixels (such a file peaked at 5.6 GB), and
    tifffile's readers made to fail the test if a pixel of anything is read."""
    tifffile.imwrite(path, np.zeros((16, 16), np.uint8), tile=(16, 16), compression="zlib", metadata=None)
    with tifffile.TiffFile(path, mode="r+b") as tif:
        tif.pages[0].tags["ImageWidth"].overwrite(20000)
        tif.pages[0].tags["ImageLength"].overwrite(20000)

    def never(*args, **kwargs):
        raise AssertionError("the pixels were read")

    for reader in (tifffile.TiffPageSeries, tifffile.TiffPage, tifffile.TiffFile):
        monkeypatch.setattr(reader, "asarray", never)
    return path


def test_a_tiff_declaring_a_huge_size_is_refused_before_a_pixel_is_read(tmp_path, monkeypatch):
    """Refused from the header; reading it would fail the test, not allocate."""
    huge_tiff(tmp_path / "huge.tif", monkeypatch)
    monkeypatch.setenv("BIOSTUDY_MEMORY", "400 MB")  # 400 MB of values, a slab averaged at a time
    one_line_error(plane(tmp_path, 'path = "huge.tif"\nvoxel = [1.0, 1.0]'),
                   "[20000, 20000] voxels: reading and averaging it needs ~459 MB of memory, 400 MB available")


def test_a_large_png_meets_the_memory_check_not_pillows_warning(tmp_path, monkeypatch, recwarn):
    """A 70-byte PNG whose header says 10000 x 10000 pixels: refused by the memory check, and Pillow's
    DecompressionBombWarning (above 89 M pixels) does not print a second, multi-line message."""
    Picture.fromarray(np.zeros((16, 16), np.uint8)).save(tmp_path / "big.png")
    data = bytearray((tmp_path / "big.png").read_bytes())
    data[16:24] = struct.pack(">II", 10000, 10000)  # IHDR width, height
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    (tmp_path / "big.png").write_bytes(bytes(data))
    monkeypatch.setenv("BIOSTUDY_MEMORY", "200 MB")
    one_line_error(plane(tmp_path, 'path = "big.png"\nvoxel = [1.0, 1.0]'),
                   "[10000, 10000] voxels: reading and averaging it needs ~259 MB of memory, 200 MB available")
    assert not [w for w in recwarn if "decompression bomb" in str(w.message)]


def test_the_memory_check_counts_the_averaging_and_honours_biostudy_memory(tmp_path, monkeypatch):
    """8 x 24 x 16 uint8 voxels: 3072 bytes as read, ~46 kB with the averaging's copies (15 bytes a voxel)."""
    imagej(tmp_path / "ij.tif", stack_with_box())
    path = scene(tmp_path, '[[biofilm]]\nshape = "image"\npath = "ij.tif"\n')
    monkeypatch.setenv("BIOSTUDY_MEMORY", "30 kB")
    with pytest.raises(BadInput, match=r"ij.tif: \[8, 24, 16\] voxels: reading and averaging it needs ~46.1 kB"):
        load_scene(path)
    monkeypatch.setenv("BIOSTUDY_MEMORY", "60 kB")
    assert load_scene(path).problem().phi0.sum() == 12
    Picture.fromarray(np.zeros((12, 16), np.uint8)).save(tmp_path / "p.png")  # 192 pixels of 1 + 1 + 14 bytes
    monkeypatch.setenv("BIOSTUDY_MEMORY", "3 kB")
    with pytest.raises(BadInput, match=r"p.png: \[12, 16\] voxels: reading and averaging it needs ~3.07 kB"):
        load_scene(plane(tmp_path, 'path = "p.png"\nvoxel = [0.5, 0.5]'))


def test_a_truncated_stack_is_refused_not_read_as_its_first_pages(tmp_path, caplog):
    imagej(tmp_path / "ij.tif", stack_with_box())
    whole = (tmp_path / "ij.tif").read_bytes()
    with tifffile.TiffFile(tmp_path / "ij.tif") as tif:
        end = tif.pages[0].dataoffsets[0] + stack_with_box().nbytes  # the pixels end here, the other pages' IFDs follow
    for name, kept in (("half.tif", len(whole) // 2), ("short.tif", end - 10)):
        (tmp_path / name).write_bytes(whole[:kept])
        one_line_error(scene(tmp_path, f'[[biofilm]]\nshape = "image"\npath = "{name}"\n'),
                       f"{name}: its ImageJ metadata declares 8 images, the file holds 1 (truncated or damaged)")
    assert not [r for r in caplog.records if r.name == "tifffile"]  # tifffile's own complaints stay off stderr
    tifffile.imwrite(tmp_path / "plain.tif", stack_with_box(), photometric="minisblack")
    tifffile.imwrite(tmp_path / "ome.tif", stack_with_box(), ome=True, metadata={
        "axes": "ZYX", "PhysicalSizeX": VOXEL[2], "PhysicalSizeY": VOXEL[1], "PhysicalSizeZ": VOXEL[0]})
    for name in ("plain.tif", "ome.tif"):
        whole = (tmp_path / name).read_bytes()
        (tmp_path / name).write_bytes(whole[:len(whole) // 2])
        one_line_error(scene(tmp_path, f'[[biofilm]]\nshape = "image"\npath = "{name}"\nvoxel = [0.5, 0.25, 0.5]\n'),
                       f"{name} ends before its pages do ({len(whole) // 2} bytes; truncated or damaged)")


def test_one_slice_with_a_z_spacing_is_a_stack_and_one_pixel_a_picture(tmp_path):
    single = stack_with_box()[:1]  # the box's bottom slice, 1 µm thick: its cells z 0, x 2..4, y 1..2
    imagej(tmp_path / "ij.tif", single, spacing=1.0)
    tifffile.imwrite(tmp_path / "ome.tif", single, ome=True, metadata={
        "axes": "ZYX", "PhysicalSizeX": VOXEL[2], "PhysicalSizeY": VOXEL[1], "PhysicalSizeZ": 1.0})
    tifffile.imwrite(tmp_path / "shaped.tif", single, photometric="minisblack", metadata={"axes": "ZYX"})
    for name, voxel in (("ij.tif", ""), ("ome.tif", ""), ("shaped.tif", "voxel = [1.0, 0.25, 0.5]")):
        region = f'[[biofilm]]\nshape = "image"\npath = "{name}"\n{voxel}\n'
        phi0 = load_scene(scene(tmp_path, region)).problem().phi0
        assert phi0.sum() == 6 and phi0[0, 1:3, 2:5].all(), name  # [z, y, x]
    one_line_error(plane(tmp_path, 'path = "ij.tif"'), "ij.tif is a 3-D z-y-x stack of one slice (the file states "
                   "its z spacing or axis) (shape [1, 24, 16]); the grid is 2-D")
    tifffile.imwrite(tmp_path / "pixel.tif", np.full((1, 1), 7, np.uint8), photometric="minisblack")
    phi0 = load_scene(plane(tmp_path, 'path = "pixel.tif"\nvoxel = [6.0, 8.0]')).problem().phi0
    assert phi0.shape == (6, 8) and phi0.all()


@pytest.mark.parametrize("value", [0, -1, float("nan"), 1e300])
def test_voxel_sizes_from_metadata_are_checked_as_the_scenes(tmp_path, value):
    imagej(tmp_path / "ij.tif", stack_with_box(), spacing=value)
    tifffile.imwrite(tmp_path / "ome.tif", stack_with_box(), ome=True, metadata={
        "axes": "ZYX", "PhysicalSizeX": value, "PhysicalSizeY": VOXEL[1], "PhysicalSizeZ": VOXEL[0]})
    for name, field in (("ij.tif", "ImageJ spacing = "), ("ome.tif", "OME PhysicalSizeX = ")):
        one_line_error(scene(tmp_path, f'[[biofilm]]\nshape = "image"\npath = "{name}"\n'),
                       f"biofilm[0].voxel: {tmp_path / name}: its metadata's {field}")
    one_line_error(scene(tmp_path, f'[[biofilm]]\nshape = "image"\npath = "ij.tif"\nvoxel = [{value}, 0.25, 0.5]\n'),
                   "biofilm[0].voxel")
    # the scene's voxel wins over the file's: a bad one in the metadata does not matter then
    given = load_scene(scene(tmp_path, '[[biofilm]]\nshape = "image"\npath = "ij.tif"\nvoxel = [0.5, 0.25, 0.5]\n'))
    assert given.problem().phi0.sum() == 12


def test_an_imagej_resolution_of_zero_or_no_spacing_is_named(tmp_path):
    imagej(tmp_path / "ij.tif", stack_with_box(), resolution=((0, 1), (4, 1)))
    one_line_error(scene(tmp_path, '[[biofilm]]\nshape = "image"\npath = "ij.tif"\n'),
                   "its metadata's XResolution = 0/1 pixels per um is not a voxel size")
    tifffile.imwrite(tmp_path / "flat.tif", stack_with_box(), imagej=True, resolution=(2.0, 4.0),
                     metadata={"unit": "um", "axes": "ZYX"})  # as Fiji saves a stack of 1 µm slices
    one_line_error(scene(tmp_path, '[[biofilm]]\nshape = "image"\npath = "flat.tif"\n'),
                   "its metadata's ImageJ spacing is missing (Fiji leaves it out when it is 1 um); give voxel = [dz")


def test_a_grey_palette_picture_is_greyscale_a_colour_one_refused(tmp_path):
    indices = np.zeros((12, 16), np.uint8)
    indices[2:6, 4:8] = 1  # grey 200: cells x 2..3, y 1..2
    indices[2:6, 8:12] = 2  # grey 50
    for name, palette in (("grey.png", [0, 0, 0, 200, 200, 200, 50, 50, 50]),
                          ("colour.png", [0, 0, 0, 200, 0, 0, 50, 50, 50])):
        picture = Picture.fromarray(indices, mode="P")
        picture.putpalette(palette)
        picture.save(tmp_path / name)
    grey = np.tile(np.array([0, 200, 50] + [0] * 253, np.uint16) * 257, (3, 1))
    tifffile.imwrite(tmp_path / "grey.tif", indices, photometric="palette", colormap=grey)
    tifffile.imwrite(tmp_path / "colour.tif", indices, photometric="palette", colormap=grey * [[1], [0], [1]])
    for name in ("grey.png", "grey.tif"):
        phi0 = load_scene(plane(tmp_path, f'path = "{name}"\nvoxel = [0.5, 0.5]\nthreshold = 100')).problem().phi0
        assert phi0.sum() == 4 and phi0[1:3, 2:4].all(), name  # [y, x]
    one_line_error(plane(tmp_path, 'path = "colour.png"\nvoxel = [0.5, 0.5]\nthreshold = 100'),
                   "colour.png is a colour picture (mode P, a colour palette)")
    one_line_error(plane(tmp_path, 'path = "colour.tif"\nvoxel = [0.5, 0.5]\nthreshold = 100'),
                   "colour.tif is a colour picture (a colour palette)")
