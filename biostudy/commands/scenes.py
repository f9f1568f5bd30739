"""`biostudy scenes`: the bundled scenes, studies, catalogues and calibrations, each with its description.

The directory is `$BIOSTUDY_STUDIES` if set, else the installed package's studies (`inputs.bundled`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..inputs import bundled

if TYPE_CHECKING:
    from rich.table import Table


def scenes() -> dict:
    """The bundled files as ``--json`` gives them: the directory, and per file its name, kind (scene, study,
    stability, calibration) and description."""
    directory = bundled.studies_dir()
    return {"kind": "scenes", "directory": str(directory),
            "entries": [{"file": e.path.name, "kind": e.kind, "description": e.description}
                        for e in bundled.entries(directory)]}


def table(listed: dict) -> Table:
    """The table the command prints of `scenes()`."""
    from rich.table import Table  # lazily: `import biostudy` stays cheap

    shown = Table(title=f"bundled scenes and studies in {listed['directory']}", show_edge=False)
    shown.add_column("file", no_wrap=True)
    shown.add_column("kind", no_wrap=True)
    shown.add_column("description")
    for entry in listed["entries"]:
        shown.add_row(entry["file"], entry["kind"], entry["description"])
    return shown
