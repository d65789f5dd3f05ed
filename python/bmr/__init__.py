"""bmr: CBH hysteresis, exact inverse and friction compensation for bi-directional MR actuators."""
from bmr._core import BmrError

__all__ = ["BmrError"]
