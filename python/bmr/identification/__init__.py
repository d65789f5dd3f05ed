"""Identification of a device model from measured runs, in data-flow order:

* :mod:`~bmr.identification.signals` — a run's input and output in the bundle's declared quantities;
* :mod:`~bmr.identification.spans` — where a run's hysteresis state is known, the input range it reaches;
* :mod:`~bmr.identification.accounting` — how many samples each fit used, and why not the others;
* :mod:`~bmr.identification.friction` — angle-periodic seal friction (paper eq 22);
* :mod:`~bmr.identification.forc` — first-order reversal curves cut from protocol runs (the paper's path);
* :mod:`~bmr.identification.lstsq` — Preisach (Everett) tables by least squares from any excitation;
* :mod:`~bmr.identification.model` — the identified model and its ``bmr-model/2`` file;
* :mod:`~bmr.identification.prediction` — ``predict()`` and ``bmr predict``: measured runs against a model,
  calibration explicit, in the declared units;
* :mod:`~bmr.identification.procedure` — ``identify()``, its ``IdentificationReport`` and ``bmr identify``.
"""
from bmr.identification.forc import FirstOrderCurves, extract_first_order_curves
from bmr.identification.friction import FrictionFit, fit_friction
from bmr.identification.lstsq import LstsqTables, RunCalibration, fit_tables_lstsq
from bmr.identification.model import Model
from bmr.identification.prediction import Prediction, RunPrediction, predict
from bmr.identification.procedure import IdentificationReport, identify

__all__ = ["FirstOrderCurves", "FrictionFit", "IdentificationReport", "LstsqTables", "Model", "Prediction",
           "RunCalibration", "RunPrediction", "extract_first_order_curves", "fit_friction", "fit_tables_lstsq",
           "identify", "predict"]
