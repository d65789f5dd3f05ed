"""bmr: CBH hysteresis, exact inverse and friction compensation for bi-directional MR actuators."""
from bmr._core import BmrError, EverettModel, fit_everett
from bmr.identify import FrictionFit, extract_first_order_curves, fit_friction, fit_tables_lstsq, identify
from bmr.io import bundle_from_files, read_table
from bmr.model import Model

__all__ = [
    "BmrError",
    "EverettModel",
    "FrictionFit",
    "Model",
    "bundle_from_files",
    "extract_first_order_curves",
    "fit_everett",
    "fit_friction",
    "fit_tables_lstsq",
    "identify",
    "read_table",
]
