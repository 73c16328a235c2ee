# sideslip: the two set-up commands are `make demo` and `make test`. Both create .venv
# from the repository's own pinned files on a machine with only Python 3.11 and pip.

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
PACKAGES := sideslip_msgs_py sideslip_sim sideslip_estimator training
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

# The main job for now: generate the paper's Table 4 test scenarios with paper noise
# and print a per-scenario summary of sideslip, lateral acceleration and speed.
demo: venv
	$(VENV)/bin/sideslip-generate --preset paper-test --out $(DEMO_OUT) --noise paper --force

bench: venv
	$(PY) bench/run.py --out bench/results.json

constraints: venv
	( echo "# Full resolved set for make test/demo (pip freeze of a working .venv). Regenerate with"; \
	  echo "# \`make constraints\` after changing requirements.txt."; \
	  $(VENV)/bin/pip freeze --exclude-editable | grep -v -i sideslip ) > constraints.txt

clean:
	rm -rf $(VENV) data/paper-test .pytest_cache .ruff_cache
