"""Build the Blender extension of ``integrations/blender/mistyle_blender`` as a zip Blender installs
(Edit > Preferences > Get Extensions > Install from Disk): ``build/mistyle_blender-<version>.zip``.

    python scripts/build_blender_addon.py [--out FOLDER]

The extension's version is mistyle's (the manifest must say the same; the build checks).
"""

from __future__ import annotations

import argparse
import re
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SOURCE = ROOT / "integrations" / "blender" / "mistyle_blender"


def manifest_version() -> str:
    text = (SOURCE / "blender_manifest.toml").read_text()
    return re.search(r'^version = "([^"]+)"', text, re.M).group(1)


def project_version() -> str:
    return re.search(r'^version = "([^"]+)"', (ROOT / "pyproject.toml").read_text(), re.M).group(1)


def build(out: Path) -> Path:
    version = manifest_version()
    if version != project_version():
        raise SystemExit(
            f"error: the add-on's manifest says version {version} and mistyle is {project_version()}; "
            "make them agree in integrations/blender/mistyle_blender/blender_manifest.toml."
        )
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"mistyle_blender-{version}.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for file in sorted(SOURCE.iterdir()):
            if file.suffix in (".py", ".toml") and file.is_file():
                archive.write(file, file.name)  # the manifest at the zip's root, as Blender expects
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=ROOT / "build")
    print(build(parser.parse_args(argv).out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
