# robustsynth: everything a fresh machine needs goes through these targets.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
EXTRAS := test,dask,control,physics,docs
# constraints.txt: the exact versions the suite last passed with (every package, the extras, pip
# and the build backend).  PIP_CONSTRAINT (not -c) so that it also holds in pip's isolated build
# environment.  `make lock` refreshes it from the newest releases, after the suite passed on them.
LOCK   := constraints.txt
LOCKED := PIP_CONSTRAINT=$(CURDIR)/$(LOCK)
# make test-latest: the same suite on the newest releases, in a venv of its own, unpinned
LATEST := .venv-latest
TESTENV := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1

.PHONY: demo test test-slow test-all test-latest lock bench baselines install clean docs docs-check docs-figures

$(PY):
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml $(LOCK) | $(PY)
	$(LOCKED) $(PY) -m pip install --quiet --upgrade pip
	$(LOCKED) $(PY) -m pip install --quiet -e '.[$(EXTRAS)]'
	$(PY) -m pip check
	touch $(STAMP)

install: $(STAMP)

## make demo: install, then run the whole job on the embedded default config -> results/default/: synthesize,
## verify, validate on the MuJoCo robot (4 episodes), export the controller as C
demo: $(STAMP)
	$(VENV)/bin/robustsynth run -o results/default --physics 4 --export c

## make test: install, then run the test suite on TEST_WORKERS processes (pytest-xdist), one BLAS
## thread each so the workers do not oversubscribe the cores; without the tests marked slow (the
## regression on configs/, the README's commands, kills and signals at random moments, the heaviest
## end-to-end runs): minutes.  make test-slow runs those, make test-all both (CI: .ci/run)
TEST_WORKERS ?= 2
test: $(STAMP)
	$(TESTENV) $(PY) -m pytest -q -n $(TEST_WORKERS) --dist worksteal -m "not slow"

test-slow: $(STAMP)
	$(TESTENV) $(PY) -m pytest -q -n $(TEST_WORKERS) --dist worksteal -m slow

test-all: $(STAMP)
	$(TESTENV) $(PY) -m pytest -q -n $(TEST_WORKERS)

## make test-latest: a fresh venv (.venv-latest) with the newest releases of every dependency (no
## lock), then the whole suite: a new cvxpy / Clarabel / numpy is noticed before users hit it
test-latest:
	rm -rf $(LATEST)
	$(PYTHON) -m venv $(LATEST)
	env -u PIP_CONSTRAINT $(LATEST)/bin/python -m pip install --quiet --upgrade pip setuptools
	env -u PIP_CONSTRAINT $(LATEST)/bin/python -m pip install --quiet --upgrade --upgrade-strategy eager -e '.[$(EXTRAS)]'
	$(LATEST)/bin/python -m pip check
	@$(LATEST)/bin/python -m pip freeze --exclude-editable | grep -iE '^(numpy|scipy|cvxpy|clarabel|scs|pydantic|click|matplotlib)=='
	$(TESTENV) $(LATEST)/bin/python -m pytest -q -n $(TEST_WORKERS) -p no:cacheprovider

## make lock: run test-latest, and only if it passed write its versions to constraints.txt (commit it)
lock: test-latest
	{ echo "# The exact versions robustsynth's suite passed with (make test-latest on $$(date -u +%F),"; \
	  echo "# Python $$($(LATEST)/bin/python -c 'import platform; print(platform.python_version())')). make demo / make test install through it;"; \
	  echo "# refresh with 'make lock'. Unpinned installs: see README, Installing."; \
	  $(LATEST)/bin/python -m pip freeze --all --exclude-editable | grep -viE '^wheel=='; } > $(LOCK).tmp
	mv $(LOCK).tmp $(LOCK)
	@echo "wrote $(LOCK): review 'git diff $(LOCK)', then commit it"

## make docs: the documentation site (docs/ -> docs/_build/html), rebuilt whole (-E: docstrings are re-read),
## offline, warnings as errors (a broken link or a missing reference fails it); the CLI, config and API
## references are generated from the code (tests/test_docs.py compares them with click and the schema)
DOCS_OUT ?= docs/_build/html
docs: $(STAMP)
	$(VENV)/bin/sphinx-build -E -W --keep-going -n -q -b html docs $(DOCS_OUT)

## make docs-figures: regenerate the figures the docs show (docs/figures/default/) from a real run: verify the
## committed default gain on configs/default.yaml, as make demo does (about 2 minutes); commit them
docs-figures: $(STAMP)
	tmp=$$(mktemp -d) && $(VENV)/bin/robustsynth verify configs/default.yaml --gains results/baselines/default/gains.json \
	  -o $$tmp && cp $$tmp/figures/*.png docs/figures/default/ && rm -rf $$tmp

## make docs-check: make docs, then open the index and the first tutorial in headless chromium: images
## load, the math renders (MathJax from the site itself, no network), no console errors
docs-check: docs
	$(PY) docs/_tools/browser_check.py $(DOCS_OUT)

## make bench: start-up, synthesis and Monte Carlo benchmarks (prints figures)
bench: $(STAMP)
	$(PY) benchmarks/run_all.py

## make baselines: regenerate results/baselines/<name>/{summary,gains}.json for every config in configs/
baselines: $(STAMP)
	$(PY) -m robustsynth.regression --write

clean:
	rm -rf $(VENV) $(LATEST) .pytest_cache .hypothesis docs/_build
