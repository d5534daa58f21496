"""The examples in the docstrings of the modules users read first run, and print what they show
(the README's and the docs' examples run in test_docs_examples.py; the batch module's, which
need Ray, in test_batch_ray.py)."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["pycinder", "pycinder.detector"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    module = importlib.import_module(name)
    failed, attempted = doctest.testmod(
        module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert attempted > 0, f"{name} has no examples to run"
    assert failed == 0, f"{failed} of {attempted} examples of {name} failed (see above)"
