# The two entry points of README.md. Each sets the machine up on first use.
PY := .venv/bin/python
STAMP := .venv/.mistyle-installed

.PHONY: demo test test-all bench-quick lint setup

demo: $(STAMP)
	$(PY) -m mistyle.demo

test: $(STAMP)
	$(PY) -m pytest -q

lint: $(STAMP)
	.venv/bin/ruff check .
	.venv/bin/ruff format --check .

test-all: $(STAMP)
	$(PY) -m pytest -q -m ''

bench-quick: $(STAMP)
	$(PY) -m pytest -q -m benchmark

setup: $(STAMP)

$(STAMP): pyproject.toml scripts/setup.sh
	bash scripts/setup.sh
