"""The time loop: two clocks, failures bisected, snapshots yielded.

The model clock takes nominal steps dt = t_end / steps (or error-controlled
steps, see `numerics.time_tolerance`); the output clock is the list of
output times, which steps land on exactly.  No step lets the growth front
cross more than one cell (`transport.courant`): a longer one is split into
equal substeps (`steps_substepped`), so that few steps and many give the
same answer to within the scheme's time error; `courant_max` is the largest
Courant number a run took.  A step that fails (linear solver
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
each output's fields handed to an output sink as they are made (`sink`).  A
run that stops (`SimulationError`) keeps what it computed: the error carries
the dataset of the outputs made and the last state accepted (`partial`).
Mechanics (if the problem asks for it) is solved only at output times:
nothing feeds back from it into phi or c.
"""
from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, replace
from typing import Callable, Iterator

import numpy as np

from .counters import Counters, declared
from .errors import Runaway, SimulationError, StepFailure
from .parallel import SERIAL, Team, cores
from .parallel.blas import blas_threads
from .problem import Problem
from .sink import Held, OutputSink
from .snapshot import Snapshot
from .transport import State, Transport
from .transport.courant import LIMIT


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
    """CPU seconds of this thread and its team's helpers spent in a repeated piece of work, the first time apart:
    the first step (or mechanics solve) of a run also loads the compiled kernels and builds the first
    hierarchies, a one-off cost that would make a small run look dearer than a larger one run after it in the
    same process.  (Not the process's CPU time: other threads of the process may run other work.)"""

    def __init__(self, team: Team) -> None:
        self.team = team
        self.first: float | None = None
        self.rest = 0.0

    def _now(self) -> float:
        return time.thread_time() + self.team.helper_seconds()

    @contextlib.contextmanager
    def spent(self) -> Iterator[None]:
        began = self._now()
        try:
            yield
        finally:
            seconds = self._now() - began
            if self.first is None:
                self.first = seconds
            else:
                self.rest += seconds


class Clock:
    """Advances a `Transport` to given times with nominal or error-controlled steps."""

    GROW, SHRINK, SAFETY = 4.0, 0.2, 0.9

    def __init__(self, transport: Transport, progress: Callable[[Progress], None] | None = None,
                 team: Team = SERIAL):
        problem = transport.problem
        self.transport = transport
        self.progress = progress
        self.t_end = problem.t_end
        self.nominal = problem.dt
        self.smallest = problem.t_end / problem.numerics.max_substeps
        self.tolerance = problem.numerics.time_tolerance
        self.dt = min(problem.first_step or self.nominal, self.nominal)  # a continuation goes on with its step
        self.steps = self.bisections = self.rejected = self.substepped = 0
        self.split: tuple[float, float] | None = None  # (end, substep) of a step split for the scheme's limit
        self.longest = np.inf if problem.step_limit is None else problem.step_limit  # what that limit allows
        self.largest_error = self.courant_max = 0.0
        self.mechanics_solves = self.mechanics_left = self.outputs = 0  # kept by `Simulation`, told in `Progress`
        self.output_seconds = 0.0
        self.cpu = CpuTime(team)  # the transport's threads

    def counters(self) -> Counters:
        return {"steps_taken": self.steps,
                "steps_bisected": self.bisections,
                "steps_rejected": self.rejected,
                "steps_substepped": self.substepped,
                "courant_max": self.courant_max,
                "largest_step_error": self.largest_error,
                "next_step": self.dt,
                "step_limit": self.longest if np.isfinite(self.longest) else 0.0}

    def advance(self, state: State, until: float) -> State:
        """Step from state.t to exactly `until`."""
        eps = 1e-12 * self.t_end
        while state.t < until - eps:
            dt = min(self.dt, until - state.t)
            if until - (state.t + dt) < 1e-6 * dt:
                dt = until - state.t
            try:
                with self.cpu.spent():  # (the limit reads the velocity, which the step then reuses)
                    dt, split = self._within_limit(state, dt)
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
            self.substepped += split
            self.courant_max = max(self.courant_max, state.courant)
            runaway = self.transport.runaway(state)
            if runaway is not None:
                raise _stopped(Runaway(state.t, *runaway), state)
            if self.progress is not None:
                self.progress(Progress(state.t, self.t_end, self.steps, self.bisections, self.rejected,
                                       self.transport.timings.get("mechanics", 0.0), self.mechanics_solves,
                                       self.mechanics_left, self.outputs, self.output_seconds))
        return state

    def _within_limit(self, state: State, dt: float) -> tuple[float, bool]:
        """The step to take from `state` instead of the clock's `dt`, and whether it is a substep.  The longest
        step the scheme's limit allows (`courant`) only shrinks over a run (`self.longest`: once the front has needed
        a step that short, the run keeps to it, as if it had asked for the steps it needs); a step longer than that
        is split into the fewest equal substeps within it, which keep their length unless it shrinks further."""
        rate = self.limit_rate(state)
        if rate > 0:
            self.longest = min(self.longest, LIMIT / rate)
            if self.longest < self.smallest * (1 - 1e-9):
                raise _stopped(SimulationError(state.t, f"the scheme's limit needs steps of {self.longest:.3g} (the "
                                                        f"front crossing one cell, the expansion growing e-fold), "
                                                        f"below t_end/max_substeps = {self.smallest:.3g}"), state)
        if self.split is not None and state.t < self.split[0] - 1e-12 * self.t_end:
            end, sub = self.split
            left = end - state.t
            if sub > self.longest:
                sub = left / np.ceil(left / self.longest)
                self.split = (end, sub)
            return min(dt, left if left - sub < 1e-6 * sub else sub), True
        self.split = None
        if dt <= self.longest:
            return dt, False
        sub = dt / np.ceil(dt / self.longest)
        self.split = (state.t + dt, sub)
        return sub, True

    def limit_rate(self, state: State) -> float:
        """1/T*: the longest step the scheme allows from `state` is LIMIT over it (`transport.courant`): the front
        crosses at most one cell, and the explicit expansion source (k_alpha alpha^n) grows at most e-fold."""
        return max(self.transport.velocity(state)[1], self.transport.problem.params.k_alpha)

    def _check_smallest(self, state: State, dt: float, cause: str, where: str):
        if dt < self.smallest * (1 - 1e-9):
            raise _stopped(SimulationError(state.t, f"{cause} (step bisected below t_end/max_substeps = "
                                                    f"{self.smallest:.3g})", where), state)

    def _attempt(self, state: State, dt: float) -> State:
        if self.tolerance is None:
            new = self.transport.step(state, dt)
            if dt >= self.dt * (1 - 1e-9):
                self.dt = min(2.0 * self.dt, self.nominal)
            return new
        full = self.transport.step(state, dt, with_nutrient=False)
        half = self.transport.step(state, 0.5 * dt)
        two = self.transport.step(half, 0.5 * dt)
        two = replace(two, courant=max(half.courant, two.courant))  # the largest of the two half steps
        error = float(np.max(np.abs(two.phi - full.phi), initial=0.0))
        if error > self.tolerance:
            raise _Rejected(error)
        self.largest_error = max(self.largest_error, error)
        factor = self.GROW if error == 0 else min(self.GROW, self.SAFETY * np.sqrt(self.tolerance / error))
        if dt >= self.dt * (1 - 1e-9):
            self.dt = dt * factor
        return two


def _stopped(error: SimulationError, state: State) -> SimulationError:
    """`error` with the last state the clock accepted, for the caller to keep (errors.SimulationError)."""
    error.last = state
    return error


def _mechanics(problem: Problem, team: Team):
    if problem.mechanics is None:
        return None
    from .mechanics import GrowthMechanics  # lazily: a scene without mechanics never imports scikit-fem

    return GrowthMechanics(problem.grid, problem.params, problem.mechanics, problem.obstacle, team=team)


class Simulation:
    """One simulation: iterate it for a `Snapshot` at every output time; its cost stays readable."""

    def __init__(self, problem: Problem, progress: Callable[[Progress], None] | None = None):
        self.started = time.perf_counter()
        self.problem = problem
        self.team = Team(problem.numerics.threads or cores())
        setup = CpuTime(self.team)  # the operators built for this grid: part of what a run costs
        with setup.spent():
            self.transport = Transport(problem, self.team)  # its first hierarchy on one BLAS thread (`Transport`)
            self.clock = Clock(self.transport, progress, self.team)
            self.mechanics = _mechanics(problem, self.team)
        self.setup_cpu = setup.first or 0.0
        self.mechanics_cpu = CpuTime(self.team)
        if self.mechanics is not None and problem.u0 is not None:
            alpha = np.zeros(problem.grid.cells_shape) if problem.alpha0 is None else problem.alpha0
            self.mechanics.start_from(problem.u0, problem.phi0, alpha)

    def __iter__(self) -> Iterator[Snapshot]:
        problem, transport, clock = self.problem, self.transport, self.clock
        setup = time.thread_time()
        with blas_threads(1):  # the first hierarchy's coarse pseudo-inverse too
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
            try:
                with blas_threads(1):
                    state = clock.advance(state, float(when))
            except SimulationError as error:  # the last state accepted is kept (errors.SimulationError)
                if error.last is not None and error.last.t > state.t and error.last.c is not None:
                    error.stopped = self._snapshot(error.last, error.last.t)
                raise
            snapshot = self._snapshot(state, float(when))
            if self._solves_mechanics(index, last):
                try:
                    self._solve_mechanics(snapshot)
                except SimulationError as error:  # the output's transport fields are kept, without u and p
                    error.stopped = snapshot
                    raise
                clock.mechanics_solves += 1
            snapshot.elapsed = time.perf_counter() - self.started
            handed = time.perf_counter()
            yield snapshot
            clock.output_seconds += time.perf_counter() - handed  # the caller's: its record, its sink

    def _snapshot(self, state: State, when: float) -> Snapshot:
        """The fields of `state` as grid arrays, with the clock's counters."""
        transport, clock = self.transport, self.clock
        assert state.c is not None  # an accepted step ends with its nutrient solved
        return Snapshot(time=when, phi=transport.full(state.phi), c=transport.full(state.c),
                        alpha=transport.full(state.alpha), steps=clock.steps, bisections=clock.bisections,
                        rejected=clock.rejected, elapsed=time.perf_counter() - self.started)

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
               "cpu_time_first": (steps.first or 0.0) + (solves.first or 0.0), "cpu_time_setup": self.setup_cpu,
               "threads": self.team.size}
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
    try:
        for snapshot in simulation:
            records.append(record(problem, snapshot))
            sink.add(snapshot)
    except SimulationError as error:  # what was computed: every output made, and the state where it stopped
        if error.stopped is not None:
            records.append(record(problem, error.stopped))
            sink.add(error.stopped)
        if records:
            error.partial = assemble(problem, records, sink.fields(), simulation.report())
        raise
    return assemble(problem, records, sink.fields(), simulation.report())
