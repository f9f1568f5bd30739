"""How much memory and disk a scene needs, known before anything is allocated.

A grid of 2000³ cells, or a million outputs, must be refused at once with the
estimate ("needs ~X GB of memory, Y GB available"), not end in a MemoryError
or an exhausted machine.  The estimate is a sum of parts, each a model of what
the solver holds, fitted to peak resident memory (VmHWM) measured on this
solver (docs/transport.md and docs/mechanics.md, "How far one machine goes";
`python benchmarks/scale.py`, `python benchmarks/mechanics_memory.py`):

- transport: per cell (matrices, the AMG hierarchy and its set-up, Krylov
  vectors, index arrays): ~1.1 kB in 3-D, ~0.8 kB in 2-D (measured peaks
  without mechanics grow by 1.03 kB per cell from 64^3 to 96^3 and by 0.75 kB
  from 400^2 to 800^2: `python benchmarks/scale.py --no-mechanics`, `--2d`);
- mechanics (`mechanics_memory`): a fixed part (imports, compiled kernels,
  the temporaries of the box of cells assembled at once) and per grid node the
  tangent in double precision (half a stencil of ndim x ndim blocks,
  `solver.mechanics.stencil`) plus what the preconditioner and the Newton
  solve hold besides, by preconditioner ("auto" means what it means to the
  solver: `solver.mechanics.linear_solver_for`): for the multigrid its
  single-precision copy of the tangent before a Newton step's new one, the
  coarser levels, the smoother's inverse diagonal blocks, the Krylov and
  Newton vectors; a direct factorisation's fill is larger;
- outputs: a run that writes its file streams its fields to disk as they
  are made, once they exceed `STREAM_ABOVE` (`streams`, `data.spool`): a few outputs' fields at a time (the one being
  made, the one being written; small outputs read back in blocks of `SPOOL_CHUNK_BYTES`) and a little
  bookkeeping per output (`STREAMED_PER_OUTPUT`), and
  measures its observables from the spool in blocks of at most
  `BLOCK_BYTES` once `solver.simulate` has returned, when the solver's
  arrays are freed (`commands.run`): the larger of the two counts; a sweep's
  case, a calibration's simulation and the API's run without a file hold
  every snapshot's fields (phi, c, alpha; p and u with mechanics) about
  three times over (the run's snapshots, the dataset, its encoding or
  transfer);
- a run continued (`run --continue`): open for the whole run, its history
  read an output at a time as it is written again (`CONTINUATION`);
- a process: ~0.32 GB for an interpreter that runs and writes a scene (each
  local worker is one), 0.06 GB more with the mechanics' imports;
- image regions: the file's values, read once and held for the run, and,
  before the solver's arrays are made, averaging them onto the grid a slab
  at a time (`image_files.averaging_bytes`).

The sum stays above the measured peaks and within 1.5 times them from 32³ to
128³ with the mechanics, to 200³ without.  What it does not cover: a
mechanics solve whose conjugate gradients fail and fall back to restarted
GMRES holds its basis too, ~50 vectors of the unknowns (~1.2 kB per node in
3-D; a rescue on the way to a refusal, docs/mechanics.md).  A run is refused
when its estimate exceeds the memory available (`memory_limits`).  Disk: a
run's dataset is about its outputs once over, and a run that streams its
outputs holds them on disk twice while it writes its file (the spool, and the
dataset's temporary made from it; compression is not counted on): checked
together against the free space of the target's file system, before anything
is computed.
"""
from __future__ import annotations

import math
import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

from solver.mechanics import Settings, linear_solver_for

from ..errors import BadInput, InvalidAt
from . import memory

PROCESS = 0.32e9  # bytes: a process that runs and writes a scene (biostudy, FiPy, xarray, dask, netCDF4 imported):
# VmHWM of `biostudy run` at 12³ 0.31 GB (benchmarks/scale.py); a bare `solver.simulate` needs ~0.2 GB
TRANSPORT_PER_CELL = {2: 0.8e3, 3: 1.1e3}
MECHANICS_IMPORTS = 0.06e9  # scikit-fem and the mechanics' compiled kernels: 12³ with mechanics 0.37 GB
ASSEMBLY_PER_CELL = {2: 5e3, 3: 35e3}  # temporaries per cell of the box assembled at once (`Settings.chunk` cells)
MECHANICS_PER_NODE = {  # bytes per grid node besides the tangent (`tangent_bytes`), by preconditioner
    ("multigrid", 3): 1.25e3, ("multigrid", 2): 0.6e3,
    ("amg", 3): 7e3, ("amg", 2): 2.5e3,  # pyamg's hierarchy, its own copy of the tangent among it
    ("direct", 3): 55e3, ("direct", 2): 7.5e3,  # the factors' fill (measured at 40³, 100²-200²)
}
COPIES = 3  # how many times the outputs are held at once, unless streamed
STREAMED = 4  # outputs' fields held at once by a run that streams them (made, spooled, read back, written)
STREAM_ABOVE = 64e6  # bytes of output fields beyond which a run that writes its file streams them (`streams`)
BLOCK_BYTES = 4e6  # fields read at once to measure a run's observables (`quantities.observables.variables`)
BLOCK_COPIES = 6  # the block, and what measuring it makes of it (NaN filled, thresholded): measured 5.5 at 32³
PER_OUTPUT = 2e3  # bytes of bookkeeping per snapshot and copy (objects, scalars), whatever the grid
STREAMED_PER_OUTPUT = 4e3  # the same of a streamed run, over all it does per output: 3.6 kB measured (VmHWM of 3001
# and 6001 outputs of 32², issue 39.7; 17 kB when its spool was read back one dask chunk an output)
SPOOL_CHUNK_BYTES = 256e3  # a streamed field read back at most this much at a time, one output at least (`data.spool`)
# `run --continue`: the run continued, open and read lazily (`data.continuation`): its file's handles and caches and
# the lazy history joined to the continuation's, above a fresh run of the same outputs: measured +21 MB from a
# history of 101 outputs of 32³, +25 MB from 201 (VmHWM, issue 39.6; read whole into memory it was +168 MB)
CONTINUATION, CONTINUATION_PER_OUTPUT = 20e6, 50e3
VALIDATION_PER_CELL = 64  # the masks and initial fields validating a scene builds (bytes per cell)
DEFAULT_OUTPUTS = 11  # snapshots of a scene that names neither outputs nor output_times


@dataclass(frozen=True)
class Estimate:
    """Bytes a run needs: memory by part, and the dataset on disk."""

    cells: int
    outputs: int
    transport: float
    mechanics: float
    snapshots: float
    disk: float
    measuring: float = 0.0  # a streamed run's observables, measured from its spool once the solver is freed
    spool: float = 0.0  # a streamed run's spool on disk, beside the dataset until the dataset is written
    images: float = 0.0  # the image files its regions read, held for the run (`images.Image.memory`)
    averaging: float = 0.0  # averaging one onto the grid, before the solver's arrays are made
    continuing: float = 0.0  # the run it continues (`run --continue`), open for the whole run

    @property
    def memory(self) -> float:
        return PROCESS + self.snapshots + self.images + self.continuing + max(
            self.transport + self.mechanics, self.measuring, self.averaging)

    @property
    def validation(self) -> float:
        return VALIDATION_PER_CELL * self.cells

    def parts(self) -> str:
        parts = [("transport", self.transport), ("mechanics", self.mechanics), ("outputs", self.snapshots),
                 ("images", self.images), ("averaging them", self.averaging), ("the run continued", self.continuing)]
        text = ", ".join(f"{name} {size(value)}" for name, value in parts if value)
        return text + (f"; then {size(self.measuring)} to measure the outputs, the solver's memory freed"
                       if self.measuring else "")


def size(value: float) -> str:
    """Bytes for people: '~3.2 GB', '~180 MB'."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if value >= scale:
            return f"~{value / scale:.3g} {unit}"
    return f"~{value / 1e3:.3g} kB"


def estimate(scene, streamed: bool = False, history: int | None = None) -> Estimate:
    """What running `scene` (a validated `Scene`, or one being validated) needs; `streamed`: as a run that writes
    its file (`biostudy run`), whose memory does not grow with its outputs once they are worth streaming;
    `history`: the outputs of the run it continues (`run --continue`)."""
    shape = list(scene.grid.shape)
    ndim = len(shape)
    cells = math.prod(shape)
    nodes = math.prod(n + 1 for n in shape)
    outputs = scene.time.count()
    mechanics = 0.0
    per_output = 3 * cells  # phi, c, alpha
    if scene.mechanics is not None and scene.mechanics.enabled:
        mechanics = mechanics_memory(linear_solver_for(scene.mechanics.linear_solver, ndim * nodes), ndim, nodes)
        per_output += cells + ndim * nodes  # p, u
    written = 8.0 * per_output * outputs
    held, measuring = COPIES * (written + PER_OUTPUT * outputs), 0.0
    continuing = 0.0 if history is None else CONTINUATION + CONTINUATION_PER_OUTPUT * history
    if streamed and written > STREAM_ABOVE:  # the observables are measured after `solver.simulate` returned
        block = max(min(BLOCK_BYTES, written), 2 * 8.0 * per_output)  # at least one output and the first
        fields_at_once = max(8.0 * per_output, 5 * SPOOL_CHUNK_BYTES)  # an output, or a block of small ones
        held, measuring = STREAMED * fields_at_once + STREAMED_PER_OUTPUT * outputs, BLOCK_COPIES * block
        return Estimate(cells, outputs, TRANSPORT_PER_CELL[ndim] * cells, mechanics, held, written, measuring,
                        written, *_images(scene), continuing)
    return Estimate(cells, outputs, TRANSPORT_PER_CELL[ndim] * cells, mechanics, held, written, measuring, 0.0,
                    *_images(scene), continuing)


def _images(scene) -> tuple[float, float]:
    """(bytes of the image files the scene's regions read, held for the run: once per file; the most that
    averaging one onto the grid holds besides), from the regions that read one (`images.Image.memory`)."""
    held: dict[str, float] = {}
    averaging = 0.0
    for kind in ("biofilm", "nutrient", "obstacle"):
        for region in getattr(scene, kind, None) or ():
            if hasattr(region, "memory"):
                path, values, peak = region.memory()
                held[path], averaging = values, max(averaging, peak)
    return sum(held.values()), averaging


def tangent_bytes(ndim: int) -> float:
    """Bytes per grid node of the mechanics' tangent: its diagonal block and the blocks to the later half of the
    3^ndim - 1 neighbours, ndim x ndim doubles each (`solver.mechanics.stencil`)."""
    return (3**ndim + 1) // 2 * ndim**2 * 8.0


def mechanics_memory(method: str, ndim: int, nodes: int) -> float:
    """Bytes the mechanics of a grid of `nodes` nodes needs with preconditioner `method` ("direct", "multigrid",
    "amg"): the fixed part, the assembly's box of cells and, per node, the tangent and the rest."""
    box = ASSEMBLY_PER_CELL[ndim] * Settings().chunk
    return MECHANICS_IMPORTS + box + nodes * (tangent_bytes(ndim) + MECHANICS_PER_NODE[(method, ndim)])


def streams(scene) -> bool:
    """Whether a run of `scene` that writes its file streams its outputs to disk as they are made: when their
    fields exceed `STREAM_ABOVE`.  Below, holding them three times over is a few hundred MB at most, and the
    spool (a second file, read back lazily) would cost a small run more than it saves (~0.5 s a run)."""
    return estimate(scene).disk > STREAM_ABOVE


MEMORY_VARIABLE = "BIOSTUDY_MEMORY"  # e.g. "16 GB": the memory this process may use, instead of the others


SIZE = re.compile(r"^\s*(?P<number>[0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*(?P<unit>[KMGT]?B)?\s*$", re.IGNORECASE)
SCALES = {"": 1.0, "B": 1.0, "KB": 1e3, "MB": 1e6, "GB": 1e9, "TB": 1e12}


def parse_size(text: str) -> float:
    """'16 GB', '512MB', '2.5e9' -> bytes; ValueError for anything else."""
    found = SIZE.match(text)
    if not found:
        raise ValueError(f"{text!r} is not a size such as '16 GB'")
    return float(found["number"]) * SCALES[(found["unit"] or "").upper()]


def memory_limits() -> list[memory.Limit]:
    """Every account of the memory a run may use here, the binding one first (`biostudy.inputs.memory`: the
    machine, the job's cgroup, a scheduler's allocation); the variable BIOSTUDY_MEMORY (e.g. "16 GB") replaces
    them all, for an allocation none of them shows."""
    given = os.environ.get(MEMORY_VARIABLE)
    if given:
        try:
            return [memory.Limit(parse_size(given), f"{MEMORY_VARIABLE}={given}")]
        except ValueError as error:
            raise BadInput(f"{error}", MEMORY_VARIABLE) from None
    return memory.limits()


def available_memory() -> float:
    """Bytes a run may use here (the smallest of `memory_limits`).  A run is refused when its estimate exceeds
    it."""
    return memory_limits()[0].bytes


def available_text() -> str:
    """'~1.57 GB of memory available (SLURM_MEM_PER_NODE=1500 (MB); the machine: ~24.3 GB)': the limit that
    binds, and the looser ones after it."""
    binding, *looser = memory_limits()
    others = "".join(f"; {limit.source}: {size(limit.bytes)}" for limit in looser)
    return f"{size(binding.bytes)} of memory available ({binding.source}{others})"


def free_disk(path: str | Path) -> float:
    """Free bytes on the file system that would hold `path` (its nearest existing ancestor's)."""
    existing = Path(path).absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    return float(shutil.disk_usage(existing if existing.is_dir() else existing.parent).free)


def too_big(need: float, what: str = "needs", parts: str = "") -> str:
    """'' if `need` bytes of memory are available, else the one-line reason: what needs how much (of which
    `parts`), and what is available by which account (BIOSTUDY_MEMORY, a cgroup, the machine: `memory_limits`)."""
    binding = memory_limits()[0]
    if need <= binding.bytes:
        return ""
    return (f"{what} {size(need)} of memory{f' ({parts})' if parts else ''}, {size(binding.bytes).lstrip('~')} "
            f"available ({binding.source})")


def validation_problem(scene) -> str:
    """'' unless validating `scene` (its masks and initial fields) could not fit in memory; then why, with the
    run's own estimate.  Called before any array of the grid's size is made."""
    found = estimate(scene)
    problem = too_big(found.validation, f"{found.cells:,} cells: validating alone needs")
    return f"{problem}; running would need {size(found.memory)} ({found.parts()})" if problem else ""


@dataclass(frozen=True)
class Preflight:
    """A command's check that a scene fits this machine, never a rule of the scene's schema: made while the scene
    is validated (`scene.scene_from_data`), once its keys are valid and before any array of the grid's size
    exists.  Validating it (its masks and initial fields) must fit in memory here; a scene that `runs` here must
    fit as a whole run (its `estimate`; `streamed`: a run that writes its file as it goes).  `InvalidAt` at the
    key to change."""

    runs: bool = False
    streamed: bool = False

    def __call__(self, scene) -> None:
        too_big = validation_problem(scene)
        if too_big:
            raise InvalidAt("grid.shape", too_big)
        if not self.runs:
            return
        found = estimate(scene, streamed=self.streamed)
        too_big = run_problem({scene.name: found}, 1)
        if too_big:
            outputs = "time.output_times" if scene.time.output_times is not None else "time.outputs"
            raise InvalidAt("grid.shape" if found.transport + found.mechanics >= found.snapshots else outputs,
                            too_big)


def run_problem(estimates: dict[str, Estimate], at_once: int, target: str | Path | None = None,
                disk: float | None = None) -> str:
    """'' if runs of these estimates (by name) fit in memory, `at_once` of them at a time (0: not here, e.g. on
    a Dask cluster), and `disk` bytes (default: their datasets) fit on the file system of `target`; else the
    one-line reason, naming the largest run."""
    if not estimates:
        return ""
    ranked = sorted(estimates.items(), key=lambda item: item[1].memory, reverse=True)
    name, one = ranked[0]
    if at_once:
        together = ranked[:at_once]
        if len(together) > 1:
            problem = too_big(sum(e.memory for _, e in together), f"{len(together)} runs at once need",
                              f"the largest, {name}: {size(one.memory)}, {one.parts()}")
            if problem:
                return f"{problem}; use fewer workers"
        problem = too_big(one.memory, "needs", f"{name}: {one.parts()}") if len(together) == 1 else ""
        if problem:
            return problem
    if target is not None:
        spool = sum(e.spool for e in estimates.values())
        written = sum(e.disk for e in estimates.values()) + spool if disk is None else disk
        free = free_disk(target)
        if written > free:
            what = (f"its dataset ({size(written - spool)}) and the spool its outputs stream to until the dataset is "
                    f"written ({size(spool)}), together" if spool else "its datasets")
            return f"needs {size(written)} of disk for {what}, {size(free).lstrip('~')} free"
    return ""
