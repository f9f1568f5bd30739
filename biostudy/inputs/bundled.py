"""The bundled scenes and studies in `studies/`, and finding a scene by name.

The directory is `$BIOSTUDY_STUDIES` if set, else the package data `biostudy/studies` (an installed
wheel: setup.py maps `studies/` there), else `studies/` beside the package (a checkout or an editable
install), else `./studies`.  A file
with a ``[grid]`` table is a scene, one with ``scene = ...`` a study, and with ``[data]`` too a
calibration.
"""
from __future__ import annotations

import difflib
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..errors import BadInput, first_line


def studies_dir() -> Path:
    if os.environ.get("BIOSTUDY_STUDIES"):
        return Path(os.environ["BIOSTUDY_STUDIES"])
    package = Path(__file__).resolve().parents[1]  # biostudy/inputs/bundled.py -> biostudy
    for candidate in (package / "studies", package.parent / "studies"):
        if candidate.is_dir():
            return candidate
    return Path("studies")


@dataclass(frozen=True)
class Entry:
    path: Path
    kind: str  # "scene", "study", "stability" (a catalogue of cases), "calibration" or "unreadable"
    description: str


def kind(data: dict) -> str:
    """What a TOML file's table is: "scene", "study", "stability" (a catalogue), "calibration" or "other"."""
    if "grid" in data:
        return "scene"
    if "case" in data:
        return "stability"
    if "scene" in data:
        return "calibration" if "data" in data else "study"
    return "other"


def entries(directory: Path | None = None) -> list[Entry]:
    """Every TOML file in the studies directory, scenes first, each with its description."""
    directory = directory or studies_dir()
    found = []
    for path in sorted(directory.glob("*.toml")):
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
            found.append(Entry(path, "unreadable", first_line(error)))
            continue
        found.append(Entry(path, kind(data), str(data.get("description", ""))))
    order = {"scene": 0, "study": 1, "calibration": 2, "stability": 3}
    return sorted(found, key=lambda e: (order.get(e.kind, 3), e.path.name))


def completions(incomplete: str, kinds: tuple[str, ...] = ("scene", "study", "stability")) -> list[tuple[str, str]]:
    """What shell completion offers for a scene or study argument: the bundled files of those kinds whose names
    start with `incomplete` (with their descriptions), and the TOML files here that do."""
    offered = [(entry.path.stem, entry.description) for entry in entries() if entry.kind in kinds
               and entry.path.stem.startswith(incomplete)]
    folder, _, stem = incomplete.rpartition("/")
    try:
        local = sorted(Path(folder or ".").glob(f"{stem}*.toml"))
    except (OSError, ValueError):
        local = []
    return offered + [(str(path) if folder else path.name, "file") for path in local]


def resolve(name: str | Path) -> Path:
    """A path as given if it exists; else a bundled file of that name ('directional' or 'directional.toml').
    A bare name that is neither is bad input, with the closest bundled name if one is close."""
    path = Path(name)
    if path.exists() or path.is_absolute() or len(path.parts) > 1 or path.is_symlink():
        return path  # a link that leads nowhere is told as such when it is read (`files.checked`)
    for candidate in (studies_dir() / path, studies_dir() / f"{path}.toml"):
        if candidate.is_file():
            return candidate
    names = sorted(p.stem for p in studies_dir().glob("*.toml"))
    close = difflib.get_close_matches(path.name.removesuffix(".toml"), names, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    raise BadInput(f"no such file, and no bundled scene or study of that name ({hint}`biostudy scenes` lists "
                   "them)", path)
