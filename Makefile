# sideslip: the two set-up commands are `make demo` and `make test`. Both create .venv
# from the repository's own pinned files on a machine with only Python 3.11 and pip.

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
PACKAGES := sideslip_msgs_py sideslip_sim sideslip_bags sideslip_estimator training
DEMO_OUT ?= data/paper-test

.PHONY: venv test lint format demo bench constraints clean

$(STAMP): requirements.txt constraints.txt $(foreach p,$(PACKAGES),$(wildcard $(p)/setup.py $(p)/pyproject.toml))
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet -r requirements.txt -c constraints.txt
	# compat editable mode puts each package's folder on sys.path, so running from the
	# repository root (where the ament package folders share the module names) works.
	$(PY) -m pip install --quiet --no-deps --no-build-isolation \
		--config-settings editable_mode=compat $(foreach p,$(PACKAGES),-e $(p))
	touch $(STAMP)

venv: $(STAMP)

lint: venv
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: venv
	$(VENV)/bin/ruff check --fix .
	$(VENV)/bin/ruff format .

test: venv lint
	$(PY) -m pytest

# make demo: the Table 4 test scenarios as labelled bags in data/paper-test/ (with a
# per-scenario summary), then the live system: the simulator drives scenario 2 in real
# time, the estimator runs the shipped PSO-LSTM, and sideslip-watch prints the estimate
# against the ground truth (ROS 2 from the PyPI wheels, loopback only).
demo: venv
	$(VENV)/bin/sideslip-generate --preset paper-test --out $(DEMO_OUT) --noise paper --force
	@echo "--- live: sim_node (scen2) -> estimator_node (pso_lstm) -> sideslip-watch ---"
	@export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-42}; \
	$(VENV)/bin/sideslip-estimator --ros-args -p backend:=pso_lstm > $(VENV)/demo-estimator.log 2>&1 & est=$$!; \
	$(VENV)/bin/sideslip-watch & watch=$$!; \
	$(VENV)/bin/sideslip-sim --ros-args -p scenario:=scen2 -p wait_for_subscribers:=1 \
		> $(VENV)/demo-sim.log 2>&1; status=$$?; \
	kill -INT $$watch; wait $$watch; kill -INT $$est; wait $$est; exit $$status

bench: venv
	$(PY) bench/run.py --out bench/results.json

constraints: venv
	( echo "# Full resolved set for make test/demo (pip freeze of a working .venv). Regenerate with"; \
	  echo "# \`make constraints\` after changing requirements.txt."; \
	  $(VENV)/bin/pip freeze --exclude-editable | grep -v -i sideslip ) > constraints.txt

clean:
	rm -rf $(VENV) data/paper-test .pytest_cache .ruff_cache
