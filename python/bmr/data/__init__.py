"""Measured data from any hysteretic device, in data-flow order:

* :mod:`~bmr.data.units` — the unit registry, conversions and unit-aware formatting (``format_value``);
* :mod:`~bmr.data.quantities` — what a device's input and output are (``Quantity``, ``Quantities``, ``ACTUATOR``);
* :mod:`~bmr.data.signals` — a signal's noise level, reversal dead-band and sample rate;
* :mod:`~bmr.data.tables` — measurement tables read from lab files (CSV, Parquet, TDMS, MAT);
* :mod:`~bmr.data.formats` — the instrument formats (ControlDesk, aixACCT, SLAC, MicroMag, Lake Shore), one module
  each, and the registry that picks a file's reader (``read_tables``);
* :mod:`~bmr.data.bundle` — bundles (a folder of runs from one device, ``bmr-bundle/1`` and ``/2``);
* :mod:`~bmr.data.readers` — actuator logs with a column mapping (``read_table``, ``bundle_from_files``);
* :mod:`~bmr.data.importing` — ``import_logs`` / ``bmr import``: raw logs of any device into a bundle.
"""
from bmr.data.bundle import Bundle, Run, read_bundle, write_bundle
from bmr.data.formats import read_tables
from bmr.data.importing import ImportResult, import_logs
from bmr.data.quantities import ACTUATOR, Quantities, Quantity
from bmr.data.readers import bundle_from_files, read_table
from bmr.data.tables import Table

__all__ = ["ACTUATOR", "Bundle", "ImportResult", "Quantities", "Quantity", "Run", "Table", "bundle_from_files",
           "import_logs", "read_bundle", "read_table", "read_tables", "write_bundle"]
