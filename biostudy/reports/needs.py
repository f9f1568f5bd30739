"""What running a scene, a study or a catalogue needs, known before anything runs (`biostudy show FILE.toml`; a
calibration's: `calibration.cost`).

The file is validated first (bad input: `BadInput`); then every case's memory
and disk are estimated (`biostudy.inputs.resources`) and set beside what this
machine has.
"""
from __future__ import annotations

from ..data import real_time
from ..inputs import bundled, resources
from ..inputs.files import read_toml
from ..inputs.resources import Preflight
from ..inputs.scene import load_scene
from ..plans import catalogue
from ..plans.study import load_study


def refused(found: resources.Estimate, what: str) -> list[str]:
    """[] if a run of this estimate fits in the memory here, else the line saying it would be refused (as `run`
    and `sweep` refuse it)."""
    problem = resources.too_big(found.memory, what)
    return [f"refused here: {problem}"] if problem else []


def needs(path) -> str:
    """What running a scene, a study or a catalogue file needs (validated first: bad input is `BadInput`), as
    text (a calibration file's: `calibration.cost.needs`)."""
    available = resources.available_text()
    what = bundled.kind(read_toml(path))
    if what in ("study", "stability"):
        plan = load_study(path, (), Preflight()) if what == "study" else catalogue.load(path, (), Preflight())
        found = {case.id: resources.estimate(plan.scenes[case.id]) for case in plan.cases}
        largest = max(found, key=lambda i: found[i].memory)
        return "\n".join([
            f"{plan.spec.name}: {len(found)} cases of {plan.scene_file.name}",
            f"largest case  {largest}: {resources.size(found[largest].memory)} of memory ({found[largest].parts()})",
            f"on disk       {resources.size(sum(e.disk for e in found.values()))} of case files, as much again "
            "for study.nc",
            f"here          {available}; N local workers need about N times the largest case"]
                         + refused(found[largest], f"the largest case, {largest}, needs"))
    scene = load_scene(path, (), Preflight())
    found = resources.estimate(scene, streamed=True)  # `biostudy run` writes its file as it goes
    mechanics = "on" if scene.mechanics is not None and scene.mechanics.enabled else "off"
    return "\n".join([
        f"{scene.name}: {' × '.join(map(str, scene.grid.shape))} cells, {scene.time.steps} steps, "
        f"{found.outputs} outputs, mechanics {mechanics}" + _real_end(scene),
        f"memory  {resources.size(found.memory)} ({found.parts()}); here {available}",
        f"on disk {resources.size(found.disk)} for the dataset" + _spooled(found)] + refused(found, "a run needs"))


def _spooled(found: resources.Estimate) -> str:
    """What a run that streams its outputs holds on disk besides its dataset while it writes it; '' if it does
    not stream them."""
    return (f", {resources.size(found.disk + found.spool)} while it is written (the outputs' spool beside it, "
            "until then)" if found.spool else "")


def _real_end(scene) -> str:
    """', to 24 h (T* = 0.5)' for a scene with t_ref (docs/time.md); '' without."""
    attrs = scene.real_time_attrs()
    return f", to {real_time.shown(attrs, scene.time.t_end)}" if attrs else ""
