import os

os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")

import numpy as np
import pytest

import pycinder


@pytest.fixture(scope="session")
def detector_1024() -> pycinder.Detector:
    """The default detector at the resolution the exactness tests are specified at."""
    return pycinder.Detector(1024)


@pytest.fixture(scope="session")
def bunny():
    from pycinder.testing import bunny as load

    return load()


def assert_matches_truth(found: np.ndarray, truth, *, context: str = "") -> dict:
    """Every clear overlap found, no clear separation reported."""
    score = truth.score(found)
    assert not score["false"], f"{context}: clearly separate pairs reported: {score['false']}"
    assert not score["missed"], f"{context}: clear overlaps missed: {score['missed']}"
    return score
