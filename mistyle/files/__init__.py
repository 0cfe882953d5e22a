"""Files: every read and write of mistyle's images, volumes, videos, style pictures and OpenVDB files.

Every file mistyle writes goes through ``atomic_output`` (``paths``), so a crash or a full disk never leaves
a half-written file. ``images``: linear OpenEXR, 8-bit PNG, environment maps, MP4 and GIF. ``volumes``:
Mitsuba ``.vol``, numpy ``.npy``/``.npz`` and ``.vdb`` densities, one frame or a sequence. ``styles``: style
pictures, decoded in one place (``load_style``). ``vdb``: OpenVDB files, read and written through the
binding of whichever interpreter has one (``vdb_convert``, ``vdb_header``; ``vdb_layout`` and ``vdb_frames``
say how mistyle lays its files out and reads a sequence's frames).
"""

from .images import (
    check_exr_layout,
    linear_to_srgb,
    load_envmap,
    read_exr,
    read_png,
    write_exr,
    write_gif,
    write_jpeg,
    write_mp4,
    write_png,
)
from .paths import atomic_output, atomic_write_bytes, check_link, check_writable_dir
from .styles import MAX_STYLE_SIDE, MIN_STYLE_SIZE, load_style
from .volumes import (
    DENSITY_SUFFIXES,
    DensityFrames,
    density_frame_files,
    load_density,
    load_density_frames,
    read_vol,
    vdb_frames_in_one_box,
    write_npy,
    write_npz,
    write_vol,
)

__all__ = [
    "DENSITY_SUFFIXES",
    "DensityFrames",
    "MAX_STYLE_SIDE",
    "MIN_STYLE_SIZE",
    "atomic_output",
    "atomic_write_bytes",
    "check_exr_layout",
    "check_link",
    "check_writable_dir",
    "density_frame_files",
    "linear_to_srgb",
    "load_density",
    "load_density_frames",
    "load_envmap",
    "load_style",
    "read_exr",
    "read_png",
    "read_vol",
    "vdb_frames_in_one_box",
    "write_exr",
    "write_gif",
    "write_jpeg",
    "write_mp4",
    "write_npy",
    "write_npz",
    "write_png",
    "write_vol",
]
