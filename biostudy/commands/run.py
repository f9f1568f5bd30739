"""`biostudy run SCENE`: one simulation, its dataset written atomically with what produced it.

The output is checked before anything is computed (`targets.check_run`): never
an input, never a file biostudy did not write; an earlier result of the same
scene is replaced and the message says so.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import xarray as xr

import solver

from ..data import store
from ..errors import Failed
from ..execution.targets import check_run
from ..execution.worker import provenance
from ..inputs import bundled
from ..inputs.keys import parse_override
from ..inputs.scene import Scene, load_scene, overrides_text
from ..quantities import dense


@dataclass(frozen=True)
class Loaded:
    """A scene ready to run: where it came from, its overrides and where its dataset goes."""

    path: Path
    scene: Scene
    overrides: tuple[str, ...]
    target: Path
    replacing: str  # what the final message adds when the target is replaced ("" if nothing is)


@dataclass(frozen=True)
class Result:
    dataset: xr.Dataset
    target: Path
    replacing: str

    def warnings(self) -> list[str]:
        """What a user should know about the result besides the summary: a vanished dense biofilm."""
        said = self.dataset.attrs.get(dense.ATTRIBUTE)
        return [str(said)] if said else []

    def message(self) -> str:
        attrs = self.dataset.attrs
        return (f"wrote {self.target} (wall time {attrs['wall_time']:.3g} s, {attrs['steps_taken']} steps, "
                f"{attrs['steps_bisected']} bisected){self.replacing}")


def default_output(scene: Scene) -> Path:
    """NAME.nc in the current directory, the scene's name made a file name."""
    return Path(re.sub(r"[^\w.+-]", "-", scene.name) + ".nc")


def load(scene: str | Path, *, overrides: tuple[str, ...] | list[str] = (), output: Path | None = None,
         force: bool = False) -> Loaded:
    """Read and validate a scene (a path or a bundled name) with its overrides, and check its output before
    anything is computed; bad input is `BadInput`."""
    path = bundled.resolve(scene)
    loaded = load_scene(path, overrides)
    target = Path(output) if output is not None else default_output(loaded)
    return Loaded(path, loaded, tuple(overrides), target, check_run(loaded, path, target, force))


def compute(loaded: Loaded, *, progress: Callable[[solver.Progress], None] | None = None) -> Result:
    """Simulate and write the dataset (stamped with the scene, its file, the overrides and the software);
    a simulation that fails, or a dataset that cannot be written, is `Failed`."""
    try:
        ds = solver.simulate(loaded.scene.problem(), progress=progress)
    except solver.SimulationError as error:
        raise Failed(f"simulation failed: {loaded.path}: {error}") from None
    text = overrides_text([parse_override(o) for o in loaded.overrides])
    ds = store.stamp(ds, loaded.scene.to_toml(), loaded.path, text, **provenance(), **loaded.scene.substratum_attrs(),
                     **dense.attrs(ds))
    try:
        store.write_atomic(ds, loaded.target)
    except OSError as error:  # e.g. the disk filled up while it ran
        raise Failed(f"cannot write {loaded.target} ({error.strerror or error}); the result is lost") from None
    return Result(ds, loaded.target, loaded.replacing)
