"""What a run counted, told by the part that counted it: a value and what it means.

Each component of a run (the nutrient's solver, the biofilm's, the clock)
reports its own counters (`counters()`), so the run's cost report collects
them without reaching into the components' insides; the dataset writes the
values as attributes (docs/model.md, "The dataset").
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Count:
    """One counter: its value and a line on what it counts."""

    value: int | float
    meaning: str


Counters = dict[str, Count]


def values(counters: Counters) -> dict[str, int | float]:
    """name -> value, for a dataset's attributes."""
    return {name: count.value for name, count in counters.items()}
