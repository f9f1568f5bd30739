"""Which face of the domain is the substratum: the one a scene names, or the single face its biofilm rests on.

COMSTAT measures a biofilm from the substratum it grows on, so thicknesses, coverage and biomass are only
what a lab reads when they are measured from that face.  A flow-cell colony fed from the bulk above (nutrient
held on z+) rests on z-: measured from z+ its `max_thickness` is the whole box and its coverage 0.  So when a
scene does not name it, the substratum is the face whose first cell layer the initial biofilm (phi >= the
substratum threshold) covers most; a held nutrient face (the agar) only wins a tie, where the biofilm touches it
as much as another face.

A scene need not have a substratum: a slab from wall to wall, a block filling the box (ties no rule settles),
a seed floating in the domain (it touches no face: the directional scene's sphere), or a plan view whose
substratum is the plane itself (the maze: its colony touches the domain's edge at the entrance, but grows into
the maze, not away from that edge), which says so with `[substratum] face = "none"`.  It
runs all the same; COMSTAT's observables are then left out of its dataset, which says why and how to get them
(`left_out`: the attribute `comstat_left_out`), since measured from an arbitrary face they would be numbers
without meaning (a floating sphere's coverage 0, its "thickness" its height above the bottom).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solver.problem import AXES, FACES

NONE = "none"  # [substratum] face = "none": the scene has no substratum (a plan view: the maze)
LEFT_OUT = "comstat_left_out"  # the dataset attribute saying why COMSTAT's observables are not there
COMSTAT = "COMSTAT's observables (biomass, mean_thickness, max_thickness, roughness, coverage, surface_to_biovolume)"


@dataclass(frozen=True)
class Substratum:
    """The face COMSTAT measures from, or None and why there is none (a sentence for `LEFT_OUT`)."""

    face: str | None
    why_none: str = ""


def normal_axis(face: str, ndim: int) -> int:
    """The axis normal to a face ("x-" ... "z+") of an array in the solver's (z, y, x) / (y, x) order (x last)."""
    return ndim - 1 - AXES.index(face[0])


def first_layer(cells: np.ndarray, face: str) -> np.ndarray:
    """The cells next to a face ("x-" ... "z+") of an array in the solver's (z, y, x) / (y, x) order."""
    return np.take(cells, 0 if face[1] == "-" else -1, axis=normal_axis(face, cells.ndim))


def left_out(reason: str, example: str | None = None) -> str:
    """The `LEFT_OUT` sentence: what is left out, why, and (given an `example` face) the key that brings it back."""
    if example is None:
        return f"{COMSTAT} left out: {reason}"
    return (f"{COMSTAT} left out: {reason}; name the substratum to get them: [substratum] face = \"{example}\" "
            f"(or --set substratum.face={example})")


def resting_face(biofilm: np.ndarray, held: tuple[str, ...]) -> Substratum:
    """The face whose first layer the boolean `biofilm` covers most (module docstring); `held`: the faces where
    the nutrient is held.  No face when the biofilm touches none or when no rule settles a tie."""
    faces = FACES[: 2 * biofilm.ndim]
    covered = {face: float(first_layer(biofilm, face).mean()) for face in faces}
    most = max(covered.values())
    if most == 0:
        bottom = {3: "z-", 2: "y-"}[biofilm.ndim]
        return Substratum(None, left_out("the initial biofilm touches no face of the domain (it floats in it)",
                                         bottom))
    tied = [face for face in faces if covered[face] == most]
    if len(tied) > 1:
        tied = [face for face in tied if face in held] or tied
    if len(tied) > 1:
        return Substratum(None, left_out(f"the initial biofilm rests on {' and '.join(tied)} alike (it covers "
                                         f"{most:.0%} of each)", tied[0]))
    return Substratum(tied[0])
