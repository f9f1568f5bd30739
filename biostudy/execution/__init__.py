"""Jobs run here, on local processes or a Dask cluster, recorded; directories claimed."""
