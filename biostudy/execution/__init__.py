"""Stage 3, execution: jobs run here, on local processes or a Dask cluster, recorded; directories claimed."""
