"""Which face of the domain is the substratum, when a scene does not say: the face its biofilm rests on.

COMSTAT measures a biofilm from the substratum it grows on, so thicknesses, coverage and biomass are only
what a lab reads when they are measured from that face.  A flow-cell colony fed from the bulk above (nutrient
held on z+) rests on z-: measured from z+ its `max_thickness` is the whole box and its coverage 0.  So the
substratum is the face whose first cell layer the initial biofilm (phi >= the substratum threshold) covers
most; a held nutrient face (the agar) only wins a tie, where the biofilm touches it as much as another face;
a tie it does not settle is ambiguous, and the scene must name the face (`[substratum] face`).  A biofilm
that touches no face (a seed floating in the domain) is measured from the bottom, z- in 3-D and y- in 2-D.
"""
from __future__ import annotations

import numpy as np

from solver.problem import AXES, FACES

from ..errors import InvalidAt


def normal_axis(face: str, ndim: int) -> int:
    """The axis normal to a face ("x-" ... "z+") of an array in the solver's (z, y, x) / (y, x) order (x last)."""
    return ndim - 1 - AXES.index(face[0])


def default_face(ndim: int) -> str:
    """The substratum when a scene names none and the biofilm touches no face: the bottom, z- in 3-D, y- in 2-D."""
    return {3: "z-", 2: "y-"}[ndim]


def first_layer(cells: np.ndarray, face: str) -> np.ndarray:
    """The cells next to a face ("x-" ... "z+") of an array in the solver's (z, y, x) / (y, x) order."""
    return np.take(cells, 0 if face[1] == "-" else -1, axis=normal_axis(face, cells.ndim))


def resting_face(biofilm: np.ndarray, held: tuple[str, ...]) -> str:
    """The face whose first layer the boolean `biofilm` covers most (module docstring); `held`: the faces where
    the nutrient is held.  InvalidAt at ``substratum.face`` when no rule decides."""
    faces = FACES[: 2 * biofilm.ndim]
    covered = {face: float(first_layer(biofilm, face).mean()) for face in faces}
    most = max(covered.values())
    if most == 0:
        return default_face(biofilm.ndim)
    tied = [face for face in faces if covered[face] == most]
    if len(tied) > 1:
        tied = [face for face in tied if face in held] or tied
    if len(tied) > 1:
        raise InvalidAt("substratum.face", f"the initial biofilm rests on {' and '.join(tied)} alike (it covers "
                                           f"{most:.0%} of each): name the substratum, e.g. face = \"{tied[0]}\"")
    return tied[0]
