"""Images that do not fit the grid (issue 36.5): a stack larger than the domain is cropped with a warning that says
how much is left out; a biofilm image whose biofilm would be cut is refused in one line; every dataset made from an
image records its sha256, voxel size and shape.  The shares are checked against counts made here, voxel by voxel."""
from __future__ import annotations

import hashlib

import numpy as np
import pytest
import tifffile
import xarray as xr
from test_cli import invoke

from biostudy.inputs.scene import load_scene

# a 2-D grid of 20 x 20 cells of 1 µm, nutrient held on y+
BASE = """\
name = "fit"
[grid]
shape = [20, 20]
[time]
t_end = 0.002
steps = 2
outputs = 2
[[nutrient]]
shape = "face"
face = "y+"
"""


def picture(folder, values: np.ndarray, name: str = "big.tif"):
    tifffile.imwrite(folder / name, values, photometric="minisblack")
    return folder / name


def scene(folder, region: str, kind: str = "biofilm", name: str = "s.toml"):
    path = folder / name
    path.write_text(BASE + f'[[{kind}]]\nshape = "image"\n{region}\n')
    return path


def colony(size: int = 80, rows: slice = slice(0, 16), columns: slice = slice(20, 40)) -> np.ndarray:
    """A 40 x 40 µm picture of 0.5 µm pixels: a colony in rows (y) and columns (x), background elsewhere."""
    values = np.zeros((size, size), np.uint8)
    values[rows, columns] = 255
    return values


def test_a_stack_larger_than_the_grid_is_cropped_with_a_warning_that_says_how_much(tmp_path):
    """40 x 40 µm in a 20 x 20 µm grid, the colony inside it: 75 % of the picture is left out, none of the colony;
    the run says so and its dataset records the sha256, voxel size and shape of the picture."""
    path = picture(tmp_path, colony())
    toml = scene(tmp_path, 'path = "big.tif"\nvoxel = [0.5, 0.5]')
    attrs = load_scene(toml).image_attrs()
    assert "75.0% of the image is left out, none of its region" in attrs["image_left_out"]
    assert "spans x 0..40 µm, y 0..40 µm, beyond the grid (x 0..20 µm, y 0..20 µm)" in attrs["image_left_out"]
    result = invoke("run", toml, "-o", tmp_path / "run.nc", "-q")
    assert result.exit_code == 0, result.output
    warned = [line for line in result.stderr.splitlines() if "cropped" in line]
    assert len(warned) == 1 and "75.0% of the image is left out" in warned[0], result.stderr
    ds = xr.open_dataset(tmp_path / "run.nc")
    assert ds.attrs["image_biofilm_0_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert ds.attrs["image_biofilm_0_shape"].tolist() == [80, 80]
    assert ds.attrs["image_biofilm_0_voxel"].tolist() == [0.5, 0.5]
    assert ds.attrs["image_biofilm_0_path"] == str(path) and "cropped" in ds.attrs["image_left_out"]
    assert float(ds.phi.isel(time=0).sum()) == 8 * 10  # the colony: 8 rows x 10 columns of 1 µm cells


@pytest.mark.parametrize("columns, origin, beyond", [(slice(20, 48), "", slice(40, None)),  # x 10..24 µm
                                                     (slice(0, 28), "origin = [-4.0, 0.0]", slice(0, 8))])  # x -4..10
def test_a_biofilm_that_would_be_cut_is_refused_in_one_line(tmp_path, columns, origin, beyond):
    """The colony reaches beyond the grid's x = 20 µm, or below its x = 0: the pixels outside are counted here."""
    values = colony(columns=columns)
    picture(tmp_path, values)
    result = invoke("run", scene(tmp_path, f'path = "big.tif"\nvoxel = [0.5, 0.5]\n{origin}'), "-o", tmp_path / "o.nc")
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), result.output
    outside = np.count_nonzero(values[:, beyond])
    share = outside / np.count_nonzero(values)
    assert f"biofilm[0].path: {tmp_path / 'big.tif'} spans x " in lines[0] and "beyond the grid" in lines[0]
    assert f"{outside} voxels of its biofilm ({share:.1%} of it) lie outside, so the biofilm would be cut" in lines[0]
    assert not (tmp_path / "o.nc").exists()


def test_shares_count_the_part_of_a_voxel_beyond_the_grid():
    """0.3 µm pixels, 70 of them: 21 µm along each axis; pixel 66 (19.8..20.1 µm) is two-thirds inside, the three
    after it outside.  A region's share inside is summed pixel by pixel here."""
    from biostudy.inputs import images

    shares = images.inside_share(0.3 * np.arange(71), 20.0)
    assert shares[:66].min() == 1.0 and shares[66] == pytest.approx((20.0 - 19.8) / 0.3) and not shares[67:].any()
    region = np.zeros((70, 70), bool)
    region[0:10, 60:70] = True  # x 18..21 µm, y 0..3 µm
    expected = sum(shares[i] for i in range(60, 70)) * 10  # each of the 10 rows, fully inside along y
    assert images.weighted_count(region, [shares, shares]) == pytest.approx(expected)
    assert images.weighted_count(region[None].repeat(3, axis=0), [np.array([1.0, 0.5, 0.0]), shares, shares]) == \
        pytest.approx(1.5 * expected)


def test_an_image_that_fits_says_nothing_and_floating_point_edges_are_inside(tmp_path):
    """200 pixels of 0.1 µm: 0.1 * 200 = 20.000000000000004 µm, the grid's edge to within rounding."""
    values = np.zeros((200, 200), np.uint8)
    values[0:50, 0:200] = 1
    picture(tmp_path, values, "exact.tif")
    attrs = load_scene(scene(tmp_path, 'path = "exact.tif"\nvoxel = [0.1, 0.1]')).image_attrs()
    assert "image_left_out" not in attrs and attrs["image_biofilm_0_shape"] == [200, 200]


def test_an_obstacle_image_cut_by_the_grid_is_warned_of_with_its_share_not_refused(tmp_path):
    values = colony(rows=slice(20, 60), columns=slice(30, 50))  # x 15..25, y 10..30 µm
    picture(tmp_path, values)
    attrs = load_scene(scene(tmp_path, 'path = "big.tif"\nvoxel = [0.5, 0.5]', kind="obstacle")).image_attrs()
    inside = np.count_nonzero(values[:40, :40])
    assert f"{1 - inside / np.count_nonzero(values):.1%} of its region" in attrs["image_left_out"]
    assert "obstacle[0]:" in attrs["image_left_out"]


def test_a_sweeps_case_files_record_the_image_and_the_sweep_says_it_was_cropped(tmp_path):
    picture(tmp_path, colony())
    scene(tmp_path, 'path = "big.tif"\nvoxel = [0.5, 0.5]')
    (tmp_path / "two.toml").write_text('scene = "s.toml"\n[sweep]\nr = [50.0, 60.0]\n')
    result = invoke("sweep", tmp_path / "two.toml", "-o", tmp_path / "out", "-q")
    assert result.exit_code == 0, result.output
    assert "2 cases were given an image larger than the grid, cropped to it" in result.stderr, result.stderr
    for case in (tmp_path / "out" / "cases").glob("*.nc"):
        with xr.open_dataset(case) as ds:
            assert ds.attrs["image_biofilm_0_sha256"] and "75.0% of the image" in ds.attrs["image_left_out"]


@pytest.mark.parametrize("rows", [6400, 240])  # the whole 80 x 80 picture at once; 3 rows at a time (27 slabs)
def test_the_part_beyond_the_grid_is_counted_a_slab_at_a_time_as_whole(tmp_path, monkeypatch, rows):
    """The spill check counts a region a slab of `SLAB_VOXELS` at a time (an image region's memory counts one
    slab, issue 39.8): rows 30..49 of 0.5 µm pixels (y 15..25 µm) in a 20 µm grid, 20 columns wide: half the
    colony (rows 40..49, 200 pixels) and three quarters of the picture lie outside, however it is sliced."""
    from biostudy.inputs import images

    path = picture(tmp_path, colony(rows=slice(30, 50)))
    monkeypatch.setattr(images, "SLAB_VOXELS", rows)
    stat = path.stat()
    found = images._spill.__wrapped__(str(path), stat.st_mtime_ns, stat.st_size, None, None, (0.5, 0.5), (0.0, 0.0),
                                      (20.0, 20.0))
    assert found == (pytest.approx(0.75), pytest.approx(0.5), 200)
