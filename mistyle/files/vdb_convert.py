"""OpenVDB files to and from numpy arrays: the helper that ``mistyle.files.vdb`` runs under an interpreter with
the OpenVDB binding.

Standalone on purpose: Debian's ``python3-openvdb`` (module ``pyopenvdb``; ``openvdb`` from OpenVDB 11 on)
is built for the system Python and its numpy 1.x, so it cannot load in mistyle's environment. This file
therefore imports only the standard library, numpy, the binding and its sibling ``vdb_header.py``, never
the rest of mistyle, and runs as a script
under that other interpreter; its functions are also importable where the binding loads in-process.

Commands (arrays in ``.npy`` files and a ``meta.json`` in a work folder)::

    python vdb_convert.py read IN.vdb WORKDIR [--grid NAME] [--also NAME]...
                                                              ->  WORKDIR/grid.npy (also0.npy, ...), meta.json
    python vdb_convert.py write OUT.vdb WORKDIR               <-  WORKDIR/meta.json and the .npy it names
    python vdb_convert.py info IN.vdb WORKDIR                 ->  WORKDIR/meta.json (no voxel data read)
    python vdb_convert.py probe                               ->  {"module": ..., "version": [13, 0, 0]} on stdout

Bindings: OpenVDB 10 (Boost.Python, ``pyopenvdb``) to 13 (nanobind, ``openvdb``), including the one the
``bpy`` wheel bundles (``openvdb_module``). A file written with 11 or later has a newer file format
version that OpenVDB 10 still reads, with a warning, bit for bit (``make test-blender`` checks both ways).

Conventions:

* arrays use mistyle's layout ``(Z, Y, X)`` (scalars) and ``(Z, Y, X, 3)`` (vectors); OpenVDB's dense copies
  are indexed ``[i][j][k]`` = ``[x][y][z]``, so every array is transposed at this boundary;
* ``index_min`` is the index coordinate ``(i, j, k)`` of array element ``[0, 0, 0]``; voxel centres sit at
  integer index coordinates;
* ``matrix`` in ``meta.json`` is the index-to-world 4x4 in OpenVDB's own (``Mat4``) convention: it acts on
  ROW vectors, ``[x, y, z, 1] = [i, j, k, 1] @ matrix``, so the translation is the last row.

Sparsity: grids are written with ``copyFromArray(..., tolerance=0)``, so voxels equal to the background
(zero) stay inactive and cost nothing. Because a file then no longer knows the dense array it came from,
``write`` records the array's index box in each grid's metadata (``mistyle_dense_min``/``_max``) and
``read`` copies that box back when it encloses the active voxels; for files from other tools the dense
box is the active voxels' bounding box.

Only the grid asked for is read (``read_grid``): the list of a file's grids, their types, transforms and
metadata comes from ``vdb_header.scan_file``, which reads the file's header and grid descriptors in Python, so grids
of types the binding does not know (Debian's OpenVDB 10 knows float, bool and vec3s; a Blender Mantaflow
cache also holds int32 and others) never stop the read of the density. ``info`` needs no binding (but
for a file written to a stream, which has no grid offsets).

Errors print one line ``error: ...`` on stderr and exit with status 2.
"""

from __future__ import annotations

import json
import os
import sys

# Run as a script, Python puts this file's folder (mistyle/files/) first on sys.path, where mistyle's own
# modules could shadow others; the helper needs none of them.
if (
    __name__ == "__main__"
    and sys.path
    and os.path.abspath(sys.path[0] or os.curdir) == os.path.dirname(os.path.abspath(__file__))
):
    del sys.path[0]

import numpy as np

if __package__:  # mistyle.files.vdb_convert, imported where the binding loads in-process
    from . import vdb_header
else:  # a script under another interpreter: its sibling file, without mistyle's folder on sys.path
    import importlib.util

    _spec = importlib.util.spec_from_file_location(
        "vdb_header", os.path.join(os.path.dirname(os.path.abspath(__file__)), "vdb_header.py")
    )
    vdb_header = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(vdb_header)

ConvertError = vdb_header.ConvertError  # one class: mistyle.files.vdb catches it from either module

DENSE_MIN_KEY = "mistyle_dense_min"
DENSE_MAX_KEY = "mistyle_dense_max"
# A dense copy of a sparse grid can be far larger than the file; 2^30 voxels are 4 GiB of float32.
MAX_DENSE_VOXELS = 2**30


def openvdb_module():
    """The OpenVDB binding, looked for in this order: ``pyopenvdb`` (OpenVDB <= 10, e.g. Debian's
    ``python3-openvdb``), ``openvdb`` (OpenVDB 11 on), then the ``openvdb`` module that the ``bpy`` wheel
    (Blender as a Python module, 5.x: OpenVDB 13) bundles in its own site-packages, which loads without
    importing Blender."""
    try:
        import pyopenvdb as vdb
    except ImportError:
        try:
            import openvdb as vdb
        except ImportError as error:
            bundled = _bpy_bundled_site_packages()
            if bundled is None:
                raise ConvertError(
                    f"{sys.executable} has no OpenVDB module (pyopenvdb, openvdb, or bpy's bundled one): {error}"
                ) from None
            sys.path.append(bundled)
            try:
                import openvdb as vdb
            except ImportError as bundled_error:
                raise ConvertError(
                    f"bpy's bundled OpenVDB module in {bundled} does not load: {bundled_error}"
                ) from None
    return vdb


def _bpy_bundled_site_packages() -> str | None:
    """The folder of the ``bpy`` wheel's bundled modules (``bpy/<version>/python/lib/python3.X/site-packages``)
    if ``bpy`` is installed for this interpreter and the folder holds an ``openvdb`` module, else None."""
    import glob
    import importlib.util

    try:
        spec = importlib.util.find_spec("bpy")
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.origin:
        return None
    pattern = os.path.join(os.path.dirname(spec.origin), "*", "python", "lib", "python3*", "site-packages")
    for folder in sorted(glob.glob(pattern)):
        if glob.glob(os.path.join(folder, "openvdb*")):
            return folder
    return None


def binding() -> dict:
    """Which binding ``openvdb_module`` loads: its module file and OpenVDB's library version."""
    vdb = openvdb_module()
    version = getattr(vdb, "LIBRARY_VERSION", None)
    return {"module": getattr(vdb, "__file__", vdb.__name__), "version": list(version) if version else None}


# ----------------------------------------------------------------------------- small helpers
def _class_name(grid) -> str:
    """The grid class as OpenVDB spells it in files ('fog volume', 'level set', 'staggered', 'unknown')."""
    name = str(grid.gridClass).lower()
    name = name.rsplit(".", 1)[-1].replace("_", " ")  # an enum ("GridClass.FOG_VOLUME") in newer bindings
    return name


def _grid_summary(grid) -> dict:
    return {"name": grid.name, "type": grid.valueTypeName, "class": _class_name(grid)}


def _grid_list(vdb, path: str) -> list:
    """All grids of ``path`` with their metadata and transforms but no voxels (cheap)."""
    vdb_header.check_file(path)
    try:
        return list(vdb.readAllGridMetadata(path))
    except Exception as error:  # the binding raises OSError, RuntimeError or its own types
        raise ConvertError(f"{path} is not a readable OpenVDB file ({vdb_header.one_line(error)}).") from None


def index_to_world_matrix(transform) -> list[list[float]]:
    """The 4x4 index-to-world matrix of a linear transform in OpenVDB's row-vector convention.

    Rebuilt from ``indexToWorld`` (the binding exposes no matrix): the image of the origin is the last
    row; the images of ``2^60`` along each index axis, less the origin and divided by ``2^60``, are the
    other rows. The step is a power of two, so scaling by it is exact, and so large that adding and
    removing the translation rounds it away: the rows come back bit for bit unless an entry is some
    1e-18 of the translation, and then within about 1e-34 of it.
    """
    origin = np.array(transform.indexToWorld((0.0, 0.0, 0.0)), dtype=np.float64)
    step = float(2**60)
    matrix = np.eye(4)
    for axis in range(3):
        point = [0.0, 0.0, 0.0]
        point[axis] = step
        matrix[axis, :3] = (np.array(transform.indexToWorld(tuple(point)), dtype=np.float64) - origin) / step
    matrix[3, :3] = origin
    return matrix.tolist()


def file_info(path: str) -> dict:
    """What ``path`` holds, without reading voxels (``describe``); read in Python, so grids of every
    type list. Only a file written to a stream, which has no grid offsets, needs the binding."""
    scan = vdb_header.scan_file(path)
    if scan["grids"] is not None:
        return vdb_header.describe(scan)
    vdb = openvdb_module()
    grids = []
    for grid in _grid_list(vdb, path):
        entry = _grid_summary(grid)
        metadata = {str(k): vdb_header.jsonable(v) for k, v in dict(grid.metadata).items()}
        linear = bool(grid.transform.isLinear)
        matrix = index_to_world_matrix(grid.transform) if linear else None
        entry.update(
            readable=entry["type"] in vdb_header.READABLE_TYPES,
            half_float=None,
            instance_of=None,
            active_voxel_count=metadata.get("file_voxel_count"),
            index_min=metadata.get("file_bbox_min"),
            index_max=metadata.get("file_bbox_max"),
            map=str(grid.transform.typeName),
            is_linear=linear,
            matrix=matrix,
            voxel_size=None if matrix is None else np.linalg.norm(np.array(matrix)[:3, :3], axis=1).tolist(),
            metadata=metadata,
        )
        grids.append(entry)
    return {
        **{k: scan[k] for k in ("file", "version", "library_version")},
        "grids": grids,
        "file_metadata": scan["file_metadata"],
    }


def grid_summaries(path: str) -> tuple[list[dict], dict]:
    """``([{"name", "type", "class"}, ...], file_metadata)`` of ``path``: read in Python (``scan_file``),
    so a grid the binding cannot read never stops the read of one it can; from the binding only for a
    file written to a stream."""
    scan = vdb_header.scan_file(path)
    if scan["grids"] is not None:
        return [{k: g[k] for k in ("name", "type", "class")} for g in scan["grids"]], scan["file_metadata"]
    return [_grid_summary(g) for g in _grid_list(openvdb_module(), path)], scan["file_metadata"]


def _dense_box(grid, active_min, active_max) -> tuple[tuple, tuple, str]:
    """The index box to copy: mistyle's recorded array box if it encloses the active voxels, else theirs."""
    try:
        recorded_min, recorded_max = grid[DENSE_MIN_KEY], grid[DENSE_MAX_KEY]
        recorded_min = tuple(int(v) for v in recorded_min)
        recorded_max = tuple(int(v) for v in recorded_max)
    except Exception:  # absent (a file from another tool) or of another type
        return active_min, active_max, "active voxels"
    if len(recorded_min) == len(recorded_max) == 3 and all(
        r0 <= a0 and a1 <= r1 for r0, a0, a1, r1 in zip(recorded_min, active_min, active_max, recorded_max)
    ):
        return recorded_min, recorded_max, "mistyle metadata"
    return active_min, active_max, "active voxels"


def read_grid(path: str, grid_name: str | None = None) -> tuple[np.ndarray, dict]:
    """Read one float (or, when named, vec3s) grid of ``path`` as a dense array and its description.

    Returns ``(array, meta)``: ``array`` is float32 ``(Z, Y, X)`` or ``(Z, Y, X, 3)``; ``meta`` holds
    ``grid``, ``value_type``, ``grid_class``, ``grids`` (every grid's name, type and class),
    ``index_min``/``index_max`` (inclusive, ``(i, j, k)``), ``dense_extent``, ``active_voxel_count``,
    ``background``, ``matrix`` (row-vector convention, see the module docstring), ``voxel_size``,
    ``is_linear``, ``transform_type``, ``grid_metadata`` and ``file_metadata``.
    """
    return read_grids(path, grid_name)[0]


def read_grids(path: str, grid_name: str | None = None, also=()) -> list[tuple[np.ndarray | None, dict]]:
    """``read_grid``'s grid, then each grid named in ``also`` (float or vec3s: a density's velocity), in
    one run of this helper, which costs a start of the interpreter and the binding per call.

    A grid of ``also`` may be empty (a velocity is all background where the smoke is still): its array is
    None and its ``meta`` has ``active_voxel_count`` 0 and no index box. The main grid may not."""
    summaries, file_metadata = grid_summaries(path)  # before the binding: a bad file fails in Python
    chosen = [vdb_header.choose_grid(path, summaries, grid_name)] + [
        vdb_header.choose_grid(path, summaries, name) for name in also
    ]
    vdb = openvdb_module()
    return [
        _read_chosen(vdb, path, grid, summaries, file_metadata, empty_ok=number > 0)
        for number, grid in enumerate(chosen)
    ]


def _read_chosen(vdb, path: str, chosen: dict, summaries, file_metadata, empty_ok: bool):
    name = chosen["name"]
    try:
        grid = vdb.read(path, name)
    except Exception as error:
        raise ConvertError(f"Cannot read grid '{name}' of {path} ({vdb_header.one_line(error)}).") from None
    transform = grid.transform
    if not transform.isLinear:
        raise ConvertError(
            f"Grid '{name}' of {path} has a non-linear ({transform.typeName}, e.g. frustum) "
            "transform, which has no single voxel box; resample it onto a linear transform "
            "first (e.g. Houdini's VDB Resample)."
        )
    vector = chosen["type"] == vdb_header.VEC3_TYPE
    background = grid.background
    meta = {
        "file": path,
        "grid": name,
        "value_type": chosen["type"],
        "grid_class": chosen["class"],
        "grids": summaries,
        "background": vdb_header.jsonable(tuple(background) if vector else float(background)),
        "matrix": index_to_world_matrix(transform),
        "voxel_size": [float(v) for v in transform.voxelSize()],
        "is_linear": True,
        "transform_type": str(transform.typeName),
        "grid_metadata": {str(k): vdb_header.jsonable(v) for k, v in dict(grid.metadata).items()},
        "file_metadata": file_metadata,
    }
    active = int(grid.activeVoxelCount())
    if active == 0:
        if empty_ok:
            return None, {**meta, "index_min": None, "index_max": None, "dense_extent": None, "active_voxel_count": 0}
        raise ConvertError(f"Grid '{name}' of {path} is empty (it has no active voxels).")
    active_min, active_max = (tuple(int(v) for v in corner) for corner in grid.evalActiveVoxelBoundingBox())
    index_min, index_max, extent_from = _dense_box(grid, active_min, active_max)
    size_xyz = tuple(hi - lo + 1 for lo, hi in zip(index_min, index_max))
    count = int(np.prod(size_xyz, dtype=np.int64))
    if count > MAX_DENSE_VOXELS:
        raise ConvertError(
            f"Grid '{name}' of {path} spans {size_xyz[0]}x{size_xyz[1]}x{size_xyz[2]} voxels "
            f"({count} dense), more than the {MAX_DENSE_VOXELS} mistyle copies into memory; "
            "crop or resample it first."
        )
    dense = np.zeros(size_xyz + ((3,) if vector else ()), dtype=np.float32)  # C-contiguous, as the binding needs
    grid.copyToArray(dense, ijk=index_min)
    array = np.ascontiguousarray(dense.transpose((2, 1, 0, 3) if vector else (2, 1, 0)))  # [i,j,k] -> [z,y,x]
    meta.update(
        index_min=list(index_min), index_max=list(index_max), dense_extent=extent_from, active_voxel_count=active
    )
    return array, meta


# ----------------------------------------------------------------------------- write
def _check_matrix(matrix) -> np.ndarray:
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ConvertError(f"The index-to-world matrix must be a finite 4x4, got shape {m.shape}.")
    if not np.array_equal(m[:, 3], [0.0, 0.0, 0.0, 1.0]):
        raise ConvertError("The index-to-world matrix (row-vector convention) must be affine: last column 0, 0, 0, 1.")
    if abs(np.linalg.det(m[:3, :3])) < 1e-300 or np.linalg.cond(m[:3, :3]) > 1e12:
        raise ConvertError("The index-to-world matrix is singular; voxels need a non-zero size along every axis.")
    return m


def _post(transform, operation: str):
    """``transform``'s method that applies ``operation`` ('Scale', 'Translate') after what it holds: the
    Boost.Python bindings (OpenVDB 10) call it ``scale``/``translate``, the pybind11/nanobind ones (11 on)
    ``postScale``/``postTranslate``; the two do the same."""
    method = getattr(transform, "post" + operation, None)
    return method if method is not None else getattr(transform, operation.lower())


def linear_transform(vdb, matrix: np.ndarray):
    """An OpenVDB transform for the row-vector index-to-world ``matrix``, kept to the last bit.

    ``createLinearTransform(matrix)`` simplifies a scale-and-translate matrix into a scale map and
    loses an ulp of the voxel size on the way (0.05 comes back as 0.04999999999999999), so such
    matrices are built from their scale and translation instead; every other matrix goes in as is.
    """
    linear, translation = matrix[:3, :3], matrix[3, :3]
    scale = np.diag(linear)
    try:
        if np.array_equal(linear, np.diag(scale)) and np.all(scale > 0):
            uniform = scale[0] == scale[1] == scale[2]
            transform = vdb.createLinearTransform(float(scale[0]) if uniform else 1.0)
            if not uniform:
                _post(transform, "Scale")(tuple(float(v) for v in scale))
            if np.any(translation != 0):
                _post(transform, "Translate")(tuple(float(v) for v in translation))
        else:
            transform = vdb.createLinearTransform(matrix.tolist())
    except Exception as error:
        raise ConvertError(f"OpenVDB refuses the index-to-world matrix ({vdb_header.one_line(error)}).") from None
    built = np.array(index_to_world_matrix(transform))
    if not np.allclose(built, matrix, rtol=1e-12, atol=1e-12 * np.abs(matrix).max()):
        raise ConvertError(f"OpenVDB turned the index-to-world matrix {matrix.tolist()} into {built.tolist()}.")
    return transform


def write_grids(path: str, matrix, index_min, grids: list[dict], metadata: dict | None = None) -> str:
    """Write ``grids`` to one ``.vdb`` file at ``path``, atomically.

    ``matrix``: index-to-world 4x4, row-vector convention. ``index_min``: ``(i, j, k)`` of element
    ``[0, 0, 0]``. ``grids``: dicts with ``name``, ``array`` (float32 ``(Z, Y, X)`` for ``kind`` 'float',
    ``(Z, Y, X, 3)`` for 'vec3'), ``class`` ('fog' or None) and optionally ``metadata`` (name -> value, set
    on the grid). ``metadata``: file-level name -> value.
    """
    vdb = openvdb_module()
    m = _check_matrix(matrix)
    ijk = tuple(int(v) for v in index_min)
    if len(ijk) != 3:
        raise ConvertError(f"index_min must be three integers (i, j, k), got {index_min}.")
    if not grids:
        raise ConvertError("There are no grids to write.")
    transform = linear_transform(vdb, m)
    built, shape, names = [], None, set()
    for spec in grids:
        name, kind = spec.get("name"), spec.get("kind")
        if not isinstance(name, str) or not name or name in names:
            raise ConvertError(f"Grid names must be distinct non-empty strings, got {name!r}.")
        names.add(name)
        array = np.asarray(spec["array"], dtype=np.float32)
        expected_ndim = {"float": 3, "vec3": 4}.get(kind)
        if expected_ndim is None:
            raise ConvertError(f"Grid '{name}': kind must be 'float' or 'vec3', got {kind!r}.")
        if array.ndim != expected_ndim or (kind == "vec3" and array.shape[-1] != 3) or min(array.shape) < 1:
            raise ConvertError(
                f"Grid '{name}' ({kind}) must be {'(Z, Y, X)' if kind == 'float' else '(Z, Y, X, 3)'} "
                f"with every size >= 1, got shape {array.shape}."
            )
        if shape is not None and array.shape[:3] != shape:
            raise ConvertError(
                f"Grid '{name}' is {array.shape[:3]} but the others are {shape}; all grids share one box."
            )
        shape = array.shape[:3]
        if not np.all(np.isfinite(array)):
            raise ConvertError(f"Grid '{name}' holds NaN or infinite values.")
        if kind == "vec3":
            grid = vdb.Vec3SGrid()
            dense = np.ascontiguousarray(array.transpose(2, 1, 0, 3))  # [z,y,x] -> [i,j,k]; the binding needs C order
            grid.copyFromArray(dense, ijk=ijk, tolerance=(0.0, 0.0, 0.0))  # zero vectors stay inactive
        else:
            grid = vdb.FloatGrid()
            grid.copyFromArray(np.ascontiguousarray(array.transpose(2, 1, 0)), ijk=ijk, tolerance=0.0)
        grid.name = name
        grid.transform = transform
        if spec.get("class") == "fog":
            grid.gridClass = vdb.GridClass.FOG_VOLUME
        grid.creator = "mistyle"
        for key, value in _checked_metadata(spec.get("metadata")).items():
            grid[key] = value
        # The array's own box, so a read gives back the same shape even with empty margins.
        grid[DENSE_MIN_KEY] = ijk
        grid[DENSE_MAX_KEY] = tuple(lo + n - 1 for lo, n in zip(ijk, array.shape[2::-1]))
        built.append(grid)
    _write_atomically(vdb, path, built, _checked_metadata(metadata))
    return path


def _checked_metadata(metadata: dict | None) -> dict:
    for key, value in (metadata or {}).items():
        if not isinstance(key, str) or not key or not isinstance(value, (str, bool, int, float)):
            raise ConvertError(f"Metadata must map names to strings or numbers, got {key!r}: {value!r}.")
    return dict(metadata or {})


def _write_atomically(vdb, path: str, grids: list, metadata: dict) -> None:
    """Write to a temporary file beside ``path`` and rename it, so a failure leaves no half-written file."""
    import tempfile

    directory, name = os.path.split(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp.vdb", dir=directory)
    except OSError as error:
        raise ConvertError(f"Cannot write {path}: {error.strerror}. Choose a writable output directory.") from None
    os.close(fd)
    try:
        vdb.write(tmp, grids=grids, metadata=metadata)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600 files; give the usual permissions
        os.replace(tmp, path)
    except Exception as error:
        raise ConvertError(f"Cannot write {path} ({vdb_header.one_line(error)}).") from None
    finally:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass


# ----------------------------------------------------------------------------- command line
def _read_command(path: str, workdir: str, grid: str | None, also: list[str]) -> None:
    (array, meta), *others = read_grids(path, grid, also)
    np.save(os.path.join(workdir, "grid.npy"), array, allow_pickle=False)
    meta["array"] = "grid.npy"
    meta["also"] = []
    for number, (other, other_meta) in enumerate(others):
        other_meta["array"] = None if other is None else f"also{number}.npy"
        if other is not None:
            np.save(os.path.join(workdir, other_meta["array"]), other, allow_pickle=False)
        other_meta.pop("grids", None)  # the same list as the main grid's
        meta["also"].append(other_meta)
    _write_json(os.path.join(workdir, "meta.json"), meta)


def _write_command(path: str, workdir: str) -> None:
    try:
        with open(os.path.join(workdir, "meta.json")) as handle:
            meta = json.load(handle)
        grids = []
        for spec in meta["grids"]:
            file = os.path.join(workdir, os.path.basename(spec["file"]))  # only files inside the work folder
            grids.append(
                {
                    "name": spec["name"],
                    "kind": spec["kind"],
                    "class": spec.get("class"),
                    "metadata": spec.get("metadata") or {},
                    "array": np.load(file, allow_pickle=False),
                }
            )
        matrix, index_min, metadata = meta["matrix"], meta["index_min"], meta.get("metadata") or {}
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise ConvertError(
            f"The work folder {workdir} does not hold a valid meta.json and its arrays ({vdb_header.one_line(error)})."
        ) from None
    write_grids(path, matrix, index_min, grids, metadata)


def _write_json(path: str, value: dict) -> None:
    with open(path, "w") as handle:
        json.dump(value, handle, indent=1, allow_nan=False)


def main(argv: list[str] | None = None) -> int:
    import argparse

    class Parser(argparse.ArgumentParser):
        def error(self, message):  # one line, like every other error of this script
            raise ConvertError(
                f"{message} (usage: vdb_convert.py read|write|info FILE WORKDIR [--grid NAME] [--also NAME]..., "
                "or vdb_convert.py probe)"
            )

    parser = Parser(prog="vdb_convert.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("command", choices=("read", "write", "info", "probe"))
    parser.add_argument("file", nargs="?")
    parser.add_argument("workdir", nargs="?")
    parser.add_argument("--grid", default=None, help="grid to read (default: 'density', else the only float grid)")
    parser.add_argument("--also", action="append", default=[], help="read this grid too (may be empty); repeatable")
    try:
        args = parser.parse_args(argv)
        if args.command == "probe":  # which binding loads here, as one JSON line on stdout
            print(json.dumps(binding()))
            return 0
        if args.file is None or args.workdir is None:
            parser.error(f"{args.command} needs FILE and WORKDIR")
        if not os.path.isdir(args.workdir):
            raise ConvertError(f"The work folder {args.workdir} does not exist.")
        if args.command == "read":
            _read_command(args.file, args.workdir, args.grid, args.also)
        elif args.command == "write":
            _write_command(args.file, args.workdir)
        else:
            _write_json(os.path.join(args.workdir, "meta.json"), file_info(args.file))
    except ConvertError as error:
        print(f"error: {vdb_header.one_line(error)}", file=sys.stderr)
        return 2
    except Exception as error:  # never a traceback: the caller shows this line to the user
        print(
            f"error: unexpected {type(error).__name__} in vdb_convert.py: {vdb_header.one_line(error)}", file=sys.stderr
        )
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
