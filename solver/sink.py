"""Where a run's fields go as they are made: an output sink.

The time loop hands every output's fields to a sink the moment they are
computed and keeps only a few numbers of each (`output.Record`): the
memory a run holds then does not grow with its number of outputs.  At the
end the sink gives each field over all outputs (`fields`) for the dataset;
the arrays may be lazy (dask) arrays reading a file back one output at a
time.  `Held` keeps them in memory (the default: a dataset returned, not
written); a caller that writes a file brings its own sink (biostudy's
`data.spool`).  The solver never knows where the fields went.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    from .snapshot import Snapshot

CELL_FIELDS = ("phi", "c", "alpha")  # on every output (dimension time)
MECHANICS_FIELDS = ("p", "u")  # on the outputs where the mechanics was solved (dimension time_mechanics)


class OutputSink(Protocol):
    """Takes each output's fields as they are made; gives every field over its outputs at the end."""

    def add(self, snapshot: Snapshot) -> None:
        """Keep phi, c, alpha of this output, and p, u if the mechanics was solved here (not None)."""

    def fields(self) -> dict[str, Any]:
        """{name: array (outputs, *field shape)} of the fields kept, in the order they were added: phi, c,
        alpha over every output; p, u over the outputs that had them (absent if none had)."""


class Held:
    """The sink that keeps every field in memory, stacked at the end."""

    def __init__(self) -> None:
        self.kept: dict[str, list[np.ndarray]] = {name: [] for name in (*CELL_FIELDS, *MECHANICS_FIELDS)}

    def add(self, snapshot: Snapshot) -> None:
        for name in (*CELL_FIELDS, *MECHANICS_FIELDS):
            value = getattr(snapshot, name)
            if value is not None:
                self.kept[name].append(value)

    def fields(self) -> dict[str, Any]:
        return {name: np.stack(values) for name, values in self.kept.items() if values}
