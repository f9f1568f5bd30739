"""COMSTAT's own terms (issue 26): the substratum a biofilm rests on, connected-volume filtering, voxel counts.

The voxel estimator is checked against an independent count written here with plain loops over the voxels
(each biofilm voxel's six neighbours inside the domain), not against the module's array code.
"""
import itertools

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.inputs.scene import load_scene
from biostudy.quantities import comstat, substratum

# a flow cell: nutrient from the bulk on z+, a cap 4 µm thick on the glass (z-)
CAP = """\
name = "cap"
[grid]
shape = [6, 6, 12]
spacing = 1.0
[time]
t_end = 0.002
steps = 2
outputs = 2
[[nutrient]]
shape = "face"
face = "z+"
[[biofilm]]
shape = "box"
lower = [0.0, 0.0, 0.0]
upper = [6.0, 6.0, 4.0]
"""
FLOATING = '[[biofilm]]\nshape = "sphere"\ncenter = [3.0, 3.0, 9.0]\nradius = 2.0\n'


def _run(write_toml, tmp_path, text, name="run.nc"):
    scene = write_toml("scene.toml", text)
    result = CliRunner().invoke(app, ["run", str(scene), "-o", str(tmp_path / name), "-q"])
    assert result.exit_code == 0, result.output
    return xr.open_dataset(tmp_path / name).isel(time=0)


def test_a_flow_cell_cap_is_measured_from_the_face_it_rests_on_not_from_the_held_nutrient(write_toml, tmp_path):
    assert load_scene(write_toml("cap.toml", CAP)).substratum_face() == "z-"
    ds = _run(write_toml, tmp_path, CAP)
    assert ds.attrs["substratum_face"] == "z-"
    assert float(ds.max_thickness) == pytest.approx(4.0) and float(ds.coverage) == pytest.approx(1.0)
    agar = CAP.replace('face = "z+"', 'face = "z-"').replace("upper = [6.0, 6.0, 4.0]", "upper = [3.0, 3.0, 4.0]")
    assert load_scene(write_toml("agar.toml", agar)).substratum_face() == "z-"  # the colony on the agar


BAND_2D = """\
name = "band"
[grid]
shape = [8, 6]
spacing = 1.0
[time]
t_end = 0.002
steps = 2
outputs = 2
[[nutrient]]
shape = "face"
face = "y+"
[[biofilm]]
shape = "box"
lower = [0.0, 2.0]
upper = [8.0, 4.0]
"""


@pytest.mark.parametrize("name, text, faces", [
    ("slab", CAP.replace("lower = [0.0, 0.0, 0.0]", "lower = [0.0, 0.0, 4.0]").replace("[6.0, 6.0, 4.0]",
                                                                                      "[6.0, 6.0, 8.0]"),
     "x- and x+ and y- and y+ alike (it covers 33% of each)"),  # a slab across the domain, off both z faces
    ("band", BAND_2D, "x- and x+ alike"),  # 2-D: a band from wall to wall
    ("box", CAP.replace("[6.0, 6.0, 4.0]", "[6.0, 6.0, 12.0]").replace('"face"\nface = "z+"', '"box"\nlower = '
                                                                       '[0.0, 0.0, 11.0]\nupper = [6.0, 6.0, 12.0]'),
     "x- and x+ and y- and y+ and z- and z+ alike (it covers 100% of each)"),  # a block filling the box
    ("floating", CAP.replace("lower = [0.0, 0.0, 0.0]", "lower = [2.0, 2.0, 4.0]").replace(
        "[6.0, 6.0, 4.0]", "[4.0, 4.0, 6.0]"), "touches no face of the domain"),
])
def test_a_scene_runs_whatever_its_biofilm_touches_and_says_why_comstat_is_left_out(write_toml, tmp_path, name,
                                                                                      text, faces):
    """Issue 33.1: a scene without a single resting face runs; COMSTAT's six observables are left out of its
    dataset, whose attribute says why and which key brings them back, and `show` prints it."""
    out = tmp_path / f"{name}.nc"
    result = CliRunner().invoke(app, ["run", str(write_toml(f"{name}.toml", text)), "-o", str(out), "-q"])
    assert result.exit_code == 0, result.output
    ds = xr.open_dataset(out)
    assert not set(substratum.QUANTITIES) & set(ds.data_vars) and "substratum_face" not in ds.attrs
    said = ds.attrs["comstat_left_out"]
    assert faces in said and "[substratum] face = " in said and "biomass" in said, said
    assert "biofilm_volume" in ds and "height" in ds  # the rest is measured as ever
    shown = CliRunner().invoke(app, ["show", str(out)], env={"COLUMNS": "400"})
    assert shown.exit_code == 0 and faces in shown.stdout and "biomass " not in shown.stdout
    named = text + '[substratum]\nface = "' + ("y-" if name == "band" else "z-") + '"\n'
    assert "biomass" in _run(write_toml, tmp_path, named, f"{name}-named.nc")  # naming the face brings them back


def test_the_directional_sphere_floats_the_maze_says_none_and_a_held_face_settles_a_tie(write_toml):
    assert load_scene("studies/directional.toml").substratum_attrs()["comstat_left_out"].startswith(
        "COMSTAT's observables (biomass, ")
    corner = CAP.replace("upper = [6.0, 6.0, 4.0]", "upper = [3.0, 3.0, 3.0]").replace('face = "z+"', 'face = "y-"') \
        .replace("shape = [6, 6, 12]", "shape = [6, 6, 6]")
    assert load_scene(write_toml("held.toml", corner)).substratum_face() == "y-"  # the held face decides a tie
    assert load_scene(write_toml("tie.toml", corner.replace('face = "y-"', 'face = "y+"'))).substratum_face() is None
    maze = load_scene("studies/maze.toml")  # a plan view: its colony touches x+ at the entrance, but says "none"
    assert maze.substratum_face() is None and "says it has none" in maze.substratum_attrs()["comstat_left_out"]
    assert load_scene("studies/maze.toml", ['substratum.face="x+"']).substratum_face() == "x+"


def test_connected_volume_filtering_counts_the_cap_alone(write_toml, tmp_path):
    cap = _run(write_toml, tmp_path, CAP, "cap.nc")
    both = _run(write_toml, tmp_path, CAP + FLOATING, "both.nc")
    assert float(both.biomass) > float(cap.biomass) + 0.5  # the sphere counts without filtering
    filtered = _run(write_toml, tmp_path, CAP + FLOATING + "[substratum]\nconnected = true\n", "filtered.nc")
    assert filtered.attrs["substratum_connected"] == 1
    for name in substratum.QUANTITIES:
        assert float(filtered[name]) == pytest.approx(float(cap[name]), rel=1e-12, abs=1e-12), name


def _count(voxels):
    """Independently: biofilm voxels, and their faces on a background voxel inside the domain (plain loops)."""
    inside, faces = 0, 0
    shape = voxels.shape
    for index in itertools.product(*map(range, shape)):
        if not voxels[index]:
            continue
        inside += 1
        for axis, step in itertools.product(range(len(shape)), (-1, 1)):
            other = list(index)
            other[axis] += step
            if 0 <= other[axis] < shape[axis] and not voxels[tuple(other)]:
                faces += 1
    return inside, faces


def test_the_voxel_estimator_counts_voxel_faces_as_comstat_does(write_toml, tmp_path):
    dome = CAP[:CAP.index("[[biofilm]]")].replace("shape = [6, 6, 12]", "shape = [16, 14, 9]") \
        + '[[biofilm]]\nshape = "sphere"\ncenter = [8.0, 7.0, 0.0]\nradius = 6.0\n[substratum]\nestimator = "voxel"\n'
    ds = _run(write_toml, tmp_path, dome)
    voxels = ds.phi.transpose("z", "y", "x").values >= 0.5
    count, faces = _count(voxels)
    assert float(ds.surface_to_biovolume) == pytest.approx(faces / count, rel=0.01)
    assert float(ds.biomass) == pytest.approx(count / (16 * 14))
    tops = [max((k + 1 for k in range(9) if voxels[k, j, i]), default=0) for j in range(14) for i in range(16)]
    assert float(ds.max_thickness) == max(tops) and float(ds.mean_thickness) == pytest.approx(np.mean(tops))
    assert float(ds.coverage) == pytest.approx(voxels[0].sum() / (16 * 14))
    subcell = substratum.surface_to_biovolume(ds.phi.transpose("z", "y", "x").values, 1.0, "z-")
    assert faces / count > 1.2 * subcell  # the staircase: larger than the level set's area


def test_connected_leaves_phi_where_the_biofilm_touches_the_substratum():
    phi = np.zeros((8, 5, 5))
    phi[:2] = 1.0  # a layer on z-
    phi[5:7, 1:3, 1:3] = 0.9  # a floating block
    phi[0, 0, 0] = np.nan  # an obstacle cell stays one
    kept = comstat.connected(phi, "z-")
    assert np.isnan(kept[0, 0, 0]) and (kept[5:7] == 0).all() and (kept[1] == 1).all()
    assert (comstat.connected(phi, "z+")[:2, 1:, 1:] == 0).all()  # seen from z+, the layer is what floats


def test_asking_for_a_left_out_observable_is_refused_before_anything_runs(write_toml, tmp_path):
    """A calibration whose table names a COMSTAT observable of a scene without a substratum, and `analyze --output`
    of one, are refused in one line (exit 2); the calibration before any simulation, the analysis before it writes."""
    from conftest import TINY_SCENE

    write_toml("tiny.toml", TINY_SCENE.replace('[substratum]\nface = "y-"\n', ""))  # the colony floats
    write_toml("table.tsv", "observableId\ttime\tmeasurement\tnoiseParameters\nbiofilm_volume\t0.1\t30\t1\n"
                            "coverage\t0.1\t0.5\t0.1\n")
    calibration = write_toml("fit.toml", 'scene = "tiny.toml"\n[data]\nmeasurements = "table.tsv"\n'
                                         '[estimate]\nr = [50.0, 150.0]\n')
    refused = CliRunner().invoke(app, ["calibrate", str(calibration), "-o", str(tmp_path / "fit")])
    lines = refused.output.strip().splitlines()
    assert refused.exit_code == 2 and len(lines) == 1, refused.output
    assert "table.tsv: line 3: observableId: coverage: COMSTAT's observables" in lines[0]
    assert "touches no face" in lines[0] and not (tmp_path / "fit").exists()
    study = write_toml("study.toml", 'scene = "tiny.toml"\n[sweep]\nr = [50.0, 100.0]\n')
    out = tmp_path / "study"
    ran = CliRunner().invoke(app, ["sweep", str(study), "-o", str(out), "-q", "--set", "time.steps=4"])
    assert ran.exit_code == 0, ran.output
    refused = CliRunner().invoke(app, ["analyze", str(out), "--output", "biomass"])
    lines = refused.output.strip().splitlines()
    assert refused.exit_code == 2 and len(lines) == 1 and "biomass: COMSTAT's observables" in lines[0], refused.output
    assert not (out / "analysis.nc").exists()
