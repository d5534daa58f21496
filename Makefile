# Set-up and everyday commands. `make demo` and `make test` work on a fresh Debian machine with
# Python 3.11+: each creates .venv, installs what it needs, and makes sure wgpu finds an adapter.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
export PYTHONUNBUFFERED := 1

.PHONY: demo test test-slow pytest docs wheel check-wheel venv lint bench clean

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip

$(VENV)/.deps-%: pyproject.toml | $(PY)
	$(PY) -m pip install -q -e ".[$*]"
	./scripts/ensure-adapter.sh $(PY)
	touch $@

venv: $(VENV)/.deps-all

demo: $(VENV)/.deps-demo
	$(VENV)/bin/pycinder demo stairs --frames 120 --out out/stairs.mp4

# The suite, then the docs built with warnings as errors, then the wheel built and checked in a
# fresh virtual environment of its own (not editable, no source tree on the path).
test: pytest docs check-wheel

# The tests marked slow (turned 500 m pairs in map coordinates: minutes on a CPU adapter) run
# apart: `make test-slow`.
pytest: $(VENV)/.deps-test
	$(PY) -m pytest -q -m "not slow"

test-slow: $(VENV)/.deps-test
	$(PY) -m pytest -q -m slow

docs: $(VENV)/.deps-test
	$(PY) -m sphinx -W --keep-going -q -b html docs docs/_build/html

wheel: $(VENV)/.deps-test
	rm -rf dist
	$(PY) -m build --outdir dist .

check-wheel: wheel
	./scripts/check-wheel.sh $(PY) dist

# The benchmarks' harness (benchmarks/) runs from this checkout: it is not in the wheel.
bench: $(VENV)/.deps-bench
	PYTHONPATH="$(CURDIR)$${PYTHONPATH:+:$$PYTHONPATH}" $(VENV)/bin/pycinder bench --out benchmarks/results

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis dist docs/_build
