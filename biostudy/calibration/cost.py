"""What a calibration will cost, known before anything runs: `biostudy show FILE.toml` says it, `calibrate`
refuses what cannot fit (docs/calibration.md, "Cost").

Every simulation of a condition writes one output per distinct measurement time of that condition (and one at
t_end), so a table of 100,000 distinct times makes every simulation hold 100,000 snapshots: its memory is the
scene's estimate (`inputs.resources.estimate`) with those outputs, not the scene's own few.  A posterior adds
the sampler's arrays, walkers x steps x parameters (`posterior_memory`), held in this process whatever runs
the simulations.
"""
from __future__ import annotations

from ..errors import BadInput
from ..inputs import resources
from .calibration import CalibrationPlan
from .calibration_method import MethodSpec

MANY_OUTPUTS = 1000  # outputs per simulation from which `calibrate` says, before it runs, what they cost


def estimates(plan: CalibrationPlan) -> dict[str, resources.Estimate]:
    """What one simulation of every condition needs: its scene with outputs at its measurement times."""
    found = {}
    for condition in plan.conditions:
        scene = plan.scenes[condition]
        timed = scene.time.model_copy(update={"output_times": plan.output_times(condition)})
        found[condition] = resources.estimate(scene.model_copy(update={"time": timed}))
    return found


def posterior_memory(method: MethodSpec, parameters: int) -> float:
    """Bytes of a posterior's chains: emcee's positions and log-probabilities (walkers x steps x (k + 1)), the
    kept samples and their values in the parameters' units (at most walkers x steps x k each)."""
    return 8.0 * method.walkers * method.steps * (3 * parameters + 1)


def chains_text(method: MethodSpec, parameters: int) -> str:
    return f"{method.walkers} walkers × {method.steps} steps × {parameters} parameters"


def outputs_text(condition: str, outputs: int) -> str:
    return f"{outputs:,} outputs per simulation of condition {condition} (one per distinct measurement time)"


def problems(plan: CalibrationPlan, runs_here: bool) -> list[BadInput]:
    """A `BadInput` for a simulation whose outputs cannot fit in memory here (`runs_here`: the simulations run
    on this machine) and for a posterior whose chains cannot: each blamed on what to change."""
    found = []
    if runs_here:
        for condition, one in estimates(plan).items():
            problem = resources.run_problem({condition: one}, 1)
            if problem:
                found.append(BadInput(f"{outputs_text(condition, one.outputs)}: {problem}; round the table's "
                                      "times to fewer distinct values", plan.data_file))
    method, k = plan.spec.method, len(plan.parameters)
    if method.name == "posterior":
        problem = resources.too_big(posterior_memory(method, k),
                                    f"the posterior's chains ({chains_text(method, k)}) need")
        if problem:
            found.append(BadInput(f"{problem}: lower steps or walkers", plan.file, "method.steps"))
    return found


def note(plan: CalibrationPlan) -> str:
    """What its many outputs make every simulation cost, said before the first one runs ('' for a few)."""
    said = [f"{outputs_text(c, e.outputs)}: {resources.size(e.memory)} of memory and "
            f"{resources.size(e.disk)} on disk each, and as slow to write" for c, e in estimates(plan).items()
            if e.outputs > MANY_OUTPUTS]
    return "; ".join(said) + ("; fewer distinct times in the table make every simulation cheaper" if said else "")
