"""pyPESTO on a calibration's simulations (docs/calibrate.md, "PEtab and pyPESTO"): `pypesto_problem`.

A lab that runs its own pipeline in pyPESTO (its optimisers, samplers, profiles, storage) takes a calibration
file (TOML, or a PEtab problem.yaml biostudy wrote) as biostudy reads it, and gets a `pypesto.Problem` whose
objective runs biostudy's simulations: case files under DIR/cases/ reused by their fingerprint (a second
pipeline on the same directory repeats no simulation, nor does ``biostudy calibrate`` into it), on `workers`
local processes or a Dask cluster, the directory owned and locked while the problem is in use; residuals and
their sensitivities by biostudy's own finite differences (`fitting.pypesto_objective`).
"""
from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterator, Sequence

from ..execution.backends import Kept
from ..execution.jobs import Execution, backend
from ..execution.ownership import Owner
from ..execution.targets import owned
from ..fitting import pypesto_objective
from ..inputs import bundled
from ..inputs.resources import Preflight
from .evaluator import Evaluator
from .problem import load_calibration


@contextlib.contextmanager
def pypesto_problem(calibration: str | Path, directory: str | Path, *, workers: int | None = None,
                    scheduler: str | None = None, set: Sequence[str] = ()) -> Iterator:  # noqa: A002
    """A `pypesto.Problem` of a calibration's simulations in `directory`, for the block (module docstring)::

        with pypesto_problem("calibrate-agar", "agar-pypesto", workers=2) as problem:
            result = pypesto.optimize.minimize(problem, n_starts=4)

    `set`: ``--set`` overrides ("time.steps=200").  Bad input is `BadInput`; a table naming σ to estimate is
    refused (`fitting.pypesto_objective`)."""
    plan = load_calibration(bundled.resolve(calibration), tuple(set), Preflight(runs=True))
    execution = Execution(workers=workers, scheduler=scheduler)
    owner = Owner("calibration", plan.spec.name, str(plan.scene_file.resolve()), tuple(p.name for p in plan.parameters))
    with owned(Path(directory), owner, "calibration.nc") as claimed:
        kept = Kept(backend(execution)) if workers or scheduler else None  # started once, as calibrate's
        try:
            runs = Evaluator(plan, claimed, execution, kept)
            yield pypesto_objective.problem(runs.objective(), [(p.range.low, p.range.high, p.log)
                                                               for p in plan.parameters])
        finally:
            if kept is not None:
                kept.end()
