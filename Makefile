# Two entry points (see README): `make replicate` runs the paper's replication and writes the report,
# `make test` runs the test suite and builds the docs. Both create .venv and install what they need on a fresh machine
# (`make test` adds the test and docs tools and the Ray extra to what the main job needs).
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.sb3-affect-installed
TOOLS_STAMP := $(VENV)/.sb3-affect-tools-installed
OUT ?= runs
DOCS_OUT ?= docs/_build/html
TEST_WORKERS ?= auto

.PHONY: venv tools test typecheck replicate docs bench clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	@echo "== creating $(VENV) (a Python virtual environment) ..."
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PY) -m pip install -q --upgrade pip
	@# (PYTHONWARNINGS: setuptools says "Editable installation" for every editable install with a package-dir map.)
	@# CPU torch first: a plain `torch` requirement would pull a multi-GB CUDA build.
	@$(PY) -c "import torch" 2>/dev/null && echo "== torch already installed" || { \
		echo "== installing CPU torch (1-3 min) ..."; \
		$(PY) -m pip install -q torch==2.13.0 || $(PY) -m pip install -q torch --index-url https://download.pytorch.org/whl/cpu; }
	@echo "== installing sb3-affect with all its extras (1-3 min) ..."
	@PYTHONWARNINGS="ignore:Editable installation" $(PY) -m pip install -q -e '.[all]'
	@echo "== compiling the compiled engine's kernels once for this machine (1-3 min; later runs load them) ..."
	@$(PY) -m sb3_affect.kernel
	@touch $(STAMP)
	@echo "== installed in $(VENV). To use the sb3-affect command in this shell: source $(VENV)/bin/activate"

# The test and docs tools and the optional Ray extra: what `make test` and `make docs` need beyond the main job's set-up.
tools: $(TOOLS_STAMP)

$(TOOLS_STAMP): $(STAMP)
	@echo "== installing the test and docs tools (1-3 min) ..."
	@PYTHONWARNINGS="ignore:Editable installation" $(PY) -m pip install -q -e '.[all,test,docs]'
	@echo "== installing the optional Ray extra (1-2 min) ..."
	@PYTHONWARNINGS="ignore:Editable installation" $(PY) -m pip install -q -e '.[ray]' || echo "note: the optional Ray extra could not be installed; Ray tests will be skipped"
	@touch $(TOOLS_STAMP)

test: tools
	$(PY) -m ruff check .
	$(VENV)/bin/lint-imports --no-logo
	@# the type check and the docs build at once, one core each (about 65 s and 25 s from a fresh clone)
	$(MAKE) --no-print-directory -j2 typecheck docs
	@# the suite on every core (pytest-xdist, each test file on one worker; its 15 slowest tests listed), then the Ray tests
	@# on their own: they start Ray instances and clusters, and a Ray driver whose node is stopped under load may exit
	@# before Python sees the loss
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile -m "not ray" --durations=15
	$(PY) -m pytest -q -m ray

typecheck: tools
	$(PY) -m mypy

# The documentation site: warnings are errors (-W), every internal reference is checked (-n: nitpicky).
docs: tools
	$(PY) -m sphinx -b html -W --keep-going -n -q docs $(DOCS_OUT)
	@echo "docs: open $(DOCS_OUT)/index.html"

replicate: venv
	@echo "== the main job: the parts listed by 'sb3-affect replicate --help' (with its wall time), then the report (rerun to resume)"
	$(VENV)/bin/sb3-affect replicate --out $(OUT)

bench: venv
	$(PY) benchmarks/bench.py

clean:
	rm -rf $(VENV) build *.egg-info docs/_build docs/auto_examples docs/generated
