"""OpenVDB (``.vdb``) input and output: densities in, densities and albedos out.

The route. OpenVDB's Python bindings 10 (Boost.Python, ``pyopenvdb``) to 13 (nanobind, ``openvdb``) all
work (``vdb_convert.openvdb_module``), but each is built for one interpreter and its numpy: Debian's
``python3-openvdb`` for the system Python and numpy 1.x, the one the ``bpy`` wheel bundles for Python
3.13. mistyle therefore runs ``mistyle/files/vdb_convert.py`` -- a standalone script that imports nothing
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

from . import vdb_header
from .vdb_layout import DENSITY_GRID, VdbTransform

INTERPRETER_ENV = "MISTYLE_VDB_PYTHON"
CONVERTER = Path(__file__).with_name("vdb_convert.py")

_PROBE_TIMEOUT_S = 120  # a cold import of numpy on a busy machine can take a while


class VdbUnavailable(ValueError):
    """No Python interpreter here can import OpenVDB's module; the message says how to get one."""


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


def existing_file(path) -> tuple[Path, dict]:
    """``path`` and what its header says (``check_vdb_layout``), or ``ValueError`` naming the file."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"VDB file {path} does not exist.")
    if not path.is_file():
        raise ValueError(f"VDB file {path} is not a file.")
    return path, check_vdb_layout(path)


def check_vdb_layout(path) -> dict:
    """What ``path``'s header, grid descriptors and each grid's metadata and transform say
    (``vdb_header.scan_file``: every grid of every type, read in Python, no voxel read and no binding
    needed), or ``ValueError`` unless the file is an OpenVDB file whose declared sizes and offsets lie
    inside it.

    OpenVDB trusts those sizes: a string length or an offset read past the end of a truncated file makes
    it allocate that many bytes, gigabytes for a minute over a file of a few kilobytes before its error.
    Reading the grid list here rather than with the binding is also what lets a file hold grids the
    binding cannot read (a Blender Mantaflow cache's int32 'flags' grid, for Debian's OpenVDB 10)."""
    try:
        return vdb_header.scan_file(os.fspath(path))
    except vdb_header.ConvertError as error:
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
    path, scan = existing_file(path)
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
            f"{meta['index_min']}..{meta['index_max']}; this is a bug in mistyle.files.vdb."
        )
    return VdbGrid(np.ascontiguousarray(array, dtype=np.float32), transform, meta["grid"], meta["file_metadata"])


def choose_grid(path, scan: dict, grid: str | None) -> dict:
    """The grid of ``scan`` (``check_vdb_layout``'s) that ``read_vdb_grid`` reads: ``grid``, else 'density',
    else the only float grid. ``ValueError`` naming the file and listing its grids when there is no such
    grid, it is of a type mistyle does not read, or there are several float grids and no 'density'."""
    try:
        return vdb_header.choose_grid(os.fspath(path), scan["grids"], grid)
    except vdb_header.ConvertError as error:
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
    path, scan = existing_file(path)
    if scan["grids"] is not None:
        info = vdb_header.describe(scan)
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
    """``mistyle-vdb FILE...`` (also ``python -m mistyle.files.vdb``): list what ``.vdb`` files hold.

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
