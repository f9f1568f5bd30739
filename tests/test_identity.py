"""A finished case's identity: options added later with a default, at any depth, keep finished cases finished;
case files of 0.3.0 (the fingerprint before) are still recognised."""
import dataclasses
import hashlib

import netCDF4
import numpy as np
import pytest

from biostudy.commands.sweep import run_study
from biostudy.execution import identity
from biostudy.execution.jobs import Execution, fingerprint
from biostudy.inputs.scene import Scene, load_scene
from biostudy.plans.study import load_study
from solver.problem import Grid, MechanicsSetup, Numerics, Parameters


def grown(kind, default=0.5):
    """`kind` (a frozen dataclass of the solver) with one more option, `new_option`, at `default`."""
    return dataclasses.make_dataclass(kind.__name__, [("new_option", float, dataclasses.field(default=default))],
                                      bases=(kind,), frozen=True)


def grow(problem, kind, **new):
    """`problem` with its `kind` option (params, numerics, grid or mechanics) as the grown class, new_option
    set by `new` (else its default)."""
    name = {Parameters: "params", Numerics: "numerics", Grid: "grid", MechanicsSetup: "mechanics"}[kind]
    now = getattr(problem, name) or kind()
    return dataclasses.replace(problem, **{name: grown(kind)(**{f.name: getattr(now, f.name)
                                                                 for f in dataclasses.fields(now)}, **new)})


def fingerprint_0_3_0(problem):
    """biostudy 0.3.0's `execution.jobs.fingerprint`, verbatim, over 0.3.0's fields: what its case files carry
    (its Problem had `consumption` where today's has `laws`)."""
    digest = hashlib.sha256()
    for part in dataclasses.fields(problem):
        if part.name == "name":
            continue
        name, value = part.name, getattr(problem, part.name)
        if name == "laws":
            name, value = "consumption", value.consumption
        if name in identity.ADDED_LATER and not isinstance(value, np.ndarray) and value == identity.ADDED_LATER[name]:
            continue
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(value).tobytes() if isinstance(value, np.ndarray) else repr(value).encode())
    return digest.hexdigest()


@pytest.mark.parametrize("kind", [Parameters, Numerics, Grid, MechanicsSetup])
def test_a_new_nested_option_counts_only_away_from_its_default(tiny_scene, kind):
    problem = load_scene(tiny_scene, ["mechanics.clamp=['y-']"]).problem()
    assert fingerprint(grow(problem, kind)) == fingerprint(problem)
    assert fingerprint(grow(problem, kind, new_option=0.7)) != fingerprint(problem)
    assert identity.legacy_fingerprint(grow(problem, kind)) == fingerprint_0_3_0(problem)
    assert identity.legacy_fingerprint(grow(problem, kind, new_option=0.7)) is None


def test_a_field_at_its_default_counts_as_absent_and_away_from_it_counts(tiny_scene):
    problem = load_scene(tiny_scene).problem()
    assert problem.mechanics is None
    assert fingerprint(dataclasses.replace(problem, numerics=Numerics())) == fingerprint(problem)
    assert fingerprint(dataclasses.replace(problem, mechanics=MechanicsSetup())) != fingerprint(problem)
    assert fingerprint(dataclasses.replace(problem, numerics=Numerics(front_band=4.0))) != fingerprint(problem)


def test_the_0_3_0_fingerprint_is_computed_as_0_3_0_did(tiny_scene):
    for overrides in ([], ["params.g=2e8", "numerics.advection='tvd'"], ["mechanics.clamp=['y-']"]):
        problem = load_scene(tiny_scene, overrides).problem()
        assert identity.legacy_fingerprint(problem) == fingerprint_0_3_0(problem), overrides


@pytest.fixture
def swept(tiny_scene, write_toml, tmp_path):
    """A finished two-case sweep of the tiny scene: (its plan, its directory)."""
    plan = load_study(write_toml("two.toml", 'scene = "tiny.toml"\n[set]\n"time.steps" = 4\n'
                                             '[sweep]\nr = [50.0, 100.0]\n'))
    out = tmp_path / "out"
    assert run_study(plan, out, Execution()).ran == ["r=50", "r=100"]
    return plan, out


def test_finished_cases_are_reused_after_a_nested_option_is_added(swept, monkeypatch):
    plan, out = swept
    compile_ = Scene.problem
    new = {}
    monkeypatch.setattr(Scene, "problem", lambda scene: grow(compile_(scene), Numerics, **new))
    again = run_study(plan, out, Execution())
    assert again.skipped == ["r=50", "r=100"] and again.ran == []
    new["new_option"] = 0.7  # the option set away from its default: a different problem
    assert run_study(plan, out, Execution()).ran == ["r=50", "r=100"]


def test_case_files_of_0_3_0_are_recognised(swept):
    plan, out = swept
    for case in plan.cases:
        with netCDF4.Dataset(out / "cases" / f"{case.id}.nc", "a") as nc:  # as 0.3.0 wrote it
            nc.setncattr("fingerprint", fingerprint_0_3_0(plan.scenes[case.id].problem()))
    again = run_study(plan, out, Execution())
    assert again.skipped == ["r=50", "r=100"] and again.ran == []
