"""The path-traced scene as files a Mitsuba user opens: ``scene.xml`` beside ``density.vol`` and ``albedo.vol``.

``write_scene_files`` writes the grids with the medium box as their bounding box (``box.MediumBox``;
the box ``gridvolume``'s ``to_world`` also gives, since Mitsuba 3 places grids by ``to_world``) and
the scene of ``pathtraced.pathtraced_scene`` -- the same medium, light, integrator and cameras
(one sensor per view, ``mi.render(scene, sensor=i)``) -- as Mitsuba 3 XML with the grids, the
environment map and the coat mesh referenced by file names relative to the XML file:

    mitsuba -m llvm_ad_rgb scene.xml            # or mi.render(mi.load_file("scene.xml"), sensor=0)

``scene_xml`` turns any scene dictionary of that builder into XML (Mitsuba 3's Python package has
no writer of its own); ``tests/test_scene_export.py`` renders both and compares them.

The file holds one medium in the box. ``render_final`` path-traces through majorant bricks
(``scenes.bricks``) unless ``--bricks 0``: a render-time speed-up with the same image in
expectation, so ``scene.xml`` reproduces its final render up to Monte Carlo noise (bit for bit with
``--bricks 0``).
"""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .box import MediumBox

DENSITY_STEM, ALBEDO_STEM, SCENE_STEM = "density", "albedo", "scene"

# The XML element of each plugin type the scene builder uses (Mitsuba's plugin categories).
PLUGIN_TAGS = {
    "volpath": "integrator",
    "prbvolpath": "integrator",
    "constant": "emitter",
    "envmap": "emitter",
    "point": "emitter",
    "area": "emitter",
    "perspective": "sensor",
    "batch": "sensor",
    "cube": "shape",
    "ply": "shape",
    "rectangle": "shape",
    "heterogeneous": "medium",
    "isotropic": "phase",
    "null": "bsdf",
    "dielectric": "bsdf",
    "hdrfilm": "film",
    "box": "rfilter",
    "independent": "sampler",
    "gridvolume": "volume",
}


def _number(value: float) -> str:
    return f"{float(value):.9g}"  # 9 significant digits round-trip float32 exactly


def _element(name: str, value, top_level: bool = False) -> ET.Element:
    """The XML element of one scene-dictionary entry ``name: value``."""
    if isinstance(value, dict):
        kind = value["type"]
        if kind == "rgb":
            colour = np.broadcast_to(np.asarray(value["value"], dtype=np.float64), (3,))
            return ET.Element("rgb", name=name, value=", ".join(map(_number, colour)))
        if kind not in PLUGIN_TAGS:
            raise ValueError(f"No XML element known for the plugin type {kind!r} (entry {name!r}).")
        element = ET.Element(PLUGIN_TAGS[kind], type=kind, **({"id": name} if top_level else {"name": name}))
        for key, item in value.items():
            if key != "type":
                element.append(_element(key, item))
        return element
    if isinstance(value, bool):
        return ET.Element("boolean", name=name, value=str(value).lower())
    if isinstance(value, (int, np.integer)):
        return ET.Element("integer", name=name, value=str(int(value)))
    if isinstance(value, (float, np.floating)):
        return ET.Element("float", name=name, value=_number(value))
    if isinstance(value, (str, Path)):
        return ET.Element("string", name=name, value=str(value))
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) == 3:
        return ET.Element("point", name=name, value=", ".join(map(_number, value)))
    if hasattr(value, "matrix"):  # mi.ScalarTransform4f
        element = ET.Element("transform", name=name)
        ET.SubElement(
            element, "matrix", value=" ".join(map(_number, np.asarray(value.matrix, dtype=np.float64).ravel()))
        )
        return element
    raise ValueError(f"Cannot write the scene entry {name!r} of type {type(value).__name__} as XML.")


def scene_xml(scene: dict) -> str:
    """Mitsuba 3 XML of a scene dictionary (``{"type": "scene", ...}``) whose grids are files."""
    if scene.get("type") != "scene":
        raise ValueError("scene_xml takes a scene dictionary with type 'scene'.")
    root = ET.Element("scene", version="3.0.0")
    for key, value in scene.items():
        if key != "type":
            root.append(_element(key, value, top_level=True))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def write_medium_grid(path, grid: np.ndarray) -> Path:
    """A ``(Z, Y, X[, C])`` grid as a ``.vol`` whose bounding box is the medium box it fills."""
    from ..files import write_vol

    box = MediumBox(grid.shape[:3])
    return write_vol(path, grid, box.bbox_min, box.bbox_max)


def write_scene_files(
    folder,
    density: np.ndarray,
    albedo: np.ndarray,
    views,
    *,
    res: int,
    spp: int,
    max_depth: int,
    density_scale: float,
    light,
    coat_ior: float | None = None,
    coat_mesh: str | Path | None = None,
    suffix: str = "",
    albedo_name: str = ALBEDO_STEM,
) -> dict[str, Path]:
    """Write ``density{suffix}.vol``, ``{albedo_name}{suffix}.vol`` and ``scene{suffix}.xml`` into
    ``folder``; returns their paths (keys ``density``, ``albedo``, ``scene``).

    Args:
        density: ``(Z, Y, X)``; albedo: ``(Z, Y, X, 3)``: the grids that were path traced.
        views, res, spp, max_depth, density_scale, light, coat_ior: as ``pathtraced_scene``.
        coat_mesh: the coat's ``.ply``; copied into ``folder`` if it is not there already.
        suffix: tells a sequence's frames apart (``_frame0003``).
    """
    from ..files import atomic_write_bytes
    from .pathtraced import pathtraced_scene

    folder = Path(folder)
    names = {"density": f"{DENSITY_STEM}{suffix}.vol", "albedo": f"{albedo_name}{suffix}.vol"}
    paths = {key: write_medium_grid(folder / name, grid) for (key, name), grid in zip(names.items(), (density, albedo))}
    scene = pathtraced_scene(
        density,
        albedo,
        views,
        res=res,
        spp=spp,
        max_depth=max_depth,
        density_scale=density_scale,
        light=light,
        coat_ior=coat_ior,
        coat_mesh=coat_mesh,
    )
    medium = scene["medium_box"]["interior"]
    for key, name in (("sigma_t", names["density"]), ("albedo", names["albedo"])):
        del medium[key]["grid"]
        medium[key]["filename"] = name
    if coat_mesh is not None and "filename" in scene["medium_box"]:
        scene["medium_box"]["filename"] = _beside(Path(coat_mesh), folder)
    emitter = scene.get("environment", {})
    if emitter.get("type") == "envmap":
        emitter["filename"] = _beside(Path(emitter["filename"]), folder)
    paths["scene"] = atomic_write_bytes(folder / f"{SCENE_STEM}{suffix}.xml", scene_xml(scene).encode())
    return paths


def _beside(path: Path, folder: Path) -> str:
    """``path``'s name in ``folder``, copying the file there unless it is there already."""
    target = folder / path.name
    if path.resolve() != target.resolve():
        shutil.copyfile(path, target)
    return path.name
