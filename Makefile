# robustsynth: everything a fresh machine needs goes through these targets.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test bench baselines install clean

$(PY):
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,dask,control]'
	touch $(STAMP)

install: $(STAMP)

## make demo: install, then run the whole job on the embedded default config -> results/default/
demo: $(STAMP)
	$(VENV)/bin/robustsynth run -o results/default

## make test: install, then run the test suite on TEST_WORKERS processes (pytest-xdist), one BLAS
## thread each so the workers do not oversubscribe the cores
TEST_WORKERS ?= 2
test: $(STAMP)
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 $(PY) -m pytest -q -n $(TEST_WORKERS)

## make bench: start-up, synthesis and Monte Carlo benchmarks (prints figures)
bench: $(STAMP)
	$(PY) benchmarks/run_all.py

## make baselines: regenerate results/baselines/<name>/{summary,gains}.json for every config in configs/
baselines: $(STAMP)
	$(PY) -m robustsynth.regression --write

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis
