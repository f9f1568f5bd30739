"""The transport of paper Eqs. 34-36: biofilm density phi, nutrient c, expansion alpha on finite volumes.

One file per part: `finite_volume` (the grid, its faces, FiPy's Laplacian),
`nutrient` (Eq. 35, quasi-steady), `biofilm` (Eq. 34, implicit), `front`
(the growth speed carried from the phi = 1/2 front), `expansion` (Eq. 36),
`linear` (the reused solvers), `bounds` (round-off projected, beyond it a
failed step) and `step` (the state and one step of all of them).
"""
from .step import State, Transport

__all__ = ["State", "Transport"]
