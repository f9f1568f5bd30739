"""Datasets on disk (atomic netCDF, case records, study.nc, ParaView files)."""
