# friction_sim developer entry points.  Everything runs through $(VENV)/bin/python
# explicitly; no virtualenv activation is needed or assumed.
#
# Two platforms, one recipe each for the venv, the tests and the demo:
#   PLATFORM=pinned (default): .venv, this machine's python3, constraints.txt;
#   PLATFORM=jazzy: .venv-jazzy, Python 3.12 with what Ubuntu 24.04 (ROS 2 Jazzy's
#     platform) has from apt: NumPy 1.26.4, SciPy 1.11.4, ... (constraints-jazzy.txt
#     in place of those lines of constraints.txt).  `make test-jazzy` runs the suite there.

PLATFORM ?= pinned
PYTEST_ARGS ?=
ifeq ($(PLATFORM),jazzy)
# pyenv's newest 3.12, else a python3.12 on PATH that runs (a pyenv shim may not);
# JAZZY_PYTHON=/path/to/python3.12 chooses another.
JAZZY_PYTHON ?= $(shell for p in $$(ls -d "$$(pyenv root 2>/dev/null)"/versions/3.12*/bin/python3.12 2>/dev/null \
                  | sort -V | tail -n 1) python3.12; do \
                  "$$p" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 12))' 2>/dev/null \
                  && { command -v "$$p"; break; }; done)
PYTHON := $(JAZZY_PYTHON)
VENV   := .venv-jazzy
CONSTRAINTS := $(VENV)/constraints.txt
else ifeq ($(PLATFORM),pinned)
PYTHON ?= python3
VENV   := .venv
CONSTRAINTS := constraints.txt
else
$(error PLATFORM = $(PLATFORM): must be pinned or jazzy)
endif
VPY    := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
# The docs' headless browser, one per checkout, on either platform (see `browser:` below).
BROWSER_DIR := tools/docs-browser
BROWSER := $(BROWSER_DIR)/node_modules/.chromium/chromium
export PLATFORM

# Keep all DDS traffic on this machine, and give each `make` invocation its own
# random domain so parallel runs (tests, demos, benches) never cross-talk.
# Computed once per invocation (simple assignment), unless given by the caller.
ifeq ($(origin ROS_DOMAIN_ID),undefined)
ROS_DOMAIN_ID := $(shell shuf -i 1-100 -n 1)
endif
ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
MPLBACKEND := Agg
export ROS_DOMAIN_ID ROS_AUTOMATIC_DISCOVERY_RANGE MPLBACKEND

.DEFAULT_GOAL := test
.PHONY: venv .venv lint test suite test-jazzy demo docs browser docs-shot bench margins clean distclean

venv .venv: $(STAMP)

$(STAMP): requirements.txt requirements-dev.txt $(CONSTRAINTS) setup.py setup.cfg
	@[ -n "$(PYTHON)" ] || { echo "PLATFORM=$(PLATFORM) needs Python 3.12: python3.12 on PATH, pyenv install 3.12, or JAZZY_PYTHON=/path/to/python3.12" >&2; exit 2; }
	$(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --disable-pip-version-check -q -U pip
	$(VPY) -m pip install --disable-pip-version-check -c $(CONSTRAINTS) -r requirements-dev.txt
	# Editable install of friction_sim itself: puts the console scripts
	# (friction-sim, slider, controller) in $(VENV)/bin.  No build isolation, so the
	# pinned setuptools from the constraints is the one that builds it.
	$(VPY) -m pip install --disable-pip-version-check -c $(CONSTRAINTS) --no-deps --no-build-isolation -e .
	touch $(VENV)/COLCON_IGNORE
	touch $@

# The Jazzy platform's constraints: constraints.txt with the lines that
# constraints-jazzy.txt names replaced by its own (pip refuses two pins of one package).
.venv-jazzy/constraints.txt: constraints.txt constraints-jazzy.txt
	@mkdir -p $(@D)
	awk 'function key(line,  parts) { split(line, parts, "=="); k = tolower(parts[1]); gsub(/_/, "-", k); return k } \
	     NR == FNR { if ($$0 ~ /==/ && $$0 !~ /^#/) over[key($$0)] = 1; next } \
	     !($$0 ~ /==/ && $$0 !~ /^#/ && (key($$0) in over))' constraints-jazzy.txt constraints.txt > $@
	cat constraints-jazzy.txt >> $@

# Static checks; configuration in pyproject.toml ([tool.ruff], [tool.mypy]).
# Both always run, so one pass shows every finding; either one failing fails lint.
lint: $(STAMP)
	@status=0; \
	echo "ruff check friction_sim test bench"; $(VPY) -m ruff check friction_sim test bench || status=1; \
	echo "mypy"; $(VPY) -m mypy || status=1; \
	exit $$status

# Lint first: a lint failure fails `make test` before any test runs.
test: lint
	$(MAKE) --no-print-directory suite

# The whole suite on this platform's venv (lint runs once, on the pinned platform), on
# PYTEST_WORKERS processes (pytest-xdist; a test file stays on one worker, each worker
# has a ROS domain of its own: test/conftest.py).
PYTEST_WORKERS ?= 2
suite: $(STAMP) $(BROWSER)
	$(VPY) -m pytest -q -n $(PYTEST_WORKERS) --dist loadfile test $(PYTEST_ARGS)

# The whole suite on the Jazzy platform (.venv-jazzy; see the top of this file).
test-jazzy:
	$(MAKE) --no-print-directory PLATFORM=jazzy suite

# How close each numeric test sits to its tolerance under several CPU settings
# (OpenBLAS kernels, NumPy's AVX-512 paths): test/margins_survey.py.
margins: $(STAMP)
	$(VPY) test/margins_survey.py $(PYTEST_ARGS)

demo: $(STAMP)
	mkdir -p out
	$(VENV)/bin/friction-sim trace --png out/fig2.png
	$(VENV)/bin/friction-sim umap --grid 101 --csv out/umap.csv --png out/umap.png
	$(VENV)/bin/friction-sim trace --png out/demo/flight.png --angle 30 --mu 0.5 --amplitude 20 --drive-force 0
	$(VENV)/bin/friction-sim conveyor --png out/demo/conveyor.png --csv out/demo/conveyor.csv
	$(VENV)/bin/friction-sim resonance --png out/demo/resonance.png --natural-frequency 52 --from 40 --to 60
	$(VENV)/bin/friction-sim experiment config/demo.yaml

# The documentation site (doc/, rosdoc2's layout) with warnings as errors: a broken
# cross-reference, a --help that cannot be formatted or a docstring that does not parse
# fails it.  The suite builds it too (test/test_docs.py), so `make test` and CI do.
docs: $(STAMP)
	$(VPY) -m sphinx -W --keep-going -q -b html doc build/docs/html
	@echo "build/docs/html/index.html"

# A headless browser for the site (tools/docs-browser): the Chromium that the npm package
# @sparticuz/chromium ships inside its tarball, driven by puppeteer-core, both pinned by
# package-lock.json; `npm ci` unpacks it into that folder's node_modules (extract.mjs).
# From the npm registry alone, with the machine's Node.js; the suite opens the site in it
# (test/test_docs_browser.py), so `make suite` installs it.  (BROWSER is set at the top.)
browser: $(BROWSER)
$(BROWSER): $(BROWSER_DIR)/package.json $(BROWSER_DIR)/package-lock.json $(BROWSER_DIR)/extract.mjs
	cd $(BROWSER_DIR) && npm ci --no-audit --no-fund
	touch $@

# The site's front page as a reader's browser shows it: a screenshot in
# build/docs/front.png, and what the page shows (title, headings, links, images, console
# errors) printed; fails on a console error, a broken image or a link to a missing file.
docs-shot: docs $(BROWSER)
	node $(BROWSER_DIR)/shot.mjs build/docs/html/index.html build/docs/front.png

bench: $(STAMP)
	@set -e; found=0; \
	for f in bench/[!_]*.py; do \
	  [ -e "$$f" ] || continue; \
	  found=1; \
	  echo "=== $$f"; \
	  $(VPY) "$$f" || { echo "bench failed: $$f" >&2; exit 1; }; \
	done; \
	[ $$found -eq 1 ] || echo "no bench/*.py found"

clean:
	rm -rf build install log out .pytest_cache .hypothesis .mypy_cache .ruff_cache *.egg-info
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf .venv .venv-jazzy $(BROWSER_DIR)/node_modules
