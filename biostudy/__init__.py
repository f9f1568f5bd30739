"""biostudy: the study service around the biofilm-growth solver.

Scene and study files (TOML, validated by pydantic), the `biostudy` command
line, netCDF datasets written atomically, resumable sweeps on local
processes or a Dask cluster.  Data flows one way: scene file -> `Scene` ->
`solver.Problem` -> `solver.simulate` -> xarray Dataset -> netCDF.

The packages are stages whose imports run one way (`tests/test_layout.py` holds the order): fitting (plain
maths), inputs, quantities, data, plans, execution, reports, plots, calibration (a feature in one place),
commands, cli; each imports only the stages before it (and `solver`, `formatting`, `errors`).

From Python (a notebook, a script; docs/results.md):

    import biostudy
    ds = biostudy.run("directional", set={"grid.shape": [10, 10, 10], "mechanics.enabled": False})
    ds.phi_mean.plot()
    study = biostudy.sweep("directional-sweep", "sweep", workers=2)
    same = biostudy.open("sweep/cases/g=1e+08_r=50.nc")
    fit = biostudy.calibrate("calibrate-agar", "fit", workers=2)
    pictures = biostudy.plot("sweep")                       # the files written
    print(biostudy.show("sweep/cases/g=1e+08_r=50.nc"))     # what `biostudy show` prints

Every command is a function here (`biostudy.api`, docs/scripting.md): `run`, `sweep`, `calibrate`,
`convergence`, `stability`, `analyze`, `plot`, `export`, `show`, `scenes` and `open`, imported when first used,
so ``import biostudy`` (which the command line does) costs nothing.
"""
from __future__ import annotations

import logging

# The library prints nothing: what it has to say goes to this logger (detail at DEBUG, what an API call did at
# INFO), silent unless the caller configures logging; warnings a result carries are `warnings.warn`
# (docs/scripting.md).  The command line puts its own handler here (`cli.logs`).
logging.getLogger("biostudy").addHandler(logging.NullHandler())

_API = {"run": "run", "sweep": "sweep", "calibrate": "calibrate", "convergence": "convergence",
        "stability": "stability", "analyze": "analyze", "plot": "plot", "export": "export", "measure": "measure",
        "show": "show",
        "scenes": "scenes", "open": "open_result"}
__all__ = [*_API, "BadInput", "Failed"]


def __getattr__(name: str):
    if name in _API:
        from . import api

        return getattr(api, _API[name])
    if name in ("BadInput", "Failed"):
        from . import errors

        return getattr(errors, name)
    raise AttributeError(f"module 'biostudy' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *__all__])
