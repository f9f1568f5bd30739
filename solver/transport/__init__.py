"""The transport of paper Eqs. 34-36: biofilm density phi, nutrient c, expansion alpha on finite volumes.

One file per part: `finite_volume` (the grid, its faces, FiPy's Laplacian),
`nutrient` (Eq. 35, quasi-steady or transient), `biofilm` (Eq. 34, implicit), `front`
(the growth speed carried from the phi = 1/2 front), `expansion` (Eq. 36 or Table 1),
`linear` (the reused solvers), `bounds` (round-off projected, beyond it a
failed step) and `step` (the state and one step of all of them).
"""
__all__ = ["State", "Transport"]


def __getattr__(name: str):
    # the step (and its compiled kernels) is imported when first asked for: reading a dataset needs only
    # `bounds` (solver.output), and a command that only reads must not pay for numba's start
    if name in __all__:
        from . import step

        return getattr(step, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
