"""A finished case's identity: the fingerprint of the compiled problem that made it.

`fingerprint` is canonical and recursive: every field of `solver.Problem` and
of the dataclasses inside it (`Grid`, `Parameters`, `Laws`, `Numerics`,
`MechanicsSetup`) that equals its default is left out, at any depth, and the
rest is hashed by name, in sorted order, by value (arrays by dtype, shape and
bytes).  A new option with a default, anywhere in the problem, therefore
leaves every finished case's identity as it was: sweeps and calibrations
finished before it are reused, not recomputed.  The laws (`Problem.laws`) are
hashed as fields of the problem itself (`INLINED`): `consumption` was one
before the laws were gathered in `solver.Laws`, so a zero-order case keeps
its identity.  An option that changes how a run is computed but not what
(`solver.declared.changes_result`: the threads) is never in it: a case
finished on 2 threads is finished for 32.

Case files written by biostudy 0.3.0 and earlier carry the fingerprint of the
scheme before (nested options hashed by their `repr`); `legacy_fingerprint`
computes it from the fields those versions knew (`KNOWN_IN_0_3_0`), so those
files are recognised too; `matches` accepts either.
"""
from __future__ import annotations

import hashlib
from dataclasses import MISSING, Field, fields, is_dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from solver.declared import changes_result
from solver.laws import Laws
from solver.problem import Grid, MechanicsSetup, Numerics, Parameters, Problem

if TYPE_CHECKING:
    import solver

NOT_PART = ("name",)  # fields of `Problem` that do not change a result
INLINED = ("laws",)  # fields of `Problem` whose own fields are hashed as the problem's (they were its fields)


def fingerprint(problem: "solver.Problem") -> str:
    """sha256 of everything that determines a run's result (not its name), each field at its default left out.
    The software's versions are not in it: a new version does not discard finished work by itself
    (`SweepReport.outdated` tells about it)."""
    return hashlib.sha256(repr(canonical(problem, NOT_PART, INLINED)).encode()).hexdigest()


def canonical(value: Any, skip: tuple[str, ...] = (), inline: tuple[str, ...] = ()) -> Any:
    """`value` as plain, comparable Python: a dataclass as a sorted tuple of (name, canonical value) of its fields
    other than their default (and than `skip`; a field in `inline`, a dataclass, by its own such fields), an array
    as (dtype, shape, sha256 of its bytes), a numpy scalar as its Python number, a sequence as a tuple."""
    if is_dataclass(value) and not isinstance(value, type):
        kept = []
        for part in fields(value):
            if part.name in skip or not changes_result(part):
                continue
            mine = canonical(getattr(value, part.name))
            if part.name in inline:
                kept.extend(mine[1])
            elif not _is_default(part, mine):
                kept.append((part.name, mine))
        return ("dataclass", tuple(sorted(kept)))
    if isinstance(value, np.ndarray):
        data = np.ascontiguousarray(value)
        return ("array", data.dtype.str, data.shape, hashlib.sha256(data.tobytes()).hexdigest())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (tuple, list)):
        return tuple(canonical(item) for item in value)
    return value


def _is_default(part: Field, mine: Any) -> bool:
    """Whether a field's canonical value is that of its declared default (a field without one never is)."""
    if part.default is not MISSING:
        return mine == canonical(part.default)
    if part.default_factory is not MISSING:
        return mine == canonical(part.default_factory())
    return False


# The fields biostudy 0.3.0 hashed, per class: what `legacy_fingerprint` reads.  Frozen: fields added since are
# not in it (a problem that sets one away from its default cannot match a file those versions wrote).
KNOWN_IN_0_3_0: dict[type, tuple[str, ...]] = {
    Problem: ("grid", "phi0", "nutrient_held", "t_end", "steps", "output_times", "params", "consumption",
              "nutrient_value", "nutrient_faces", "obstacle", "numerics", "mechanics", "start_time", "alpha0",
              "c0", "u0", "first_step"),
    Grid: ("shape", "spacing"),
    Parameters: ("mu", "nu", "d", "beta", "k_alpha", "k", "g", "r"),
    Numerics: ("advection", "gradient_floor", "nutrient_tolerance", "biofilm_tolerance", "max_substeps",
               "time_tolerance", "growth_velocity", "front_band"),
    MechanicsSetup: ("clamp", "slide", "residual_stiffness", "every", "newton_tolerance", "max_newton_iterations",
                     "linear_solver", "pressure"),
    Laws: ("consumption",),  # 0.3.0's Problem.consumption: the laws are read as fields of the problem (INLINED)
}
# Fields `solver.Problem` gained after sweeps had been recorded, with their defaults: at those 0.3.0 left them
# out of its fingerprint, so that the cases older sweeps finished stayed finished.
ADDED_LATER = {"start_time": 0.0, "alpha0": None, "c0": None, "u0": None, "first_step": None, "step_limit": None}


class _Unknown(Exception):
    """A field 0.3.0 did not know is set away from its default: no file of 0.3.0 can describe this problem."""


def legacy_fingerprint(problem: "solver.Problem") -> str | None:
    """The fingerprint biostudy 0.3.0 and earlier recorded for `problem` (top-level fields hashed by name and
    `repr`, arrays by their bytes), or None if the problem sets an option those versions did not have."""
    try:
        _known(problem, Problem)
        digest = hashlib.sha256()
        for name in KNOWN_IN_0_3_0[Problem]:
            value = getattr(problem.laws if name in KNOWN_IN_0_3_0[Laws] else problem, name)
            if name in ADDED_LATER and not isinstance(value, np.ndarray) and value == ADDED_LATER[name]:
                continue
            digest.update(name.encode())
            digest.update(np.ascontiguousarray(value).tobytes() if isinstance(value, np.ndarray)
                          else _legacy_repr(value).encode())
    except _Unknown:
        return None
    return digest.hexdigest()


def _legacy_repr(value: Any) -> str:
    """`repr` as 0.3.0's dataclasses wrote it: only the fields it knew, under the class's name then."""
    for kind, names in KNOWN_IN_0_3_0.items():
        if isinstance(value, kind):
            _known(value, kind)
            return f"{kind.__qualname__}({', '.join(f'{n}={_legacy_repr(getattr(value, n))}' for n in names)})"
    return repr(value)


def _known(value: Any, kind: type) -> None:
    """Raise `_Unknown` if `value` sets a field 0.3.0's `kind` did not have away from its default."""
    for part in fields(value):
        if part.name in INLINED:
            _known(getattr(value, part.name), Laws)
        elif part.name not in KNOWN_IN_0_3_0[kind] and part.name not in NOT_PART and changes_result(part) \
                and not _is_default(part, canonical(getattr(value, part.name))):
            raise _Unknown(part.name)


def matches(recorded: object, problem_print: str, problem_legacy: str | None) -> bool:
    """Whether a case file's recorded fingerprint is the problem's, in today's scheme or (a file of 0.3.0 or
    earlier) in the scheme before."""
    return recorded is not None and str(recorded) in (problem_print, problem_legacy)
