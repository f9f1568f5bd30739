"""Where results go, claimed before anything is computed: a run's output file, a job's directory.

A result is never lost to an unwritable path after hours of computing, and
never overwrites an input or a file biostudy did not write: `check_run`
looks at one run's output before it starts; `owned` claims a sweep's (a
convergence, stability or calibration run's) directory: locked for this
process, owned by one study (`ownership`).
"""
from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterator

from ..data import claims
from ..data.targets import replaceable, writable
from ..errors import BadInput
from ..inputs import resources
from ..inputs.scene import Scene
from . import ownership


@contextlib.contextmanager
def owned(out_dir: str | Path, owner: ownership.Owner, summary: str, force: bool = False,
          shared: bool = False, reports: tuple[str, ...] = (), digested: tuple[str, ...] = ()) -> Iterator[Path]:
    """Claim a sweep's directory for `owner` (`ownership.claimed`; `shared`: an array task) and check, before
    anything runs or is recorded there, that its summary file (study.nc, ...) may be replaced, that its
    `reports` (the names of the Markdown reports and pictures it writes) are absent or biostudy's
    (`claims.unproven`), that its `digested` files (which cannot carry a mark: simulation.tsv) are absent or
    have the sha256 the summary records (`claims.undigested`), and, in a directory no biostudy run owned before
    (taken with `force`), that every file in cases/ is a dataset biostudy wrote: a file biostudy cannot prove
    it wrote is never replaced, `force` or not."""
    def check(directory: Path, biostudys: bool) -> None:
        problems = claims.unproven([directory / name for name in reports], "a report or picture")
        attrs = None
        try:
            attrs = replaceable(directory / summary, damaged_ok=biostudys)
        except BadInput as error:
            problems.append(error)
        problems += claims.undigested([directory / name for name in digested], attrs, summary)
        for path in [] if biostudys else sorted(directory.glob("cases/*.nc")):
            try:
                replaceable(path)
            except BadInput as error:
                problems.append(error)
        if problems:
            raise BadInput.every(problems)

    with ownership.claimed(out_dir, owner, force, check, shared) as directory:
        yield directory


def claim_run(target: Path) -> claims.Claim:
    """The output of one run, reserved for it (`claims.claim`): `BadInput` while another run computes it."""
    return claims.claim(target)


def check_run(scene: Scene, scene_file: Path | None, target: Path, force: bool = False,
              inputs: list[Path] = (), history: int | None = None) -> str:
    """Before one run computes anything: `BadInput` unless its dataset can be written to `target` and the
    run fits in memory; returns what the final message adds when `target` is replaced.

    `target` is never an input (the scene file, a mask or image it reads, `inputs` such as the run it
    continues) nor a file biostudy did not write; an earlier result of the same scene is replaced, anything
    else biostudy wrote (another scene's result, a sweep's file) only with `force`.  `history`: the outputs
    of the run it continues, if it continues one (its memory: `resources.estimate`).
    """
    writable(target)
    masks = [r.path for kind in ("biofilm", "nutrient", "obstacle") for r in getattr(scene, kind)
             if getattr(r, "shape", None) in ("mask", "image")]
    previous = replaceable(target, [p for p in (scene_file, *masks, *inputs) if p])
    too_big = resources.run_problem({scene.name: resources.estimate(scene, streamed=True, history=history)}, 1,
                                    target)
    if too_big:
        raise BadInput(too_big, scene_file)
    if previous is None:
        return ""
    if "case_id" in previous or "sweep_mode" in previous:
        what = "a file of a sweep"
    elif previous.get("scene_file") != (str(Path(scene_file).resolve()) if scene_file else ""):
        what = f"the result of another scene ({previous.get('scene_file', 'unknown')})"
    else:
        return "; it replaces the earlier result of the same scene"
    if not force:
        raise BadInput(f"holds {what}; give --force to replace it, or choose another output", target)
    return f"; it replaces {what} (--force)"
