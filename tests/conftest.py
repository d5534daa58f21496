import os

os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")

import numpy as np
import pytest

import pycinder


@pytest.fixture(scope="session")
def detector() -> pycinder.Detector:
    """The default detector (focused strategy, default tolerance), reused across tests."""
    return pycinder.Detector()


@pytest.fixture(scope="session")
def bunny():
    from pycinder.testing import bunny as load

    return load()


def assert_matches_truth(found: np.ndarray, truth, *, context: str = "") -> dict:
    """Every pair that must be found is found, and no separate pair is reported."""
    score = truth.score(found)
    assert not score["false"], f"{context}: separate pairs reported: {score['false']}"
    assert not score["missed"], f"{context}: pairs that must be found were missed: {score['missed']}"
    return score


def pytest_terminal_summary(terminalreporter) -> None:
    """One line per test that compared stored answers, saying which comparison it made (bit
    for bit or within bounds: see ``tests/test_answers.py``)."""
    lines = [f"{report.nodeid}: compared {value}"
             for reports in terminalreporter.stats.values() for report in reports
             if getattr(report, "when", None) == "call"
             for name, value in getattr(report, "user_properties", ()) if name == "comparison"]
    if lines:
        terminalreporter.write_sep("-", "stored answers")
        for line in lines:
            terminalreporter.write_line(line)
