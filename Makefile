# Every target creates .venv on a fresh machine (Python >= 3.11) and installs what it needs.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test bench lint clean web

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -q -e '.[test,bench]'
	touch $(STAMP)

# The block page's JavaScript (Blockly, three.js) from npm, pinned by web/package-lock.json,
# into web/node_modules (git-ignored); 'parmor blocks' copies what the page needs from there.
WEB_STAMP := web/node_modules/.installed

$(WEB_STAMP): web/package.json web/package-lock.json
	cd web && npm ci --no-audit --no-fund
	touch $(WEB_STAMP)

web: $(WEB_STAMP)

demo: $(STAMP) $(WEB_STAMP)
	$(BIN)/parmor abilities
	$(BIN)/parmor design walking --no-input || test $$? -eq 3
	$(BIN)/parmor design walking --answer grasping=yes
	$(BIN)/parmor design pick-and-place --param object_shape=oval --json
	$(BIN)/parmor design driving line-tracking obstacle-avoidance --out demo/cart --force
	$(BIN)/parmor run examples/square.py demo/cart
	$(BIN)/parmor blocks demo/cart

test: $(STAMP) $(WEB_STAMP)
	$(BIN)/python -m pytest

bench: $(STAMP)
	$(BIN)/python bench/bench.py

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

clean:
	rm -rf $(VENV) build *.egg-info web/node_modules
