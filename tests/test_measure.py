"""A lab's confocal stack measured by the model's own COMSTAT code (issue 36.2): every observable against a
voxel count written here with plain loops (anisotropic voxels, substrata on either side, the connected-volume
filter), a run's voxel estimator against its own exported TIFF measured, time series as frames, and the
image-input rules (one line, nothing read past a declared size)."""
from __future__ import annotations

import itertools
import os
from collections import deque

import numpy as np
import pytest
import tifffile
import xarray as xr
from test_cli import invoke

from biostudy.errors import BadInput
from biostudy.inputs import stacks
from biostudy.quantities import stack_measures

VOXEL = (0.5, 0.2, 0.3)  # dz, dy, dx: a confocal stack's anisotropic voxels
AXIS = {"z": 0, "y": 1, "x": 2}


def imagej(path, values, voxel=VOXEL, axes="ZYX"):
    tifffile.imwrite(path, values, imagej=True, resolution=(1 / voxel[2], 1 / voxel[1]),
                     metadata={"spacing": voxel[0], "unit": "um", "axes": axes})
    return path


def blobs(seed: int, shape=(7, 6, 9)) -> np.ndarray:
    """Grey values 0..255: a mat on z = 0 with holes, columns of random height on it, and a floating piece."""
    rng = np.random.default_rng(seed)
    values = np.zeros(shape, np.uint8)
    values[0] = np.where(rng.random(shape[1:]) < 0.7, 200, 30)
    heights = rng.integers(0, shape[0] - 3, shape[1:])  # below the floating piece, a layer apart
    for j, i in itertools.product(range(shape[1]), range(shape[2])):
        values[: heights[j, i], j, i] = 180
    values[shape[0] - 2:, 1:3, 2:4] = 250  # a piece floating near the top
    values[shape[0] - 1, 4, 7] = 90  # below the threshold: background
    return values


def by_hand(mask: np.ndarray, voxel, face: str, connected: bool) -> dict:
    """COMSTAT's definitions, voxel by voxel with loops: biofilm voxels (optionally only those reached from the
    substratum layer through faces), columns normal to the face, faces between biofilm and background."""
    axis, side = AXIS[face[0]], face[1]
    n = mask.shape
    at_face = (lambda idx: idx[axis] == 0) if side == "-" else (lambda idx: idx[axis] == n[axis] - 1)
    kept = set(zip(*np.nonzero(mask)))
    if connected:
        reached, queue = set(), deque(idx for idx in kept if at_face(idx))
        reached.update(queue)
        while queue:
            idx = queue.popleft()
            for a, step in itertools.product(range(3), (-1, 1)):
                other = tuple(v + step if b == a else v for b, v in enumerate(idx))
                if other in kept and other not in reached:
                    reached.add(other)
                    queue.append(other)
        kept = reached
    cell = voxel[0] * voxel[1] * voxel[2]
    lateral = [a for a in range(3) if a != axis]
    area = n[lateral[0]] * voxel[lateral[0]] * n[lateral[1]] * voxel[lateral[1]]
    heights = []
    for u, v in itertools.product(range(n[lateral[0]]), range(n[lateral[1]])):
        top = 0.0
        for w in range(n[axis]):
            idx = [0, 0, 0]
            idx[lateral[0]], idx[lateral[1]], idx[axis] = u, v, w
            if tuple(idx) in kept:
                distance = (w + 1) if side == "-" else (n[axis] - w)
                top = max(top, distance * voxel[axis])
        heights.append(top)
    surface = 0.0
    for idx in kept:
        for a, step in itertools.product(range(3), (-1, 1)):
            other = tuple(v + step if b == a else v for b, v in enumerate(idx))
            if 0 <= other[a] < n[a] and other not in kept:
                surface += cell / voxel[a]
    mean = sum(heights) / len(heights)
    layer = [idx for idx in itertools.product(*map(range, n)) if at_face(idx)]
    return {"biomass": len(kept) * cell / area, "mean_thickness": mean, "max_thickness": max(heights),
            "roughness": sum(abs(h - mean) for h in heights) / len(heights) / mean,
            "coverage": sum(idx in kept for idx in layer) / len(layer),
            "surface_to_biovolume": surface / (len(kept) * cell)}


@pytest.mark.parametrize("face, connected, seed", [("z-", False, 1), ("z-", True, 2), ("x+", False, 3),
                                                   ("y-", True, 4)])
def test_every_observable_equals_a_voxel_count_by_hand(tmp_path, face, connected, seed):
    values = blobs(seed)
    frames = stacks.load(imagej(tmp_path / "s.tif", values))
    assert frames.voxel == pytest.approx(VOXEL, rel=1e-6) and frames.values.shape == (1, *values.shape)
    voxel = frames.voxel
    found = stack_measures.measure(frames, threshold=100, face=face, connected=connected)
    expected = by_hand(values >= 100, voxel, face, connected)
    assert found.face == face and len(found.rows) == 1
    for name, value in expected.items():
        assert found.rows[0][name] == pytest.approx(value, rel=1e-12), name
    if connected and face == "z-":  # the filter took the floating piece away
        assert expected["biomass"] < by_hand(values >= 100, voxel, face, False)["biomass"]


def test_the_substratum_is_found_as_a_scenes_and_a_tie_asks_for_it(tmp_path):
    values = blobs(5)
    frames = stacks.load(imagej(tmp_path / "s.tif", values))
    assert stack_measures.measure(frames, threshold=100).face == "z-"  # the mat covers z = 0 most
    slab = np.zeros((4, 6, 6), np.uint8)
    slab[:, :, 0] = slab[:, :, -1] = 1  # two walls, x- and x+ alike
    with pytest.raises(BadInput, match=r"substratum: the initial biofilm rests on x- and x\+ alike .*: give the "
                                       r"substratum \(its face"):
        stack_measures.measure(stacks.load(imagej(tmp_path / "tie.tif", slab)))
    with pytest.raises(BadInput, match=r"substratum: 'q-' is not a face of a 3-D stack"):
        stack_measures.measure(frames, threshold=100, face="q-")


def test_a_runs_voxel_observables_equal_its_exported_stack_measured(tmp_path):
    """The same code: a 3-D run with [substratum] estimator = "voxel" records its COMSTAT observables; its phi,
    exported as Fiji's TZYX hyperstack (float32, ImageJ voxel sizes), measured at threshold 0.5 gives them."""
    scene = tmp_path / "colony.toml"
    scene.write_text('name = "colony"\n[grid]\nshape = [8, 7, 6]\nspacing = 1.5\n[time]\nt_end = 0.02\nsteps = 4\n'
                     'outputs = 3\n[[biofilm]]\nshape = "box"\nlower = [3.0, 1.5, 0.0]\nupper = [9.0, 7.5, 3.0]\n'
                     '[[nutrient]]\nshape = "face"\nface = "z+"\n[substratum]\nface = "z-"\nestimator = "voxel"\n')
    assert invoke("run", scene, "-o", tmp_path / "run.nc", "-q").exit_code == 0
    assert invoke("export", tmp_path / "run.nc", tmp_path / "tiff", "--format", "tiff").exit_code == 0
    frames = stacks.load(tmp_path / "tiff" / "phi.tif")
    assert frames.values.shape == (3, 6, 7, 8) and frames.voxel == pytest.approx((1.5, 1.5, 1.5))
    found = stack_measures.measure(frames, threshold=0.5, face="z-")
    ds = xr.open_dataset(tmp_path / "run.nc")
    for name in stack_measures.OBSERVABLES:
        np.testing.assert_allclose([row[name] for row in found.rows], ds[name].values, rtol=1e-12, err_msg=name)
    assert ds.biomass.values[0] == pytest.approx(4 * 4 * 2 * 1.5**3 / (12 * 10.5))  # the box: 4 x 4 x 2 cells


def test_a_time_series_is_one_row_per_frame(tmp_path):
    series = np.stack([blobs(seed) for seed in (6, 7, 8)])
    frames = stacks.load(imagej(tmp_path / "t.tif", series, axes="TZYX"))
    assert frames.values.shape == (3, 7, 6, 9)
    found = stack_measures.measure(frames, threshold=100, face="z-")
    for t, row in enumerate(found.rows):
        assert row == pytest.approx(by_hand(series[t] >= 100, frames.voxel, "z-", False), rel=1e-12)


def test_a_segmented_stack_needs_no_threshold_a_greyscale_one_does(tmp_path):
    values = blobs(9)
    segmented = stacks.load(imagej(tmp_path / "seg.tif", (values >= 100).astype(np.uint8) * 255))
    grey = stacks.load(imagej(tmp_path / "grey.tif", values))
    assert stack_measures.measure(segmented).rows == stack_measures.measure(grey, threshold=100).rows
    with pytest.raises(BadInput, match=r"threshold: .*grey.tif is greyscale \(\d+ voxels neither 0 nor 250\)"):
        stack_measures.measure(grey)


def one_line(call) -> str:
    with pytest.raises(BadInput) as raised:
        call()
    assert len(raised.value.lines()) == 1
    return str(raised.value)


def test_bad_stacks_are_one_line_each(tmp_path, monkeypatch):
    values = blobs(10)
    tifffile.imwrite(tmp_path / "plain.tif", values, photometric="minisblack")
    imagej(tmp_path / "ij.tif", values)
    with tifffile.TiffFile(tmp_path / "ij.tif") as tif:
        end = tif.pages[0].dataoffsets[0] + values.nbytes  # the pixels end here, the other pages' IFDs follow
    (tmp_path / "short.tif").write_bytes((tmp_path / "ij.tif").read_bytes()[:end - 10])
    tifffile.imwrite(tmp_path / "channels.tif", np.stack([values, values], axis=1), imagej=True,
                     metadata={"axes": "ZCYX"})
    (tmp_path / "dir.tif").mkdir()
    os.mkfifo(tmp_path / "fifo.tif")
    (tmp_path / "text.txt").write_text("x")
    cases = {
        lambda: stacks.load(tmp_path / "plain.tif"): "plain.tif states no voxel size (no ImageJ or OME metadata); "
                                                     "give the voxel size (voxel: dz,dy,dx in µm)",
        lambda: stacks.load(tmp_path / "plain.tif", [0.5, 0.2]): "voxel: has 2 entries; ",
        lambda: stacks.load(tmp_path / "plain.tif", [0.5, 0.2, -1.0]): "voxel: -1 is not a voxel size",
        lambda: stacks.load(tmp_path / "short.tif"): "short.tif: its ImageJ metadata declares 7 images, the file "
                                                     "holds 1",
        lambda: stacks.load(tmp_path / "channels.tif"): "measure takes one greyscale or segmented z-y-x stack or "
                                                        "y-x picture (one channel, a time series as frames (T first)",
        lambda: stacks.load(tmp_path / "dir.tif"): "dir.tif: is a directory, not a TIFF stack or PNG picture",
        lambda: stacks.load(tmp_path / "fifo.tif"): "fifo.tif: is a FIFO (named pipe), not a TIFF stack",
        lambda: stacks.load(tmp_path / "none.tif"): "none.tif: no such file",
        lambda: stacks.load(tmp_path / "text.txt"): "text.txt: is not a TIFF or PNG file",
    }
    for call, expected in cases.items():
        assert expected in one_line(call), expected


def test_a_stack_declaring_more_than_the_memory_is_refused_before_a_pixel_is_read(tmp_path, monkeypatch):
    """A 300-byte tiled TIFF whose header says 20000 x 20000 pixels; measuring it would need the values (1 byte
    each) and 8 bytes a voxel more: refused from the header."""
    from test_images_files import huge_tiff

    path = huge_tiff(tmp_path / "huge.tif", monkeypatch)
    monkeypatch.setenv("BIOSTUDY_MEMORY", "2 GB")
    assert "[1, 20000, 20000] voxels: reading and measuring it needs ~3.6 GB of memory, 2 GB available" in one_line(
        lambda: stacks.load(path, [1.0, 1.0]))


def test_the_petab_table_of_a_time_series_is_read_by_a_calibration_and_by_petab(tmp_path):
    """Issue 36.2: measure's --petab table of a 3-frame series at 0, 12, 24 h is the measurement table a calibration
    reads (its σ named per observable, estimated) and that petab's own check takes."""
    from test_calibration_hostile import SCENE

    from biostudy.calibration.problem import load_calibration
    from biostudy.reports import measured

    series = np.stack([blobs(seed) for seed in (11, 12, 13)])
    frames = stacks.load(imagej(tmp_path / "colony 1.tif", series, axes="TZYX"))
    rows = measured.records([stack_measures.measure(frames, threshold=100, face="z-")], [0.0, 12.0, 24.0])
    text = measured.petab_text(rows, observables=("biomass", "max_thickness"))
    (tmp_path / "m.tsv").write_text(text)
    lines = text.splitlines()
    assert lines[0] == "observableId\tsimulationConditionId\ttime\tmeasurement\tnoiseParameters\tdatasetId"
    assert lines[1:3] == [f"biomass\t\t0.0\t{rows[0]['biomass']!r}\tsigma_biomass\tcolony_1",
                          f"max_thickness\t\t0.0\t{rows[0]['max_thickness']!r}\tsigma_max_thickness\tcolony_1"]
    (tmp_path / "speck.toml").write_text(SCENE.replace("t_end = 0.1", "t_end = 1.0"))
    (tmp_path / "c.toml").write_text('scene = "speck.toml"\n[data]\nmeasurements = "m.tsv"\ntime_unit = "h"\n'
                                     't_ref = "48 h"\n[estimate]\ng = [1e7, 1e10, "log"]\n')
    plan = load_calibration(tmp_path / "c.toml")
    assert [m.value for m in plan.measurements] == [rows[t][n] for t in range(3) for n in ("biomass",
                                                                                           "max_thickness")]
    assert [n.name for n in plan.noise] == ["sigma_biomass", "sigma_max_thickness"]
    np.testing.assert_allclose(plan.times, np.repeat([0.0, 0.25, 0.5], 2))
    petab = pytest.importorskip("petab.v1")
    from petab.v1.lint import check_measurement_df

    check_measurement_df(petab.get_measurement_df(tmp_path / "m.tsv"))


def test_the_measurement_table_is_a_new_file_never_one_that_is_there(tmp_path, monkeypatch):
    """--petab refuses a file that is there, and keeps one that appears while the stacks are measured (linked into
    place, not renamed over); nothing else is left in the folder."""
    from biostudy.commands import measure
    from biostudy.reports import measured

    stack = imagej(tmp_path / "s.tif", blobs(14))
    (tmp_path / "mine.tsv").write_text("my table")
    with pytest.raises(BadInput, match=r"mine.tsv: petab: exists; the measurement table is written as a new file"):
        measure.measure([stack], threshold=100, petab=tmp_path / "mine.tsv", time=[1.0])
    with pytest.raises(BadInput, match=r"time: gives 2 times for 1 frames"):
        measure.measure([stack], threshold=100, petab=tmp_path / "m.tsv", time=[1.0, 2.0])
    made = measured.petab_text

    def meanwhile(*args, **kwargs):
        (tmp_path / "m.tsv").write_text("a colleague's table")
        return made(*args, **kwargs)

    monkeypatch.setattr(measured, "petab_text", meanwhile)
    with pytest.raises(BadInput, match=r"m.tsv: petab: appeared while the stacks were measured; it is kept"):
        measure.measure([stack], threshold=100, petab=tmp_path / "m.tsv", time=[1.0])
    assert (tmp_path / "m.tsv").read_text() == "a colleague's table"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.tsv", "mine.tsv", "s.tif"]


def test_measure_from_the_command_line_and_from_python_alike(tmp_path):
    """`biostudy measure` (--json, --petab with --time) and `biostudy.measure` give the same records and tables;
    a mistake is one line, keyed by the flag on the command line and by the name in Python."""
    import json

    import biostudy

    series = np.stack([blobs(seed) for seed in (15, 16)])
    stack = imagej(tmp_path / "t.tif", series, axes="TZYX")
    result = invoke("measure", stack, "--threshold", "100", "--substratum", "z-", "--json", "--petab",
                    tmp_path / "cli.tsv", "--time", "0,12", "--noise", "biomass=0.2")
    assert result.exit_code == 0, result.output
    records = biostudy.measure(stack, threshold=100, substratum="z-", petab=tmp_path / "api.tsv", time=[0, 12],
                               noise={"biomass": 0.2})
    assert json.loads(result.stdout) == records and [r["time"] for r in records] == [0.0, 12.0]
    assert (tmp_path / "cli.tsv").read_text() == (tmp_path / "api.tsv").read_text()
    written = (tmp_path / "cli.tsv").read_text()
    assert "biomass\t\t0.0\t" in written and "\t0.2\tt\n" in written
    assert f"wrote {tmp_path / 'cli.tsv'}" in result.stderr
    table = invoke("measure", stack, "--threshold", "100").stdout
    assert table.startswith("| file | frame | time | biomass (µm) |")
    assert "substratum z-, biofilm: values >= 100" in table
    for args, line in ((["--petab", tmp_path / "x.tsv"], "error: --time: the measurement table needs the time"),
                       (["--voxel", "0.5,-1,2"], "error: --voxel: give voxel sizes: numbers > 0"),
                       (["--substratum", "w+"], "error: --substratum: unknown face 'w+'")):
        bad = invoke("measure", stack, "--threshold", "100", *args)
        assert bad.exit_code == 2 and bad.stderr.strip().startswith(line) and len(bad.stderr.splitlines()) == 1, \
            bad.stderr
    with pytest.raises(BadInput, match=r"^time: the measurement table needs the time"):
        biostudy.measure(stack, threshold=100, petab=tmp_path / "x.tsv")
