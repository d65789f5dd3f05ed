"""Shared fixtures. Helper modules next to this file (reference plants written independently of bmr's own code)
are importable by the tests of every topic folder."""
import os
from pathlib import Path

import pytest

from preisach_plant import first_order_curves

REPO = Path(__file__).resolve().parents[2]
SLAC_DATA_ENV = "BMR_SLAC_DATA"


def slac_data_dir() -> Path:
    """The SLAC LCLS-II quadrupole 4194 measurements (public repository roussel-ryan/diff_hysteresis,
    examples/fitting/data: strdat.ruN / strplt.ruN files). Not redistributed with bmr: point ``BMR_SLAC_DATA`` at
    a copy, or place it at ``../shared/data/slac-quad-4194`` beside the repository."""
    env = os.environ.get(SLAC_DATA_ENV)
    return Path(env) if env else REPO.parent / "shared" / "data" / "slac-quad-4194"


@pytest.fixture(scope="session")
def slac_data() -> Path:
    d = slac_data_dir()
    if not (d / "strdat.ru3").is_file():
        pytest.skip(f"needs the SLAC quadrupole 4194 measurements (strdat.ru3..8 from the public repository "
                    f"roussel-ryan/diff_hysteresis, examples/fitting/data); set {SLAC_DATA_ENV} to their folder "
                    f"(looked in {d})")
    return d


@pytest.fixture(scope="session")
def preisach_curves():
    """First-order curves of a 200-threshold Preisach plant, 21 per family."""
    return first_order_curves(200, 21)


@pytest.fixture(scope="session")
def small_curves():
    """A cheaper 60-threshold plant, 13 curves per family."""
    return first_order_curves(60, 13)
