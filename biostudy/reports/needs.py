"""What running a scene, a study or a catalogue needs, known before anything runs (`biostudy show FILE.toml`).

The file is validated first (bad input: `BadInput`); then every case's memory
and disk are estimated (`biostudy.inputs.resources`) and set beside what this
machine has.
"""
from __future__ import annotations

from ..data import real_time
from ..inputs import bundled, resources
from ..inputs.files import read_toml
from ..inputs.scene import load_scene
from ..plans import calibration_cost, catalogue
from ..plans.calibration import load_calibration
from ..plans.study import load_study


def _refused(found: resources.Estimate, what: str) -> list[str]:
    """[] if a run of this estimate fits in the memory here, else the line saying it would be refused (as `run`
    and `sweep` refuse it)."""
    problem = resources.too_big(found.memory, what)
    return [f"refused here: {problem}"] if problem else []


def needs(path) -> str:
    """What running a scene or a study file needs (validated first: bad input is `BadInput`), as text."""
    available = resources.available_text()
    what = bundled.kind(read_toml(path))
    if what in ("study", "stability"):
        plan = load_study(path) if what == "study" else catalogue.load(path)
        found = {case.id: resources.estimate(plan.scenes[case.id]) for case in plan.cases}
        largest = max(found, key=lambda i: found[i].memory)
        return "\n".join([
            f"{plan.spec.name}: {len(found)} cases of {plan.scene_file.name}",
            f"largest case  {largest}: {resources.size(found[largest].memory)} of memory ({found[largest].parts()})",
            f"on disk       {resources.size(sum(e.disk for e in found.values()))} of case files, as much again "
            "for study.nc",
            f"here          {available}; N local workers need about N times the largest case"]
                         + _refused(found[largest], f"the largest case, {largest}, needs"))
    if what == "calibration":
        plan = load_calibration(path)
        found = calibration_cost.estimates(plan)  # outputs at the measurement times, as `calibrate` runs them
        largest = max(found, key=lambda i: found[i].memory)
        method, k = plan.spec.method, len(plan.parameters)
        chains = ([f"chains        {resources.size(calibration_cost.posterior_memory(method, k))} of memory "
                   f"({calibration_cost.chains_text(method, k)})"] if method.name == "posterior" else [])
        return "\n".join([
            f"{plan.spec.name}: {k} parameters, {len(plan.measurements)} measurements, "
            f"{len(found)} conditions of {plan.scene_file.name}",
            f"one simulation {resources.size(found[largest].memory)} of memory ({found[largest].parts()}), "
            f"{resources.size(found[largest].disk)} on disk (every simulation is kept under cases/), "
            f"{calibration_cost.outputs_text(largest, found[largest].outputs)}",
            *chains,
            f"here          {available}; N local workers need about N times one simulation"]
                         + _refused(found[largest], "one simulation needs"))
    scene = load_scene(path)
    found = resources.estimate(scene, streamed=True)  # `biostudy run` writes its file as it goes
    mechanics = "on" if scene.mechanics is not None and scene.mechanics.enabled else "off"
    return "\n".join([
        f"{scene.name}: {' × '.join(map(str, scene.grid.shape))} cells, {scene.time.steps} steps, "
        f"{found.outputs} outputs, mechanics {mechanics}" + _real_end(scene),
        f"memory  {resources.size(found.memory)} ({found.parts()}); here {available}",
        f"on disk {resources.size(found.disk)} for the dataset" + _spooled(found)] + _refused(found, "a run needs"))


def _spooled(found: resources.Estimate) -> str:
    """What a run that streams its outputs holds on disk besides its dataset while it writes it; '' if it does
    not stream them."""
    return (f", {resources.size(found.disk + found.spool)} while it is written (the outputs' spool beside it, "
            "until then)" if found.spool else "")


def _real_end(scene) -> str:
    """', to 24 h (T* = 0.5)' for a scene with t_ref (docs/time.md); '' without."""
    attrs = scene.real_time_attrs()
    return f", to {real_time.shown(attrs, scene.time.t_end)}" if attrs else ""
