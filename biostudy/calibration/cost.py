"""What a calibration will cost, known before anything runs: `biostudy show FILE.toml` says it (`needs`),
`calibrate` refuses what cannot fit (`problems`; docs/calibration.md, "Cost").

Every simulation of a condition writes one output per distinct measurement time of that condition (and one at
t_end), so a table of 100,000 distinct times makes every simulation hold 100,000 snapshots: its memory is the
scene's estimate (`inputs.resources.estimate`) with those outputs, not the scene's own few.  A method may hold
more in this process whatever runs the simulations (`Method.memory`: a posterior's chains, walkers x steps x
parameters).
"""
from __future__ import annotations

from pathlib import Path

from ..errors import BadInput
from ..inputs import resources
from ..inputs.resources import Preflight
from ..reports.needs import refused
from .methods import chosen
from .problem import CalibrationPlan, load_calibration

MANY_OUTPUTS = 1000  # outputs per simulation from which `calibrate` says, before it runs, what they cost


def estimates(plan: CalibrationPlan) -> dict[str, resources.Estimate]:
    """What one simulation of every condition needs: its scene with outputs at its measurement times."""
    found = {}
    for condition in plan.conditions:
        scene = plan.scenes[condition]
        timed = scene.time.model_copy(update={"output_times": plan.output_times(condition)})
        found[condition] = resources.estimate(scene.model_copy(update={"time": timed}))
    return found


def outputs_text(condition: str, outputs: int) -> str:
    return f"{outputs:,} outputs per simulation of condition {condition} (one per distinct measurement time)"


def problems(plan: CalibrationPlan, runs_here: bool) -> list[BadInput]:
    """A `BadInput` for a simulation whose outputs cannot fit in memory here (`runs_here`: the simulations run
    on this machine) and for what the method holds here (`Method.memory`) if it cannot: each blamed on what to
    change."""
    found = []
    if runs_here:
        for condition, one in estimates(plan).items():
            problem = resources.run_problem({condition: one}, 1)
            if problem:
                found.append(BadInput(f"{outputs_text(condition, one.outputs)}: {problem}; round the table's "
                                      "times to fewer distinct values", plan.data_file))
    held = chosen(plan.spec.method).memory(len(plan.parameters))
    if held is not None:
        problem = resources.too_big(held.bytes, f"{held.what} ({held.parts}) need")
        if problem:
            found.append(BadInput(f"{problem}: {held.remedy}", plan.file, f"method.{held.key}"))
    return found


def workers_problem(plan: CalibrationPlan, workers: int | None) -> BadInput | None:
    """A `BadInput` if `workers` local simulations at once, each as large as the largest, cannot fit in memory
    here: said before anything runs or is claimed, as `sweep` refuses its largest cases `--workers` at a time (a
    calibration's rounds grow to that many simulations only later: its starts, then the Jacobians' points)."""
    if not workers or workers < 2:
        return None
    found = estimates(plan)
    largest = max(found, key=lambda condition: found[condition].memory)
    one = found[largest]
    problem = resources.too_big(workers * one.memory, f"{workers} simulations at once (--workers {workers}) need",
                                f"each up to {resources.size(one.memory)}, condition {largest}: {one.parts()}")
    return BadInput(f"{problem}; use fewer workers", plan.file) if problem else None


def note(plan: CalibrationPlan) -> str:
    """What its many outputs make every simulation cost, said before the first one runs ('' for a few)."""
    said = [f"{outputs_text(c, e.outputs)}: {resources.size(e.memory)} of memory and "
            f"{resources.size(e.disk)} on disk each, and as slow to write" for c, e in estimates(plan).items()
            if e.outputs > MANY_OUTPUTS]
    return "; ".join(said) + ("; fewer distinct times in the table make every simulation cheaper" if said else "")


def needs(path: Path) -> str:
    """What running a calibration file needs (validated first: bad input is `BadInput`), as `show` says it: one
    simulation's memory and disk with its outputs at the measurement times, as `calibrate` runs it, and what the
    method holds besides."""
    plan = load_calibration(path, (), Preflight())
    found = estimates(plan)
    largest = max(found, key=lambda i: found[i].memory)
    k = len(plan.parameters)
    held = chosen(plan.spec.method).memory(k)
    return "\n".join([
        f"{plan.spec.name}: {k} parameters, {len(plan.measurements)} measurements, "
        f"{len(found)} conditions of {plan.scene_file.name}",
        f"one simulation {resources.size(found[largest].memory)} of memory ({found[largest].parts()}), "
        f"{resources.size(found[largest].disk)} on disk (every simulation is kept under cases/), "
        f"{outputs_text(largest, found[largest].outputs)}",
        *([f"{held.label:<13} {resources.size(held.bytes)} of memory ({held.parts})"] if held is not None else []),
        f"here          {resources.available_text()}; N local workers need about N times one simulation"]
                     + refused(found[largest], "one simulation needs"))
