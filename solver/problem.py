"""The plain description of one simulation: grid, parameters, masks, clocks.

Everything the solver needs and nothing it does not: numpy arrays and frozen
dataclasses, no files, no validation framework.  The study service
(`biostudy.scene`) compiles a validated scene into a `Problem`; tests build
problems directly.

Array convention: every per-cell array has shape ``grid.cells_shape``, i.e.
``(nz, ny, nx)`` in 3-D and ``(ny, nx)`` in 2-D, so that the C-order
flattening is FiPy's cell order (x fastest).  Per-node arrays have shape
``grid.nodes_shape`` = ``(nz+1, ny+1, nx+1)`` / ``(ny+1, nx+1)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Literal, get_args

import numpy as np

from .declared import OptionError, ParameterInfo, option, parameter
from .laws import Consumption as Consumption  # Consumption: re-exported (transport imports it here)
from .laws import Laws

AXES = ("x", "y", "z")
Face = Literal["x-", "x+", "y-", "y+", "z-", "z+"]
FACES: tuple[Face, ...] = get_args(Face)
Advection = Literal["upwind", "tvd"]
GrowthVelocity = Literal["front", "pointwise"]
LinearSolver = Literal["auto", "multigrid", "direct", "amg"]
LINEAR_SOLVERS: tuple[LinearSolver, ...] = get_args(LinearSolver)
Pressure = Literal["recovered", "element"]
PRESSURES: dict[Pressure, str] = {  # which pressure a dataset holds (solver/mechanics/pressure.py, docs/mechanics.md)
    "recovered": "Q1/P0 element pressure without its spurious (checkerboard) modes: p = w kappa (Theta - 1) "
                 "filtered at interior nodes",
    "element": "Q1/P0 mean-dilatation element pressure p = w kappa (Theta - 1), as in the paper (carries "
               "checkerboard modes where the pressure is rough)",
}


@dataclass(frozen=True)
class Grid:
    """Structured grid of cubic cells, origin at 0.

    shape: cells along x, y[, z] (two entries: a 2-D scene).
    spacing: cell edge h in µm.
    """

    shape: tuple[int, ...]
    spacing: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, "shape", tuple(int(n) for n in self.shape))
        if len(self.shape) not in (2, 3) or min(self.shape) < 1:
            raise ValueError(f"grid shape must have 2 or 3 positive entries, got {self.shape}")
        if not self.spacing > 0:
            raise ValueError(f"grid spacing must be positive, got {self.spacing}")

    @property
    def ndim(self) -> int:
        return len(self.shape)

    @property
    def axes(self) -> tuple[str, ...]:
        """Axis names in scene order, e.g. ('x', 'y', 'z')."""
        return AXES[: self.ndim]

    @property
    def cells_shape(self) -> tuple[int, ...]:
        """Shape of per-cell arrays: (nz, ny, nx) or (ny, nx)."""
        return tuple(reversed(self.shape))

    @property
    def nodes_shape(self) -> tuple[int, ...]:
        return tuple(n + 1 for n in self.cells_shape)

    @property
    def n_cells(self) -> int:
        return int(np.prod(self.shape))

    @property
    def cell_volume(self) -> float:
        """µm³ in 3-D, µm² in 2-D (per unit thickness)."""
        return self.spacing**self.ndim

    @property
    def extent(self) -> tuple[float, ...]:
        """Physical size along x, y[, z] in µm."""
        return tuple(n * self.spacing for n in self.shape)

    def centres(self, axis: str) -> np.ndarray:
        """Cell-centre coordinates along one axis (µm)."""
        n = self.shape[AXES.index(axis)]
        return (np.arange(n) + 0.5) * self.spacing

    def nodes(self, axis: str) -> np.ndarray:
        """Node coordinates along one axis (µm)."""
        n = self.shape[AXES.index(axis)]
        return np.arange(n + 1) * self.spacing

    def cell_coordinates(self) -> tuple[np.ndarray, ...]:
        """Broadcastable centre coordinates (x, y[, z]), each of ``cells_shape``."""
        grids = np.meshgrid(*(self.centres(a) for a in reversed(self.axes)), indexing="ij")
        return tuple(reversed(grids))


def face_problem(face: str, ndim: int) -> str | None:
    """What is wrong with naming `face` on an `ndim`-D grid, or None: the one rule (and message) wherever a
    face meets a grid (held nutrient, clamped or sliding mechanics, the substratum)."""
    faces = FACES[: 2 * ndim]
    return None if face in faces else f"'{face}' is not a face of a {ndim}-D grid (faces: {', '.join(faces)})"


def repeated(items) -> int | None:
    """The index of the first item that an earlier one already is, or None."""
    for index, item in enumerate(items):
        if item in items[:index]:
            return index
    return None


def times_problem(times, t_end: float) -> tuple[int, str] | None:
    """(index, what is wrong) of the first output time outside [0, t_end] or not after the one before, or None."""
    for i, t in enumerate(times):
        if not 0 <= t <= t_end:
            return i, f"{t:g} lies outside [0, t_end = {t_end:g}]"
        if i and t <= times[i - 1]:
            return i, f"{t:g} does not come after {times[i - 1]:g}"
    return None


def inside_problem(cells: np.ndarray, obstacle: np.ndarray, named: str = "an obstacle") -> str | None:
    """What is wrong with holding the nutrient on `cells` beside `obstacle` (boolean arrays alike), or None."""
    overlap = np.count_nonzero(cells & obstacle)
    return f"lies inside {named} ({overlap} cells in common)" if overlap else None


def blocked_problem(obstacle: np.ndarray) -> str | None:
    """What is wrong with an obstacle mask that leaves no cell open, or None."""
    return "covers every cell of the grid" if np.all(obstacle) else None


def held_faces_problem(faces: list[str], ndim: int) -> tuple[int, str] | None:
    """(index, what is wrong) of the first face of those where the nutrient is held that is no face of an
    `ndim`-D grid or is held twice (its boundary flux would count twice), or None."""
    for index, face in enumerate(faces):
        problem = face_problem(face, ndim)
        if problem:
            return index, problem
    twice = repeated(faces)
    return None if twice is None else (twice, f"'{faces[twice]}' is held twice")


@dataclass(frozen=True)
class Parameters:
    """Model parameters, paper Table 2 (defaults) in µm and normalised time T*; see `parameter`."""

    mu: float = parameter(3.3557, "Pa", "shear modulus mu", gt=0)
    nu: float = parameter(0.49, "1", "Poisson ratio nu", ge=0, lt=0.5)
    d: float = parameter(1e10, "um^2/T*", "nutrient diffusivity d", gt=0)
    beta: float = parameter(2.0, "um^2/T*", "phase-field regularisation beta", ge=0)
    k_alpha: float = parameter(1e-3, "1/T*", "growth factor k_alpha", ge=0)
    k: float = parameter(1.0, "1", "half-velocity constant k (Monod)", gt=0)
    g: float = parameter(1e8, "1/T*", "consumption g (0: no consumption)", ge=0)
    r: float = parameter(100.0, "um/T*", "growth parameter r (0: no directed growth)", ge=0)

    @property
    def kappa(self) -> float:
        """Bulk modulus kappa = 2 mu (1 + nu) / (3 (1 - 2 nu)), Pa."""
        return 2.0 * self.mu * (1.0 + self.nu) / (3.0 * (1.0 - 2.0 * self.nu))


def parameter_infos(parameters=None) -> tuple[ParameterInfo, ...]:
    """The declared parameters of a `Parameters` class or instance (default: `Parameters`), in order."""
    found = []
    for f in fields(Parameters if parameters is None else parameters):
        if "units" not in f.metadata:
            continue
        if not isinstance(f.default, (int, float)):
            raise TypeError(f"parameter {f.name} is declared without a default value")
        found.append(ParameterInfo(f.name, float(f.default), f.metadata["units"], f.metadata["long_name"],
                                   dict(f.metadata["bounds"])))
    return tuple(found)


@dataclass(frozen=True)
class Numerics:
    """How the equations are discretised and solved (each option says what it does); defaults are the robust
    choice.  The growth velocity "front" is built in `transport/front.py`; the nutrient direction is
    grad(c) / max(|grad c|, gradient_floor * max|grad c|), so it fades out linearly where c is flat."""

    advection: Advection = option("upwind", "upwind: monotone, first order (numerical diffusion ~ |v| h / 2); "
                                            "tvd: van Leer limited, second order where smooth, still bounded")
    gradient_floor: float = option(1e-3, "the nutrient direction grad c/|grad c| fades out where |grad c| < "
                                         "gradient_floor * max|grad c|", "1", gt=0, lt=1)
    nutrient_tolerance: float = option(1e-10, "relative residual of the nutrient's linear solves", "1", gt=0, lt=1)
    biofilm_tolerance: float = option(1e-12, "relative residual of the biofilm's linear solves", "1", gt=0, lt=1)
    max_substeps: int = option(1_000_000, "smallest step is t_end / max_substeps (paper: 1e6); a run needing less "
                                          "stops with a diagnosis", "1", ge=1)
    time_tolerance: float | None = option(None, "adaptive steps (step doubling): local error in phi (max norm) per "
                                                "step kept below this (absent: fixed nominal steps, bisected on "
                                                "failure)", "1", gt=0)
    growth_velocity: GrowthVelocity = option(
        "pointwise", "pointwise: r c/(k+c) grad c/|grad c| in every cell (Eq. 34 as written; keeps dense biofilm "
                     "dense only on cells of ~1/8 µm); front: the growth speed taken at the phi = 1/2 front and "
                     "carried along its normals: the sharp-interface limit, dense biofilm stays dense on 1 µm cells "
                     "(docs/paper.md)")
    front_band: float = option(3.0, "growth_velocity = front: cells within this many cells of the front take the "
                                    "front's speed", "1", ge=1, le=10)
    threads: int | None = option(None, "threads of the run's per-step kernels and linear solvers' products (absent: "
                                       "the cores the machine or the batch job gives the run); the results are the "
                                       "same bit for bit for every count", "1", result=False, ge=1)


@dataclass(frozen=True)
class MechanicsSetup:
    """Growth mechanics (paper 2.1, 2.3.1, 3); solved only at output times (each option says what it does).

    newton_tolerance: |R| <= tolerance * growth load, and the predicted next
        increment <= tolerance * |u| (energy norm).
    max_newton_iterations: Newton steps per load step (the other caps are
        in `solver.mechanics.settings.Settings`).
    """

    clamp: tuple[Face, ...] = option((), "faces (x-, x+, y-, y+, z-, z+) with all displacement zero")
    slide: tuple[Face, ...] = option((), "faces with zero normal displacement")
    residual_stiffness: float = option(1e-4, "relative stiffness of void cells (phi = 0): the weight w = eps + "
                                             "(1 - eps) phi^2 on shear and bulk energy", "1", gt=0, lt=1)
    every: int = option(1, "solve at every n-th output time (and the last)", "1", ge=1)
    newton_tolerance: float = 1e-6
    max_newton_iterations: int = 25
    linear_solver: LinearSolver = option(
        "auto", "preconditioner of the Newton steps' Krylov solves: multigrid (geometric), direct (factorisation), "
                "amg (pyamg smoothed aggregation), or auto (direct for small problems, multigrid beyond; "
                "docs/mechanics.md)")
    pressure: Pressure = option(
        "recovered", "the p in the dataset: recovered (Q1/P0's element pressure with its checkerboard modes "
                     "filtered out at interior nodes) or element (the paper's Q1/P0 element pressure); "
                     "docs/mechanics.md")

    def __post_init__(self):
        for name in ("clamp", "slide"):
            for face in getattr(self, name):
                if face not in FACES:
                    raise OptionError(name, f"unknown face {face!r}; faces are {FACES}")
            twice = repeated(getattr(self, name))
            if twice is not None:
                raise OptionError(name, f"lists {getattr(self, name)[twice]!r} twice")
        both = sorted(set(self.clamp) & set(self.slide))
        if both:
            raise OptionError("slide", f"{', '.join(both)} already clamped")
        if self.linear_solver not in LINEAR_SOLVERS:
            raise OptionError("linear_solver", f"unknown linear solver {self.linear_solver!r}; use one of "
                                               f"{LINEAR_SOLVERS}")
        if self.pressure not in PRESSURES:
            raise OptionError("pressure", f"unknown pressure {self.pressure!r}; use one of {tuple(PRESSURES)}")


@dataclass(frozen=True, eq=False)
class Problem:
    """One simulation (docs/model.md): initial state, sources, obstacles, clocks.

    phi0: initial biofilm density per cell (0 in obstacles).
    nutrient_held: cells where c is held at ``nutrient_value`` at all times.
    nutrient_value: held concentration per cell (read where nutrient_held).
    nutrient_faces: boundary faces where c is held, as (face, value) pairs, e.g.
        (("z-", 1.0),): a Dirichlet condition on the grid's outer face (the
        paper's "nodes on the bottom plane"); the cells next to it stay free
        and may hold biofilm.  phi keeps zero flux there.
    obstacle: rigid solid cells: no phi, no c, no flux across their faces.
    output_times: the output clock, increasing, within [0, t_end].
    steps: nominal number of steps over [0, t_end] (the model clock).
    mechanics: None leaves the mechanics out entirely.
    laws: which form of the model's laws (consumption, expansion, the nutrient's dynamics; `laws.Laws`).

    A continuation (`solver.restart`) starts from another run's last state
    instead of from rest: at ``start_time`` (> 0) with ``phi0``, ``alpha0``
    and ``c0`` (per cell), ``u0`` (the displacement the mechanics last
    converged to, per node, components x, y[, z]), the clock's step
    ``first_step`` and the longest step the scheme's limit has allowed so far
    ``step_limit`` (`timeloop.Clock`); its outputs at or before ``start_time``
    belong to the run it continues and are not computed again.  None: alpha =
    0, c solved from phi0, the mechanics at rest, the nominal step, no limit
    seen yet.
    """

    grid: Grid
    phi0: np.ndarray
    nutrient_held: np.ndarray
    t_end: float
    steps: int
    output_times: np.ndarray
    params: Parameters = field(default_factory=Parameters)
    laws: Laws = field(default_factory=Laws)
    nutrient_value: np.ndarray = None  # type: ignore[assignment]  # None: 1 everywhere (__post_init__)
    nutrient_faces: tuple[tuple[str, float], ...] = ()
    obstacle: np.ndarray = None  # type: ignore[assignment]  # None: no obstacle (__post_init__)
    numerics: Numerics = field(default_factory=Numerics)
    mechanics: MechanicsSetup | None = None
    start_time: float = 0.0
    alpha0: np.ndarray | None = None
    c0: np.ndarray | None = None
    u0: np.ndarray | None = None
    first_step: float | None = None
    step_limit: float | None = None
    name: str = "unnamed"

    def __post_init__(self):
        shape = self.grid.cells_shape
        fix = object.__setattr__
        fix(self, "phi0", np.asarray(self.phi0, dtype=float).reshape(shape))
        fix(self, "nutrient_held", np.asarray(self.nutrient_held, dtype=bool).reshape(shape))
        value = np.ones(shape) if self.nutrient_value is None else self.nutrient_value
        fix(self, "nutrient_value", np.broadcast_to(np.asarray(value, dtype=float), shape).copy())
        obstacle = np.zeros(shape, bool) if self.obstacle is None else self.obstacle
        fix(self, "obstacle", np.asarray(obstacle, dtype=bool).reshape(shape))
        fix(self, "output_times", np.asarray(self.output_times, dtype=float).ravel())
        fix(self, "nutrient_faces", tuple((str(face), float(value)) for face, value in self.nutrient_faces))
        for name, shaped in (("alpha0", shape), ("c0", shape), ("u0", (*self.grid.nodes_shape, self.grid.ndim))):
            if getattr(self, name) is not None:
                fix(self, name, np.asarray(getattr(self, name), dtype=float).reshape(shaped))
        fix(self, "start_time", float(self.start_time))
        self._check()

    def _check(self):
        if not (self.t_end > 0 and self.steps >= 1):
            raise ValueError("t_end must be positive and steps at least 1")
        times = self.output_times
        if times.size == 0:
            raise OptionError("output_times", "no output time")
        wrong = times_problem(times, self.t_end)
        if wrong:
            raise OptionError(f"output_times[{wrong[0]}]", wrong[1])
        held_twice = held_faces_problem([face for face, _ in self.nutrient_faces], self.grid.ndim)
        if held_twice:
            raise OptionError(f"nutrient_faces[{held_twice[0]}]", held_twice[1])
        values = np.concatenate([self.nutrient_value[self.nutrient_held], [v for _, v in self.nutrient_faces]])
        if np.any((values < 0) | (values > 1)):
            raise ValueError("held nutrient values must lie in [0, 1]")
        inside = inside_problem(self.nutrient_held, self.obstacle)
        if inside:
            raise OptionError("nutrient_held", inside)
        if not 0 <= self.start_time < self.t_end:
            raise ValueError("start_time must lie in [0, t_end)")
        if not np.any(times > self.start_time):
            raise ValueError("no output time after start_time")
        if self.start_time == 0 and np.any((self.phi0 < 0) | (self.phi0 > 1)):
            raise ValueError("initial phi must lie in [0, 1]")
        if not np.all(np.isfinite(self.phi0) & (self.phi0 >= 0)):  # a continued phi may exceed 1 (the alpha source)
            raise ValueError("initial phi must be finite and >= 0")
        for name in ("alpha0", "c0", "u0"):
            if getattr(self, name) is not None and not np.all(np.isfinite(getattr(self, name))):
                raise ValueError(f"{name} must be finite")
        if self.alpha0 is not None and np.any(self.alpha0 <= -1):
            raise ValueError("alpha0 must be > -1")
        for name in ("first_step", "step_limit"):
            if getattr(self, name) is not None and not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")
        blocked = blocked_problem(self.obstacle)
        if blocked:
            raise OptionError("obstacle", blocked)

    @property
    def dt(self) -> float:
        """Nominal step of the model clock."""
        return self.t_end / self.steps
