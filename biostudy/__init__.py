"""biostudy: the study service around the biofilm-growth solver.

Scene and study files (TOML, validated by pydantic), the `biostudy` command
line, netCDF datasets written atomically, resumable sweeps on local
processes or a Dask cluster.  Data flows one way: scene file -> `Scene` ->
`solver.Problem` -> `solver.simulate` -> xarray Dataset -> netCDF.
"""
