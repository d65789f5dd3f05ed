"""Experiments on the virtual actuator (``bmr.VirtualActuator``): the paper's protocols and bundles of them
(:mod:`~bmr.simulation.experiments`), excitations for the diagnosis (:mod:`~bmr.simulation.excitation`) and the
reference controllers the compensator is measured against (:mod:`~bmr.simulation.baselines`)."""
from bmr.simulation import experiments
from bmr.simulation.experiments import simulate_bundle

__all__ = ["experiments", "simulate_bundle"]
