# Quick start: `make demo` (the verification report of the paper scenario -> reports/paper/)
# and `make test` (the whole suite).
# Each target creates the virtual environment and installs the project first.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp

.PHONY: demo test bench install clean lock

# constraints.txt pins the whole dependency set (the report's versions table lists it): the same
# bytes on every machine. Refresh it with `make lock`.
$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c constraints.txt -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

# `visnav report` exits 1 when a requirement is falsified or the nominal task fails: the report is
# written and says which; the demo fails on bad input (2), a run that could not complete (3), an
# internal error (4) or an interruption (130)
demo: $(STAMP)
	@$(VENV)/bin/visnav report --scenario paper --out reports/paper; status=$$?; \
	if [ $$status -eq 1 ]; then echo "make demo: reports/paper/ written; a requirement is FALSIFIED or the task failed (the verdict table and the summary are at the top of report.md)"; fi; \
	test $$status -le 1

# two workers (pytest-xdist), whole files per worker: the full report's regeneration
# (tests/visnav/app/test_report_committed.py, ~4 min) runs beside the rest of the suite; one BLAS thread per
# worker (two workers on two cores: threaded products would contend, as the CLI's own pin avoids)
test: $(STAMP)
	OPENBLAS_NUM_THREADS=1 $(PY) -m pytest -q -n 2 --dist loadfile

bench: $(STAMP)
	$(PY) benchmarks/bench_paper_scenario.py
	$(PY) benchmarks/bench_bdf_step.py
	$(PY) benchmarks/bench_events.py
	$(PY) benchmarks/bench_analyse.py
	$(PY) benchmarks/bench_campaign.py
	$(PY) benchmarks/bench_stiffness.py
	$(PY) benchmarks/bench_fuzz.py

# resolve '.[test]' afresh (newest releases) in a scratch venv and pin what it installed; then run
# `make demo` and commit constraints.txt with the regenerated reports/paper/
lock:
	rm -rf .lock-venv
	$(PYTHON) -m venv .lock-venv
	.lock-venv/bin/python -m pip install --quiet --upgrade pip
	.lock-venv/bin/python -m pip install --quiet -e '.[test]'
	{ sed -n '/^#/p' constraints.txt; .lock-venv/bin/python -m pip freeze --exclude-editable | sort -f; } > constraints.txt.new
	mv constraints.txt.new constraints.txt
	rm -rf .lock-venv
	@echo "constraints.txt refreshed: run make demo and commit constraints.txt and reports/paper/"

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis
