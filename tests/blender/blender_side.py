"""What ``tests/test_blender.py`` runs inside Blender (the ``bpy`` wheel's Python, not mistyle's).

    python blender_side.py recipe JOB.json     # docs/usage.md's Blender recipe by hand, then a Cycles render
    python blender_side.py addon JOB.json      # install and enable the add-on, run its operator, render
    python blender_side.py addon_sequence JOB.json   # the add-on on a two-frame VDB sequence
    python blender_side.py addon_cache JOB.json      # the add-on on a real fluid cache: where its frames lie
    python blender_side.py profile JOB.json    # the density's mass along each world axis, read with OpenVDB 13

``JOB.json`` holds the inputs (paths, camera, sizes); the answers go to ``JOB["result"]`` as JSON. The
camera is mistyle's own, read from the ``scene.xml`` of the render to compare with and moved into
Blender's Z-up world, so both renders look at the medium from the same place.
"""

from __future__ import annotations

import json
import math
import os
import sys
import xml.etree.ElementTree as ElementTree

import bpy
import numpy as np
from mathutils import Matrix

Y_UP_TO_Z_UP = Matrix(((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1)))  # vdb_layout.up_axis_matrix("z")


def mistyle_camera(scene_xml: str) -> tuple[Matrix, float]:
    """The first sensor of mistyle's ``scene.xml`` as a Blender camera matrix (Z-up world) and its
    horizontal field of view in degrees. Mitsuba's camera looks along its +z with +x to the left;
    Blender's looks along -z with +x to the right."""
    sensor = ElementTree.parse(scene_xml).getroot().find("sensor")
    fov = float(sensor.find("float[@name='fov']").get("value"))
    assert sensor.find("string[@name='fov_axis']").get("value") == "x"
    values = [float(v) for v in sensor.find("transform/matrix").get("value").split()]
    to_world = Matrix([values[0:4], values[4:8], values[8:12], values[12:16]])
    flip = Matrix(((-1, 0, 0, 0), (0, 1, 0, 0), (0, 0, -1, 0), (0, 0, 0, 1)))
    return Y_UP_TO_Z_UP @ to_world @ flip, fov


def set_up_render(job: dict) -> None:
    """Camera, light and film as mistyle's render had them: its constant white environment, its view,
    the background hidden (transparent film); Cycles on the CPU with no denoiser."""
    scene = bpy.context.scene
    matrix, fov = mistyle_camera(job["scene_xml"])
    camera = bpy.data.objects.new("mistyle camera", bpy.data.cameras.new("mistyle camera"))
    scene.collection.objects.link(camera)
    camera.data.sensor_fit = "HORIZONTAL"
    camera.data.angle = math.radians(fov)
    camera.matrix_world = matrix
    scene.camera = camera
    world = bpy.data.worlds.new("mistyle light")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    background.inputs["Strength"].default_value = job["radiance"]
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = job["spp"]
    scene.cycles.use_denoising = False
    scene.render.film_transparent = True
    scene.render.resolution_x = scene.render.resolution_y = job["res"]
    scene.render.resolution_percentage = 100
    if job["image"].endswith(".png"):  # a picture to look at: Blender's own display transform
        scene.render.image_settings.file_format = "PNG"
        scene.render.image_settings.color_mode = "RGBA"
    else:
        scene.render.image_settings.file_format = "OPEN_EXR"
        scene.render.image_settings.color_depth = "32"


def render(path: str) -> None:
    bpy.context.scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def recipe(job: dict) -> dict:
    """docs/usage.md's Blender recipe, step by step, as a user clicks it."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    vdb = job["vdb"]
    # 1. File > Import > OpenVDB: volume.vdb
    bpy.ops.object.volume_import(filepath=vdb, directory=os.path.dirname(vdb), files=[{"name": os.path.basename(vdb)}])
    volume = bpy.context.active_object
    # 2. A new material (Principled Volume): Color white, Color Attribute Cd, Density the file's
    #    mistyle_world_density_scale, Density Attribute density.
    material = bpy.data.materials.new("Material")
    material.use_nodes = True
    nodes = material.node_tree.nodes
    nodes.clear()
    principled = nodes.new("ShaderNodeVolumePrincipled")
    output = nodes.new("ShaderNodeOutputMaterial")
    material.node_tree.links.new(principled.outputs["Volume"], output.inputs["Volume"])
    principled.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    principled.inputs["Color Attribute"].default_value = "Cd"
    principled.inputs["Density"].default_value = job["world_density_scale"]
    principled.inputs["Density Attribute"].default_value = "density"
    volume.data.materials.append(material)
    # 3. Render Properties > Light Paths > Max Bounces: Total and Volume 16.
    scene.cycles.max_bounces = 16
    scene.cycles.volume_bounces = 16
    # 4.-5. (the comparison's) mistyle's light and camera, transparent film.
    set_up_render(job)
    render(job["image"])
    volume.data.grids.load()
    return {"grids": sorted(grid.name for grid in volume.data.grids), "object": volume.name}


def install_addon(job: dict) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.extensions.package_install_files(filepath=job["addon_zip"], repo="user_default", enable_on_install=True)
    preferences = bpy.context.preferences.addons[job["addon_module"]].preferences
    preferences.command = job["command"]
    preferences.output = job["addon_out"]


def addon(job: dict) -> dict:
    """Install the add-on from its zip, run its operator on a volume object of ``job["input_vdb"]``,
    render the volume it adds."""
    install_addon(job)
    scene = bpy.context.scene
    source = bpy.data.objects.new("smoke", bpy.data.volumes.new("smoke"))
    source.data.filepath = job["input_vdb"]
    scene.collection.objects.link(source)
    bpy.context.view_layer.objects.active = source
    source.select_set(True)
    source.mistyle.style = job["style"]
    source.mistyle.quality = "FAST"
    result = bpy.ops.mistyle.stylize()
    added = [obj for obj in scene.objects if obj.type == "VOLUME" and obj is not source]
    answer = {"operator": sorted(result), "added": [obj.name for obj in added]}
    if len(added) != 1:
        return answer
    stylized = added[0]
    source.hide_render = True
    material = stylized.data.materials[0]
    principled = next(node for node in material.node_tree.nodes if node.bl_idname == "ShaderNodeVolumePrincipled")
    answer.update(
        colour=list(principled.inputs["Color"].default_value),
        colour_attribute=principled.inputs["Color Attribute"].default_value,
        density=principled.inputs["Density"].default_value,
        density_attribute=principled.inputs["Density Attribute"].default_value,
        linked=principled.outputs["Volume"].is_linked,
        volume_bounces=scene.cycles.volume_bounces,
        filepath=bpy.path.abspath(stylized.data.filepath),
        matrix_equal=stylized.matrix_world == source.matrix_world,
    )
    set_up_render(job)
    render(job["image"])
    # A bad input: the error is reported in Blender's UI and nothing is added.
    source.mistyle.style = job["missing_style"]
    try:
        failed = bpy.ops.mistyle.stylize()
    except RuntimeError as error:  # an operator's ERROR report raises in background mode
        failed = {"error": str(error)}
    answer["bad_input"] = failed if isinstance(failed, dict) else sorted(failed)
    answer["after_bad_input"] = len([obj for obj in scene.objects if obj.type == "VOLUME"])
    return answer


def stylized_sequence(job: dict, location=(0.0, 0.0, 0.0), quality: str | None = None):
    """Install the add-on, make a volume object of the VDB sequence ``job["frames"]`` (numbered from 1, as
    Blender's caches are) at ``location``, and run the add-on's operator on it over the scene's frame
    range: ``(scene, source, the operator's result, the volume objects it added)``."""
    install_addon(job)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, len(job["frames"])
    source = bpy.data.objects.new("fluid", bpy.data.volumes.new("fluid"))
    source.data.filepath = job["frames"][0]
    source.data.is_sequence = True
    source.data.frame_duration = len(job["frames"])
    source.location = location
    scene.collection.objects.link(source)
    bpy.context.view_layer.objects.active = source
    source.mistyle.style = job["style"]
    if quality is not None:
        source.mistyle.quality = quality
    result = bpy.ops.mistyle.stylize()
    added = [obj for obj in scene.objects if obj.type == "VOLUME" and obj is not source]
    return scene, source, result, added


def addon_sequence(job: dict) -> dict:
    """The add-on on a VDB sequence (``job["frames"]``, numbered from 1 as Blender's caches are) over the
    scene's frame range: one mistyle run, one new volume object that plays the stylized frames."""
    scene, source, result, added = stylized_sequence(job)
    answer = {"operator": sorted(result), "added": [obj.name for obj in added]}
    if len(added) == 1:
        volume = added[0].data
        answer.update(is_sequence=volume.is_sequence, frame_duration=volume.frame_duration, files=[])
        for frame in range(scene.frame_start, scene.frame_end + 1):
            scene.frame_set(frame)
            volume.grids.load()
            answer["files"].append(os.path.basename(volume.grids.frame_filepath))
    return answer


def density_voxels(path: str) -> tuple[np.ndarray, np.ndarray, float]:
    """``(positions (N, 3), densities (N,), voxel size)`` of the voxels of ``path``'s density grid that hold
    density, in the file's world space (read with the OpenVDB module the bpy wheel bundles)."""
    bpy.utils.expose_bundled_modules()
    import openvdb

    grid = openvdb.read(path, "density")
    low, high = grid.evalActiveVoxelBoundingBox()
    size = tuple(h - lo + 1 for lo, h in zip(low, high))
    dense = np.zeros(size, np.float32)
    grid.copyToArray(dense, ijk=low)
    i, j, k = np.nonzero(dense > 0)
    origin = np.array(grid.transform.indexToWorld(tuple(float(v) for v in low)))
    steps = [
        np.array(grid.transform.indexToWorld(tuple(float(v + (a == axis)) for a, v in enumerate(low)))) - origin
        for axis in range(3)
    ]
    world = origin + np.outer(i, steps[0]) + np.outer(j, steps[1]) + np.outer(k, steps[2])
    return world, dense[i, j, k], float(np.linalg.norm(steps[0]))


def addon_cache(job: dict) -> dict:
    """The add-on on a real Blender fluid cache (``job["frames"]``, a volume object moved away from the
    origin) over the scene's frame range, and where each frame's density lies in Blender's world: for
    the source and the stylized object at every frame, the density-weighted centre and the box of the
    voxels that hold density, through the object's matrix and the frame's own file."""
    scene, source, result, added = stylized_sequence(job, location=(1.5, -2.0, 0.5), quality="FAST")
    answer = {"operator": sorted(result), "added": [obj.name for obj in added], "frames": []}
    if len(added) != 1:
        return answer
    for frame in range(scene.frame_start, scene.frame_end + 1):
        scene.frame_set(frame)
        placed = {}
        for role, obj in (("source", source), ("stylized", added[0])):
            obj.data.grids.load()
            positions, densities, voxel = density_voxels(obj.data.grids.frame_filepath)
            matrix = np.array(obj.matrix_world)
            world = positions @ matrix[:3, :3].T + matrix[:3, 3]
            placed[role] = {
                "file": os.path.basename(obj.data.grids.frame_filepath),
                "centre": (densities @ world / densities.sum()).tolist(),
                "low": world.min(axis=0).tolist(),
                "high": world.max(axis=0).tolist(),
                "voxel": voxel,
                "translation": matrix[:3, 3].tolist(),
            }
        answer["frames"].append(placed)
    return answer


def profile(job: dict) -> dict:
    """Density mass per world-axis coordinate of ``job["vdb"]``'s density grid (read with the OpenVDB
    module the bpy wheel bundles): for each axis a histogram over the voxels' world positions."""
    world, mass, _ = density_voxels(job["vdb"])
    profiles = {}
    for axis, name in enumerate("xyz"):
        keys = np.round(world[:, axis], 6)
        values, inverse = np.unique(keys, return_inverse=True)
        profiles[name] = np.bincount(inverse, weights=mass).tolist()
    import openvdb  # bundled with the bpy wheel (density_voxels exposes it)

    return {"profiles": profiles, "openvdb": list(openvdb.LIBRARY_VERSION)}


if __name__ == "__main__":
    command, job_path = sys.argv[1], sys.argv[2]
    with open(job_path) as handle:
        job = json.load(handle)
    commands = {"recipe": recipe, "addon": addon, "addon_sequence": addon_sequence, "addon_cache": addon_cache}
    answer = {**commands, "profile": profile}[command](job)
    with open(job["result"], "w") as handle:
        json.dump(answer, handle)
