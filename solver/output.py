"""Snapshots -> xarray.Dataset (layout: docs/model.md, "The dataset").

Dimensions time, [z,] y, x (cell centres, µm, with their cell bounds) and, with
the mechanics, time_mechanics (the outputs where it was solved), [z_node,]
y_node, x_node and component for the displacement.  Units (udunits spellings,
`cf_units`) and long names travel with every variable and coordinate; the
parameters are scalar variables with their units and also attributes, which
carry the numerics, the counters and where the wall time went, so a result
says what it cost and how it was computed.  Variables a scene does not ask for
(u, p without mechanics) are absent, not filled.
"""
from __future__ import annotations

import functools
import importlib.metadata as metadata
import platform
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import xarray as xr

from .problem import AXES, PRESSURES, Problem, parameter_infos
from .series import BIOFILM_THRESHOLD, SERIES, SLAB_THICKNESS, cell_volume
from .transport.bounds import ROUNDOFF

if TYPE_CHECKING:
    from .snapshot import Snapshot

FIELDS = {
    "phi": ("1", "biofilm density phi (0 void, 1 dense biofilm)"),
    "c": ("1", "nutrient concentration c"),
    "alpha": ("1", "local expansion alpha (growth deformation Fg = (1 + alpha) I)"),
    "p": ("Pa", "hydrostatic Cauchy stress tr(sigma)/3 (negative = compression)"),
}
PACKAGES = ("numpy", "scipy", "fipy", "pyamg", "scikit-fem", "xarray")
NORMALISED_TIME = "T*"  # t / t_ref: dimensionless


def cf_units(units: str) -> str:
    """The udunits spelling of a model unit.  T* = t / t_ref is dimensionless, so a rate per T* has the
    units of its numerator: 'um^2/T*' -> 'um^2', 'um/T*' -> 'um', '1/T*' -> '1'; other units are written as
    they are ('um', 'um^3', 'Pa', 's', '1'), spelled so that udunits and plain pint both read them (powers with
    '^': pint reads 'um3' as a unit named um3, and 'um-1' as um minus 1)."""
    head, per, rest = units.partition("/" + NORMALISED_TIME)
    if NORMALISED_TIME in rest or NORMALISED_TIME in head:
        raise ValueError(f"T* may only divide a unit: {units!r}")
    return (head or "1") if per else units


def cf_attrs(units: str, long_name: str, **extra) -> dict:
    """units and long_name of a variable: udunits units, and the model's own units (per T*) kept
    readable in the long name ('consumption g [1/T*]')."""
    shown = cf_units(units)
    return {"units": shown, "long_name": long_name if shown == units else f"{long_name} [{units}]", **extra}


NO_FILL = {"_FillValue": None}  # coordinates never have missing values (CF 2.5.1)
# T* is dimensionless: not a CF time (no unit of time, no epoch), so no axis = "T" and no standard_name
# (docs/model.md, "The dataset").
TIME_ATTRS = {"units": "1", "long_name": "normalised time T* = t / t_ref (dimensionless)"}


def versions(packages=PACKAGES, python: bool = True) -> dict:
    """`version_<package>` of the installed packages named (and of python), as the datasets record them."""
    versions = {"version_python": platform.python_version()} if python else {}
    for name in packages:
        found = installed(name)
        if found is not None:
            versions[f"version_{name.replace('-', '_')}"] = found
    return versions


@functools.lru_cache(maxsize=None)
def installed(name: str) -> str | None:
    """A package's installed version (None: not installed), read from its metadata once per process: reading it
    parses the package's METADATA file (~1.5 ms), and every dataset a process makes records it."""
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def _coordinates(problem: Problem) -> dict:
    """Cell centres with their bounds (the cell faces; z points up) and grid nodes, µm."""
    grid = problem.grid
    coords: dict[str, tuple] = {}
    for axis in grid.axes:
        attrs = {"units": "um", "long_name": f"{axis} of cell centre", "axis": axis.upper(),
                 "bounds": f"{axis}_bounds", **({"positive": "up"} if axis == "z" else {})}
        coords[axis] = (axis, grid.centres(axis), attrs, NO_FILL)
        nodes = grid.nodes(axis)
        coords[f"{axis}_bounds"] = ((axis, "bounds"), np.stack([nodes[:-1], nodes[1:]], axis=1), {},
                                    NO_FILL)  # units and long name are its cell centre's (CF 7.1)
        coords[f"{axis}_node"] = (f"{axis}_node", nodes, {"units": "um", "long_name": f"{axis} of grid node"},
                                  NO_FILL)
    return coords


def parameter_variables(problem: Problem) -> dict:
    """The model parameters as scalar variables with units (kappa, derived from mu and nu, stays an
    attribute: a variable would not follow a sweep of mu)."""
    p = problem.params
    return {info.name: ((), float(getattr(p, info.name)), cf_attrs(info.units, info.long_name))
            for info in parameter_infos(p)}


@dataclass(frozen=True)
class Record:
    """What the dataset keeps of one output besides its fields: time, counters, the series measured on it."""

    time: float
    steps: int
    bisections: int
    rejected: int
    elapsed: float
    series: dict[str, float]  # `series.SERIES` measured on this output
    solved: bool  # the mechanics was solved at this output
    mechanics: dict = field(default_factory=dict)


def record(problem: Problem, snapshot: Snapshot) -> Record:
    """The output's `Record`: its series measured on its fields (open cells), before the fields go to a sink."""
    grid = problem.grid
    volume = cell_volume(grid.spacing, grid.ndim)
    measured = {s.name: s.measure(getattr(snapshot, s.field), ~problem.obstacle, volume) for s in SERIES}
    return Record(snapshot.time, snapshot.steps, snapshot.bisections, snapshot.rejected, snapshot.elapsed, measured,
                  snapshot.p is not None, dict(snapshot.mechanics))


def _attributes(problem: Problem, report: dict, snapshots) -> dict:
    p, n = problem.params, problem.numerics
    attrs = {
        "Conventions": "CF-1.10",
        "title": f"biofilm growth: {problem.name}",
        "source": "biostudy solver (finite-volume transport on a FiPy-built Laplacian, Q1/P0 growth mechanics)",
        "model": "Hamilton-principle biofilm growth (paper Eqs. 34-36, as in docs/model.md)",
        "grid_shape": np.array(problem.grid.shape, dtype=np.int32),
        "grid_spacing": problem.grid.spacing,
        **{info.name: float(getattr(p, info.name)) for info in parameter_infos(p)},
        "kappa": p.kappa,
        "consumption": problem.laws.consumption,
        "expansion": problem.laws.expansion,
        "nutrient_dynamics": problem.laws.nutrient,
        "advection": n.advection,
        "growth_velocity": n.growth_velocity,
        **({"front_band": n.front_band} if n.growth_velocity == "front" else {}),
        **({"nutrient_faces": ", ".join(f"{face} = {value:g}" for face, value in problem.nutrient_faces)}
           if problem.nutrient_faces else {}),
        "gradient_floor": n.gradient_floor,
        "nutrient_tolerance": n.nutrient_tolerance,
        "biofilm_tolerance": n.biofilm_tolerance,
        "max_substeps": n.max_substeps,
        "time_stepping": "fixed nominal steps, bisected on failure" if n.time_tolerance is None
        else f"step doubling, local error in phi (max norm) <= {n.time_tolerance:g} per step",
        "time_tolerance": n.time_tolerance if n.time_tolerance is not None else 0.0,
        "t_end": problem.t_end,
        "steps_nominal": problem.steps,
        "biofilm_threshold": BIOFILM_THRESHOLD,
        "mechanics": "on" if problem.mechanics is not None else "off",
        "wall_time": report["wall_time"],
        **{name: value for name, value in report.items() if name not in ("wall_time", "timings")},  # counters
        "bounds_roundoff": ROUNDOFF,
        **{f"wall_time_{stage}": seconds for stage, seconds in report["timings"].items()},
        **versions(),
    }
    if problem.grid.ndim == 2:
        attrs["slab_thickness"] = SLAB_THICKNESS
    if problem.mechanics is not None:
        m = problem.mechanics
        attrs.update({
            "mechanics_clamp": ",".join(m.clamp), "mechanics_slide": ",".join(m.slide),
            "mechanics_residual_stiffness": m.residual_stiffness, "mechanics_every": m.every,
            "mechanics_newton_tolerance": m.newton_tolerance, "mechanics_pressure": m.pressure,
            "mechanics_linear_solver_choice": m.linear_solver, "mechanics_pressure_comment": PRESSURES[m.pressure],
        })
        solved = [s.mechanics for s in snapshots if s.mechanics]
        for key, value in (solved[-1] if solved else {}).items():
            if isinstance(value, (int, float, str)) and not isinstance(value, bool):
                attrs[f"mechanics_{key}"] = value
    return attrs


def assemble(problem: Problem, records: list[Record], fields: dict[str, Any], report: dict) -> xr.Dataset:
    """The run as a Dataset: fields (as an `OutputSink` gives them: numpy or lazy arrays, one output along
    the first axis), time series, static masks, attributes."""
    grid = problem.grid
    cell_dims = tuple(reversed(grid.axes))
    node_dims = tuple(f"{a}_node" for a in cell_dims)
    times = np.array([r.time for r in records])

    data: dict[str, tuple] = {}
    for name in ("phi", "c", "alpha"):
        units, long_name = FIELDS[name]
        data[name] = (("time", *cell_dims), fields[name], {"units": units, "long_name": long_name})
    solved = [r for r in records if r.solved]
    if problem.mechanics is not None:
        units, long_name = FIELDS["p"]
        empty = (0, *grid.cells_shape)
        data["p"] = (("time_mechanics", *cell_dims), fields.get("p", np.zeros(empty)),
                     {"units": units, "long_name": long_name, "pressure": problem.mechanics.pressure,
                      "comment": PRESSURES[problem.mechanics.pressure]})
        data["u"] = (("time_mechanics", *node_dims, "component"),
                     fields.get("u", np.zeros((0, *(n + 1 for n in grid.cells_shape), grid.ndim))),
                     {"units": "um", "long_name": "displacement of grid node"})
        data["newton_iterations"] = ("time_mechanics", np.array([r.mechanics.get("newton_iterations", -1)
                                                                 for r in solved], dtype=np.int32),
                                     {"units": "1", "long_name": "Newton iterations of the mechanics"})
    for series in SERIES:
        data[series.name] = ("time", np.array([r.series[series.name] for r in records]), series.attrs(grid.ndim))
    for name, counter, long_name in (("steps_taken", "steps", "accepted steps so far"),
                                     ("steps_bisected", "bisections", "bisected (failed) steps so far"),
                                     ("steps_rejected", "rejected", "steps rejected by the error control so far")):
        data[name] = ("time", np.array([getattr(r, counter) for r in records], dtype=np.int64),
                      {"units": "1", "long_name": long_name})
    data["elapsed"] = ("time", np.array([r.elapsed for r in records]),
                       {"units": "s", "long_name": "wall time since the start of the run"})
    data["obstacle"] = (cell_dims, problem.obstacle.astype(np.int8),
                        {"units": "1", "long_name": "rigid obstacle cell",
                         "flag_values": np.array([0, 1], dtype=np.int8), "flag_meanings": "open obstacle"})
    data["nutrient_source"] = (cell_dims, problem.nutrient_held.astype(np.int8),
                               {"units": "1", "long_name": "cell where c is held (nutrient source)",
                                "flag_values": np.array([0, 1], dtype=np.int8), "flag_meanings": "free held"})
    data.update(parameter_variables(problem))
    coords = _coordinates(problem)
    coords["time"] = ("time", times, TIME_ATTRS, NO_FILL)
    if problem.mechanics is not None:
        coords["time_mechanics"] = ("time_mechanics", np.array([r.time for r in solved]),
                                    {**TIME_ATTRS, "long_name": "normalised time T* of the outputs where the "
                                                                "mechanics was solved"}, NO_FILL)
        coords["component"] = ("component", list(AXES[: grid.ndim]),
                               {"long_name": "displacement component", "units": "1"})
    else:
        coords = {k: v for k, v in coords.items() if not k.endswith("_node")}
    return xr.Dataset(data, coords=coords, attrs=_attributes(problem, report, records))


def on_output_times(ds: xr.Dataset) -> xr.Dataset:
    """The dataset with u, p and newton_iterations on `time`, NaN at the outputs where the mechanics was
    not solved, instead of on `time_mechanics`: for code that walks the outputs by index.  A dataset without
    `time_mechanics` (no mechanics, or written before it existed) is returned as it is."""
    if "time_mechanics" not in ds.dims:
        return ds
    moved = {name: ds[name].rename(time_mechanics="time").reindex(time=ds["time"].values)
             for name in ds.data_vars if "time_mechanics" in ds[name].dims}
    return ds.drop_vars([*moved, "time_mechanics"]).assign(moved)
