"""Diagnosis of what the paper's model (friction + CBH) gets wrong in a bundle, the named cause and the extended
model. One concept per module:

* :mod:`~bmr.diagnosis.procedure` — ``diagnose()`` and ``bmr diagnose``: the whole procedure and its result.
* :mod:`~bmr.diagnosis.residuals` — evaluation data from the first saturation on, nominal residual, noise floor,
  residual structure against angle, time, current level, current rate and reversal order.
* :mod:`~bmr.diagnosis.field` — the field path of a (possibly extended) model: input lag/delay, output map,
  refined tables.
* :mod:`~bmr.diagnosis.effects` — the effect library (the physical effect vocabulary plus ``table_resolution``).
* :mod:`~bmr.diagnosis.selection` — blocked folds, grouped forward selection and its acceptance rule.
* :mod:`~bmr.diagnosis.extended_model` — the nominal model plus accepted effects: simulate, save, compensate.
* :mod:`~bmr.diagnosis.many` — ``diagnose_many()``: many bundles on Dask, one row each in a Parquet table.
Figures and the HTML report live in :mod:`bmr.report.diagnosis`.
"""
from bmr.diagnosis.many import diagnose_many
from bmr.diagnosis.procedure import Diagnosis, diagnose

__all__ = ["Diagnosis", "diagnose", "diagnose_many"]
