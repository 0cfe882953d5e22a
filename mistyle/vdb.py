"""OpenVDB (``.vdb``) input and output: densities in, densities and albedos out.

The route. OpenVDB's Python bindings 10 (Boost.Python, ``pyopenvdb``) to 13 (nanobind, ``openvdb``) all
work (``vdb_convert.openvdb_module``), but each is built for one interpreter and its numpy: Debian's
``python3-openvdb`` for the system Python and numpy 1.x, the one the ``bpy`` wheel bundles for Python
3.13. mistyle therefore runs ``mistyle/vdb_convert.py`` -- a standalone script that imports nothing
from mistyle -- under an interpreter that has a binding, and the two exchange ``.npy`` arrays and a JSON
sidecar through a temporary folder. ``vdb_interpreter`` finds that interpreter, in this order:
``$MISTYLE_VDB_PYTHON`` if set (the user's choice, always a subprocess); this Python, in-process, when
a binding (or ``bpy``'s bundled one) loads with its numpy; ``/usr/bin/python3`` (Debian's); ``python3``
on the PATH. Without one, ``VdbUnavailable`` names the fix.

Conventions:

* arrays use mistyle's layout, ``arr[z, y, x]`` (``(Z, Y, X)``) and ``(Z, Y, X, 3)`` for colours
  (``mistyle.scenes.box``); OpenVDB's index coordinates are ``(i, j, k) = (x, y, z)``, so array element
  ``[z, y, x]`` is voxel ``index_min + (x, y, z)``;
* OpenVDB puts voxel centres at integer index coordinates, so the cells of a ``(Z, Y, X)`` array cover
  the index box ``index_min - 0.5 .. index_min + (X, Y, Z) - 0.5``;
* ``VdbTransform.matrix`` is the index-to-world 4x4 acting on COLUMN vectors, ``world = matrix @ (i, j,
  k, 1)``, translation in ``matrix[:3, 3]`` -- the convention of ``MediumBox.unit_to_world_matrix`` and
  Mitsuba's ``to_world``. (OpenVDB's own ``Mat4`` acts on row vectors, its transpose; the converter's
  ``meta.json`` stores that, and this module transposes at the boundary.)

Round trips are exact: float32 values are copied bit for bit, voxels equal to zero stay inactive
(OpenVDB's background, so files stay sparse) and read back as zero, and the array's own index box is
recorded in each grid's metadata, so ``read_vdb`` gives back the written shape even when the margins are
empty. The matrix is stored as doubles and comes back bit for bit, scale-and-translate and rotated
alike (``vdb_convert.linear_transform`` and ``index_to_world_matrix`` say how; an ulp at worst). Files
from other tools read as the bounding box of their active voxels.

Files as DCCs write them: a file's grids -- names, types, classes, transforms, metadata -- are listed in
Python from its header (``check_vdb_layout``, ``vdb_info``; no binding needed), and only the grid asked
for is read with the binding, so grids of types the binding cannot read (Debian's OpenVDB 10 knows float,
bool and vec3s; Blender's Mantaflow cache also holds an int32 'flags' grid) never stop a read.
``mistyle-vdb FILE`` (``main``) prints what a file holds. Sequences whose active box changes from frame
to frame are lined up in ``io.load_density_frames``, which also reads their velocities with
``read_vdb_frame`` (``find_velocity`` says which grid and in which units; ``VdbVelocity.at`` samples it
at a density's voxels as world displacement per frame; ``world_to_index`` gives the voxels per frame of
``mistyle.warp``).

Up axes: mistyle renders with +y up. ``upright`` turns a grid read from a Z-up world (Blender) so that
its y axis is that world's up, with the transform that keeps every voxel in place, and
``VdbTransform.for_medium_box(shape, "z")`` places mistyle's box in such a world; ``mistyle_metadata`` is
what mistyle's files say of themselves (density scales, up axis, units, albedo, style, version).

Grid names: ``DENSITY_GRID`` ('density', class fog volume) is what Blender, Houdini and most renderers
look for. The albedo is written only as ``ALBEDO_GRID`` ('Cd', a vec3 grid of linear RGB single-scattering
albedo in [0, 1]), Houdini's name for colour fields: Houdini's Volume Visualization picks it up as its
diffuse field; in Blender, type ``Cd`` into the Principled Volume node's Color Attribute with its Color
white (README's recipe; the add-on in ``integrations/blender`` wires it).
"""

from __future__ import annotations

import functools
import json
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .conventions import UP_AXES

DENSITY_GRID = "density"
ALBEDO_GRID = "Cd"
INTERPRETER_ENV = "MISTYLE_VDB_PYTHON"
CONVERTER = Path(__file__).with_name("vdb_convert.py")

_PROBE_TIMEOUT_S = 120  # a cold import of numpy on a busy machine can take a while


class VdbUnavailable(ValueError):
    """No Python interpreter here can import OpenVDB's module; the message says how to get one."""


@dataclass(frozen=True)
class VdbTransform:
    """Where a grid sits: the index-to-world matrix and the index of array element ``[0, 0, 0]``.

    ``matrix``: 4x4 float64 acting on column vectors, ``world = matrix @ (i, j, k, 1)``.
    ``index_min``: ``(i, j, k) = (x, y, z)`` index of ``arr[0, 0, 0]``.
    """

    matrix: np.ndarray
    index_min: tuple[int, int, int] = (0, 0, 0)

    def __post_init__(self):
        matrix = np.array(self.matrix, dtype=np.float64)
        if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)):
            raise ValueError(f"A VDB transform needs a finite 4x4 index-to-world matrix, got shape {matrix.shape}.")
        if not np.array_equal(matrix[3], [0.0, 0.0, 0.0, 1.0]):
            raise ValueError(
                "The index-to-world matrix must be affine (last row 0, 0, 0, 1; column vectors, "
                f"translation in matrix[:3, 3]), got last row {matrix[3].tolist()}."
            )
        if np.linalg.cond(matrix[:3, :3]) > 1e12:
            raise ValueError("The index-to-world matrix is singular; voxels need a non-zero size along every axis.")
        index_min = tuple(self.index_min)
        if len(index_min) != 3 or not all(float(v).is_integer() for v in index_min):
            raise ValueError(f"index_min must be three integers (i, j, k), got {self.index_min}.")
        matrix.flags.writeable = False  # frozen means frozen
        object.__setattr__(self, "matrix", matrix)
        object.__setattr__(self, "index_min", tuple(int(v) for v in index_min))

    def __eq__(self, other):
        if not isinstance(other, VdbTransform):
            return NotImplemented
        return self.index_min == other.index_min and np.array_equal(self.matrix, other.matrix)

    def __hash__(self):
        return hash((self.index_min, self.matrix.tobytes()))

    @property
    def voxel_size(self) -> np.ndarray:
        """World length of one voxel step along ``i``, ``j`` and ``k`` (= x, y, z), shape ``(3,)``."""
        return np.linalg.norm(self.matrix[:3, :3], axis=0)

    def index_to_world(self, points_xyz) -> np.ndarray:
        """World positions ``(..., 3)`` of index coordinates ``(..., 3)`` ordered ``(i, j, k) = (x, y, z)``."""
        points = np.asarray(points_xyz, dtype=np.float64)
        if points.shape[-1:] != (3,):
            raise ValueError(f"Index coordinates are (..., 3) arrays ordered (i, j, k), got shape {points.shape}.")
        return points @ self.matrix[:3, :3].T + self.matrix[:3, 3]

    def voxel_centre(self, x: float, y: float, z: float) -> np.ndarray:
        """World position ``(3,)`` of the centre of array element ``arr[z, y, x]``."""
        return self.index_to_world(np.add(self.index_min, (x, y, z)))

    def world_bbox(self, shape_zyx) -> tuple[np.ndarray, np.ndarray]:
        """World-axis-aligned ``(min, max)`` corners (each ``(3,)``) around the cells of a ``(Z, Y, X)`` array.

        Voxel centres sit at integer index coordinates, so the cells span ``index_min - 0.5`` to
        ``index_max + 0.5``; a rotated grid gives the box around its eight corners.
        """
        size_xyz = np.array(_shape3(shape_zyx)[::-1], dtype=np.float64)
        low = np.array(self.index_min, dtype=np.float64) - 0.5
        corners = np.array([[low[a] + size_xyz[a] * bit for a, bit in enumerate(bits)] for bits in np.ndindex(2, 2, 2)])
        world = self.index_to_world(corners)
        return world.min(axis=0), world.max(axis=0)

    @classmethod
    def for_medium_box(cls, shape_zyx, up: str = "y") -> VdbTransform:
        """The transform that puts a ``(Z, Y, X)`` grid where mistyle renders it (``mistyle.scenes.box``).

        The medium box is centred at the origin with its longest side 1 and cubic voxels of side
        ``1 / max(Z, Y, X)``; the centre of ``arr[z, y, x]`` is ``bbox_min + (x + 0.5, y + 0.5, z + 0.5) *
        voxel_size``. For densities that came from a file without a transform of its own. ``up``: the
        world up axis of the scene the file goes to (``up_axis_matrix``): mistyle's up (+y) becomes it.
        """
        z, y, x = _shape3(shape_zyx)
        voxel = 1.0 / max(z, y, x)
        bbox_min = -0.5 * voxel * np.array([x, y, z], dtype=np.float64)
        matrix = np.diag([voxel, voxel, voxel, 1.0])
        matrix[:3, 3] = bbox_min + 0.5 * voxel
        return cls(up_axis_matrix(up) @ matrix, (0, 0, 0))


def up_axis_matrix(up: str) -> np.ndarray:
    """4x4 (column vectors) from mistyle's world (+y up, the camera orbit's axis) to a world whose up
    axis is ``up`` (``conventions.UP_AXES``): the identity for ``y``; for ``z`` (Blender) the rotation of
    +90 degrees about x, ``(x, y, z) -> (x, -z, y)``, so mistyle's front view (from +z) looks along +y in
    the new world, Blender's front. Entries are 0 and +-1, so it moves a matrix without rounding."""
    if up == "y":
        return np.eye(4)
    if up == "z":
        return np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    raise ValueError(f"The up axis is one of {', '.join(UP_AXES)}, got {up!r}.")


def upright(array: np.ndarray, transform: VdbTransform, up: str) -> tuple[np.ndarray, VdbTransform]:
    """``array`` (``(Z, Y, X)`` or ``(Z, Y, X, 3)``, as read) turned so that its Y axis, the one mistyle
    renders as up, is the index axis that points most along the world's ``up`` axis, and the transform
    that keeps every voxel where it was in the world.

    The turn is a proper rotation of the index axes (the image is not mirrored): the chosen axis becomes
    j, and of the other two the first in i, j, k order becomes i. Files whose j axis already points up
    come back unchanged (the same objects). The array is copied, not resampled, so values are exact.
    """
    world_up = up_axis_matrix(up)[:3, 1]
    linear = transform.matrix[:3, :3]
    alignment = world_up @ linear  # per index axis i, j, k: its world direction's component along up
    axis = int(np.argmax(np.abs(alignment)))
    sign = 1 if alignment[axis] > 0 else -1
    if axis == 1 and sign > 0:
        return array, transform
    # Columns: the old index axes that the new i, j, k run along (signed unit vectors).
    new_to_old = np.zeros((3, 3))
    new_to_old[axis, 1] = sign
    first = min(a for a in range(3) if a != axis)
    new_to_old[first, 0] = 1.0
    new_to_old[:, 2] = np.cross(new_to_old[:, 0], new_to_old[:, 1])
    size_ijk = np.array(array.shape[:3][::-1])
    # Array axes in (i, j, k) order first: element [z, y, x] is index (x, y, z).
    vector = array.ndim == 4
    ijk = array.transpose((2, 1, 0, 3) if vector else (2, 1, 0))
    order = [int(np.flatnonzero(new_to_old[:, n])[0]) for n in range(3)]
    turned = ijk.transpose(order + ([3] if vector else []))
    flips = tuple(n for n in range(3) if new_to_old[order[n], n] < 0)
    if flips:
        turned = np.flip(turned, axis=flips)
    turned = np.ascontiguousarray(turned.transpose((2, 1, 0, 3) if vector else (2, 1, 0)))
    # New local index n maps to old index index_min + new_to_old @ n + offset (offset: the flipped axes' far end).
    offset = np.zeros(3)
    for n in flips:
        offset[order[n]] = size_ijk[order[n]] - 1
    to_old = np.eye(4)
    to_old[:3, :3] = new_to_old
    to_old[:3, 3] = np.asarray(transform.index_min, dtype=np.float64) + offset
    return turned, VdbTransform(transform.matrix @ to_old, (0, 0, 0))


def _shape3(shape_zyx) -> tuple[int, int, int]:
    shape = tuple(int(n) for n in shape_zyx)
    if len(shape) != 3 or min(shape) < 1:
        raise ValueError(f"A grid shape is (Z, Y, X) with every size >= 1, got {tuple(shape_zyx)}.")
    return shape


# ----------------------------------------------------------------------------- what mistyle's files say
UP_AXIS_KEY = "mistyle_up_axis"


def mistyle_metadata(
    transform: VdbTransform, shape_zyx, *, density_scale: float, up: str, style: str, checkpoint: str
) -> dict:
    """The metadata mistyle writes on ``volume.vdb`` (file and grids): what a Blender or Houdini user
    needs to render the medium as mistyle did. ``shape_zyx``: the grids' array shape.

    ``mistyle_density_scale`` is mistyle's, per unit of its medium box (longest side 1);
    ``mistyle_world_density_scale`` is the same extinction per unit of the file's world, what to type into
    Blender's Principled Volume Density or Houdini's density scale (``sigma_t = it * density``)."""
    from .version import __version__

    voxel = transform.voxel_size
    longest = float(np.max(np.array(_shape3(shape_zyx)[::-1]) * voxel))
    return {
        "mistyle_version": __version__,
        "mistyle_style": style,
        "mistyle_checkpoint": checkpoint,
        "mistyle_density_scale": float(density_scale),
        "mistyle_world_density_scale": float(density_scale) / longest,
        "mistyle_albedo": f"'{ALBEDO_GRID}' is the single-scattering albedo, linear RGB in [0, 1]",
        UP_AXIS_KEY: up,
        "mistyle_units": f"world units of the transform; the medium's longest side is {longest:.6g} of them",
    }


def recorded_up_axis(file_metadata: dict) -> str:
    """The up axis a file mistyle wrote records, else ``y`` (OpenVDB's and Houdini's convention)."""
    up = str(file_metadata.get(UP_AXIS_KEY, "y")).lower()
    return up if up in UP_AXES else "y"


# ----------------------------------------------------------------------------- finding the binding
@dataclass(frozen=True)
class _Route:
    python: str
    in_process: bool
    clean_env: bool  # run it without our PYTHONPATH/PYTHONHOME (not for an interpreter the user named)

    def env(self) -> dict | None:
        return _clean_env() if self.clean_env else None


def _clean_env() -> dict:
    """Our environment without the variables that would point another Python at our packages."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}


def _probe(python: str, env: dict | None) -> str | None:
    """``None`` if ``python`` loads numpy and an OpenVDB binding (``vdb_convert.openvdb_module``), else why not."""
    try:
        result = subprocess.run(
            [python, str(CONVERTER), "probe"],
            check=False,
            capture_output=True,
            text=True,
            timeout=_PROBE_TIMEOUT_S,
            env=env,
            stdin=subprocess.DEVNULL,
        )
    except (OSError, subprocess.SubprocessError) as error:
        return f"cannot run it ({error})"
    if result.returncode == 0:
        return None
    lines = result.stderr.strip().splitlines()
    return lines[-1].removeprefix("error: ") if lines else f"exit status {result.returncode}"


def _import_in_process() -> bool:
    from . import vdb_convert

    try:
        vdb_convert.openvdb_module()
    except Exception:  # ConvertError, or a binding built against another numpy failing at load
        return False
    return True


@functools.cache
def _find_route(override: str | None) -> _Route:
    """The interpreter to run the converter with; cached per value of ``$MISTYLE_VDB_PYTHON``."""
    fix = (
        "Install OpenVDB's Python module with `apt-get install python3-openvdb` (Debian/Ubuntu; `make setup` "
        f"tries this), or set {INTERPRETER_ENV} to a Python interpreter that can `import pyopenvdb` (or "
        "`openvdb`) and numpy."
    )
    if override:
        python = shutil.which(override) or override
        why = _probe(python, None)
        if why is not None:
            raise VdbUnavailable(f"{INTERPRETER_ENV}={override} cannot load OpenVDB's module ({why}). {fix}")
        return _Route(python, False, False)
    tried = []
    candidates = [sys.executable, "/usr/bin/python3", shutil.which("python3")]
    for python in candidates:
        if not python or any(os.path.realpath(python) == os.path.realpath(t) for t in tried):
            continue
        tried.append(python)
        if _probe(python, _clean_env()) is not None:
            continue
        # Only after a subprocess proved the binding loads: a binding built for another numpy can
        # abort the interpreter that imports it, and this one is ours.
        if python == sys.executable and _import_in_process():
            return _Route(python, True, False)
        return _Route(python, False, True)
    raise VdbUnavailable(
        "Reading and writing OpenVDB (.vdb) files needs OpenVDB's Python module, and no "
        f"interpreter here has it (tried {', '.join(tried)}). {fix}"
    )


def vdb_interpreter() -> str:
    """The Python interpreter that reads and writes ``.vdb`` files for mistyle (this one when in-process).

    Raises:
        VdbUnavailable: no interpreter can import OpenVDB's module; the message names the fix.
    """
    return _find_route(os.environ.get(INTERPRETER_ENV) or None).python


def _run_converter(route: _Route, *args: str) -> None:
    """Run ``vdb_convert.py`` with ``args``; its one-line error becomes a ``ValueError``."""
    try:
        result = subprocess.run(
            [route.python, str(CONVERTER), *args],
            check=False,
            capture_output=True,
            text=True,
            env=route.env(),
            stdin=subprocess.DEVNULL,
        )
    except OSError as error:
        raise VdbUnavailable(
            f"Cannot run the OpenVDB interpreter {route.python} ({error}); set {INTERPRETER_ENV} "
            "to a Python with OpenVDB's module."
        ) from None
    if result.returncode == 0:
        return
    lines = [line for line in result.stderr.strip().splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error: ")]
    if result.returncode == 2 and errors:
        raise ValueError(errors[-1][len("error: ") :])
    how = (
        f"was killed by signal {-result.returncode}"
        if result.returncode < 0
        else f"stopped with exit status {result.returncode}"
    )
    raise ValueError(
        f"The OpenVDB converter ({route.python} {CONVERTER.name}) {how}: {lines[-1] if lines else 'no message'}."
    )


def _convert_in_process(function, *args):
    from . import vdb_convert

    try:
        return getattr(vdb_convert, function)(*args)
    except vdb_convert.ConvertError as error:
        raise ValueError(str(error)) from None


def _existing_file(path) -> tuple[Path, dict]:
    """``path`` and what its header says (``check_vdb_layout``), or ``ValueError`` naming the file."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"VDB file {path} does not exist.")
    if not path.is_file():
        raise ValueError(f"VDB file {path} is not a file.")
    return path, check_vdb_layout(path)


def check_vdb_layout(path) -> dict:
    """What ``path``'s header, grid descriptors and each grid's metadata and transform say
    (``vdb_convert.scan_file``: every grid of every type, read in Python, no voxel read and no binding
    needed), or ``ValueError`` unless the file is an OpenVDB file whose declared sizes and offsets lie
    inside it.

    OpenVDB trusts those sizes: a string length or an offset read past the end of a truncated file makes
    it allocate that many bytes, gigabytes for a minute over a file of a few kilobytes before its error.
    Reading the grid list here rather than with the binding is also what lets a file hold grids the
    binding cannot read (a Blender Mantaflow cache's int32 'flags' grid, for Debian's OpenVDB 10)."""
    from . import vdb_convert

    try:
        return vdb_convert.scan_file(os.fspath(path))
    except vdb_convert.ConvertError as error:
        raise ValueError(str(error)) from None
    except OSError as error:
        raise ValueError(f"Cannot read {path}: {error.strerror}.") from None


# ----------------------------------------------------------------------------- reading
class VdbGrid(NamedTuple):
    """``read_vdb_grid``'s result."""

    array: np.ndarray  # (Z, Y, X) or (Z, Y, X, 3) float32
    transform: VdbTransform
    name: str
    file_metadata: dict  # the file's metadata (``write_vdb``'s ``metadata``; mistyle's keys in ``METADATA_KEYS``)


def read_vdb(path, grid: str | None = None) -> tuple[np.ndarray, VdbTransform, str]:
    """``(array, transform, grid_name)`` of ``read_vdb_grid``."""
    return read_vdb_grid(path, grid)[:3]


def read_vdb_grid(path, grid: str | None = None) -> VdbGrid:
    """Read one grid of a ``.vdb`` file as a dense array: ``(array, transform, grid_name)``.

    The grid is ``grid`` if given (a float grid reads as ``(Z, Y, X)``, a vec3 grid such as 'Cd' as
    ``(Z, Y, X, 3)``), else the float grid named 'density', else the file's only float grid
    (``choose_grid``). Only that grid is read: the file's other grids may be of any type, including
    those the binding cannot read (a Mantaflow cache's int32 'flags'). The array
    is float32 and covers the written array's box for files from ``write_vdb``, the active voxels'
    bounding box otherwise; ``transform.index_min`` is the index of its element ``[0, 0, 0]``.

    Raises:
        VdbUnavailable: no interpreter has OpenVDB's module (the message names the fix).
        ValueError: a missing or unreadable file, no such grid (the message lists the file's grids),
            several float grids and no 'density', an empty grid, or a non-linear (frustum) transform.
    """
    return read_vdb_grids(path, grid)[0]


def read_vdb_grids(path, grid: str | None = None, also=()) -> tuple[VdbGrid, list[VdbGrid | None]]:
    """``read_vdb_grid``'s grid, and each grid named in ``also`` (float or vec3s, e.g. a density's
    velocity), read in one run of the converter: ``(grid, [also_grid or None, ...])``, None for a grid of
    ``also`` that is empty (no active voxel; the main grid may not be). Each has its own transform and box."""
    path, scan = _existing_file(path)
    also = [str(name) for name in also]
    if scan["grids"] is not None:  # choose here, so a bad choice fails before any binding is looked for
        grid = choose_grid(path, scan, grid)["name"]
        for name in also:
            choose_grid(path, scan, name)
    route = _find_route(os.environ.get(INTERPRETER_ENV) or None)
    if route.in_process:
        (array, meta), *others = _convert_in_process("read_grids", os.fspath(path), grid, also)
    else:
        with tempfile.TemporaryDirectory(prefix="mistyle-vdb-") as workdir:
            options = (["--grid", grid] if grid is not None else []) + [
                word for name in also for word in ("--also", name)
            ]
            _run_converter(route, "read", os.fspath(path), workdir, *options)
            with open(Path(workdir) / "meta.json") as handle:
                meta = json.load(handle)
            array = np.load(Path(workdir) / meta["array"], allow_pickle=False)
            others = [
                (None if m["array"] is None else np.load(Path(workdir) / m["array"], allow_pickle=False), m)
                for m in meta.get("also", [])
            ]
    return _vdb_grid(array, meta), [None if a is None else _vdb_grid(a, m) for a, m in others]


def _vdb_grid(array: np.ndarray, meta: dict) -> VdbGrid:
    # meta["matrix"] is OpenVDB's row-vector matrix; ours acts on column vectors.
    transform = VdbTransform(np.array(meta["matrix"], dtype=np.float64).T, tuple(meta["index_min"]))
    expected = tuple(hi - lo + 1 for lo, hi in zip(meta["index_min"], meta["index_max"]))[::-1]
    if array.shape[:3] != expected:
        raise ValueError(
            f"The OpenVDB converter returned a {array.shape} array for the index box "
            f"{meta['index_min']}..{meta['index_max']}; this is a bug in mistyle.vdb."
        )
    return VdbGrid(np.ascontiguousarray(array, dtype=np.float32), transform, meta["grid"], meta["file_metadata"])


def choose_grid(path, scan: dict, grid: str | None) -> dict:
    """The grid of ``scan`` (``check_vdb_layout``'s) that ``read_vdb_grid`` reads: ``grid``, else 'density',
    else the only float grid. ``ValueError`` naming the file and listing its grids when there is no such
    grid, it is of a type mistyle does not read, or there are several float grids and no 'density'."""
    from . import vdb_convert

    try:
        return vdb_convert.choose_grid(os.fspath(path), scan["grids"], grid)
    except vdb_convert.ConvertError as error:
        raise ValueError(str(error)) from None


def vdb_info(path) -> dict:
    """What a ``.vdb`` file holds, without reading its voxels; every grid, whatever its type.

    ``{"file", "version", "library_version", "grids": [{"name", "type" ('float', 'vec3s', 'int32', ...),
    "class" ('fog volume', ...), "readable" (mistyle reads float and vec3s grids), "half_float",
    "active_voxel_count", "index_min", "index_max" (inclusive (i, j, k); None where the file does not
    record them or the grid is empty), "map", "is_linear", "matrix" (OpenVDB's row-vector convention;
    ``VdbTransform`` takes its transpose), "voxel_size", "metadata"}, ...], "file_metadata": {...}}``.

    Read in Python from the file's header (``check_vdb_layout``), so it needs no OpenVDB binding; only a
    file written to a stream, which has no grid offsets, goes through the converter.
    """
    from . import vdb_convert

    path, scan = _existing_file(path)
    if scan["grids"] is not None:
        info = vdb_convert.describe(scan)
    else:
        route = _find_route(os.environ.get(INTERPRETER_ENV) or None)
        if route.in_process:
            info = _convert_in_process("file_info", os.fspath(path))
        else:
            with tempfile.TemporaryDirectory(prefix="mistyle-vdb-") as workdir:
                _run_converter(route, "info", os.fspath(path), workdir)
                with open(Path(workdir) / "meta.json") as handle:
                    info = json.load(handle)
    for grid in info["grids"]:  # an empty grid's recorded box is inverted (INT_MAX..INT_MIN): no box
        low, high = grid.get("index_min"), grid.get("index_max")
        if low is not None and high is not None and any(a > b for a, b in zip(low, high)):
            grid["index_min"] = grid["index_max"] = None
    return info


# ----------------------------------------------------------------------------- passengers
PASSENGER_GRIDS = ("temperature", "flame", "heat", "color", "Cd")
"""Grids of a source file that a DCC's shaders read beside its density (a fire's temperature and flame,
Mantaflow's heat, a smoke's colour: Blender's ``color``, Houdini's ``Cd``): carried into the ``volume.vdb``
mistyle writes, so an artist's fire shader still finds them. Their values are not stylized."""
SOURCE_PREFIX = "source_"
"""A passenger named like a grid mistyle writes itself (the source's own ``Cd``) is written with this prefix."""


def passenger_grids(path, density_grid: str | None = None) -> tuple[dict, dict]:
    """The grids of ``PASSENGER_GRIDS`` that the ``.vdb`` file ``path`` holds, other than its density grid
    (``choose_grid``'s for ``density_grid``), as read. Returns ``(grids, skipped)``: ``{name: VdbGrid}``,
    and ``{name: reason}`` for a grid left out because it holds NaN or infinite values. An empty grid (no
    active voxel) is left out silently (a shader reads zero where a grid is missing, as where it is
    empty), and so is a grid of a type mistyle does not read (``vdb_info`` lists them)."""
    path, scan = _existing_file(path)
    grids = scan["grids"] if scan["grids"] is not None else vdb_info(path)["grids"]
    density = choose_grid(path, scan, density_grid)["name"] if scan["grids"] is not None else density_grid
    counts = {g["name"]: g.get("active_voxel_count", g.get("metadata", {}).get("file_voxel_count")) for g in grids}
    names = [
        g["name"]
        for g in grids
        if g["name"] in PASSENGER_GRIDS and g["readable"] and g["name"] != density and counts[g["name"]] != 0
    ]
    if not names:
        return {}, {}
    # The converter reads a main grid and others: a passenger known to hold voxels is the main one, so the
    # density (read already, when the frame was loaded) is not read again.
    main = next((name for name in names if counts[name]), None)
    if main is None:
        _, read = read_vdb_grids(path, density, names)
    else:
        first, rest = read_vdb_grids(path, main, [name for name in names if name != main])
        read = [first, *rest]
        names = [main, *(name for name in names if name != main)]
    found, skipped = {}, {}
    for name, grid in zip(names, read):
        if grid is None:
            continue
        if not np.all(np.isfinite(grid.array)):
            skipped[name] = f"{int(np.count_nonzero(~np.isfinite(grid.array)))} NaN or infinite value(s)"
            continue
        found[name] = grid
    return found, skipped


def passengers_at(grids: dict, target: VdbTransform, shape_zyx) -> dict:
    """``passenger_grids``' grids sampled at the voxel centres of a ``(Z, Y, X)`` array placed by ``target``
    (the density as mistyle writes it: turned and padded, ``io.load_density_frames``), keyed by the name
    they are written under (``SOURCE_PREFIX`` before a name mistyle writes itself): a scalar grid as
    ``(Z, Y, X)``, a colour as ``(Z, Y, X, 3)``, zero outside the grid's own box."""
    shape = _shape3(shape_zyx)
    return {
        (SOURCE_PREFIX + name if name in (DENSITY_GRID, ALBEDO_GRID) else name): _resampled(
            grid.array, grid.transform, target, shape
        )
        for name, grid in grids.items()
    }


# ----------------------------------------------------------------------------- velocities
VELOCITY_GRIDS = ("velocity", "vel", "v")
"""The names a velocity grid goes by, looked for in this order: Blender's, Houdini's, and the short one."""
_COMPONENT_SUFFIXES = ((".x", ".y", ".z"), ("_x", "_y", "_z"))  # a velocity kept as three float grids (Houdini)
DEFAULT_FPS = 24.0
"""Frames per second assumed where neither the caller nor the file says: Blender's and Houdini's default."""
FPS_KEYS = ("fps", "frame_rate", "frames_per_second")  # file metadata that may say it
MANTAFLOW_KEY = "file_base_resolution"
"""Grid metadata that Mantaflow, Blender's fluid solver, writes on every grid of its cache (its
``META_BASE_RES``, extern/mantaflow/preprocessed/fileio/iovdb.cpp); OpenVDB itself never does."""
MANTAFLOW_TIME_PER_SECOND = 2.5
"""Mantaflow's velocities are in its solver's units: cells per solver time unit. Blender lets one frame
last ``0.1 * (25 / fps) * time_scale`` of them (``frame_length`` in blenkernel's fluid.cc, the comment
'dt = 0.1 is at 25fps'), so a second is 2.5 solver time units at the domain's default Time Scale of 1.
The file records neither the frame rate nor the time scale."""


@dataclass(frozen=True)
class VelocitySource:
    """Where a ``.vdb`` file keeps its velocity and what its values mean (``find_velocity``)."""

    file: str
    grids: tuple[str, ...]  # one vec3s grid, or three float grids (x, y, z)
    staggered: bool  # a vec3s grid of class 'staggered' (a MAC grid): component a on the lower face along axis a
    units: str  # 'world' (world units/s), 'index' (the grid's voxels/s: is_local_space) or 'mantaflow'
    fps: float
    fps_from: str  # where ``fps`` comes from, in words

    @property
    def per_frame(self) -> float:
        """The factor from the file's time unit to one frame."""
        return (MANTAFLOW_TIME_PER_SECOND if self.units == "mantaflow" else 1.0) / self.fps

    def describe(self) -> str:
        """One line for the user: the grid, the units read and what was assumed."""
        name = f"grid '{self.grids[0]}'" if len(self.grids) == 1 else "grids " + ", ".join(f"'{g}'" for g in self.grids)
        staggered = " (staggered: faces averaged to cell centres)" if self.staggered else ""
        if self.units == "mantaflow":
            units = (
                "Blender Mantaflow's solver units, cells per solver time unit, 2.5 of which make a second at the "
                "domain's Time Scale 1 (assumed: the cache does not record it)"
            )
        elif self.units == "index":
            units = "voxels per second (the grid says is_local_space)"
        else:
            units = "world units per second"
        return f"velocity from {name}{staggered}, in {units}, at {self.fps:g} fps ({self.fps_from})"


def find_velocity(path, scan: dict, name: str | None = None, fps: float | None = None) -> VelocitySource | None:
    """The velocity grid(s) of a ``.vdb`` file (``scan``: ``check_vdb_layout``'s), or None.

    ``name``: the grid to use, a vec3s grid or the base name of three float grids ``NAME.x``/``.y``/``.z``
    (or ``_x``...); ``ValueError`` naming the file and listing its grids when there is none. None: the
    first of ``VELOCITY_GRIDS`` that the file has, else None. Units: a grid written by Mantaflow (it
    carries ``MANTAFLOW_KEY``) is in Mantaflow's solver units (``MANTAFLOW_TIME_PER_SECOND``); one whose
    metadata says ``is_local_space`` in its own voxels per second; any other in world units per second,
    OpenVDB's convention for vectors and what Houdini's 'vel' and Blender's volume objects (Velocity Unit
    'Second', the default) use. ``fps``: frames per second, else the file's metadata (``FPS_KEYS``), else
    ``DEFAULT_FPS``.
    """
    grids = scan.get("grids")
    if grids is None:  # a file written to a stream: no grid list without the binding, so no velocity
        return None
    by_name = {}
    for grid in grids:
        by_name.setdefault(grid["name"], grid)
    chosen = None
    for candidate in [name] if name else VELOCITY_GRIDS:
        grid = by_name.get(candidate)
        if grid is not None and grid["type"] == "vec3s":
            chosen = (candidate,)
            break
        for suffixes in _COMPONENT_SUFFIXES:
            parts = [by_name.get(candidate + suffix) for suffix in suffixes]
            if all(part is not None and part["type"] == "float" for part in parts):
                chosen = tuple(candidate + suffix for suffix in suffixes)
                break
        if chosen:
            break
    if chosen is None:
        if not name:
            return None
        held = ", ".join(f"'{g['name']}' ({g['type']})" for g in grids) or "no grids"
        raise ValueError(
            f"{path} has no velocity grid '{name}' (a vec3s grid, or float grids '{name}.x', '{name}.y', "
            f"'{name}.z'); it holds {held}. Name the files' velocity grid, or read them without velocities "
            "(velocity_grid='')."
        )
    first = by_name[chosen[0]]
    metadata = first.get("metadata", {})
    if len(chosen) == 1 and MANTAFLOW_KEY in metadata:
        units = "mantaflow"
    elif metadata.get("is_local_space") is True:
        units = "index"
    else:
        units = "world"
    if fps is not None:
        fps_from = "given"
    else:
        recorded = {key: scan["file_metadata"].get(key) for key in FPS_KEYS}
        found = [(k, v) for k, v in recorded.items() if _positive_number(v)]
        fps, fps_from = (
            (float(found[0][1]), f"the file's '{found[0][0]}' metadata")
            if found
            else (DEFAULT_FPS, "assumed: the file records no frame rate")
        )
    if not _positive_number(fps):
        raise ValueError(f"Frames per second must be a positive number, got {fps!r}.")
    staggered = len(chosen) == 1 and first["class"] == "staggered"
    return VelocitySource(os.fspath(path), chosen, staggered, units, float(fps), fps_from)


def _positive_number(value) -> bool:
    return (
        isinstance(value, (int, float, np.number))
        and not isinstance(value, bool)
        and bool(np.isfinite(value))
        and value > 0
    )


class VdbVelocity(NamedTuple):
    """A file's velocity as read (``read_vdb_frame``): its grids as they are, sampled where asked (``at``)."""

    source: VelocitySource
    grids: list  # a VdbGrid per name of ``source.grids``; None for an empty one (no motion)

    def at(self, transform: VdbTransform, shape_zyx) -> np.ndarray:
        """The world displacement of one frame, ``(Z, Y, X, 3)`` float32 world-axis components, at the
        voxel centres of a ``(Z, Y, X)`` array placed by ``transform``: a staggered grid's faces averaged
        to cell centres, copied where the grids share the array's lattice, trilinear where they do not
        (another resolution), zero where the velocity grid has no voxel."""
        return _velocity_per_frame(self.source, self.grids, transform, shape_zyx)


class VdbFrame(NamedTuple):
    """``read_vdb_frame``'s result."""

    density: VdbGrid
    velocity: VdbVelocity | None


def read_vdb_frame(
    path, grid: str | None = None, velocity_grid: str | None = None, fps: float | None = None
) -> VdbFrame:
    """A frame of a sequence: the density grid (``read_vdb_grid``) and the file's velocity grid(s), read
    in one run of the converter.

    The velocity (``find_velocity``: ``velocity_grid``, else the first of ``VELOCITY_GRIDS``; ``''``:
    none) is kept as read, on its own box, and sampled later with ``VdbVelocity.at`` wherever the caller
    places the frame: a sequence's frames share the union of their boxes, and a semi-Lagrangian warp
    reads the velocity where the smoke arrives, beyond the box of the frame's own smoke. ``world_to_index``
    then gives the voxels per frame that ``mistyle.warp`` uses.

    Raises:
        ValueError: as ``read_vdb_grid``; a ``velocity_grid`` the file does not have; non-finite velocities.
    """
    path, scan = _existing_file(path)
    source = find_velocity(path, scan, velocity_grid, fps) if velocity_grid != "" else None
    density, extra = read_vdb_grids(path, grid, source.grids if source else ())
    if source is None:
        return VdbFrame(density, None)
    for name, read in zip(source.grids, extra):
        if read is not None and not np.all(np.isfinite(read.array)):
            bad = int(np.count_nonzero(~np.isfinite(read.array)))
            raise ValueError(
                f"Grid '{name}' of {path} holds {bad} NaN or infinite velocity value(s); export the velocity "
                "again, or read the frames without velocities (velocity_grid='')."
            )
    return VdbFrame(density, VdbVelocity(source, extra))


def world_to_index(vectors: np.ndarray, transform: VdbTransform) -> np.ndarray:
    """World vectors ``(..., 3)`` as index steps of ``transform`` (``(x, y, z)`` = along ``i, j, k``, the
    array's last, middle and first axes): a world displacement per frame becomes the voxels per frame of
    ``mistyle.warp``, whatever the grid's voxel size, rotation or turn (``upright``)."""
    to_index = np.linalg.inv(transform.matrix[:3, :3]).T.astype(np.float32)
    return np.ascontiguousarray(np.asarray(vectors, np.float32) @ to_index)


def _velocity_per_frame(source: VelocitySource, grids: list, target: VdbTransform, shape_zyx) -> np.ndarray:
    """World displacement per frame ``(Z, Y, X, 3)`` at the centres of a ``(Z, Y, X)`` array placed by
    ``target``, from the velocity grids of ``source`` (None for an empty one: no motion)."""
    shape = _shape3(shape_zyx)
    present = [grid for grid in grids if grid is not None]
    if not present:
        return np.zeros(shape + (3,), np.float32)
    if len(grids) == 1:
        values, transform = present[0].array, present[0].transform
        if source.staggered:
            values, transform = _cell_centred(values, transform)
        sampled = _resampled(values, transform, target, shape)
    else:
        sampled = np.stack(
            [
                np.zeros(shape, np.float32) if g is None else _resampled(g.array, g.transform, target, shape)
                for g in grids
            ],
            axis=-1,
        )
    # float32 throughout: a sequence's union box can hold many millions of voxels, three values each.
    if source.units != "world":  # index steps of the velocity grid (Mantaflow's cells): to world vectors
        sampled = sampled @ present[0].transform.matrix[:3, :3].T.astype(np.float32)
    sampled *= np.float32(source.per_frame)
    return sampled


def _cell_centred(values: np.ndarray, transform: VdbTransform) -> tuple[np.ndarray, VdbTransform]:
    """A staggered (MAC) vec3 grid's values at its cell centres, on a box one voxel larger on every side.

    OpenVDB's staggered convention, which Mantaflow's MAC grids follow: component a of voxel n sits on the
    voxel's lower face along index axis a (x at ``(i - 1/2, j, k)``), so the centre of voxel n has the mean
    of the faces of n and n + 1. Outside the read box the grid holds its background, zero."""
    padded = np.pad(values, ((1, 1), (1, 1), (1, 1), (0, 0)))
    centred = np.empty_like(padded)
    for component, axis in ((0, 2), (1, 1), (2, 0)):  # x runs along the array's last axis
        face = padded[..., component]
        upper = np.zeros_like(face)
        take, put = [slice(None)] * 3, [slice(None)] * 3
        take[axis], put[axis] = slice(1, None), slice(None, -1)
        upper[tuple(put)] = face[tuple(take)]
        centred[..., component] = 0.5 * (face + upper)
    return centred, VdbTransform(transform.matrix, tuple(np.subtract(transform.index_min, 1)))


_RESAMPLE_CHUNK = 1 << 20  # target voxels per step of the trilinear sampling: bounds its temporary arrays


def _resampled(values: np.ndarray, transform: VdbTransform, target: VdbTransform, shape_zyx) -> np.ndarray:
    """``values`` (``(Z', Y', X')`` or ``(Z', Y', X', C)`` at the voxel centres of ``transform``, zero
    outside their box) at the voxel centres of a ``(Z, Y, X)`` array placed by ``target``: copied when the
    two share a lattice (the grids of one file, as a rule), else trilinear (a grid at another resolution)."""
    shape = _shape3(shape_zyx)
    channels = values.shape[3:]
    source = values.reshape(values.shape[:3] + (-1,))
    linear = transform.matrix[:3, :3]
    step = np.linalg.solve(linear, target.matrix[:3, :3])  # source index steps per target index step
    corner = target.index_to_world(np.asarray(target.index_min, np.float64))
    start = np.linalg.solve(linear, corner - transform.matrix[:3, 3]) - np.asarray(transform.index_min)
    size = np.array(source.shape[:3][::-1])  # (x, y, z)
    out = np.zeros(shape + (source.shape[3],), np.float32)
    if np.allclose(step, np.eye(3), rtol=0.0, atol=1e-6) and np.allclose(start, np.round(start), rtol=0.0, atol=1e-6):
        offset = np.round(start).astype(np.int64)  # source voxel = target voxel + offset, (x, y, z)
        low = np.maximum(0, -offset)
        high = np.minimum(np.array(shape[::-1]), size - offset)
        if np.all(high > low):
            out[low[2] : high[2], low[1] : high[1], low[0] : high[0]] = source[
                low[2] + offset[2] : high[2] + offset[2],
                low[1] + offset[1] : high[1] + offset[1],
                low[0] + offset[0] : high[0] + offset[0],
            ]
        return out.reshape(shape + channels)
    flat = source.reshape(-1, source.shape[3])
    count = int(np.prod(shape))
    target_out = out.reshape(-1, source.shape[3])
    for begin in range(0, count, _RESAMPLE_CHUNK):
        number = np.arange(begin, min(count, begin + _RESAMPLE_CHUNK))
        z, rest = np.divmod(number, shape[1] * shape[2])
        y, x = np.divmod(rest, shape[2])
        where = start + np.stack([x, y, z], axis=-1) @ step.T  # (N, 3) in the source's local (x, y, z)
        base = np.floor(where).astype(np.int64)
        frac = where - base
        total = np.zeros((len(number), source.shape[3]), np.float64)
        for bits in np.ndindex(2, 2, 2):
            voxel = base + bits
            inside = np.all((voxel >= 0) & (voxel < size), axis=1)
            weight = np.prod(np.where(bits, frac, 1.0 - frac), axis=1) * inside
            voxel = np.clip(voxel, 0, size - 1)
            total += weight[:, None] * flat[(voxel[:, 2] * size[1] + voxel[:, 1]) * size[0] + voxel[:, 0]]
        target_out[number] = total
    return out.reshape(shape + channels)


# ----------------------------------------------------------------------------- writing
def _checked_metadata(metadata: dict | None) -> dict:
    checked = {}
    for key, value in (metadata or {}).items():
        if not isinstance(key, str) or not key:
            raise ValueError(f"VDB metadata names are non-empty strings, got {key!r}.")
        if isinstance(value, np.generic):
            value = value.item()
        if not isinstance(value, (str, bool, int, float)) or (isinstance(value, float) and not np.isfinite(value)):
            raise ValueError(f"VDB metadata '{key}' must be a string, a finite number or a bool, got {value!r}.")
        checked[key] = value
    return checked


def _grid_spec(name, value, shape) -> tuple[str, np.ndarray]:
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"VDB grid names are non-empty strings, got {name!r}.")
    array = np.asarray(value)
    if not (
        np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer) or array.dtype == np.bool_
    ):
        raise ValueError(f"VDB grid '{name}' has the type {array.dtype}; give real numbers.")
    if array.ndim == 3:
        kind = "float"
    elif array.ndim == 4 and array.shape[-1] == 3:
        kind = "vec3"
    else:
        raise ValueError(
            f"VDB grid '{name}' must be (Z, Y, X) (a scalar such as a density) or (Z, Y, X, 3) "
            f"(a colour such as an albedo), got shape {array.shape}."
        )
    if min(array.shape) < 1:
        raise ValueError(f"VDB grid '{name}' is empty (shape {array.shape}).")
    if shape is not None and array.shape[:3] != shape:
        raise ValueError(
            f"VDB grid '{name}' is {array.shape[:3]} (Z, Y, X) but the grids before it are {shape}; "
            "all grids of a file share one voxel box."
        )
    values = array.astype(np.float32)
    if not np.all(np.isfinite(values)):
        raise ValueError(f"VDB grid '{name}' holds NaN or infinite values (or values beyond float32).")
    return kind, values


def write_vdb(
    path, transform: VdbTransform, grids: dict, metadata: dict | None = None, grid_metadata: dict | None = None
) -> Path:
    """Write named grids that share one voxel box to one ``.vdb`` file, atomically.

    ``grids`` maps names to float arrays ``(Z, Y, X)`` (FloatGrid) or ``(Z, Y, X, 3)`` (Vec3SGrid), e.g.
    ``{DENSITY_GRID: density, ALBEDO_GRID: albedo}``; the density grid gets the class fog volume. Values
    are stored as float32, and zeros stay inactive, so empty space costs nothing (mask an albedo with
    ``density > 0`` to keep it sparse too). ``transform`` places the grid (``VdbTransform.for_medium_box``
    for mistyle's own box). ``metadata``: file-level ``name -> str | int | float | bool``;
    ``grid_metadata``: the same kind, set on every grid (Houdini shows a grid's as primitive attributes).

    Raises:
        VdbUnavailable: no interpreter has OpenVDB's module (the message names the fix).
        ValueError: bad shapes, non-finite values, bad metadata, or an unwritable path.
    """
    if not isinstance(transform, VdbTransform):
        raise ValueError(
            f"write_vdb needs a VdbTransform (e.g. VdbTransform.for_medium_box(shape)), got {type(transform).__name__}."
        )
    if not isinstance(grids, dict) or not grids:
        raise ValueError("write_vdb needs at least one grid, as a dict {name: array}.")
    specs, shape = [], None
    for name, value in grids.items():
        kind, values = _grid_spec(name, value, shape)
        shape = values.shape[:3]
        specs.append({"name": name, "kind": kind, "class": "fog" if name == DENSITY_GRID else None, "array": values})
    file_metadata, on_grids = _checked_metadata(metadata), _checked_metadata(grid_metadata)
    for spec in specs:
        spec["metadata"] = on_grids
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ValueError(f"Cannot write {path}: {error.strerror}. Choose a writable output directory.") from None
    matrix = transform.matrix.T.tolist()  # OpenVDB's row-vector convention
    route = _find_route(os.environ.get(INTERPRETER_ENV) or None)
    if route.in_process:
        _convert_in_process("write_grids", os.fspath(path), matrix, list(transform.index_min), specs, file_metadata)
        return path
    with tempfile.TemporaryDirectory(prefix="mistyle-vdb-") as workdir:
        sidecar = {"matrix": matrix, "index_min": list(transform.index_min), "metadata": file_metadata, "grids": []}
        for number, spec in enumerate(specs):
            file = f"grid{number}.npy"
            np.save(Path(workdir) / file, spec["array"], allow_pickle=False)
            sidecar["grids"].append(
                {
                    "name": spec["name"],
                    "file": file,
                    "kind": spec["kind"],
                    "class": spec["class"],
                    "metadata": spec["metadata"],
                }
            )
        with open(Path(workdir) / "meta.json", "w") as handle:
            json.dump(sidecar, handle, allow_nan=False)
        _run_converter(route, "write", os.fspath(path), workdir)
    return path


# ----------------------------------------------------------------------------- mistyle-vdb
# Shown in each grid's line, or OpenVDB's own bookkeeping (per-leaf sizes for delayed loading), so left
# out of its metadata lines.
_SHOWN_KEYS = (
    "class",
    "name",
    "file_bbox_min",
    "file_bbox_max",
    "file_voxel_count",
    "file_voxel_size",
    "file_delayed_load",
)


def _format_value(value) -> str:
    if isinstance(value, float):
        return f"{value:.9g}"
    if isinstance(value, list):
        return "(" + ", ".join(_format_value(v) for v in value) + ")"
    return str(value)


def describe_vdb(info: dict) -> str:
    """``vdb_info``'s result as text: one line per grid (name, type, class, active voxels, index box and
    its size, voxel size, world box, whether mistyle reads it), then the file's and each grid's metadata."""
    version = f"OpenVDB file format {info['version']}"
    if info.get("library_version"):
        version += f", written by OpenVDB {'.'.join(str(v) for v in info['library_version'])}"
    lines = [f"{info['file']}: {version}, {len(info['grids'])} grid(s)"]
    for grid in info["grids"]:
        kind = grid["type"] + (" (saved as half)" if grid.get("half_float") else "")
        words = [f"  {grid['name']}: {kind}, class {grid['class']}"]
        count, low, high = grid.get("active_voxel_count"), grid.get("index_min"), grid.get("index_max")
        if count is not None:
            words.append(f"{count} active voxels")
        if low is not None and high is not None:
            size = "x".join(str(b - a + 1) for a, b in zip(low, high))
            words.append(f"index box {tuple(low)}..{tuple(high)} ({size})")
        matrix, voxel = grid.get("matrix"), grid.get("voxel_size")
        if voxel is not None:
            same = max(voxel) - min(voxel) <= 1e-12 * max(voxel)
            words.append(f"voxel size {_format_value(voxel[0] if same else voxel)}")
        if matrix is not None and low is not None and high is not None:
            corner = VdbTransform(np.array(matrix).T, tuple(low))
            shape = tuple(b - a + 1 for a, b in zip(low, high))[::-1]
            world_low, world_high = corner.world_bbox(shape)
            words.append(f"world box {_format_value(world_low.tolist())}..{_format_value(world_high.tolist())}")
        elif grid.get("is_linear") is False:
            words.append(f"non-linear transform ({grid.get('map')})")
        readable = grid.get("readable", grid["type"] in ("float", "vec3s"))
        words.append("mistyle reads it" if readable else "not read by mistyle (float and vec3s grids only)")
        lines.append(", ".join(words))
    if info.get("file_metadata"):
        lines.append("file metadata:")
        lines += [f"  {key} = {_format_value(value)}" for key, value in sorted(info["file_metadata"].items())]
    for grid in info["grids"]:
        rest = {k: v for k, v in grid.get("metadata", {}).items() if k not in _SHOWN_KEYS}
        if rest:
            lines.append(f"grid '{grid['name']}' metadata:")
            lines += [f"  {key} = {_format_value(value)}" for key, value in sorted(rest.items())]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``mistyle-vdb FILE...`` (also ``python -m mistyle.vdb``): list what ``.vdb`` files hold.

    A command of its own rather than a ``mistyle-render --info`` flag: it reads only the files' headers,
    in Python, so it answers at once and needs neither the renderer nor an OpenVDB binding, and it
    lists every grid, including those ``mistyle-render`` cannot read, to pick ``--grid`` from."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="mistyle-vdb",
        description="List the grids of OpenVDB files (types, classes, voxel counts, index and world boxes, "
        "voxel sizes, metadata), read from their headers: no voxel is read and no OpenVDB module is needed.",
    )
    parser.add_argument("files", nargs="+", type=Path, metavar="FILE", help=".vdb files, or folders of them")
    parser.add_argument("--json", action="store_true", help="print vdb_info's JSON instead of text")
    args = parser.parse_args(argv)
    files = []
    for path in args.files:
        files += sorted(p for p in path.iterdir() if p.suffix.lower() == ".vdb") if path.is_dir() else [path]
    failed, reports = 0, []
    for path in files:
        try:
            info = vdb_info(path)
        except (ValueError, OSError) as error:
            print(f"error: {error}", file=sys.stderr)
            failed += 1
            continue
        reports.append(info)
        if not args.json:
            print(describe_vdb(info))
    if args.json:  # one file: its object; several, or a folder: a list
        single = len(args.files) == 1 and not args.files[0].is_dir() and len(reports) == 1
        print(json.dumps(reports[0] if single else reports, indent=1))
    if not files:
        print(f"error: no .vdb files in {', '.join(map(str, args.files))}.", file=sys.stderr)
        return 2
    return 2 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
