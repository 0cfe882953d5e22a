"""README.md's generated tables match the committed results, and its Python examples (and those of the
reference documents it sends readers to) run."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"```([A-Za-z0-9_+-]*)\s*$")

# Runs the blocks in order in one namespace, as a reader pastes them into one session; each block is
# compiled at its own lines of the document so that a traceback points there.
RUN_BLOCKS = """
import json, sys
namespace = {"__name__": "__main__"}
for line, source in json.load(sys.stdin):
    exec(compile("\\n" * line + source, sys.argv[1], "exec"), namespace)
"""
DOCUMENTS = ("README.md", "docs/usage.md", "docs/architecture.md")
"""The documents whose ```python blocks are run, each in an interpreter of its own."""


def python_blocks(text: str) -> list[tuple[int, str]]:
    """``(line index of the first line, source)`` of each ```python block; an AssertionError for a fence
    line that neither opens nor closes a block (a closing fence with text after it runs on)."""
    blocks, opened, language, lines = [], None, "", text.splitlines()
    for index, line in enumerate(lines):
        if not line.startswith("```"):
            continue
        match = FENCE.fullmatch(line)
        assert match, f"README.md:{index + 1}: a fence line holds more than ``` and a language: {line!r}"
        if opened is None:
            opened, language = index, match.group(1)
        else:
            assert not match.group(1), f"README.md:{index + 1}: a block opens inside the block of line {opened + 1}"
            if language == "python":
                blocks.append((opened + 1, "\n".join(lines[opened + 1 : index]) + "\n"))
            opened = None
    assert opened is None, f"README.md:{opened + 1}: the block never closes"
    return blocks


def test_readme_tables_are_generated_from_the_results():
    result = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "readme_tables.py"), "--check"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("document", DOCUMENTS)
def test_readme_fences_open_and_close(document):
    assert python_blocks((ROOT / document).read_text())


@pytest.mark.parametrize("document", DOCUMENTS)
def test_readme_python_examples_run(tmp_path, document):
    """Every ```python block of ``document``, in order, in a fresh interpreter whose working folder holds
    only links to the examples' inputs (``examples/``), so the files the examples write land in ``tmp_path``."""
    blocks = python_blocks((ROOT / document).read_text())
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    result = subprocess.run(
        [sys.executable, "-c", RUN_BLOCKS, document],
        input=json.dumps(blocks),
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-3000:]


def test_readme_stays_a_front_page():
    """README.md is the way in (the commands, the quick start, where quality stands); the reference lives in
    docs/, which it links."""
    assert len((ROOT / "README.md").read_text().splitlines()) <= 250
