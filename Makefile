# drillgym: two set-up commands for a newcomer.
#   make demo   simulate the built-in rig (torsional stick-slip at 1 V) and plot it
#   make test   run the test suite
# Both create the virtual environment .venv on first use (idempotent).

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip
STAMP  := $(VENV)/.installed

.PHONY: venv demo test lint docs bench clean

venv: $(STAMP)

# torch first: `pip install torch==2.13.0` takes the local CPU build; installing it
# after stable-baselines3 would pull several GB of CUDA wheels instead.
$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install --upgrade pip wheel setuptools
	$(PIP) install torch==2.13.0
	$(PIP) install -e '.[dev,docs]'
	$(VENV)/bin/drillgym prepare  # compile the identification's models once (about 1 min, side by side), not in the user's first one
	touch $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(VENV)/bin/drillgym simulate --config torsional --u 1.0 --duration 30 --out out/demo.csv --plot out/demo.png
	@echo "wrote out/demo.csv and out/demo.png"

# the import contracts, the lint rules and the formatting of pyproject.toml first (seconds), then the suite
test: lint
	$(PY) -m pytest -q -n 2 --dist loadgroup tests

lint: $(STAMP)
	$(VENV)/bin/lint-imports
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

# the documentation site into site/ (mkdocs.yml; warnings are errors)
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict -d site

bench: $(STAMP)
	$(PY) benchmarks/bench_simulator.py

clean:
	rm -rf $(VENV) out site .pytest_cache
