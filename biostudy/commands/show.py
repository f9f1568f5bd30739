"""`biostudy show FILE...`: what a run, a case, a study or a scene file says, and several runs side by side.

One dataset: its summary (`reports.show`; a run's file read at a glance,
netCDF4 alone: `reports.glance`); a scene, study or calibration file (TOML):
what running it needs (`reports.needs`); several runs: how they differ
(`reports.compare`).  `records` are the same numbers for ``--json``.  Nothing
is imported here before it is needed: `show` of a run's file reads it without
xarray.
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from ..errors import BadInput
from ..formatting import UNCUT
from ..inputs import bundled

if TYPE_CHECKING:
    from rich.console import RenderableType

    from ..reports.compare import Comparison

RUNS_AND_STUDIES = "show reads runs, cases and study.nc"


@dataclass(repr=False)
class Shown:
    """What `show` says: the `view` a terminal prints (plain text for a scene file's needs), the numbers of
    ``--json`` (`record`; None for a scene file), and for several runs their `comparison`.  A notebook shows
    it as the command prints it."""

    view: RenderableType
    record: dict | list | None = None
    comparison: Comparison | None = None

    def text(self, width: int = UNCUT) -> str:
        """The view as plain text, as the command prints it to a file: tables as wide as their content (or cut
        to `width` columns)."""
        if isinstance(self.view, str):
            return self.view + "\n"
        from rich.console import Console  # lazily (module docstring)

        written = io.StringIO()
        Console(file=written, width=width, soft_wrap=True).print(self.view)
        return written.getvalue()

    def __str__(self) -> str:
        return self.text()

    __repr__ = __str__


PETAB = (".yaml", ".yml")  # a PEtab problem: a calibration file (`calibration.petab_in`)


def _is_scene_file(path: Path) -> bool:
    """A scene, study or calibration file (TOML, or a PEtab problem.yaml), or the name of a bundled one."""
    return path.suffix in (".toml", *PETAB) or (not path.exists() and not path.suffix)


def _dataset(path: Path):
    from ..data.reading import open_result  # lazily (module docstring)

    return open_result(path / "study.nc" if path.is_dir() else path, doing=RUNS_AND_STUDIES)


def record(path: str | Path) -> dict:
    """The record of what `show PATH` prints (`--json`): a run, a case, a failed case's record or a study."""
    path = Path(path)
    if _is_scene_file(path):
        raise BadInput("--json is for datasets (a run, a case, a study); a scene or study file's needs are "
                       "printed as text", path, "--json")
    from ..reports import glance, records  # lazily

    found = glance.read(path) if path.is_file() else None
    if found is not None:
        return records.run_record(*found)
    from ..reports.show import run_series  # lazily

    ds = _dataset(path)
    return records.study_record(ds) if "sweep_mode" in ds.attrs else records.run_record(*run_series(ds))


def records(paths: Sequence[str | Path]) -> dict | list[dict]:
    """`--json`: the record of one file, or a list of them for several."""
    found = [record(p) for p in paths]
    return found[0] if len(found) == 1 else found


def view(given: Sequence[str | Path]) -> tuple[RenderableType, Comparison | None]:
    """What `show` prints of `given`, and for several runs how they differ; bad input is `BadInput`."""
    paths = [Path(p) for p in given]
    if not paths:
        raise BadInput("give a file to show: a run, a case, a study or a scene file", None, "paths")
    if len(paths) > 1:
        from ..data.reading import open_result  # lazily
        from ..reports.compare import compare, comparison  # lazily

        runs = [open_result(p, ("run",), "show of several files sets runs side by side") for p in paths]
        found = comparison(runs)
        return compare(runs, paths, found), found
    path = paths[0]
    if _is_scene_file(path):
        from ..calibration import cost  # lazily
        from ..inputs.files import read_toml  # lazily
        from ..reports import needs  # lazily

        path = bundled.resolve(path)
        calibration = path.suffix in PETAB or bundled.kind(read_toml(path)) == "calibration"
        return (cost.needs if calibration else needs.needs)(path), None
    from ..reports.glance import glance  # lazily

    at_a_glance = glance(path) if path.is_file() else None  # a run's file: netCDF4 alone, no xarray
    if at_a_glance is not None:
        return at_a_glance, None
    from ..reports.show import summary  # lazily

    return summary(_dataset(path)), None


def show(paths: Sequence[str | Path]) -> Shown:
    """`view` and, for datasets, `records` of `paths`."""
    shown, compared = view(paths)
    found = None if any(_is_scene_file(Path(p)) for p in paths) else records(paths)
    return Shown(shown, found, compared)
