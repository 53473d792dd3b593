# friction_sim developer entry points.  Everything runs through .venv/bin/python
# explicitly; no virtualenv activation is needed or assumed.

PYTHON ?= python3
VENV   := .venv
VPY    := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
PYTEST_ARGS ?=

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
.PHONY: venv .venv lint test demo bench clean distclean

venv .venv: $(STAMP)

$(STAMP): requirements.txt requirements-dev.txt constraints.txt setup.py setup.cfg
	$(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --disable-pip-version-check -q -U pip
	$(VPY) -m pip install --disable-pip-version-check -c constraints.txt -r requirements-dev.txt
	# Editable install of friction_sim itself: puts the console scripts
	# (friction-sim, slider, controller) in .venv/bin.  No build isolation, so the
	# pinned setuptools from constraints.txt is the one that builds it.
	$(VPY) -m pip install --disable-pip-version-check -c constraints.txt --no-deps --no-build-isolation -e .
	touch $(VENV)/COLCON_IGNORE
	touch $@

# Static checks; configuration in pyproject.toml ([tool.ruff], [tool.mypy]).
# Both always run, so one pass shows every finding; either one failing fails lint.
lint: $(STAMP)
	@status=0; \
	echo "ruff check friction_sim test bench"; $(VPY) -m ruff check friction_sim test bench || status=1; \
	echo "mypy"; $(VPY) -m mypy || status=1; \
	exit $$status

# Lint first: a lint failure fails `make test` before any test runs.
test: $(STAMP) lint
	$(VPY) -m pytest -q test $(PYTEST_ARGS)

demo: $(STAMP)
	mkdir -p out
	$(VENV)/bin/friction-sim trace --png out/fig2.png
	$(VENV)/bin/friction-sim umap --grid 101 --csv out/umap.csv --png out/umap.png
	$(VENV)/bin/friction-sim trace --png out/demo/flight.png --angle 30 --mu 0.5 --amplitude 20 --drive-force 0
	$(VENV)/bin/friction-sim conveyor --png out/demo/conveyor.png --csv out/demo/conveyor.csv
	$(VENV)/bin/friction-sim experiment config/demo.yaml

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
	rm -rf $(VENV)
