"""A scene file (docs/scenes.md): one simulation, validated, then compiled to a `solver.Problem`.

The pydantic models below are the schema: every key, its unit and meaning,
its allowed range (the parameters' from `solver.Parameters`, docs/model.md), and the cross-field
rules (shapes inside the grid, nutrient sources not inside obstacles, output
times within [0, t_end], ...).  `load_scene` reads a TOML file, applies
``--set KEY=VALUE`` overrides (dotted keys, values parsed as TOML) and
validates; `Scene.problem()` builds the solver's plain description.

Besides the model's own keys, the ``[model]``, ``[numerics]`` and ``[mechanics]`` tables and
``[time] output_times`` map onto the solver's settings (`NumericsSpec`,
`MechanicsSpec`, `Time`: each field says what it does; the README lists them
all, and `tests/test_docs.py` checks that it does).  ``[params]``, ``[model]``,
``[numerics]`` and ``[mechanics]`` are derived from the solver's declarations
(`declared`), so an option added to `solver.Laws`, `solver.Numerics` or
`solver.MechanicsSetup` is a scene key at once.  ``[substratum]`` (face,
threshold) says where and how the COMSTAT observables are measured
(`biostudy.quantities.substratum`); it changes nothing in the simulation, and
the datasets record it (`Scene.substratum_attrs`).
"""
from __future__ import annotations

import copy
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, Union

import numpy as np
from pydantic import BaseModel, Field, ValidationError, ValidationInfo, create_model, model_validator

import solver
from solver.problem import Face, blocked_problem, face_problem, held_faces_problem, inside_problem
from solver.series import BIOFILM_THRESHOLD

from ..errors import BadInput, InvalidAt, from_validation_error
from .clock import Time
from .declared import CONFIG, parameters_model, settings_model, union_tags, unit_field
from .files import read_toml
from .geometry import SHAPES as DRAWN
from .geometry import BoundaryFace, Grate, Maze, Shape
from .images import Image
from .keys import Origins, all_keys, apply_overrides, blame, field_of, given_by
from .substratum_face import LEFT_OUT, NONE, Substratum, left_out, resting_face
from .tomltext import dumps as toml_dumps

if TYPE_CHECKING:
    from .resources import Preflight

class GridSpec(BaseModel):
    """Structured grid of cubic cells, origin at 0."""

    model_config = CONFIG
    shape: list[Annotated[int, Field(ge=1)]] = Field(
        min_length=2, max_length=3, description="cells along x, y[, z]; two entries make a 2-D scene")
    spacing: float = unit_field(1.0, "edge of the cubic cells, µm", "um", gt=0)

    def solver_grid(self) -> solver.Grid:
        return solver.Grid(tuple(self.shape), self.spacing)


Params = parameters_model()


Model = settings_model(solver.Laws, "Model", "Which form of the model's laws (solver.Laws; docs/model.md): the "
                       "defaults are Eqs. 34-36 with first-order consumption and a quasi-steady nutrient.")
NumericsSpec = settings_model(solver.Numerics, "NumericsSpec", "How the equations are discretised "
                              "(solver.Numerics); the defaults are the robust choice.")
MechanicsSpec = settings_model(
    solver.MechanicsSetup, "MechanicsSpec", "Growth mechanics (paper 2.1, 2.3.1, 3), solved at output times; "
    "absent table = off.", enabled=(bool, Field(True, description="solve the growth mechanics (u and p in the "
                                                                  "dataset)")))


SHAPES = (*DRAWN, Image)  # what a region of biofilm or nutrient may be; an obstacle may also be generated
AnyShape = Annotated[Union[(*SHAPES, Maze, Grate)], Field(discriminator="shape")]


class SubstratumSpec(BaseModel):
    """Where and how the COMSTAT observables (biomass, thicknesses, roughness, coverage, surface to biovolume) are
    measured.  Measurement only: the simulation is the same whatever it says."""

    model_config = CONFIG
    face: Literal[Face, "none"] | None = Field(
        None, description="the face the biofilm grows on (x-, x+, y-, y+, z-, z+), or none; default: the single "
                          "face the initial biofilm rests on; without one (none, a floating biofilm, several faces "
                          "alike) COMSTAT's observables are left out (inputs/substratum_face.py)")
    threshold: float = unit_field(BIOFILM_THRESHOLD, "biofilm is phi >= threshold for the substratum observables", "1",
                                  gt=0, lt=1)
    connected: bool = Field(False, description="COMSTAT's connected-volume filtering: only biofilm connected to "
                                               "the substratum (through cells sharing a face) counts")
    estimator: Literal["subcell", "voxel"] = Field(
        "subcell", description="subcell: the interpolated level set, continuous in phi (for fitting); voxel: "
                               "COMSTAT's counts on the segmented cells (to compare with a lab's COMSTAT table)")


def _valued(role: str, description: str, shapes=SHAPES, **extra):
    """The shape union with a `value` key (0..1, default 1) for one kind of region."""
    members = tuple(create_model(f"{role}{shape.__name__}", __base__=shape,
                                 value=(float, Field(1.0, ge=0, le=1, description=description)), **extra)
                    for shape in shapes)
    return Annotated[Union[members], Field(discriminator="shape")]


BiofilmRegion = _valued("Biofilm", "initial phi inside the shape, 0..1", edge=(float, Field(
    0.0, ge=0, description="width of a smooth edge, µm: phi = value (1 - tanh(distance / edge)) / 2 across the "
                           "surface instead of a step (0: a step); smooth data show the schemes' asymptotic "
                           "convergence orders", json_schema_extra={"units": "um"})))
NutrientRegion = _valued("Nutrient", "nutrient c held inside the shape (or on the face) at all times, 0..1",
                         shapes=(*SHAPES, BoundaryFace))


def initial_biofilm(regions, grid: solver.Grid) -> np.ndarray:
    """phi at t = 0: a step region sets its cells (later regions win); a smooth one raises phi to its profile."""
    phi0 = np.zeros(grid.cells_shape)
    for region in regions:
        if getattr(region, "scale", None) is not None:  # an image's grey values are phi
            cells = region.cells(grid)
            phi0[cells] = region.density(grid)[cells]
        elif region.edge > 0:
            profile = 0.5 * region.value * (1.0 - np.tanh(region.distance(grid) / region.edge))
            np.maximum(phi0, profile, out=phi0)
        else:
            phi0[region.cells(grid)] = region.value
    return phi0


class Scene(BaseModel):
    """One simulation: grid, parameters, laws, clocks, regions, numerics, mechanics."""

    model_config = CONFIG
    name: str = Field("", description="short name (default: the file's name without .toml)")
    description: str = Field("", description="one line shown by `biostudy scenes`")
    grid: GridSpec
    params: Params = Field(default_factory=Params)
    model: Model = Field(default_factory=Model)
    time: Time = Field(default_factory=Time)
    biofilm: list[BiofilmRegion] = Field([], description="regions of initial phi (later regions win)")
    nutrient: list[NutrientRegion] = Field([], description="nutrient sources: c held at value at all times")
    obstacle: list[AnyShape] = Field([], description="rigid solids: no phi, no c, no flux")
    numerics: NumericsSpec = Field(default_factory=NumericsSpec)
    mechanics: MechanicsSpec | None = Field(None, description="growth mechanics; absent = off")
    substratum: SubstratumSpec = Field(default_factory=SubstratumSpec)

    @model_validator(mode="after")
    def _fits_the_grid(self, info: ValidationInfo):
        """The rules between tables, each a step: a command's memory check first, if it gives one
        (`resources.Preflight`: before any array of the grid's size is made; what the machine holds is no rule of
        the scene), then the regions, the nutrient sources, the clock and the faces the scene names."""
        preflight = (info.context or {}).get("preflight")
        if preflight is not None:
            preflight(self)
        grid = self.grid.solver_grid()
        self._regions_fit(grid)
        self._sources_free(grid)
        if self.numerics.max_substeps < self.time.steps:
            raise InvalidAt("numerics.max_substeps", f"must be >= time.steps = {self.time.steps} "
                                                     f"(got {self.numerics.max_substeps})")
        self._faces_exist(grid)
        return self

    def _regions_fit(self, grid: solver.Grid) -> None:
        """Every region inside the grid and covering a cell; grey values only for biofilm; a cell left open."""
        for kind in ("biofilm", "nutrient", "obstacle"):
            for i, region in enumerate(getattr(self, kind)):
                try:
                    region.check(grid)
                except InvalidAt as error:
                    raise InvalidAt(".".join(filter(None, (f"{kind}[{i}]", error.key))), error.problem) from None
        for i, region in enumerate(self.biofilm):
            spill = region.spill(grid) if isinstance(region, Image) else None
            if spill is not None and spill.voxels:
                raise InvalidAt(f"biofilm[{i}].path", f"{region.path} spans {spill.spans}, beyond the grid "
                                f"({spill.grid}): {spill.voxels} voxels of its biofilm ({spill.region:.1%} of it) lie "
                                "outside, so the biofilm would be cut; enlarge grid.shape, move origin, or crop the "
                                "stack")
        for kind in ("nutrient", "obstacle"):
            for i, region in enumerate(getattr(self, kind)):
                if getattr(region, "scale", None) is not None:
                    raise InvalidAt(f"{kind}[{i}].scale", "only a biofilm region takes phi from an image's grey "
                                                          "values; give threshold (or a segmented image)")
        blocked = blocked_problem(self._union(self.obstacle, grid))
        if blocked:
            raise InvalidAt("obstacle", blocked)

    def _sources_free(self, grid: solver.Grid) -> None:
        """Each face held once, no nutrient source inside an obstacle (the solver's rules, told at the scene's keys)."""
        held = [i for i, source in enumerate(self.nutrient) if isinstance(source, BoundaryFace)]
        found = held_faces_problem([self.nutrient[i].face for i in held], grid.ndim)
        if found:
            raise InvalidAt(f"nutrient[{held[found[0]]}].face", found[1])
        for i, source in enumerate(self.nutrient):
            for j, solid in enumerate(self.obstacle):
                inside = inside_problem(source.cells(grid), solid.cells(grid), f"obstacle[{j}]")
                if inside:
                    raise InvalidAt(f"nutrient[{i}]", inside)

    def _faces_exist(self, grid: solver.Grid) -> None:
        """The substratum's and the mechanics' faces are faces of this grid (`solver.problem.face_problem`)."""
        named = [("substratum.face", self.substratum.face)] if self.substratum.face not in (None, NONE) else []
        if self.mechanics is not None:
            named += [(f"mechanics.{name}", face) for name in ("clamp", "slide") for face in getattr(self.mechanics,
                                                                                                    name)]
        for key, face in named:
            problem = face_problem(face, grid.ndim)
            if problem:
                raise InvalidAt(key, problem)

    @staticmethod
    def _union(regions: list[Shape], grid: solver.Grid) -> np.ndarray:
        cells = np.zeros(grid.cells_shape, bool)
        for region in regions:
            cells |= region.cells(grid)
        return cells

    def problem(self) -> solver.Problem:
        """The solver's plain description of this scene (masks in the solver's (z, y, x) order)."""
        grid = self.grid.solver_grid()
        phi0 = initial_biofilm(self.biofilm, grid)
        held = np.zeros(grid.cells_shape, bool)
        value = np.ones(grid.cells_shape)
        faces = tuple((region.face, region.value) for region in self.nutrient if isinstance(region, BoundaryFace))
        for region in self.nutrient:
            cells = region.cells(grid)
            held |= cells
            value[cells] = region.value
        blocked = self._union(self.obstacle, grid)
        phi0[blocked] = 0.0  # biofilm does not live inside a solid
        mechanics = self.mechanics.solver_settings() if self.mechanics is not None and self.mechanics.enabled else None
        return solver.Problem(
            grid=grid, phi0=phi0, nutrient_held=held, nutrient_value=value, nutrient_faces=faces, obstacle=blocked,
            t_end=self.time.t_end, steps=self.time.steps, output_times=self.time.times(),
            params=solver.Parameters(**self.params.model_dump()), laws=self.model.solver_settings(),
            numerics=self.numerics.solver_settings(), mechanics=mechanics, name=self.name)

    def substratum_face(self) -> str | None:
        """The substratum: the face the scene names, else the single face the initial biofilm rests on, else
        None (`substratum_face.resting_face`: a floating biofilm, or several faces alike)."""
        return self.substratum_found().face

    def substratum_found(self) -> Substratum:
        """The substratum's face, or why there is none."""
        if self.substratum.face == NONE:
            return Substratum(None, left_out("the scene says it has none ([substratum] face = \"none\")"))
        if self.substratum.face is not None:
            return Substratum(self.substratum.face)
        grid = self.grid.solver_grid()
        biofilm = initial_biofilm(self.biofilm, grid) >= self.substratum.threshold
        biofilm &= ~self._union(self.obstacle, grid)
        held = tuple(region.face for region in self.nutrient if isinstance(region, BoundaryFace))
        return resting_face(biofilm, held)

    def substratum_attrs(self) -> dict:
        """What a dataset records so that the substratum observables can be computed from it alone; without a
        substratum, `LEFT_OUT` (why COMSTAT's observables are not there, and how to get them) instead of its face."""
        found = self.substratum_found()
        where = {"substratum_face": found.face} if found.face is not None else {LEFT_OUT: found.why_none}
        return {**where, "substratum_threshold": self.substratum.threshold,
                "substratum_connected": int(self.substratum.connected),
                "substratum_estimator": self.substratum.estimator}

    def image_attrs(self) -> dict:
        """The provenance of every image region (``image_biofilm_0_path``, ``_sha256``, ``_shape`` [z,] y, x voxels,
        ``_voxel`` [dz,] dy, dx µm, ``_origin`` [z,] y, x µm) and, where an image reaches beyond the grid,
        ``image_left_out``: how much of it was left out (`quantities.alerts` says it after a run)."""
        found: dict = {}
        left_out = []
        grid = self.grid.solver_grid()
        for kind in ("biofilm", "nutrient", "obstacle"):
            for i, region in enumerate(getattr(self, kind)):
                if not isinstance(region, Image):
                    continue
                name = f"image_{kind}_{i}"
                found.update({f"{name}_path": region.path, f"{name}_sha256": region.sha256,
                              f"{name}_shape": list(region.image_shape), f"{name}_voxel": list(region.voxel_size),
                              f"{name}_origin": list(reversed(region.origin or [0.0] * grid.ndim))})
                spill = region.spill(grid)
                if spill is not None:
                    cut = f", {spill.region:.1%} of its region" if spill.voxels else ", none of its region"
                    left_out.append(f"{kind}[{i}]: {region.path} spans {spill.spans}, beyond the grid ({spill.grid}): "
                                    f"{spill.image:.1%} of the image is left out{cut}")
        if left_out:
            found["image_left_out"] = "an image larger than the grid was cropped to it: " + "; ".join(left_out)
        return found

    def real_time_attrs(self) -> dict:
        """{"t_ref": ...} when the scene says what T* = 1 is in real time (`data.real_time` adds time_real)."""
        return {"t_ref": self.time.t_ref} if self.time.t_ref is not None else {}

    def to_toml(self) -> str:
        """The scene as TOML text (every key, defaults filled in): what the dataset records."""
        return toml_dumps(self.model_dump(mode="json", exclude_none=True))


# ---------------------------------------------------------------------------------------------
# Loading


SCENE_KEYS = frozenset(all_keys(Scene))
SHAPE_TAGS = union_tags(Scene)  # the shapes each list of regions takes, as errors leave them out of keys


def key_info(key: str) -> tuple[str, str]:
    """(long_name, units) of a dotted scene key, from the schema; for sweep coordinates."""
    found = field_of(Scene, key)
    if found is None or not found.description:
        return f"scene key {key}", "1"
    return found.description, str((found.json_schema_extra or {}).get("units", "1"))


def scene_from_data(data: dict, file: str | Path, origins: Origins | None = None,
                    preflight: Preflight | None = None) -> Scene:
    """Validate raw TOML data of a scene; `file` names it in errors and anchors relative paths; an error in a
    value that an override gave names that override instead (`origins`).  `preflight`: a command's check that
    the scene fits this machine, made before the grid's arrays are (`resources.Preflight`)."""
    file = Path(file)
    data = copy.deepcopy(data)
    if isinstance(data.get("name", ""), str) and not data.get("name"):
        data["name"] = file.stem
    try:
        return Scene.model_validate(data, context={"base": file.parent, "preflight": preflight})
    except ValidationError as error:
        raise blame(from_validation_error(error, file, known_keys=SCENE_KEYS, tags=SHAPE_TAGS), origins) from None


def read_scene_data(path: str | Path) -> dict:
    """Raw TOML data of a scene file; a study file given here is bad input."""
    data = read_toml(path)
    if "scene" in data and "grid" not in data:
        raise BadInput("this is a study file (it has scene = ...); run it with `biostudy sweep`", path)
    return data


def load_scene(path: str | Path, overrides: list[str] | tuple[str, ...] = (),
               preflight: Preflight | None = None) -> Scene:
    """Read, override and validate a scene file: the only way a scene file becomes a `Scene` (`preflight`: see
    `scene_from_data`)."""
    data = read_scene_data(path)
    return scene_from_data(data, path, given_by(apply_overrides(data, overrides), "--set"), preflight)


def overrides_text(pairs: list[tuple[str, Any]] | dict) -> str:
    """Overrides as TOML text ('"params.g" = 1e10' lines) for the dataset's attributes."""
    items = dict(pairs)
    return toml_dumps(items).strip() if items else ""
