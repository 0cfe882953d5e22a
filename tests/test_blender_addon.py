"""The Blender add-on's package, without Blender (``make test-blender`` runs it in Blender itself)."""

import ast
import subprocess
import sys
import zipfile
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parent.parent


def test_the_extension_zip_has_its_manifest_at_the_root_and_mistyles_version(tmp_path):
    result = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "build_blender_addon.py"), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        check=True,
    )
    path = Path(result.stdout.strip())
    with zipfile.ZipFile(path) as archive:
        assert sorted(archive.namelist()) == ["__init__.py", "blender_manifest.toml"]
        manifest = tomllib.loads(archive.read("blender_manifest.toml").decode())
        source = archive.read("__init__.py").decode()
    from mistyle import __version__

    assert manifest["version"] == __version__ and path.name == f"mistyle_blender-{__version__}.zip"
    assert manifest["type"] == "add-on" and manifest["id"] == "mistyle" and manifest["license"]
    tree = ast.parse(source)  # valid Python; bpy is only there in Blender
    functions = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert {"register", "unregister", "wire_material", "mistyle_command"} <= functions


def test_the_add_on_runs_mistyle_render_with_blenders_up_axis():
    """The command the add-on builds asks for a Z-up volume.vdb with options mistyle-render has."""
    source = (ROOT / "integrations" / "blender" / "mistyle_blender" / "__init__.py").read_text()
    from mistyle.render_final import parser

    options = {string for action in parser()._actions for string in action.option_strings}
    used = {
        node.value
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.startswith("--")
    }
    assert used <= options, used - options
    assert '"--up", "z"' in source
