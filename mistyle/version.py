"""mistyle's version, in a module of its own: the modules that record it in their files (checkpoints, VDB
metadata, generated data) import it from here, not from the package root above them."""

__version__ = "0.1.0"  # pyproject.toml's [project] version (tests/test_layout.py keeps the two equal)
