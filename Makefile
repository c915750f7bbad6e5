# Two entry points (see README): `make replicate` runs the paper's replication and writes the report,
# `make test` runs the test suite. Both create .venv and install everything on a fresh machine.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.sb3-affect-installed
OUT ?= runs

.PHONY: venv test replicate lint bench clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	# CPU torch first: a plain `torch` requirement would pull a multi-GB CUDA build.
	$(PY) -c "import torch" 2>/dev/null || $(PY) -m pip install -q torch==2.13.0 \
		|| $(PY) -m pip install -q torch --index-url https://download.pytorch.org/whl/cpu
	$(PY) -m pip install -q -e '.[test]'
	$(PY) -m pip install -q -e '.[ray]' || echo "note: the optional Ray extra could not be installed; Ray tests will be skipped"
	touch $(STAMP)

test: venv
	$(PY) -m ruff check .
	$(PY) -m mypy
	$(PY) -m pytest -q

replicate: venv
	$(VENV)/bin/sb3-affect replicate --out $(OUT)

bench: venv
	$(PY) benchmarks/bench.py

clean:
	rm -rf $(VENV) build *.egg-info
