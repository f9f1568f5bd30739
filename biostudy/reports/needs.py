"""What running a scene, a study or a catalogue needs, known before anything runs (`biostudy show FILE.toml`).

The file is validated first (bad input: `BadInput`); then every case's memory
and disk are estimated (`biostudy.inputs.resources`) and set beside what this
machine has.
"""
from __future__ import annotations

from ..inputs import bundled, resources
from ..inputs.files import read_toml
from ..inputs.scene import load_scene
from ..plans import catalogue
from ..plans.calibration import load_calibration
from ..plans.study import load_study


def needs(path) -> str:
    """What running a scene or a study file needs (validated first: bad input is `BadInput`), as text."""
    available = f"{resources.size(resources.available_memory()).lstrip('~')} of memory available"
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
            f"here          {available}; N local workers need about N times the largest case"])
    if what == "calibration":
        plan = load_calibration(path)
        found = {name: resources.estimate(scene) for name, scene in plan.plan.scenes.items()}
        largest = max(found, key=lambda i: found[i].memory)
        return "\n".join([
            f"{plan.spec.name}: {len(plan.parameters)} parameters, {len(plan.measurements)} measurements, "
            f"{len(found)} conditions of {plan.plan.scene_file.name}",
            f"one simulation {resources.size(found[largest].memory)} of memory ({found[largest].parts()}), "
            f"{resources.size(found[largest].disk)} on disk (every simulation is kept under cases/)",
            f"here          {available}; N local workers need about N times one simulation"])
    scene = load_scene(path)
    found = resources.estimate(scene, streamed=True)  # `biostudy run` writes its file as it goes
    mechanics = "on" if scene.mechanics is not None and scene.mechanics.enabled else "off"
    return "\n".join([
        f"{scene.name}: {' × '.join(map(str, scene.grid.shape))} cells, {scene.time.steps} steps, "
        f"{found.outputs} outputs, mechanics {mechanics}",
        f"memory  {resources.size(found.memory)} ({found.parts()}); {available} here",
        f"on disk {resources.size(found.disk)} for the dataset"])
