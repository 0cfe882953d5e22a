"""Copy some grids of an OpenVDB file into a new file, byte for byte: how the Mantaflow test files here were
cut down from a real Blender cache (tests/data/SOURCES.toml).

    python tests/data/subset_vdb.py IN.vdb OUT.vdb GRID [GRID ...]

Why not the binding: Debian's OpenVDB 10 binding cannot read a Mantaflow cache's int32 'flags' grid, which
is the grid the tests need, and rewriting would change the data (half floats, Blender's metadata). Each
grid's bytes, from its compression flags to the end of its voxel data, hold no file offset, so they are
copied unchanged; only the header's grid count and each descriptor's three offsets are written anew.
Files whose grids were written to a stream (no offsets) or that use grid instancing are refused.
"""

from __future__ import annotations

import struct
import sys
from pathlib import Path


def _string(data: bytes, at: int) -> tuple[bytes, int]:
    (length,) = struct.unpack_from("<I", data, at)
    return data[at + 4 : at + 4 + length], at + 4 + length


def subset(source: Path, target: Path, names: list[str]) -> list[str]:
    data = source.read_bytes()
    magic, version = struct.unpack_from("<qI", data, 0)
    if magic != 0x56444220 or not 222 <= version <= 225:
        raise SystemExit(f"{source}: not an OpenVDB file of format version 222-225 (got {version}).")
    at = 12 + 8  # magic, version, library major and minor
    if data[at] == 0:
        raise SystemExit(f"{source}: its grids were written to a stream, without offsets.")
    at += 1 + 36  # the offsets flag, the UUID
    (count,) = struct.unpack_from("<I", data, at)  # file metadata entries
    at += 4
    for _ in range(count):
        _, at = _string(data, at)
        _, at = _string(data, at)
        _, at = _string(data, at)
    header, at = data[:at], at
    (grids,) = struct.unpack_from("<i", data, at)
    at += 4
    kept = []
    for _ in range(grids):
        name, at = _string(data, at)
        kind, at = _string(data, at)
        parent, at = _string(data, at)
        grid, block, end = struct.unpack_from("<qqq", data, at)
        if parent:
            raise SystemExit(f"{source}: grid {name!r} is an instance of {parent!r}; instancing is not copied.")
        if name.decode() in names:
            kept.append((name, kind, data[grid:end], block - grid))
        at = end
    missing = set(names) - {name.decode() for name, *_ in kept}
    if missing:
        raise SystemExit(f"{source} has no grid named {', '.join(sorted(missing))}.")
    out = bytearray(header + struct.pack("<i", len(kept)))
    for name, kind, body, block in kept:
        for text in (name, kind, b""):
            out += struct.pack("<I", len(text)) + text
        grid = len(out) + 24
        out += struct.pack("<qqq", grid, grid + block, grid + len(body)) + body
    target.write_bytes(bytes(out))
    return [name.decode() for name, *_ in kept]


if __name__ == "__main__":
    if len(sys.argv) < 4:
        raise SystemExit(__doc__)
    print(subset(Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3:]))
