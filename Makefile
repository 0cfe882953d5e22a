# The two entry points of README.md. Each sets the machine up on first use.
PY := .venv/bin/python
STAMP := .venv/.mistyle-installed

BLENDER_STAMP := .venv-blender/.mistyle-installed

.PHONY: demo test test-all test-blender test-browser blender-addon bench-quick lint setup

demo: $(STAMP)
	$(PY) -m mistyle.demo

test: $(STAMP)
	$(PY) -m pytest -q

lint: $(STAMP)
	.venv/bin/ruff check .
	.venv/bin/ruff format --check .

test-all: $(STAMP)
	$(PY) -m pytest -q -m ''

# Blender itself (the bpy wheel in .venv-blender, Python 3.13): README's recipe, the add-on, OpenVDB 10 <-> 13.
test-blender: $(STAMP) $(BLENDER_STAMP)
	MISTYLE_BLENDER_PYTHON=.venv-blender/bin/python $(PY) -m pytest -q -s -m blender tests/test_blender.py

# mistyle-preview in headless Chromium (Debian's, driven by Playwright).
test-browser: $(STAMP)
	bash scripts/setup_browser.sh
	$(PY) -m pytest -q -s -m browser tests/test_preview_browser.py

# The Blender extension zip: build/mistyle_blender-<version>.zip
blender-addon: $(STAMP)
	$(PY) scripts/build_blender_addon.py

bench-quick: $(STAMP)
	$(PY) -m pytest -q -m benchmark

setup: $(STAMP)

$(STAMP): pyproject.toml scripts/setup.sh
	bash scripts/setup.sh

$(BLENDER_STAMP): scripts/setup_blender.sh
	bash scripts/setup_blender.sh
