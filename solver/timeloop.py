"""The time loop: two clocks, failures bisected, snapshots yielded.

The model clock takes nominal steps dt = t_end / steps (or error-controlled
steps, see `numerics.time_tolerance`); the output clock is the list of
output times, which steps land on exactly.  A step that fails (linear solver
not converged, NaN, bounds) is bisected, as in the paper, until the step
would fall below t_end / max_substeps (paper: 1e6); then the run stops with a
`SimulationError` naming time, cause and place.  After a bisection the step
grows back by doubling.

The transport's vector operations (norms and dot products of CG and
BiCGSTAB) run on one BLAS thread: they are too short to gain from threads,
and OpenBLAS's threads, when the cores are busy with anything else, turned a
25 600-entry norm from 6 µs into 6.7 ms (docs/transport.md).

`evolve` is a generator of `Snapshot`s (one per output time) that tests can
step with ``next()``; `simulate` runs it to the end and returns the dataset,
each output's fields handed to an output sink as they are made (`sink`).
Mechanics (if the problem asks for it) is solved only at output times:
nothing feeds back from it into phi or c.
"""
from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, replace
from typing import Callable, Iterator

import numpy as np
from threadpoolctl import threadpool_limits

from .counters import Counters, declared
from .errors import SimulationError, StepFailure
from .problem import Problem
from .sink import Held, OutputSink
from .snapshot import Snapshot
from .transport import State, Transport


@dataclass(frozen=True)
class Progress:
    """Reported after every accepted step."""

    time: float
    t_end: float
    steps: int
    bisections: int
    rejected: int
    mechanics_seconds: float = 0.0  # wall time of the mechanics solves so far: their cost is not in proportion
    mechanics_solves: int = 0  # to simulated time (they come at outputs), so a time-left estimate counts them
    mechanics_left: int = 0  # apart: how many are done and how many are still to come
    outputs: int = 0  # how many outputs this run makes: the dataset made of them at the end takes time too
    output_seconds: float = 0.0  # wall time its outputs took so far where they were handed over (a sink writing
    # them to disk), which is not a step's: the time left prices the dataset made at the end in steps without it


class _Rejected(Exception):
    """Step-doubling error above tolerance (not a failure: the controller shrinks the step)."""

    def __init__(self, error: float):
        self.error = error


class CpuTime:
    """CPU seconds of this thread spent in a repeated piece of work, the first time apart: the first step (or
    mechanics solve) of a run also loads the compiled kernels and builds the first hierarchies, a one-off cost
    that would make a small run look dearer than a larger one run after it in the same process."""

    def __init__(self) -> None:
        self.first: float | None = None
        self.rest = 0.0

    @contextlib.contextmanager
    def spent(self) -> Iterator[None]:
        began = time.thread_time()
        try:
            yield
        finally:
            seconds = time.thread_time() - began
            if self.first is None:
                self.first = seconds
            else:
                self.rest += seconds


class Clock:
    """Advances a `Transport` to given times with nominal or error-controlled steps."""

    GROW, SHRINK, SAFETY = 4.0, 0.2, 0.9

    def __init__(self, transport: Transport, progress: Callable[[Progress], None] | None = None):
        problem = transport.problem
        self.transport = transport
        self.progress = progress
        self.t_end = problem.t_end
        self.nominal = problem.dt
        self.smallest = problem.t_end / problem.numerics.max_substeps
        self.tolerance = problem.numerics.time_tolerance
        self.dt = min(problem.first_step or self.nominal, self.nominal)  # a continuation goes on with its step
        self.steps = self.bisections = self.rejected = 0
        self.largest_error = 0.0
        self.mechanics_solves = self.mechanics_left = self.outputs = 0  # kept by `Simulation`, told in `Progress`
        self.output_seconds = 0.0
        self.cpu = CpuTime()

    def counters(self) -> Counters:
        return {"steps_taken": self.steps,
                "steps_bisected": self.bisections,
                "steps_rejected": self.rejected,
                "largest_step_error": self.largest_error,
                "next_step": self.dt}

    def advance(self, state: State, until: float) -> State:
        """Step from state.t to exactly `until`."""
        eps = 1e-12 * self.t_end
        while state.t < until - eps:
            dt = min(self.dt, until - state.t)
            if until - (state.t + dt) < 1e-6 * dt:
                dt = until - state.t
            try:
                with self.cpu.spent():
                    new = self._attempt(state, dt)
            except _Rejected as rejection:  # (only error-controlled steps reject: a tolerance is set)
                assert self.tolerance is not None
                self.rejected += 1
                self.dt = dt * max(self.SHRINK, self.SAFETY * np.sqrt(self.tolerance / rejection.error))
                self._check_smallest(state, self.dt, f"error estimate {rejection.error:.3g} above "
                                                     f"time_tolerance {self.tolerance:g}", "")
                continue
            except StepFailure as failure:
                self.bisections += 1
                self.dt = 0.5 * dt
                self._check_smallest(state, self.dt, failure.cause, failure.where)
                continue
            state = new if abs(new.t - until) > eps else replace(new, t=until)
            self.steps += 1
            if self.progress is not None:
                self.progress(Progress(state.t, self.t_end, self.steps, self.bisections, self.rejected,
                                       self.transport.timings.get("mechanics", 0.0), self.mechanics_solves,
                                       self.mechanics_left, self.outputs, self.output_seconds))
        return state

    def _check_smallest(self, state: State, dt: float, cause: str, where: str):
        if dt < self.smallest * (1 - 1e-9):
            raise SimulationError(state.t, f"{cause} (step bisected below t_end/max_substeps = "
                                           f"{self.smallest:.3g})", where)

    def _attempt(self, state: State, dt: float) -> State:
        if self.tolerance is None:
            new = self.transport.step(state, dt)
            if dt >= self.dt * (1 - 1e-9):
                self.dt = min(2.0 * self.dt, self.nominal)
            return new
        full = self.transport.step(state, dt, with_nutrient=False)
        half = self.transport.step(state, 0.5 * dt)
        two = self.transport.step(half, 0.5 * dt)
        error = float(np.max(np.abs(two.phi - full.phi), initial=0.0))
        if error > self.tolerance:
            raise _Rejected(error)
        self.largest_error = max(self.largest_error, error)
        factor = self.GROW if error == 0 else min(self.GROW, self.SAFETY * np.sqrt(self.tolerance / error))
        if dt >= self.dt * (1 - 1e-9):
            self.dt = dt * factor
        return two


def _mechanics(problem: Problem):
    if problem.mechanics is None:
        return None
    from .mechanics import GrowthMechanics  # lazily: a scene without mechanics never imports scikit-fem

    return GrowthMechanics(problem.grid, problem.params, problem.mechanics, problem.obstacle)


class Simulation:
    """One simulation: iterate it for a `Snapshot` at every output time; its cost stays readable."""

    def __init__(self, problem: Problem, progress: Callable[[Progress], None] | None = None):
        self.started = time.perf_counter()
        self.problem = problem
        setup = time.thread_time()
        with threadpool_limits(limits=1, user_api="blas"):  # one BLAS thread throughout: the same bits anywhere
            self.transport = Transport(problem)
        self.clock = Clock(self.transport, progress)
        self.mechanics = _mechanics(problem)
        self.setup_cpu = time.thread_time() - setup  # the operators built for this grid: part of what a run costs
        self.mechanics_cpu = CpuTime()
        if self.mechanics is not None and problem.u0 is not None:
            alpha = np.zeros(problem.grid.cells_shape) if problem.alpha0 is None else problem.alpha0
            self.mechanics.start_from(problem.u0, problem.phi0, alpha)

    def __iter__(self) -> Iterator[Snapshot]:
        problem, transport, clock = self.problem, self.transport, self.clock
        setup = time.thread_time()
        with threadpool_limits(limits=1, user_api="blas"):  # the first hierarchy's coarse pseudo-inverse too
            state = transport.initial()
        self.setup_cpu += time.thread_time() - setup
        last = len(problem.output_times) - 1
        # a continuation's outputs up to its start belong to the run it continues (indices stay the scene's:
        # the mechanics is solved at the same outputs as in a run straight to t_end)
        first = 0 if problem.start_time == 0 else int(np.searchsorted(
            problem.output_times, problem.start_time * (1 + 1e-12) + 1e-12 * problem.t_end, side="right"))
        solved_at = [i for i in range(first, last + 1) if self._solves_mechanics(i, last)]
        clock.outputs = last + 1 - first
        for index, when in enumerate(problem.output_times):
            if index < first:
                continue
            clock.mechanics_left = sum(i >= index for i in solved_at)
            with threadpool_limits(limits=1, user_api="blas"):
                state = clock.advance(state, float(when))
            assert state.c is not None  # an accepted step ends with its nutrient solved
            snapshot = Snapshot(
                time=float(when), phi=transport.full(state.phi), c=transport.full(state.c),
                alpha=transport.full(state.alpha), steps=clock.steps, bisections=clock.bisections,
                rejected=clock.rejected, elapsed=0.0,
            )
            if self._solves_mechanics(index, last):
                self._solve_mechanics(snapshot)
                clock.mechanics_solves += 1
            snapshot.elapsed = time.perf_counter() - self.started
            handed = time.perf_counter()
            yield snapshot
            clock.output_seconds += time.perf_counter() - handed  # the caller's: its record, its sink

    def _solves_mechanics(self, index: int, last: int) -> bool:
        """Whether u and p are solved at output `index` (every `mechanics.every`-th, and the last)."""
        every = self.problem.mechanics.every if self.problem.mechanics is not None else 0
        return self.mechanics is not None and every > 0 and (index % every == 0 or index == last)

    def _solve_mechanics(self, snapshot: Snapshot):
        began = time.perf_counter()
        with self.mechanics_cpu.spent():
            result = self.mechanics.solve(np.nan_to_num(snapshot.phi), np.nan_to_num(snapshot.alpha), snapshot.time)
        self.transport.timings["mechanics"] += time.perf_counter() - began
        snapshot.u, snapshot.p = result.u, result.p
        snapshot.mechanics = {"newton_iterations": result.newton_iterations, "seconds": result.seconds, **result.info}

    def report(self) -> dict:
        """What the run cost: wall time, counters, where the time went."""
        steps, solves = self.clock.cpu, self.mechanics_cpu
        cpu = {"cpu_time_loop": steps.rest + solves.rest,
               "cpu_time_first": (steps.first or 0.0) + (solves.first or 0.0), "cpu_time_setup": self.setup_cpu}
        return {"wall_time": time.perf_counter() - self.started, "timings": dict(self.transport.timings),
                **declared({**self.clock.counters(), **self.transport.counters(), **cpu})}


def evolve(problem: Problem, progress: Callable[[Progress], None] | None = None) -> Iterator[Snapshot]:
    """Yield a `Snapshot` at every output time; ``next()`` steps it in tests."""
    return iter(Simulation(problem, progress))


def simulate(problem: Problem, progress: Callable[[Progress], None] | None = None, sink: OutputSink | None = None):
    """Run `problem` to t_end and return its dataset (see `output.assemble`).  Each output's fields go to `sink`
    as they are made (default: held in memory, `sink.Held`); the loop itself keeps only their `output.Record`."""
    from .output import assemble, record  # lazily: xarray only where a dataset is made (tests step `evolve`)

    sink = Held() if sink is None else sink
    simulation = Simulation(problem, progress)
    records = []
    for snapshot in simulation:
        records.append(record(problem, snapshot))
        sink.add(snapshot)
    return assemble(problem, records, sink.fields(), simulation.report())
