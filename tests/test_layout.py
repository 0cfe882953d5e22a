"""The package map of README.md, enforced: imports flow one way and inference never needs training."""

import ast
from pathlib import Path

import pytest

import mistyle

ROOT = Path(mistyle.__file__).parent
# A unit may import units of a lower layer only (or itself). Same as the map in README.md.
LAYERS = [
    {"conventions", "version"},
    {"tone", "volume", "warp", "resample", "backend", "progress", "stops", "memo"},
    {"files", "ownership", "advection"},
    {"scenes", "pages", "outputs", "style"},
    {"integrators"},
    {"bridge_torch", "reference_torch", "pathtrace", "denoise", "adam"},
    {"model", "objective"},
    {"fit", "response", "data", "solid_texture"},
    {"colour_match"},
    {"stylizer"},
    {"look"},
    {"pipeline"},
    {"api", "benchmark", "job"},
    {"render_final", "train"},
    {"demo", "farm", "preview"},
]
RANK = {unit: rank for rank, units in enumerate(LAYERS) for unit in units}
INFERENCE = ("stylizer", "look", "pipeline", "api", "benchmark", "job", "render_final", "demo", "farm", "preview")


def unit_of(module: str) -> str:
    return module.split(".")[1] if "." in module else module


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path) -> set[str]:
    """Every mistyle module ``path`` imports, at module level or inside functions."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name.startswith("mistyle.")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target == "mistyle":  # `from mistyle import x` or `from . import x` at the top
                found |= {f"mistyle.{alias.name}" for alias in node.names}
            elif target.startswith("mistyle."):
                found.add(target)
    return found


def unit_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for path in ROOT.rglob("*.py"):
        if path == ROOT / "__init__.py":
            continue  # the lazy public attributes (mistyle.stylize, ...) point at api by design
        source = unit_of(module_name(path))
        for target in imports_of(path):
            graph.setdefault(source, set()).add(unit_of(target))
    return graph


def test_every_unit_has_a_layer():
    units = {unit_of(module_name(p)) for p in ROOT.rglob("*.py") if p != ROOT / "__init__.py"}
    assert units <= RANK.keys(), f"add {sorted(units - RANK.keys())} to LAYERS and README's package map"


def test_imports_only_go_down_the_layers():
    upward = sorted(
        (source, target)
        for source, targets in unit_graph().items()
        for target in targets
        if target in RANK and target != source and RANK[target] >= RANK[source]
    )
    assert not upward, f"imports that go up or sideways: {upward}"


def test_inference_never_reaches_the_training_package():
    graph = unit_graph()
    for start in INFERENCE:
        seen, todo = set(), [start]
        while todo:
            unit = todo.pop()
            if unit not in seen:
                seen.add(unit)
                todo += graph.get(unit, ())
        assert "train" not in seen or start == "train", f"{start} reaches mistyle.train"


def module_imports(path: Path, modules: set[str]) -> set[str]:
    """The mistyle modules ``path`` imports, at module level or inside functions: ``from .pkg import mod``
    names the module ``mod``, ``from .mod import name`` the module ``mod``."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name in modules}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                target = ".".join(base[: len(base) - node.level + 1] + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                if f"{target}.{alias.name}" in modules:
                    found.add(f"{target}.{alias.name}")
                elif target in modules:
                    found.add(target)
    return found - {name}


def test_no_module_imports_itself_back():
    """Within a unit too, imports flow one way: no cycle of modules (a cycle ties their load order and
    their tests together). The package root, whose public names load ``api`` lazily, is left out."""
    paths = {module_name(p): p for p in ROOT.rglob("*.py") if p != ROOT / "__init__.py"}
    modules = set(paths)
    edges = {name: module_imports(path, modules) for name, path in paths.items()}
    state, cycles = {}, []

    def visit(module, trail):
        state[module] = "open"
        for target in sorted(edges[module]):
            if state.get(target) == "open":
                cycles.append(trail[trail.index(target) :] + [target])
            elif target not in state:
                visit(target, trail + [target])
        state[module] = "done"

    for module in sorted(edges):
        if module not in state:
            visit(module, [module])
    assert not cycles, f"import cycles: {cycles}"


def test_the_version_is_the_projects():
    import tomllib

    project = tomllib.loads((ROOT.parent / "pyproject.toml").read_text())["project"]
    assert mistyle.__version__ == project["version"]


MAX_FUNCTION_LINES = 120
"""A function longer than this is split into parts that each say what they do (issue #50)."""


def test_no_function_of_the_package_is_longer_than_a_screenful_or_two():
    long = []
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{path.relative_to(ROOT.parent)}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {', '.join(long)}"


MAX_MODULE_LINES = 600
"""A module longer than this holds more than one role: split it by role (issue #50)."""


def test_no_module_of_the_package_is_longer_than_one_role():
    long = [
        f"{path.relative_to(ROOT.parent)} ({lines} lines)"
        for path in sorted(ROOT.rglob("*.py"))
        if (lines := len(path.read_text().splitlines())) > MAX_MODULE_LINES
    ]
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {', '.join(long)}"


def test_the_checkout_travels_to_a_gpu_machine():
    """At most 64 MiB reach a lent GPU machine, the packed Mitsuba and Dr.Jit (``pack.sh``) about 22 of
    them: the tracked files stay under 35 MiB. Figures of renders are JPEGs; checkpoints only a recipe
    starts from are recovered from history, not kept in the tree."""
    import subprocess

    listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT.parent, capture_output=True, text=True)
    if listed.returncode != 0:
        pytest.skip("not a git checkout")
    tracked = [ROOT.parent / name for name in listed.stdout.split("\0") if name]
    size = sum(path.stat().st_size for path in tracked if path.is_file())
    assert size <= 35 * 2**20, f"the tracked files are {size / 2**20:.1f} MiB"
