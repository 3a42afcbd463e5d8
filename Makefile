# wtftc: every target does its own set-up (a .venv with the project installed) first.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp

.PHONY: help setup openfast regenerate check-generated test lint run verify bench headline scorecards clean

help:
	@echo "make run              set up, then the paper's three cases on both plants into out/cases/"
	@echo "make verify           set up, check generated/, verify the generated controller code"
	@echo "make test             set up, get OpenFAST, run the whole test suite"
	@echo "make openfast         get OpenFAST 5.0.0 and TurbSim into wtftc's cache (docs/openfast.md)"
	@echo "make regenerate       rebuild generated/ from derivation/ (SymPy -> CasADi)"
	@echo "make check-generated  fail with a diff if generated/ is stale"
	@echo "make bench            set up, time the closed loop through every method (out/bench/)"
	@echo "make lint             ruff"
	@echo "make headline         remake the README's table of the committed scorecards (results/)"
	@echo "make scorecards       remake (or resume) the committed scorecards in results/ (hours: results/README.md)"

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "wtftc needs Python >= 3.11; set PYTHON=python3.11")'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	@# ROSCO's controller library for the ROSCO-in-the-loop tests and rows, without the
	@# 1.4 GB its wheel pulls in (wisdem, openmdao, ...): wtftc needs only libdiscon and
	@# its ControllerInterface (docs/controllers.md). OpenFAST's input-file reader for
	@# `wtftc turbine import`, without the pandas it declares (its reader does not use it);
	@# deepdiff, because ROSCO's toolbox imports it through openfast-io. Every install with
	@# dependencies comes first and the two --no-deps ones last, so that pip's resolver never
	@# re-checks them and set-up prints no ERROR line (issue 30)
	$(PY) -m pip install --quiet pyzmq pyyaml ruamel.yaml 'deepdiff>8.0'
	$(PY) -m pip install --quiet --no-deps 'rosco==2.10.6' 'openfast-io==5.0.0'
	@touch $(STAMP)

setup: $(STAMP)

# OpenFAST 5.0.0 and TurbSim, the second engine (docs/openfast.md): found, or installed
# into wtftc's cache from the prebuilt archive, or built from source
openfast: setup
	$(VENV)/bin/wtftc openfast get

regenerate: setup
	$(PY) -m derivation.generate generated

check-generated: setup
	$(PY) -m derivation.check_generated

# the suite's files spread over the cores (pytest-xdist), each file whole on one worker: its
# module fixtures (a compiled library, an OpenFAST run) are built once. (Not loadgroup:
# pytest-xdist 3.8's groups do not take under pytest 9.) TEST_WORKERS=0: one process
TEST_WORKERS ?= auto
test: setup openfast
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile --durations=25

lint: setup
	$(VENV)/bin/ruff check .

run: setup
	$(VENV)/bin/wtftc cases --out out/cases

bench: setup openfast
	$(PY) -m bench --out out/bench

verify: setup check-generated
	$(VENV)/bin/wtftc verify --out out/verify

# the README's table of the committed scorecards, from results/*/scorecard.json
headline: setup
	$(PY) -c 'from pathlib import Path; from wtftc.campaign.scorecard import headline as h; p = Path("README.md"); p.write_text(h.main(p, Path("results")))'

# the committed scorecards (results/README.md): each resumes where it stopped
scorecards: setup openfast
	$(VENV)/bin/wtftc scorecard --turbine nrel5mw --seeds 6 --screen 1 --out results/scorecard_nrel5mw
	$(VENV)/bin/wtftc scorecard --turbine iea15mw --seeds 6 --screen 1 --out results/scorecard_iea15mw

clean:
	rm -rf out .pytest_cache .ruff_cache
