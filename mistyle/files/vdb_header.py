"""The header of an OpenVDB file read in Python: its grids' names, types, classes, transforms and
metadata, with no voxel read and no binding (``scan_file``), and the grid a read should take (``choose_grid``).

Standalone like ``vdb_convert.py``, which runs it under another interpreter: only the standard library and
numpy.
"""

from __future__ import annotations

import os

import numpy as np

DENSITY_GRID = "density"
FLOAT_TYPE = "float"
VEC3_TYPE = "vec3s"


class ConvertError(Exception):
    """A problem with the input, explained in one line for the user."""


def one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def jsonable(value):
    """Metadata values as JSON: numbers, strings and booleans as they are, vectors as lists, others as text."""
    if isinstance(value, (bool, int, str)) or value is None:
        return value
    if isinstance(value, float):
        return value if np.isfinite(value) else str(value)
    if isinstance(value, (tuple, list)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return jsonable(value.item())
    return str(value)


def describe_grids(grids: list[dict]) -> str:
    return ", ".join(f"'{g['name']}' ({g['type']})" for g in grids) or "no grids"


def check_file(path: str) -> None:
    if not os.path.exists(path):
        raise ConvertError(f"{path} does not exist.")
    if not os.path.isfile(path):
        raise ConvertError(f"{path} is not a file.")


# ----------------------------------------------------------------------------- the file's layout, in Python
# OpenVDB's file layout (io/Archive.cc, io/File.cc, io/GridDescriptor.cc, math/Maps.h), little-endian: the
# header (int64 magic, uint32 file version, two uint32 library version numbers from version 211, a uint8
# "has grid offsets" from 212, a uint8 compression flag in 220-221, a 36-character UUID from 218, else 16
# bytes), the file metadata, an int32 grid count and one descriptor per grid: name, type and, from 216,
# instance parent (uint32-length strings), then the int64 file offsets of the grid, its voxel data and its
# end; the next descriptor starts at the end offset. At the grid offset: a uint32 compression flag (from
# 222), the grid's metadata, its transform (map type name, then the map's doubles), then the voxels.
# Metadata (file and grid alike): a uint32 count, then per entry a name, a type name, a uint32 size and
# that many bytes.
#
# Reading this much in Python, rather than with the binding's readAllGridMetadata, is what lets mistyle
# open any file a DCC writes: Debian's OpenVDB 10 binding knows float, bool and vec3s grids only, and
# refuses to list the grids of a Blender Mantaflow cache (int32 'flags' among them) at all, while it
# reads the one grid asked for by name. It also checks that every declared size and offset lies inside
# the file: OpenVDB trusts them, and a length read past the end of a truncated file makes it allocate
# that many bytes, gigabytes for a minute over a file of a few kilobytes before its error.
VDB_MAGIC = 0x56444220
KNOWN_FILE_VERSION = 225  # OpenVDB 13 writes 225 (half grids); 10 writes 224; the layout read here is older
_GRID_OFFSETS_VERSION = 212
_INSTANCING_VERSION = 216
_UUID_VERSION = 218
_NEW_TRANSFORM_VERSION = 219
_GRID_COMPRESSION_VERSION = 222
_HALF_FLOAT_SUFFIX = "_HalfFloat"  # on the type name of float grids saved as 16-bit halves
_NAME_SEPARATOR = "\x1e"  # before the index OpenVDB appends to the second and later grids of one name
# Grid value types mistyle reads: scalars (densities, temperatures) and 3-vectors (colours, velocities).
READABLE_TYPES = (FLOAT_TYPE, VEC3_TYPE)
_METADATA_FORMATS = {  # metadata type name -> (numpy dtype, count); 'string' is text
    "bool": ("<u1", 1),
    "int32": ("<i4", 1),
    "int64": ("<i8", 1),
    "float": ("<f4", 1),
    "double": ("<f8", 1),
    **{f"vec{n}{t}": ({"i": "<i4", "s": "<f4", "d": "<f8"}[t], n) for n in (2, 3, 4) for t in "isd"},
    "mat4s": ("<f4", 16),
    "mat4d": ("<f8", 16),
}


class _Stream:
    """Reads little-endian numbers and OpenVDB's strings from ``path``, refusing anything past its end."""

    FIX = "it is damaged or truncated (an interrupted copy or download?); copy or export it again"

    def __init__(self, handle, path: str, size: int):
        self.handle, self.path, self.size = handle, path, size

    def tell(self) -> int:
        return self.handle.tell()

    def seek(self, offset: int) -> None:
        self.handle.seek(offset)

    def read(self, count: int, what: str) -> bytes:
        if count > self.size - self.tell():
            raise ConvertError(f"{self.path} ends inside its {what} at byte {self.size}; {self.FIX}.")
        return self.handle.read(count)

    def numbers(self, form: str, count: int, what: str) -> np.ndarray:
        return np.frombuffer(self.read(np.dtype(form).itemsize * count, what), dtype=form)

    def number(self, form: str, what: str):
        return self.numbers(form, 1, what)[0].item()

    def block(self, what: str) -> bytes:
        """A uint32 length and that many bytes (strings and metadata values)."""
        length = self.number("<u4", what)
        if length > self.size - self.tell():
            raise ConvertError(
                f"{self.path} declares a {what} of {length} bytes at byte {self.tell() - 4}, past its end at "
                f"byte {self.size}; {self.FIX}."
            )
        return self.handle.read(length)

    def string(self, what: str) -> str:
        return self.block(what).decode("utf-8", errors="replace")


def _metadata_value(type_name: str, data: bytes):
    """A metadata value as JSON-able Python: numbers, strings, booleans, lists for vectors and matrices;
    a type this does not know (or a size that does not fit it) as a short description."""
    if type_name == "string":
        return data.decode("utf-8", errors="replace")
    form = _METADATA_FORMATS.get(type_name)
    if form is None or len(data) != np.dtype(form[0]).itemsize * form[1]:
        return f"<{type_name}, {len(data)} bytes>"
    values = np.frombuffer(data, dtype=form[0])
    if type_name == "bool":
        return bool(values[0])
    if form[1] == 1:
        return jsonable(values[0].item())
    if form[1] == 16:
        return [jsonable(row) for row in values.reshape(4, 4).tolist()]
    return jsonable(values.tolist())


def _metadata(stream: _Stream, what: str) -> dict:
    count = stream.number("<u4", f"{what} count")
    if count > (stream.size - stream.tell()) // 12:  # an entry takes at least 12 bytes
        raise ConvertError(
            f"{stream.path} declares {count} {what} entries, more than its last {stream.size - stream.tell()} "
            f"bytes can hold; {stream.FIX}."
        )
    entries = {}
    for _ in range(count):
        name = stream.string(f"{what} name")
        type_name = stream.string(f"{what} type name")
        entries[name] = _metadata_value(type_name, stream.block(f"{what} value"))
    return entries


def _transform(stream: _Stream, version: int) -> dict:
    """A grid's transform: OpenVDB's map type and, for a linear map, the index-to-world matrix in
    OpenVDB's row-vector convention (``index_to_world_matrix``), copied from the file's doubles."""
    map_type = stream.string("grid transform type")
    if version < _NEW_TRANSFORM_VERSION:  # an older encoding; the binding still reads it
        return {"map": map_type, "is_linear": None, "matrix": None}
    matrix = np.eye(4)
    if map_type in ("ScaleTranslateMap", "UniformScaleTranslateMap"):
        matrix[3, :3] = stream.numbers("<f8", 3, "grid transform")  # translation, then scale
        matrix[[0, 1, 2], [0, 1, 2]] = stream.numbers("<f8", 3, "grid transform")
    elif map_type in ("ScaleMap", "UniformScaleMap"):
        matrix[[0, 1, 2], [0, 1, 2]] = stream.numbers("<f8", 3, "grid transform")
    elif map_type == "TranslationMap":
        matrix[3, :3] = stream.numbers("<f8", 3, "grid transform")
    elif map_type in ("AffineMap", "UnitaryMap"):  # a UnitaryMap writes the AffineMap it holds
        matrix = stream.numbers("<f8", 16, "grid transform").reshape(4, 4).copy()
    else:  # NonlinearFrustumMap, or a map this reader does not know
        linear = False if map_type == "NonlinearFrustumMap" else None  # None: not known here
        return {"map": map_type, "is_linear": linear, "matrix": None}
    return {"map": map_type, "is_linear": True, "matrix": matrix.tolist()}


def value_type(tree_type: str) -> str:
    """The value type of an OpenVDB tree type name: 'Tree_float_5_4_3' -> 'float', 'Tree_vec3s_5_4_3' ->
    'vec3s', 'Tree_int32_5_4_3' -> 'int32', 'Tree_ValueMask_5_4_3' -> 'mask', 'Tree_ptdataidx32_5_4_3' ->
    'ptdataidx32' (point data); the name itself when it is not a tree type."""
    parts = tree_type.removesuffix(_HALF_FLOAT_SUFFIX).split("_")
    if len(parts) < 3 or parts[0] != "Tree" or not all(part.isdigit() for part in parts[2:]):
        return tree_type
    return "mask" if parts[1] == "ValueMask" else parts[1]


def scan_file(path: str) -> dict:
    """What ``path`` holds, read in Python from its header, grid descriptors and each grid's metadata and
    transform (a few hundred bytes a grid; no voxel and no binding): every grid of every type, so a file
    with grids that the binding cannot read (int32, bool, mask, point data) still lists.

    Returns ``{"file", "version" (OpenVDB's file format version), "library_version" ([major, minor] of the
    OpenVDB that wrote it, where recorded), "file_metadata", "grids"}``; ``grids`` is None for a file
    written to a stream (no offsets to find each grid by), else a list of ``{"name", "type" (value type:
    'float', 'vec3s', 'int32', ...), "tree_type", "half_float", "instance_of", "class" ('fog volume',
    'level set', ..., 'unknown'), "readable" (mistyle reads float and vec3s grids), "metadata",
    "transform" ({"map", "is_linear", "matrix"})}``.

    Raises ConvertError naming the file when it is not an OpenVDB file or a size or offset that it
    declares lies past its end (a truncated or damaged file).
    """
    check_file(path)
    with open(path, "rb") as handle:
        try:
            return _scan(_Stream(handle, path, os.path.getsize(path)))
        except ConvertError as error:
            version = _file_version(handle)
            if version is None or version <= KNOWN_FILE_VERSION:
                raise
            # A layout newer than this reader knows may be why; say so rather than call the file damaged.
            raise ConvertError(
                f"{error} (The file has OpenVDB file format {version}, newer than the {KNOWN_FILE_VERSION} "
                "mistyle knows: if it reads in the OpenVDB that wrote it, please report this.)"
            ) from None


def _file_version(handle) -> int | None:
    """The file format version of an OpenVDB file (None when it does not start with the magic number)."""
    handle.seek(0)
    data = handle.read(12)
    if len(data) < 12 or int(np.frombuffer(data[:8], "<i8")[0]) != VDB_MAGIC:
        return None
    return int(np.frombuffer(data[8:], "<u4")[0])


def _scan(stream: _Stream) -> dict:
    """``scan_file``'s work, on an open file."""
    path, size = stream.path, stream.size
    if size < 8 or stream.number("<i8", "header") != VDB_MAGIC:
        raise ConvertError(f"{path} is not a readable OpenVDB file (it does not start with OpenVDB's magic number).")
    version = stream.number("<u4", "header")
    library = None
    if version < 211:  # separate major, minor and patch numbers
        version = 100 * version + 10 * stream.number("<u4", "header") + stream.number("<u4", "header")
    else:
        library = stream.numbers("<u4", 2, "header").tolist()
    offsets = version < _GRID_OFFSETS_VERSION or stream.read(1, "header") != b"\x00"
    if 220 <= version < 222:
        stream.read(1, "header")  # the file-wide compression flag
    stream.read(36 if version >= _UUID_VERSION else 16, "header")  # the UUID
    file_metadata = _metadata(stream, "file metadata")
    info = {"file": path, "version": version, "library_version": library, "file_metadata": file_metadata}
    if not offsets:  # grids written to a stream follow inline, with no offsets to find them by
        info["grids"] = None
        return info
    count = stream.number("<i4", "grid count")
    if not 0 <= count <= (size - stream.tell()) // 36:  # a descriptor takes at least 36 bytes
        raise ConvertError(
            f"{path} declares {count} grid(s), more than its last {size - stream.tell()} bytes can "
            f"describe; {stream.FIX}."
        )
    grids = []
    for _ in range(count):
        name = stream.string("grid name").split(_NAME_SEPARATOR)[0]
        tree_type = stream.string("grid type name")
        parent = stream.string("grid instance parent name") if version >= _INSTANCING_VERSION else ""
        start = stream.tell() + 24
        grid_at, block_at, end_at = stream.numbers("<i8", 3, "grid descriptor").tolist()
        if not start <= grid_at <= block_at <= end_at <= size:
            raise ConvertError(
                f"{path} declares a grid spanning bytes {grid_at}..{end_at} (voxel data from {block_at}), but "
                f"the file holds {size} bytes; {stream.FIX}."
            )
        stream.seek(grid_at)
        if version >= _GRID_COMPRESSION_VERSION:
            stream.read(4, "grid compression flags")
        metadata = _metadata(stream, f"grid '{name}' metadata")
        transform = _transform(stream, version)
        kind = value_type(tree_type)
        grids.append(
            {
                "name": name,
                "type": kind,
                "tree_type": tree_type,
                "half_float": tree_type.endswith(_HALF_FLOAT_SUFFIX),
                "instance_of": parent.split(_NAME_SEPARATOR)[0] or None,
                "class": str(metadata.get("class", "unknown")),
                "readable": kind in READABLE_TYPES,
                "metadata": metadata,
                "transform": transform,
            }
        )
        stream.seek(end_at)
    info["grids"] = grids
    return info


# ----------------------------------------------------------------------------- read
def describe(scan: dict) -> dict:
    """``file_info`` of a ``scan_file`` result that lists its grids: per grid the name, value type, class,
    whether mistyle reads it, the active voxel count and index box where the file records them (OpenVDB's
    writer does, as the grid metadata ``file_voxel_count`` and ``file_bbox_min``/``_max``), the transform
    (``matrix`` in OpenVDB's row-vector convention, ``voxel_size``) and the grid's metadata."""
    grids = []
    for grid in scan["grids"]:
        metadata, transform = grid["metadata"], grid["transform"]
        matrix = transform["matrix"]
        grids.append(
            {
                "name": grid["name"],
                "type": grid["type"],
                "class": grid["class"],
                "readable": grid["readable"],
                "half_float": grid["half_float"],
                "instance_of": grid["instance_of"],
                "active_voxel_count": metadata.get("file_voxel_count"),
                "index_min": metadata.get("file_bbox_min"),
                "index_max": metadata.get("file_bbox_max"),
                "map": transform["map"],
                "is_linear": transform["is_linear"],
                "matrix": matrix,
                # Row-vector convention: row a is the world step of one voxel along index axis a.
                "voxel_size": None if matrix is None else np.linalg.norm(np.array(matrix)[:3, :3], axis=1).tolist(),
                "metadata": metadata,
            }
        )
    return {
        "file": scan["file"],
        "version": scan["version"],
        "library_version": scan["library_version"],
        "grids": grids,
        "file_metadata": scan["file_metadata"],
    }


def choose_grid(path: str, grids: list[dict], name: str | None) -> dict:
    """The summary of the grid to read: ``name``, else 'density', else the only float grid. Only the
    chosen grid is ever read, so grids of other types (a Mantaflow cache's int32 'flags') do no harm."""
    if name is not None:
        matches = [g for g in grids if g["name"] == name]
        if not matches:
            raise ConvertError(f"{path} has no grid named '{name}'; it holds {describe_grids(grids)}.")
        if matches[0]["type"] not in READABLE_TYPES:
            raise ConvertError(
                f"Grid '{name}' of {path} holds {matches[0]['type']} values; mistyle reads float "
                f"(scalar) and vec3s (colour) grids. The file holds {describe_grids(grids)}."
            )
        return matches[0]
    floats = [g for g in grids if g["type"] == FLOAT_TYPE]
    if not floats:
        raise ConvertError(
            f"{path} holds no float grid to read as a density; it holds {describe_grids(grids)}. Export the "
            "density as a float (fog volume) grid."
        )
    for grid in floats:
        if grid["name"] == DENSITY_GRID:
            return grid
    if len(floats) == 1:
        return floats[0]
    raise ConvertError(
        f"{path} holds several float grids ({describe_grids(floats)}) and none is named "
        f"'{DENSITY_GRID}'; name the one to read (--grid NAME, or grid=NAME in mistyle.files.vdb.read_vdb)."
    )
