"""Measured data: bundles (a folder of runs from one device, ``bmr-bundle/1``) and readers that bring lab logs
(CSV, Parquet, NI TDMS, MATLAB) in with a column mapping and unit conversion."""
from bmr.data.bundle import Bundle, Run, read_bundle, write_bundle
from bmr.data.readers import bundle_from_files, read_table

__all__ = ["Bundle", "Run", "bundle_from_files", "read_bundle", "read_table", "write_bundle"]
