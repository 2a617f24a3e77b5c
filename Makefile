# Every target creates .venv on a fresh machine (Python >= 3.11) and installs what it needs.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# The project's packages, compiled to bytecode at install and before each target that runs
# parmor (only what changed; pip does not for an editable install): where
# PYTHONDONTWRITEBYTECODE is set, each parmor process would otherwise compile every module
# it imports, ~0.13 s of its start-up.
PACKAGES := asp adron synth kinematics gaits export program
BYTECODE := $(BIN)/python -m compileall -q $(PACKAGES)

.PHONY: demo test bench lint clean web docs schemas

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -q -e '.[test,bench]'
	$(BYTECODE)
	touch $(STAMP)

# The block page's JavaScript (Blockly, three.js) from npm, pinned by web/package-lock.json,
# into web/node_modules (git-ignored); 'parmor blocks' copies what the page needs from there.
WEB_STAMP := web/node_modules/.installed

$(WEB_STAMP): web/package.json web/package-lock.json
	cd web && npm ci --no-audit --no-fund
	touch $(WEB_STAMP)

web: $(WEB_STAMP)

demo: $(STAMP) $(WEB_STAMP)
	$(BYTECODE)
	$(BIN)/parmor abilities
	$(BIN)/parmor design walking --no-input || test $$? -eq 3
	$(BIN)/parmor design walking --answer grasping=no --answer rough-terrain-walking=no
	$(BIN)/parmor design pick-and-place --param object_shape=oval --json
	$(BIN)/parmor design driving line-tracking obstacle-avoidance --out demo/cart --force
	$(BIN)/parmor run examples/square.py demo/cart
	$(BIN)/parmor blocks demo/cart

# Two processes, each file's tests (and its module fixtures) on one: pytest-xdist, in the
# test extras. Not --dist loadgroup: pytest-xdist 3.8 tags a group in Item._nodeid, which
# pytest 9 no longer reads, so its groups are ignored and the tests spread one by one.
test: $(STAMP) $(WEB_STAMP)
	$(BYTECODE)
	$(BIN)/python -m pytest -n 2 --dist loadfile

bench: $(STAMP)
	$(BYTECODE)
	$(BIN)/python bench/bench.py

# The JSON Schemas of the user file formats (adron/schemas/), written from their models.
schemas: $(STAMP)
	$(BIN)/python -m adron.write_schemas

# The documentation site into site/ (git-ignored); `make test` builds it too (tests/project/test_docs.py).
docs: $(STAMP)
	$(BIN)/python -m mkdocs build --strict

# ruff, and the import contracts of pyproject.toml (make test checks them too: tests/project/test_layers.py)
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports --no-logo

clean:
	rm -rf $(VENV) build *.egg-info web/node_modules
