"""mistyle for Blender: give a volume object the look of a picture, and bring the result back wired.

Properties editor > Object Data (of a volume object) > mistyle. The add-on runs ``mistyle-render``
from mistyle's own environment as a subprocess (Preferences > Add-ons > mistyle: the command), on the
object's OpenVDB file, or on the scene's frame range of a VDB sequence, with ``--up z`` (Blender's
world is Z-up), and imports the ``volume.vdb`` it writes as a new volume object at the source's place.
Its material is the README's recipe (``wire_material``): a Principled Volume with Color white (it
multiplies the attribute), ``Cd`` as Color Attribute, ``density`` as Density Attribute and Density the
file's ``mistyle_world_density_scale``; Cycles' volume bounces are raised to ``MIN_VOLUME_BOUNCES``.

Progress goes to the status bar while mistyle runs; its one-line errors go to the info area. In
background mode (``blender -b``, ``bpy`` as a module) the operator waits for mistyle instead.
"""

from __future__ import annotations

import os
import queue
import re
import shutil
import subprocess
import tempfile
import threading
import time

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, PointerProperty, StringProperty

ALBEDO_ATTRIBUTE = "Cd"
DENSITY_ATTRIBUTE = "density"
DEFAULT_DENSITY_SCALE = 20.0
"""mistyle's default extinction per unit density in its medium box (longest side 1)."""
MIN_VOLUME_BOUNCES = 16
"""mistyle path traces full multiple scattering; Blender's default of 0 volume bounces leaves a faint haze."""
MATERIAL_NAME = "mistyle volume"
SUFFIX_DIGITS = re.compile(r"(\d+)$")


# ----------------------------------------------------------------------------- settings
def _package() -> str:
    return __package__ or __name__


class MistylePreferences(bpy.types.AddonPreferences):
    bl_idname = _package()

    command: StringProperty(
        name="mistyle-render",
        description="mistyle-render of mistyle's own environment, e.g. /opt/mistyle/.venv/bin/mistyle-render",
        subtype="FILE_PATH",
        default="mistyle-render",
    )
    output: StringProperty(
        name="Output folder",
        description="Where mistyle writes its outputs, one folder per object ('//' is the .blend's folder; "
        "an unsaved file uses the system's temporary folder)",
        subtype="DIR_PATH",
        default="//mistyle/",
    )

    def draw(self, context):
        self.layout.prop(self, "command")
        self.layout.prop(self, "output")


class MistyleSettings(bpy.types.PropertyGroup):
    style: StringProperty(name="Style", description="The style picture (PNG, JPEG or EXR)", subtype="FILE_PATH")
    style_2: StringProperty(
        name="Second style", description="Optional: a second picture mixed with the first", subtype="FILE_PATH"
    )
    mix: FloatProperty(
        name="Mix", description="The second style's share (0: the first style alone)", min=0.0, max=1.0, default=0.5
    )
    strength: FloatProperty(
        name="Strength", description="0: a uniform grey medium ... 1: the full style", min=0.0, max=1.0, default=1.0
    )
    look: StringProperty(
        name="Look",
        description="A look file (mistyle-render --save-look): applied to every frame instead of the style",
        subtype="FILE_PATH",
    )
    quality: EnumProperty(
        name="Quality",
        items=(
            ("FAST", "Fast", "The feed-forward network and colour match: seconds a frame (--refine 0)"),
            ("FULL", "Full", "mistyle-render's default: a look fitted on the frame or the sequence's key frames"),
        ),
        default="FAST",
    )
    density_scale: FloatProperty(
        name="Density scale",
        description="mistyle's extinction per unit density, in its medium box (longest side 1)",
        min=1e-3,
        max=1e6,
        default=DEFAULT_DENSITY_SCALE,
    )
    use_frame_range: BoolProperty(
        name="Scene frame range",
        description="For a VDB sequence: stylize the frames of the scene's range (else the current frame only)",
        default=True,
    )


# ----------------------------------------------------------------------------- the command
def volume_frames(volume, scene, use_frame_range: bool) -> list[tuple[int, str]]:
    """``[(scene frame, file)]`` to stylize: the volume's file, or the files of its sequence for the
    scene's frame range (or the current frame)."""
    path = bpy.path.abspath(volume.filepath)
    if not volume.is_sequence:
        return [(scene.frame_current, path)]
    folder, name = os.path.split(path)
    stem, extension = os.path.splitext(name)
    prefix = SUFFIX_DIGITS.sub("", stem)
    numbered = {}
    for other in os.listdir(folder or "."):
        other_stem, other_extension = os.path.splitext(other)
        match = SUFFIX_DIGITS.search(other_stem)
        if other_extension == extension and match and other_stem[: match.start()] == prefix:
            numbered[int(match.group(1))] = os.path.join(folder, other)
    frames = range(scene.frame_start, scene.frame_end + 1) if use_frame_range else [scene.frame_current]
    chosen = []
    for frame in frames:
        # Blender's mapping of a scene frame to a sequence file (Volume.frame_start, frame_offset).
        number = frame - volume.frame_start + 1 + volume.frame_offset
        if number in numbered:
            chosen.append((frame, numbered[number]))
    return chosen


def output_folder(preferences, obj) -> str:
    base = preferences.output
    if base.startswith("//") and not bpy.data.filepath:
        base = os.path.join(tempfile.gettempdir(), "mistyle_blender")
    return os.path.join(bpy.path.abspath(base), bpy.path.clean_name(obj.name))


def mistyle_command(preferences, settings, density: str, out: str) -> list[str]:
    """The ``mistyle-render`` command line for ``settings`` on ``density`` (a .vdb file or a folder)."""
    command = [bpy.path.abspath(preferences.command) if os.sep in preferences.command else preferences.command]
    command += ["--density", density]
    if settings.look:
        command += ["--look", bpy.path.abspath(settings.look)]
    elif settings.style_2 and settings.mix > 0:
        first, second = bpy.path.abspath(settings.style), bpy.path.abspath(settings.style_2)
        command += ["--mix", f"{first}:{1 - settings.mix:.6g}", f"{second}:{settings.mix:.6g}"]
    else:
        command += ["--style", bpy.path.abspath(settings.style)]
    if settings.strength < 1 and not settings.look:
        command += ["--strength", f"{settings.strength:.6g}"]
    command += ["--density-scale", f"{settings.density_scale:.6g}"]
    if settings.quality == "FAST":
        command += ["--refine", "0"]
    # Blender renders the result itself: mistyle's own check render is kept small.
    command += ["--up", "z", "--res", "128", "--spp", "16", "--out", out, "--overwrite"]
    return command


def check_inputs(settings, frames) -> str | None:
    """Why the operator cannot run (one line), or None."""
    if not frames:
        return "The volume has no OpenVDB file for these frames; load a .vdb file or sequence first."
    missing = [path for _, path in frames if not os.path.isfile(path)]
    if missing:
        return f"The volume's file {missing[0]} does not exist."
    if not frames[0][1].lower().endswith(".vdb"):
        return f"mistyle reads OpenVDB files; {os.path.basename(frames[0][1])} is not one."
    if not settings.look and not settings.style:
        return "Choose a style picture (or a look file) in the mistyle panel first."
    for path in (settings.look, settings.style, settings.style_2 if settings.mix > 0 else ""):
        if path and not os.path.isfile(bpy.path.abspath(path)):
            return f"{bpy.path.abspath(path)} does not exist."
    return None


# ----------------------------------------------------------------------------- the result
def file_world_density_scale(path: str) -> float | None:
    """``mistyle_world_density_scale`` from a mistyle ``.vdb``'s metadata, read with the OpenVDB module that
    Blender bundles; None where it cannot be read."""
    try:
        if hasattr(bpy.utils, "expose_bundled_modules"):
            bpy.utils.expose_bundled_modules()
        import openvdb

        value = openvdb.readMetadata(path)["mistyle_world_density_scale"]
        return float(value)
    except Exception:  # no bundled module, or not a mistyle file: the caller falls back
        return None


def wire_material(volume, density: float) -> bpy.types.Material:
    """The README's recipe: Principled Volume with Color white, ``Cd`` into Color, ``density`` into Density
    times ``density``; the material becomes the volume's only one."""
    material = bpy.data.materials.new(MATERIAL_NAME)
    if bpy.app.version < (5, 0, 0):  # node trees are always on from Blender 5
        material.use_nodes = True
    nodes = material.node_tree.nodes
    nodes.clear()
    output = nodes.new("ShaderNodeOutputMaterial")
    principled = nodes.new("ShaderNodeVolumePrincipled")
    principled.location = (-300, 0)
    principled.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)  # it multiplies the attribute
    principled.inputs["Color Attribute"].default_value = ALBEDO_ATTRIBUTE
    principled.inputs["Density"].default_value = density
    principled.inputs["Density Attribute"].default_value = DENSITY_ATTRIBUTE
    material.node_tree.links.new(principled.outputs["Volume"], output.inputs["Volume"])
    volume.materials.clear()
    volume.materials.append(material)
    return material


def import_result(context, source, out: str, frames: list[tuple[int, str]]) -> bpy.types.Object:
    """A new volume object of mistyle's output in ``out``, placed where ``source`` is."""
    if len(frames) == 1 and not source.data.is_sequence:
        files = [os.path.join(out, "volume.vdb")]
    else:
        files = sorted(
            os.path.join(out, name) for name in os.listdir(out) if name.startswith("volume") and name.endswith(".vdb")
        )
    if not files or not all(os.path.isfile(path) for path in files):
        raise RuntimeError(f"mistyle wrote no volume.vdb into {out}.")
    volume = bpy.data.volumes.new(f"{source.name} mistyle")
    volume.filepath = files[0]
    if len(files) > 1 or source.data.is_sequence:
        volume.is_sequence = True
        volume.frame_duration = len(files)
        volume.frame_start = frames[0][0]
        volume.frame_offset = -1  # files are numbered from 0: frame_start shows number 0
    density = file_world_density_scale(files[0])
    wire_material(volume, DEFAULT_DENSITY_SCALE if density is None else density)
    result = bpy.data.objects.new(volume.name, volume)
    result.matrix_world = source.matrix_world.copy()
    (source.users_collection[0] if source.users_collection else context.scene.collection).objects.link(result)
    cycles = getattr(context.scene, "cycles", None)
    if cycles is not None and cycles.volume_bounces < MIN_VOLUME_BOUNCES:
        cycles.volume_bounces = MIN_VOLUME_BOUNCES
        cycles.max_bounces = max(cycles.max_bounces, MIN_VOLUME_BOUNCES)
    return result


# ----------------------------------------------------------------------------- the operator
def _last_error(lines: list[str]) -> str:
    for line in reversed(lines):
        if line.strip():
            return line.strip()
    return "mistyle stopped without a message"


class MISTYLE_OT_stylize(bpy.types.Operator):
    """Stylize this volume with mistyle and add the result as a new volume object"""

    bl_idname = "mistyle.stylize"
    bl_label = "Stylize with mistyle"
    bl_options = {"REGISTER"}

    _process = None
    _timer = None

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == "VOLUME"

    def prepare(self, context):
        obj = context.object
        settings = obj.mistyle
        preferences = context.preferences.addons[_package()].preferences
        frames = volume_frames(obj.data, context.scene, settings.use_frame_range)
        problem = check_inputs(settings, frames)
        if problem is not None:
            return None, problem
        out = output_folder(preferences, obj)
        os.makedirs(os.path.dirname(out), exist_ok=True)
        if len(frames) == 1 and not obj.data.is_sequence:
            density = frames[0][1]
        else:
            # A folder that holds exactly the chosen frames, in order: mistyle reads a folder as a sequence.
            density = tempfile.mkdtemp(prefix="mistyle-frames-")
            for index, (_, path) in enumerate(frames):
                os.symlink(path, os.path.join(density, f"frame_{index:05d}.vdb"))
        self._source, self._out, self._frames, self._density = obj, out, frames, density
        return mistyle_command(preferences, settings, density, out), None

    def start(self, command):
        self._lines = []
        self._queue = queue.Queue()
        self._started = time.monotonic()
        environment = dict(os.environ, MISTYLE_PROGRESS="lines")
        for variable in ("PYTHONPATH", "PYTHONHOME"):  # Blender's, not mistyle's
            environment.pop(variable, None)
        self._process = subprocess.Popen(
            command,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=environment,
            text=True,
            bufsize=1,
        )
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        buffer = ""
        for chunk in iter(lambda: self._process.stdout.read(256), ""):
            buffer += chunk
            *complete, buffer = re.split(r"[\r\n]", buffer)
            for line in complete:
                if line.strip():
                    self._queue.put(line.strip())
        if buffer.strip():
            self._queue.put(buffer.strip())
        self._queue.put(None)

    def finish(self, context) -> set:
        if self._density != self._frames[0][1]:
            shutil.rmtree(self._density, ignore_errors=True)
        if self._process.returncode != 0:
            self.report({"ERROR"}, f"mistyle: {_last_error(self._lines)}")
            return {"CANCELLED"}
        try:
            result = import_result(context, self._source, self._out, self._frames)
        except RuntimeError as error:
            self.report({"ERROR"}, f"mistyle: {error}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"mistyle: added {result.name} from {self._out}")
        return {"FINISHED"}

    def execute(self, context):
        command, problem = self.prepare(context)
        if problem is not None:
            self.report({"ERROR"}, problem)
            return {"CANCELLED"}
        try:
            self.start(command)
        except OSError as error:
            self.report(
                {"ERROR"},
                f"Cannot run {command[0]} ({error.strerror}); set the mistyle-render command in the add-on's "
                "preferences.",
            )
            return {"CANCELLED"}
        if bpy.app.background:  # no event loop to poll from: wait
            while (line := self._queue.get()) is not None:
                self._lines.append(line)
            self._process.wait()
            return self.finish(context)
        self._timer = context.window_manager.event_timer_add(0.25, window=context.window)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._process.terminate()
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        done = False
        while not self._queue.empty():
            line = self._queue.get()
            if line is None:
                done = True
            else:
                self._lines.append(line)
        elapsed = time.monotonic() - self._started
        latest = self._lines[-1] if self._lines else "starting"
        context.workspace.status_text_set(f"mistyle ({elapsed:.0f} s, Esc to stop): {latest}")
        if not done:
            return {"RUNNING_MODAL"}
        self._process.wait()
        context.window_manager.event_timer_remove(self._timer)
        context.workspace.status_text_set(None)
        return self.finish(context)


class MISTYLE_PT_volume(bpy.types.Panel):
    bl_label = "mistyle"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == "VOLUME"

    def draw(self, context):
        settings = context.object.mistyle
        layout = self.layout
        layout.use_property_split = True
        layout.prop(settings, "look")
        column = layout.column()
        column.enabled = not settings.look
        column.prop(settings, "style")
        column.prop(settings, "style_2")
        row = column.row()
        row.enabled = bool(settings.style_2)
        row.prop(settings, "mix")
        column.prop(settings, "strength")
        column.prop(settings, "quality")
        layout.prop(settings, "density_scale")
        if context.object.data.is_sequence:
            layout.prop(settings, "use_frame_range")
        layout.operator(MISTYLE_OT_stylize.bl_idname, icon="BRUSH_DATA")


CLASSES = (MistylePreferences, MistyleSettings, MISTYLE_OT_stylize, MISTYLE_PT_volume)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Object.mistyle = PointerProperty(type=MistyleSettings)


def unregister():
    del bpy.types.Object.mistyle
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
