"""What a finished run must say besides its numbers: the checks that warn in words.

Each check reads a run's dataset and returns '' or a sentence: `dense` (the dense biofilm vanished while the
biofilm grew, a grid artefact), `retreat` (the biofilm shrank or vanished, the model's own retreat from
where the nutrient is not), `quasi_steady` (diffusion does not settle the nutrient within a step, which the
model assumes) and `image_left_out` (an image region larger than the grid, cropped to it: the scene records how
much, `inputs.scene.Scene.image_attrs`).  Commands store each sentence as the dataset attribute named by its check,
print it after a run, and list the runs that raised it in sweeps and calibrations.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import xarray as xr

from . import dense, quasi_steady, retreat


@dataclass(frozen=True)
class Alert:
    attribute: str  # the dataset attribute holding the check's sentence
    check: Callable[[xr.Dataset], str]
    runs: str  # what the runs that raised it did, for a list of them


IMAGE_LEFT_OUT = "image_left_out"  # the scene's sentence (`inputs.scene.Scene.image_attrs`), recorded before this


def _image_left_out(ds: xr.Dataset) -> str:
    return str(ds.attrs.get(IMAGE_LEFT_OUT, ""))


ALERTS = (
    Alert(dense.ATTRIBUTE, dense.vanished,
          "lost their dense biofilm (phi >= 0.8) while the biofilm grew, likely a grid artefact"),
    Alert(retreat.ATTRIBUTE, retreat.lost,
          "lost a quarter or more of their biofilm (the model retreats from where the nutrient is not)"),
    Alert(quasi_steady.ATTRIBUTE, quasi_steady.unsettled,
          "have a nutrient that diffusion does not settle within a step (the model takes it as settled)"),
    Alert(IMAGE_LEFT_OUT, _image_left_out, "were given an image larger than the grid, cropped to it"),
)
ATTRIBUTES = tuple(alert.attribute for alert in ALERTS)


def attrs(ds: xr.Dataset) -> dict[str, str]:
    """{attribute: sentence} of every check the dataset raises: for its attributes."""
    found = {alert.attribute: alert.check(ds) for alert in ALERTS}
    return {name: sentence for name, sentence in found.items() if sentence}


def said(attrs: Mapping) -> list[str]:
    """The sentences recorded in a dataset's (or case record's) attributes, in the checks' order."""
    return [str(attrs[name]) for name in ATTRIBUTES if attrs.get(name)]


def summaries(raised: Mapping[str, Mapping[str, str]], runs: str) -> list[str]:
    """One line per check raised by some of many runs: how many `runs` (e.g. 'cases'), which, and the first's
    sentence; `raised` maps an attribute to {run id: sentence}."""
    lines = []
    for alert in ALERTS:
        found = raised.get(alert.attribute, {})
        if found:
            ids = sorted(found)
            lines.append(f"{len(ids)} {runs} {alert.runs} ({', '.join(ids[:3])}{', ...' if len(ids) > 3 else ''}): "
                         f"{found[ids[0]]}")
    return lines
