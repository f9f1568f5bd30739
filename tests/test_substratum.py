"""Substratum observables (biostudy.quantities.substratum) against values computed by hand on synthetic fields.

The fields are built from ramps: phi = clip(0.5 + d / (2 w), 0, 1) with d the signed distance to the wanted
surface, so phi = 0.5 exactly on it and is linear across it over a width 2 w.  Where phi is linear (unclipped)
at the cell centres around the surface, linear interpolation puts the level set exactly on it, so the
hand values are exact; a curved surface (the hemisphere) is approximated to second order in h.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr

from biostudy.quantities import substratum as sub
from biostudy.quantities.substratum import substratum_observables as observe
from solver.problem import FACES

NAMES = ("biomass", "mean_thickness", "max_thickness", "roughness", "coverage", "surface_to_biovolume")


def ramp(distance, width):
    return np.clip(0.5 + np.asarray(distance) / (2.0 * width), 0.0, 1.0)


def centres(n, h=1.0):
    return (np.arange(n) + 0.5) * h


def slab(thickness, shape, h=1.0, width=1.0):
    """phi of a flat slab on the bottom face (axis 0) crossing 0.5 at `thickness`."""
    profile = ramp(thickness - centres(shape[0], h), width)
    return profile.reshape((-1,) + (1,) * (len(shape) - 1)) * np.ones(shape)


def check(values, expected, rel=1e-12, abs=1e-12):
    for name, value in expected.items():
        if math.isnan(value):
            assert math.isnan(values[name]), name
        else:
            assert values[name] == pytest.approx(value, rel=rel, abs=abs), name


# ---- flat slab, thin film, threshold ---------------------------------------------------------------------------

@pytest.mark.parametrize("h", [1.0, 0.5])
@pytest.mark.parametrize("shape", [(10, 6, 8), (10, 8)], ids=["3-D", "2-D"])
def test_flat_slab_crossing_at_3_3_um(h, shape):
    # phi = 1, 1, 0.9, 0.4, 0 at centres 0.5 ... 4.5 µm (h = 1): the crossing is 2.5 + 0.4/0.5 = 3.3 µm
    n = int(round(shape[0] / h))
    phi = slab(3.3, (n,) + tuple(int(round(s / h)) for s in shape[1:]), h)
    face = "z-" if len(shape) == 3 else "y-"
    check(observe(phi, h, face), {"biomass": 3.3, "mean_thickness": 3.3, "max_thickness": 3.3, "roughness": 0.0,
                                  "coverage": 1.0, "surface_to_biovolume": 1 / 3.3})
    np.testing.assert_allclose(sub.thickness_profile(phi, h, face), 3.3, rtol=1e-12)
    assert sub.surface_area(phi, h, face) == pytest.approx(sub.substratum_area(phi, h, face), rel=1e-12)


def test_threshold_may_be_set():
    # phi = 1, 1, 0.9, 0.4, 0 at the centres 0.5 ... 4.5 µm crosses 0.3 at 3.5 + (0.4 - 0.3)/0.4 = 3.75 µm
    phi = slab(3.3, (10, 6, 8))
    values = observe(phi, 1.0, "z-", threshold=0.3)
    check(values, {"biomass": 3.75, "mean_thickness": 3.75, "max_thickness": 3.75, "surface_to_biovolume": 1 / 3.75})


def test_film_thinner_than_half_a_cell():
    # phi = 0.45, 0.2, 0 at the centres 0.5, 1.5, 2.5 µm: continued linearly to the substratum (0.575 there) it
    # crosses 0.5 at 0.3 µm, while the first layer (0.45) is below the threshold: no coverage
    phi = slab(0.3, (6, 5, 7), width=2.0)
    check(observe(phi, 1.0, "z-"), {"biomass": 0.3, "mean_thickness": 0.3, "max_thickness": 0.3, "roughness": 0.0,
                                     "coverage": 0.0, "surface_to_biovolume": 1 / 0.3})


# ---- steps of known heights ------------------------------------------------------------------------------------

STEPS = np.array([2.0] * 4 + [3.5] * 4 + [1.2] * 4)  # µm, twelve columns of 1 µm


def steps_2d():
    # phi linear in z with the same slope in every column (w = 5 µm: unclipped wherever the level set passes), so
    # between two column centres the level set is the straight line joining the columns' tops
    return ramp(STEPS[None, :] - centres(10)[:, None], 5.0)


def steps_by_hand():
    """The height map: 2.0 on [0, 3.5], 2.0 -> 3.5 on [3.5, 4.5], 3.5 on [4.5, 7.5], 3.5 -> 1.2 on [7.5, 8.5],
    1.2 on [8.5, 12] (the side walls mirror: flat over the half cell next to them)."""
    integral = 3.5 * 2.0 + (2.0 + 3.5) / 2 + 3.0 * 3.5 + (3.5 + 1.2) / 2 + 3.5 * 1.2  # 26.8 = sum of the columns
    mean = integral / 12  # 2.2333
    d1, d2, d3 = 2.0 - mean, 3.5 - mean, 1.2 - mean

    def across(a, b):  # ∫ |L - mean| over one cell where L - mean goes linearly from a to b, of opposite signs
        return (a * a + b * b) / (2 * abs(a - b))

    absolute = 3.5 * abs(d1) + across(d1, d2) + 3.0 * abs(d2) + across(d2, d3) + 3.5 * abs(d3)  # 9.36722
    length = 3.5 + math.hypot(1.0, 1.5) + 3.0 + math.hypot(1.0, 2.3) + 3.5  # the level set, µm
    return {"biomass": mean, "mean_thickness": mean, "max_thickness": 3.5, "roughness": absolute / integral,
            "coverage": 1.0, "surface_to_biovolume": length / integral}


def test_steps_2d():
    phi = steps_2d()
    np.testing.assert_allclose(sub.thickness_profile(phi, 1.0, "y-"), STEPS, rtol=1e-12)
    expected = steps_by_hand()
    check(observe(phi, 1.0, "y-"), expected)
    assert expected["roughness"] == pytest.approx(0.349523, abs=1e-6)
    # COMSTAT's column formula, mean |L_i - mean| / mean, would say 0.378: the height map ramps across a step
    assert np.mean(np.abs(STEPS - STEPS.mean())) / STEPS.mean() == pytest.approx(0.378109, abs=1e-6)


def test_steps_3d_extruded():
    phi = np.repeat(steps_2d()[:, None, :], 5, axis=1)  # (z, y, x), uniform along y
    check(observe(phi, 1.0, "z-"), steps_by_hand())
    np.testing.assert_allclose(sub.thickness_profile(phi, 1.0, "z-"), np.tile(STEPS, (5, 1)), rtol=1e-12)


def test_pore_counts_in_biomass_and_surface_not_in_thickness():
    # a slab 6.3 µm thick (dense below 5.3 µm) with an empty block of 2 x 4 cells inside (rows 2-3, columns 4-7):
    # its level set runs through the faces' midpoints and cuts each corner cell's quarter to a triangle of 1/8
    phi = slab(6.3, (10, 12))
    phi[2:4, 4:8] = 0.0
    pore = 2 * 4 - 4 * (0.25 - 0.125)  # 7.5 µm²
    perimeter = 2 * (4 - 1) + 2 * (2 - 1) + 4 * math.sqrt(0.5)  # straight sides between the corner cuts, and cuts
    area = 12 * 6.3 - pore
    check(observe(phi, 1.0, "y-"), {"biomass": area / 12, "mean_thickness": 6.3, "max_thickness": 6.3,
                                    "roughness": 0.0, "coverage": 1.0,
                                    "surface_to_biovolume": (12 + perimeter) / area})


# ---- hemisphere, half disc: refinement ---------------------------------------------------------------------------

def dome(radius, h, ndim, side=14.0, height=8.0, width=2.0, centre=(7.0, 7.0)):
    """A ball of `radius` centred on the substratum (z = 0), phi a ramp in the distance from its centre."""
    z = centres(int(round(height / h)), h)
    lateral = [centres(int(round(side / h)), h)] * (ndim - 1)
    grids = np.meshgrid(z, *lateral, indexing="ij")
    distance = np.sqrt(grids[0] ** 2 + sum((g - c) ** 2 for g, c in zip(grids[1:], centre)))
    return ramp(radius - distance, width)


def relative_errors(ndim, h, r=5.0, side=14.0):
    phi = dome(r, h, ndim)
    face = "z-" if ndim == 3 else "y-"
    values = observe(phi, h, face)
    volume, surface = sub.biovolume(phi, h, face), sub.surface_area(phi, h, face)
    section = math.sqrt(r * r - h * h / 4)  # the first layer's plane cuts the ball h/2 above its centre
    if ndim == 3:
        exact = {"volume": 2 / 3 * math.pi * r**3, "surface": 2 * math.pi * r**2, "ratio": 3 / r,
                 "coverage": math.pi * section**2 / side**2}
    else:
        exact = {"volume": math.pi * r**2 / 2, "surface": math.pi * r, "ratio": 2 / r, "coverage": 2 * section / side}
    got = {"volume": volume, "surface": surface, "ratio": values["surface_to_biovolume"],
           "coverage": values["coverage"]}
    assert values["mean_thickness"] == pytest.approx(values["biomass"], rel=1e-12)  # no pores, no overhangs
    assert values["max_thickness"] == pytest.approx(r, abs=h)
    return {k: abs(got[k] / exact[k] - 1) for k in exact}


@pytest.mark.parametrize("ndim", [3, 2])
def test_hemisphere_converges_at_second_order(ndim):
    # measured relative errors at h = 1, 1/2, 1/4 µm (r = 5 µm), 3-D: volume 2.1e-2, 5.6e-3, 1.4e-3; surface 9.9e-3,
    # 2.8e-3, 7.4e-4; 3/r 1.1e-2, 2.8e-3, 7.0e-4; coverage 8.6e-3, 2.1e-3, 5.3e-4; 2-D: volume 7.3e-3, 2.0e-3,
    # 5.0e-4; length 1.3e-3, 4.6e-4, 1.3e-4; 2/r 6.0e-3, 1.5e-3, 3.7e-4: second order (4 per halving in the limit),
    # the error of placing a curved surface by linear interpolation between cell centres
    errors = [relative_errors(ndim, h) for h in (1.0, 0.5, 0.25)]
    for name in errors[0]:
        e = [err[name] for err in errors]
        assert e[2] < 2e-3, (name, e)
        assert e[0] > 2.5 * e[1] and e[1] > 2.5 * e[2], (name, e)


# ---- coverage of a known footprint ---------------------------------------------------------------------------

def wall(position, shape, h=1.0):
    """Biofilm filling x < position from the substratum to the opposite face (a vertical wall along x)."""
    x = centres(shape[-1], h)
    return ramp(position - x, 2.0) * np.ones(shape)


def test_coverage_of_a_half_plane_footprint():
    phi = wall(5.3, (6, 5, 12))
    values = observe(phi, 1.0, "z-")
    # the biofilm is the box x < 5.3 µm, 6 µm tall; its surface the wall x = 5.3 (6 x 5 µm²)
    check(values, {"coverage": 5.3 / 12, "biomass": 5.3 * 6 / 12, "mean_thickness": 5.3 * 6 / 12,
                   "max_thickness": 6.0, "surface_to_biovolume": 1 / 5.3,
                   "roughness": (5.3 * (6 - 2.65) + 6.7 * 2.65) / 12 / 2.65})


def test_coverage_2d_first_layer_by_hand():
    # first layer 1, 1, 0.8, 0.2, 0 ...: covered from the wall to 2.5 + 0.3/0.6 = 3.0 µm
    phi = np.zeros((6, 12))
    phi[0, :4] = [1.0, 1.0, 0.8, 0.2]
    assert sub.coverage(phi, 1.0, "y-") == pytest.approx(3.0 / 12, rel=1e-12)


# ---- faces -----------------------------------------------------------------------------------------------------

def on_face(field, face):
    """A field given with the normal first (index 0 at the substratum) placed on `face` of a (z, y, x) or (y, x)
    array."""
    axis = field.ndim - 1 - "xyz".index(face[0])
    phi = np.moveaxis(field, 0, axis)
    return np.flip(phi, axis) if face[1] == "+" else phi


def asymmetric(ndim):
    """An off-centre dome on a staircase of different heights: nothing is symmetric."""
    phi = dome(4.0, 1.0, ndim, side=12.0, height=9.0, centre=(4.3, 6.8)[: ndim - 1])
    x = centres(12)
    steps = ramp(np.where(x < 6, 1.7, np.where(x < 9, 2.6, -1.0))[None, :] - centres(9)[:, None], 1.0)
    steps = steps if ndim == 2 else steps[:, None, :] * np.ones((1, 12, 1))
    return np.maximum(phi, steps)


@pytest.mark.parametrize("ndim", [3, 2])
def test_every_face_gives_the_same_numbers(ndim):
    field = asymmetric(ndim)  # given on the bottom face
    bottom = "z-" if ndim == 3 else "y-"
    reference, profile = observe(field, 1.0, bottom), sub.thickness_profile(field, 1.0, bottom)
    for face in FACES[: 2 * ndim]:
        phi = on_face(field, face)
        check(observe(phi, 1.0, face), reference, rel=1e-10, abs=1e-12)
        np.testing.assert_allclose(sub.thickness_profile(phi, 1.0, face), profile, rtol=1e-12)
    assert reference["roughness"] > 0.1 and 0 < reference["coverage"] < 1


def test_lateral_mirror_and_transpose_change_only_the_triangulation():
    # marching cubes splits a cell's non-planar quadrilateral into two triangles along a diagonal that depends on
    # the orientation, so a mirrored field differs by a fraction of the discretisation error (measured <= 2e-4
    # relative here, where that error is ~1e-2 at h = 1 µm); column quantities are exact
    field = asymmetric(3)
    reference = observe(field, 1.0, "z-")
    for phi in (field[:, ::-1, :], field[:, :, ::-1], field.transpose(0, 2, 1)):
        values = observe(phi, 1.0, "z-")
        check(values, reference, rel=1e-3)
        check(values, {n: reference[n] for n in ("max_thickness", "coverage")}, rel=1e-12)


def test_faces_that_do_not_exist():
    with pytest.raises(ValueError, match=r"^'z-' is not a face of a 2-D grid \(faces: x-, x\+, y-, y\+\)$"):
        sub.biomass(np.zeros((4, 4)), 1.0, "z-")
    with pytest.raises(ValueError, match="'bottom' is not a face of a 3-D grid"):
        sub.biomass(np.zeros((4, 4, 4)), 1.0, "bottom")
    with pytest.raises(ValueError, match="2-D or 3-D"):
        sub.biomass(np.zeros(4), 1.0, "x-")


# ---- obstacles, empty, full ---------------------------------------------------------------------------------------

def test_obstacle_columns_2d_by_hand():
    # the slab of 3.3 µm (phi 1, 1, 0.9, 0.4, 0 up the columns) beside an obstacle filling columns 0 and 1
    phi = slab(3.3, (10, 12))
    phi[:, :2] = np.nan
    # the obstacle's cells count as phi = 0: the level set runs half-way between them and the slab's centres
    # (x = 2.0) where the slab's phi is 1, and is cut across the corner where it is 0.9 and 0.4: in the strip
    # 1.5 < x < 2.5 the biofilm is 0.5 x 0.5 (ghost half cell) + 0.5 x 1 + a trapezium 0.5 -> 0.5 - 0.5/0.9 + 0.5
    # up to z = 2.5, and above it the triangle (2.0556, 2.5), (2.5, 2.5), (2.5, 3.3)
    cut = 0.5 / 0.9  # where the level set crosses z = 2.5: x = 1.5 + cut
    strip = 0.25 + 0.5 + (0.5 + (1.0 - cut)) / 2 + 0.5 * (1.0 - cut) * 0.8
    area = strip + 9.5 * 3.3
    length = 9.5 + math.hypot(1.0 - cut, 0.8) + math.hypot(cut - 0.5, 1.0) + 1.5  # top, cut, slant, x = 2 below
    expected = {"biomass": area / 12, "mean_thickness": area / 12, "max_thickness": 3.3,
                "coverage": 10 / 12, "surface_to_biovolume": length / area}
    values = observe(phi, 1.0, "y-")
    check(values, expected)
    np.testing.assert_allclose(sub.thickness_profile(phi, 1.0, "y-"), [0, 0] + [3.3] * 10, rtol=1e-12)
    zeros = np.nan_to_num(phi, nan=0.0)
    check(observe(zeros, 1.0, "y-"), values)  # NaN is exactly "not biofilm"


def test_obstacle_away_from_the_biofilm_changes_nothing():
    phi = slab(3.3, (12, 8, 8))
    reference = observe(phi, 1.0, "z-")
    phi[7:10, 2:5, 3:6] = np.nan
    check(observe(phi, 1.0, "z-"), reference)


@pytest.mark.parametrize("shape", [(5, 6, 7), (5, 6)], ids=["3-D", "2-D"])
def test_empty_and_full(shape):
    face = "z-" if len(shape) == 3 else "y-"
    check(observe(np.zeros(shape), 1.0, face),
          {"biomass": 0.0, "mean_thickness": 0.0, "max_thickness": 0.0, "roughness": math.nan, "coverage": 0.0,
           "surface_to_biovolume": math.nan})
    assert not np.any(sub.thickness_profile(np.zeros(shape), 1.0, face))
    check(observe(np.full(shape, np.nan), 1.0, face), {"biomass": 0.0, "roughness": math.nan})
    # filling the domain: no surface exposed to liquid
    check(observe(np.ones(shape), 1.0, face),
          {"biomass": 5.0, "mean_thickness": 5.0, "max_thickness": 5.0, "roughness": 0.0, "coverage": 1.0,
           "surface_to_biovolume": 0.0})


# ---- continuity: no steps of one cell ----------------------------------------------------------------------------

def test_slab_top_shifting_by_fractions_of_a_cell():
    for thickness in np.linspace(3.0, 4.0, 21):
        phi = slab(thickness, (10, 4, 5))
        check(observe(phi, 1.0, "z-"), {"biomass": thickness, "mean_thickness": thickness,
                                         "max_thickness": thickness, "surface_to_biovolume": 1 / thickness},
              rel=1e-10)


@pytest.mark.parametrize("shape", [(6, 5, 12), (6, 12)], ids=["3-D", "2-D"])
def test_side_wall_shifting_by_fractions_of_a_cell(shape):
    positions = np.linspace(4.0, 6.0, 21)
    face = "z-" if len(shape) == 3 else "y-"
    values = [observe(wall(x, shape), 1.0, face) for x in positions]
    for x, v in zip(positions, values):
        check(v, {"biomass": 6 * x / 12, "mean_thickness": 6 * x / 12, "coverage": x / 12,
                  "surface_to_biovolume": 1 / x}, rel=1e-10)
    # COMSTAT's column mean jumps by a column's height as the wall passes a column centre
    column_mean = [sub.thickness_profile(wall(x, shape), 1.0, face).mean() for x in positions]
    assert np.unique(np.round(column_mean, 9)).size == 3  # x < 4.5, 4.5 < x < 5.5, x > 5.5


def test_growing_dome_changes_every_observable_smoothly():
    # r from 4.0 to 5.0 µm in steps of h/40: a cell-counting observable moves in steps (increments of 0, 1, 2
    # cells); these have increments that vary by at most a few per cent from one step to the next
    radii = np.linspace(4.0, 5.0, 41)
    series = {n: [] for n in NAMES}
    for r in radii:
        for n, v in observe(dome(r, 1.0, 3, width=1.0, centre=(7.2, 6.9)), 1.0, "z-").items():
            series[n].append(v)
    for n, values in series.items():
        steps = np.diff(values)
        assert np.all(np.sign(steps) == np.sign(steps[0])), n  # monotone
        assert np.max(np.abs(np.diff(steps))) < 0.1 * np.mean(np.abs(steps)), n


# ---- the table --------------------------------------------------------------------------------------------------

def test_table_names_units_and_functions():
    assert tuple(sub.QUANTITIES) == NAMES
    units = {q.name: q.units for q in sub.QUANTITIES.values()}
    assert units == {"biomass": "um", "mean_thickness": "um", "max_thickness": "um", "roughness": "1",
                     "coverage": "1", "surface_to_biovolume": "um^-1"}
    cf_units = pytest.importorskip("cf_units")  # udunits: the reduced spellings are the ratios they stand for
    assert cf_units.Unit("um3/um2").convert(1.0, "um") == 1.0 and cf_units.Unit("um2/um3").convert(1.0, "um^-1") == 1.0
    phi = asymmetric(3)
    together = observe(phi, 1.0, "z-")
    for q in sub.QUANTITIES.values():
        assert q.long_name
        assert q.compute(phi, 1.0, "z-") == pytest.approx(together[q.name], rel=1e-12)


# ---- the scene's [substratum], recorded in the datasets; a vanished dense biofilm ---------------------------------

AGAR = """\
name = "agar-tiny"
[grid]
shape = [12, 12]
[time]
t_end = 0.1
steps = 25
outputs = 3
[[nutrient]]
shape = "face"
face = "y-"
[[biofilm]]
shape = "box"
lower = [3.0, 0.0]
upper = [9.0, 3.0]
[numerics]
advection = "tvd"
growth_velocity = "front"
"""


def test_the_substratum_defaults_to_the_face_the_biofilm_rests_on_and_a_run_records_it(write_toml, tmp_path):
    from typer.testing import CliRunner

    from biostudy.cli import app
    from biostudy.inputs.scene import load_scene

    scene = write_toml("agar.toml", AGAR)
    assert load_scene(scene).substratum_face() == "y-"  # the colony rests on the agar
    assert load_scene(scene, ['nutrient.0.face="x+"']).substratum_face() == "y-"  # a held face it does not touch
    assert load_scene(scene, ['substratum.face="x-"']).substratum_face() == "x-"
    plain = write_toml("plain.toml", AGAR.replace('shape = "face"\nface = "y-"', 'shape = "box"\nlower = [0.0, '
                                                  '11.0]\nupper = [12.0, 12.0]'))
    assert load_scene(plain).substratum_face() == "y-"  # no held face: where the colony rests
    out = tmp_path / "run.nc"
    result = CliRunner().invoke(app, ["run", str(scene), "-o", str(out), "-q", "--set", "substratum.threshold=0.4"])
    assert result.exit_code == 0, result.output
    ds = xr.open_dataset(out)  # a run with --set keeps its shape
    assert ds.attrs["substratum_face"] == "y-" and ds.attrs["substratum_threshold"] == 0.4
    expected = [sub.biomass(phi, 1.0, "y-", 0.4) for phi in ds.phi.values]
    shown = CliRunner().invoke(app, ["show", str(out)])
    assert shown.exit_code == 0 and "biomass" in shown.stdout and "surface_to_biovolume" in shown.stdout
    from biostudy.quantities import observables

    np.testing.assert_allclose(observables.evaluate(ds, "biomass").values, expected, rtol=1e-12)
    assert expected[-1] > expected[0] > 0
    import matplotlib.pyplot as plt

    from biostudy.plots import series

    figure = series.figure(ds.load())  # plot's series: a third panel with the substratum's measures
    lines = {line.get_label(): line.get_ydata() for line in figure.axes[2].lines}
    np.testing.assert_allclose(lines["biomass"], expected, rtol=1e-12)
    plt.close(figure)


@pytest.mark.parametrize("face, expected", [
    ('"z-"', "substratum.face: 'z-' is not a face of a 2-D grid (faces: x-, x+, y-, y+)"),
    ('"w-"', "substratum.face: must be 'x-', 'x+', 'y-', 'y+', 'z-', 'z+' or 'none'"),
])
def test_a_wrong_substratum_face_is_one_line(write_toml, tmp_path, face, expected):
    from typer.testing import CliRunner

    from biostudy.cli import app

    scene = write_toml("agar.toml", AGAR + f"[substratum]\nface = {face}\n")
    result = CliRunner().invoke(app, ["run", str(scene), "-q", "-o", str(tmp_path / "out.nc")])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and str(scene) in lines[0], result.stderr
    assert not (tmp_path / "out.nc").exists()


def _series(dense, biofilm):
    """A 2-D dataset of 1 µm cells whose phi >= 0.8 and phi >= 0.5 cover the given numbers of cells per output."""
    phi = np.zeros((len(dense), 10, 10))
    for t, (d, b) in enumerate(zip(dense, biofilm)):
        flat = phi[t].reshape(-1)
        flat[:b] = 0.6
        flat[:d] = 0.9
    coords = {"time": np.linspace(0, 1, len(dense)), "y": np.arange(10) + 0.5, "x": np.arange(10) + 0.5}
    return xr.Dataset({"phi": (("time", "y", "x"), phi)}, coords=coords,
                      attrs={"grid_shape": np.array([10, 10]), "grid_spacing": 1.0, "steps_nominal": 100})


def test_dense_biofilm_vanishing_while_the_biofilm_grew_is_told_with_the_check():
    from biostudy.quantities import dense

    said = dense.vanished(_series([6, 4, 0, 0], [10, 30, 12, 0]))
    assert said.startswith("dense biofilm (phi >= 0.8) vanished by T* = 0.667 (it was 6 µm² at T* = 0) while the "
                           "biofilm (phi >= 0.5) grew from 10 to 30 µm² (T* = 0.333)")
    assert said.endswith("--set grid.shape=[20,20] --set grid.spacing=0.5 --set time.steps=200")
    assert dense.vanished(_series([6, 8, 9], [10, 20, 30])) == ""  # kept dense
    assert dense.vanished(_series([6, 3, 0], [10, 8, 6])) == ""  # everything shrank: not this artefact
    assert dense.vanished(_series([0, 0, 0], [10, 20, 30])) == ""  # never dense


def test_a_run_whose_dense_biofilm_vanished_warns_and_records_it(write_toml, tmp_path):
    from typer.testing import CliRunner

    from biostudy.cli import app

    # the model as written on 1 µm cells (pointwise velocity) dissolves the dense colony (docs/paper.md)
    scene = write_toml("agar.toml", AGAR.replace('growth_velocity = "front"', 'growth_velocity = "pointwise"')
                       .replace("t_end = 0.1\nsteps = 25", "t_end = 0.3\nsteps = 75").replace("outputs = 3",
                                                                                           "outputs = 7"))
    out = tmp_path / "run.nc"
    result = CliRunner().invoke(app, ["run", str(scene), "-o", str(out), "-q"])
    assert result.exit_code == 0, result.output
    assert "warning: dense biofilm (phi >= 0.8) vanished by T* =" in result.stderr
    assert "--set grid.shape=[24,24] --set grid.spacing=0.5 --set time.steps=150" in result.stderr
    assert "vanished" in xr.open_dataset(out).attrs["dense_biofilm_vanished"]
    kept = CliRunner().invoke(app, ["run", str(scene), "-o", str(tmp_path / "front.nc"), "-q", "--set",
                                    'numerics.growth_velocity="front"'])
    assert kept.exit_code == 0 and "warning" not in kept.stderr
    assert "dense_biofilm_vanished" not in xr.open_dataset(tmp_path / "front.nc").attrs


def test_a_sweep_records_the_substratum_in_its_cases_and_study_nc_carries_the_observables(write_toml, tmp_path):
    from typer.testing import CliRunner

    from biostudy.cli import app

    write_toml("agar.toml", AGAR)
    study = write_toml("sweep.toml", 'scene = "agar.toml"\n[set]\n"substratum.threshold" = 0.4\n[sweep]\n'
                                     'r = [50.0, 100.0]\n')
    result = CliRunner().invoke(app, ["sweep", str(study), "-o", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 0, result.output
    case = xr.open_dataset(tmp_path / "out" / "cases" / "r=100.nc")
    assert case.attrs["substratum_face"] == "y-" and case.attrs["substratum_threshold"] == 0.4
    ds = xr.open_dataset(tmp_path / "out" / "study.nc")
    assert ds.biomass.dims == ("r", "time") and ds.biomass.attrs["units"] == "um"
    expected = [sub.biomass(phi, 1.0, "y-", 0.4) for phi in case.phi.isel(r=0).values]
    np.testing.assert_allclose(ds.biomass.sel(r=100.0).values, expected, rtol=1e-12)
    assert float(ds.biomass.sel(r=100.0).isel(time=-1)) > float(ds.biomass.sel(r=50.0).isel(time=-1))
    # another threshold measures the same runs again: nothing is simulated, study.nc follows the scene
    again = CliRunner().invoke(app, ["sweep", str(study), "-o", str(tmp_path / "out"), "-q", "--set",
                                     "substratum.threshold=0.3"])
    assert again.exit_code == 0 and "nothing to run" in again.stderr, again.output
    lower = [sub.biomass(phi, 1.0, "y-", 0.3) for phi in case.phi.isel(r=0).values]
    np.testing.assert_allclose(xr.open_dataset(tmp_path / "out" / "study.nc").biomass.sel(r=100.0).values, lower,
                               rtol=1e-12)
    assert lower[-1] > expected[-1]
