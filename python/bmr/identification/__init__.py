"""Identification of a device model from measured runs, in data-flow order:

* :mod:`~bmr.identification.spans` — where a run's hysteresis state is known, the input range it reaches;
* :mod:`~bmr.identification.friction` — angle-periodic seal friction (paper eq 22);
* :mod:`~bmr.identification.forc` — first-order reversal curves cut from protocol runs (the paper's path);
* :mod:`~bmr.identification.lstsq` — Preisach (Everett) tables by least squares from any excitation;
* :mod:`~bmr.identification.model` — the identified model and its ``bmr-model/1`` file;
* :mod:`~bmr.identification.procedure` — ``identify()`` and ``bmr identify``: all of the above on a bundle.
"""
from bmr.identification.forc import FirstOrderCurves, extract_first_order_curves
from bmr.identification.friction import FrictionFit, fit_friction
from bmr.identification.procedure import identify
from bmr.identification.lstsq import LstsqTables, fit_tables_lstsq
from bmr.identification.model import Model

__all__ = ["FirstOrderCurves", "FrictionFit", "LstsqTables", "Model", "extract_first_order_curves", "fit_friction",
           "fit_tables_lstsq", "identify"]
