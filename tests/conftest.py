import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

import wbc

# CI replays the same examples every run (a red CI must be reproducible); locally
# hypothesis explores new ones (that is how the HiGHS cycling case was found)
settings.register_profile("ci", derandomize=True)
# the fuzz campaign (tests/test_fuzz.py): `pytest tests/test_fuzz.py --hypothesis-profile=nightly`
# or `WBC_FUZZ_EXAMPLES=5000 pytest tests/test_fuzz.py` (the count is split over the fuzz tests)
settings.register_profile("nightly", max_examples=int(os.environ.get("WBC_FUZZ_EXAMPLES") or 3000), deadline=None)
if os.environ.get("WBC_FUZZ_EXAMPLES"):
    settings.load_profile("nightly")
elif os.environ.get("CI"):
    settings.load_profile("ci")

ROOT = Path(__file__).resolve().parents[1]
TASKS = ROOT / "tasks"
#: working directory of `python -c` subprocesses: outside the checkout, so that they import
#: the installed wbc (from the checkout root, `-c` would import the source tree, which has
#: no wbc.models in a non-editable install)
NEUTRAL = tempfile.gettempdir()


@pytest.fixture(scope="session")
def youbot() -> wbc.Robot:
    return wbc.load_robot("youbot")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def random_youbot_configurations(rng: np.random.Generator, count: int) -> np.ndarray:
    """Base anywhere in a 10 m square with any heading; arm joints uniform within eq. (1)."""
    deg = np.pi / 180.0
    low = np.array([-5.0, -5.0, -np.pi, -169 * deg, -65 * deg, -151 * deg, -102.5 * deg, -167.5 * deg])
    high = np.array([5.0, 5.0, np.pi, 169 * deg, 90 * deg, 146 * deg, 102.5 * deg, 167.5 * deg])
    return rng.uniform(low, high, size=(count, 8))
