# Quick start: `make demo` (the verification report of the paper scenario -> reports/paper/)
# and `make test` (the whole suite).
# Each target creates the virtual environment and installs the project first.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp

.PHONY: demo test bench install clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/visnav report --scenario paper --out reports/paper

test: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) benchmarks/bench_paper_scenario.py
	$(PY) benchmarks/bench_bdf_step.py
	$(PY) benchmarks/bench_events.py
	$(PY) benchmarks/bench_analyse.py
	$(PY) benchmarks/bench_campaign.py
	$(PY) benchmarks/bench_stiffness.py
	$(PY) benchmarks/bench_fuzz.py

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis
