import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from preisach_plant import first_order_curves  # noqa: E402

SHARED = Path(__file__).resolve().parents[1] / ".." / "shared"


@pytest.fixture(scope="session")
def preisach_curves():
    """First-order curves of a 200-threshold Preisach plant, 21 per family."""
    return first_order_curves(200, 21)


@pytest.fixture(scope="session")
def small_curves():
    """A cheaper 60-threshold plant, 13 curves per family."""
    return first_order_curves(60, 13)
