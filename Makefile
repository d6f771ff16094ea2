# `make demo` runs the cloth demo, `make test` the tests; both set up ./.venv on first use.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: install test test-fast demo package validate farm-check clean

install: $(STAMP)

$(STAMP): requirements-dev.txt requirements-extension.txt
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else "bpy 5.0.1 needs Python 3.11: run make PYTHON=/path/to/python3.11")'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements-dev.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps -r requirements-extension.txt
	touch $(STAMP)

validate: $(STAMP)
	$(PY) scripts/build_extension.py validate

# The Open Job Description template of farm/ (openjd-cli comes with requirements-dev.txt).
farm-check: $(STAMP)
	$(VENV)/bin/openjd check farm/retime.openjd.yaml

test: validate
	$(PY) -m pytest

test-fast: validate
	$(PY) -m pytest -m "not slow"

demo: $(STAMP)
	$(PY) demo/cloth_demo.py

package: $(STAMP)
	$(PY) scripts/build_extension.py build

clean:
	rm -rf $(VENV) wheels dist build demo_output .pytest_cache
