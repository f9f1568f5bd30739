"""Stage 4, data: datasets on disk (atomic netCDF, case records, study.nc, ParaView files)."""
