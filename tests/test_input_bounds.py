"""Every input file is checked before it costs memory or time, and a bad one fails with one clear line.

Real damaged files throughout: headers that declare more than the file holds, truncated archives and
images, symbolic link loops and broken links, values beyond float32, NaN pixels. The errors must come
at once (a lying header used to make numpy allocate what it declares), name the file, and say what to do.
"""

import os
import time
import zipfile

import numpy as np
import pytest
from numpy.lib import format as npy_format

import mistyle
from mistyle.conventions import MAX_EXTINCTION, MAX_GRID_VOXELS
from mistyle.files import (
    check_exr_layout,
    load_density,
    load_density_frames,
    load_envmap,
    load_style,
    read_exr,
    read_vol,
    write_exr,
    write_vol,
)
from mistyle.volume import validate_extinction


def one_line_error(call, *match):
    """``call()``'s ValueError, asserted to be one line holding every text of ``match``, raised within a second."""
    started = time.perf_counter()
    with pytest.raises(ValueError) as caught:
        call()
    message = str(caught.value)
    assert "\n" not in message and all(text in message for text in match), message
    assert time.perf_counter() - started < 1.0
    return message


def lying_npy_bytes(shape, payload: bytes) -> bytes:
    """An ``.npy`` whose header declares ``shape`` float32 but which holds ``payload`` after it."""
    import io

    buffer = io.BytesIO()
    npy_format.write_array_header_1_0(buffer, {"descr": "<f4", "fortran_order": False, "shape": shape})
    return buffer.getvalue() + payload


@pytest.fixture
def grid():
    """An 8^3 blob, largest density 1."""
    z, y, x = np.mgrid[:8, :8, :8]
    blob = np.clip(1.0 - np.sqrt((x - 3.5) ** 2 + (y - 3.5) ** 2 + (z - 3.5) ** 2) / 4.0, 0.0, None)
    return (blob / blob.max()).astype(np.float32)


# ----------------------------------------------------------------------------- declared sizes
def test_an_npy_header_declaring_more_than_the_file_holds_is_refused_before_allocating(tmp_path, grid):
    """numpy allocates what a header declares: 256 GiB for a 2 KB file that declares 4096^3 floats."""
    path = tmp_path / "lying.npy"
    path.write_bytes(lying_npy_bytes((4096, 4096, 4096), grid.tobytes()))
    one_line_error(lambda: load_density(path), "lying.npy", "4096x4096x4096", "truncated or its header is wrong")
    truncated = tmp_path / "truncated.npy"
    np.save(truncated, grid)
    truncated.write_bytes(truncated.read_bytes()[:-100])
    one_line_error(lambda: load_density(truncated), "truncated.npy", "only 1948 bytes follow")


def test_a_grid_beyond_the_voxel_bound_is_refused_by_its_header(tmp_path):
    """A file that really holds what it declares, but more voxels than mistyle reads: a sparse file of
    MAX_GRID_VOXELS + 1 bytes (its header declares uint8 values), read no further than the header."""
    side = round(MAX_GRID_VOXELS ** (1 / 3)) + 1
    header = lying_npy_bytes((side, side, side), b"").replace(b"'<f4'", b"'|u1'")
    path = tmp_path / "big.npy"
    with open(path, "wb") as handle:
        handle.write(header)
        handle.truncate(len(header) + side**3)  # a sparse file: no disk, no memory
    message = one_line_error(lambda: load_density(path), "big.npy", f"up to {MAX_GRID_VOXELS} voxels")
    assert "crop or downsample" in message


def test_npz_archives_truncated_damaged_or_lying_fail_in_one_line(tmp_path, grid):
    good = tmp_path / "good.npz"
    np.savez_compressed(good, density=grid)
    np.testing.assert_array_equal(load_density(good), grid)
    raw = good.read_bytes()
    (tmp_path / "truncated.npz").write_bytes(raw[: len(raw) // 2])
    one_line_error(lambda: load_density(tmp_path / "truncated.npz"), "truncated.npz", "not a complete .npz")
    # A stored (uncompressed) archive with 200 bytes of its member's data overwritten: the CRC fails.
    plain = tmp_path / "plain.npz"
    np.savez(plain, density=grid)
    damaged = bytearray(plain.read_bytes())
    damaged[1200:1400] = bytes(range(200))
    (tmp_path / "damaged.npz").write_bytes(bytes(damaged))
    one_line_error(lambda: load_density(tmp_path / "damaged.npz"), "damaged.npz", "density.npy is damaged")
    # A member whose .npy header declares 4096^3 floats.
    with zipfile.ZipFile(tmp_path / "lying.npz", "w") as archive:
        archive.writestr("density.npy", lying_npy_bytes((4096, 4096, 4096), grid.tobytes()))
    one_line_error(lambda: load_density(tmp_path / "lying.npz"), "lying.npz", "member density.npy", "4096x4096x4096")


def test_a_damaged_npy_header_is_one_line(tmp_path, grid):
    path = tmp_path / "scrambled.npy"
    np.save(path, grid)
    raw = bytearray(path.read_bytes())
    raw[20:30] = b"@#$%^&*()!"  # inside the header's dictionary
    path.write_bytes(bytes(raw))
    one_line_error(lambda: load_density(path), "scrambled.npy", "header is damaged", "np.save")


def test_vol_files_are_checked_against_their_size_before_reading(tmp_path, grid):
    path = write_vol(tmp_path / "cut.vol", grid)
    np.testing.assert_array_equal(read_vol(path), grid)
    path.write_bytes(path.read_bytes()[:-10])
    one_line_error(lambda: load_density(path), "cut.vol", "truncated")
    path.write_bytes(path.read_bytes()[:20])
    one_line_error(lambda: load_density(path), "cut.vol", "header is cut short (20 of", "truncated")
    colours = write_vol(tmp_path / "colours.vol", np.stack([grid] * 3, axis=-1))
    one_line_error(lambda: load_density(colours), "holds 3 values a voxel", "not a density", "--grid")


# ----------------------------------------------------------------------------- links
def test_symbolic_link_loops_and_broken_links_are_named(tmp_path, grid):
    loop = tmp_path / "loop.npy"
    loop.symlink_to(loop)
    one_line_error(lambda: load_density(loop), "loop.npy is a symbolic link loop")
    picture = tmp_path / "loop.png"
    picture.symlink_to(picture)
    one_line_error(lambda: load_style(picture), "loop.png is a symbolic link loop", "--style")
    gone = tmp_path / "gone.npy"
    gone.symlink_to(tmp_path / "nowhere.npy")
    one_line_error(lambda: load_density(gone), "gone.npy is a broken symbolic link", "nowhere.npy")


def test_a_frames_folder_with_a_broken_link_is_refused_naming_it(tmp_path, grid):
    """Skipping the link would render the sequence one frame short without a word."""
    frames = tmp_path / "frames"
    frames.mkdir()
    for number in (0, 1, 3):
        np.save(frames / f"smoke_{number:03d}.npy", grid)
    (frames / "smoke_002.npy").symlink_to(tmp_path / "elsewhere" / "smoke_002.npy")
    one_line_error(lambda: load_density_frames(frames), "smoke_002.npy is a broken symbolic link", "restore the frame")
    (frames / "smoke_002.npy").unlink()
    assert load_density_frames(frames).names == ["smoke_000", "smoke_001", "smoke_003"]


def test_a_folder_whose_frames_lie_in_a_subfolder_names_it(tmp_path, grid):
    """A Blender cache's root holds config/ and data/; its frames are in data/."""
    cache = tmp_path / "cache_fluid"
    (cache / "config").mkdir(parents=True)
    (cache / "data").mkdir()
    np.save(cache / "data" / "fluid_data_0001.npy", grid)
    one_line_error(lambda: load_density_frames(cache), "holds no", f"its subfolder {cache / 'data'} does")


def test_unpadded_frame_numbers_are_in_frame_order(tmp_path, grid):
    """Not every simulator pads its frame numbers: smoke_10 comes after smoke_9, not after smoke_1."""
    frames = tmp_path / "frames"
    frames.mkdir()
    for number in (1, 2, 9, 10, 11):
        np.save(frames / f"smoke_{number}.npy", grid * number)
    loaded = load_density_frames(frames)
    assert loaded.names == ["smoke_1", "smoke_2", "smoke_9", "smoke_10", "smoke_11"]
    assert [float(frame.max() / grid.max()) for frame in loaded.densities] == [1, 2, 9, 10, 11]


# ----------------------------------------------------------------------------- values
def test_float64_values_beyond_float32_are_named_as_such(tmp_path, grid):
    """1e300 is finite in float64 and inf in float32: the file holds no NaN/inf values to report."""
    density = grid.astype(np.float64)
    density[density > 0.5] = 1e300
    np.save(tmp_path / "wide.npy", density)
    message = one_line_error(lambda: load_density(tmp_path / "wide.npy"), "beyond float32's range", "1e+300")
    assert "NaN" not in message


def test_extinction_beyond_the_bound_is_refused_with_the_bound(grid):
    assert validate_extinction(grid * MAX_EXTINCTION / 20.0, 20.0) == pytest.approx(MAX_EXTINCTION)
    one_line_error(
        lambda: validate_extinction(grid * 8.4e5, 20.0, "blob.npy"),
        "blob.npy holds densities up to 8.4e+05",
        "extinction of 1.68e+07",
        f"up to {MAX_EXTINCTION:g}",
        "--density-scale",
    )


def test_stylize_refuses_a_density_whose_renders_would_not_end(mi, grid, tmp_path, tiny_checkpoint_factory):
    """Density 8.4e5 (below MAX_DENSITY) at scale 20: the colour match's path-traced renders take a time in
    proportion to the extinction, over a day; mistyle refuses it at once."""
    checkpoint = tiny_checkpoint_factory(tmp_path / "tiny.pt")
    style = np.random.default_rng(0).random((16, 16, 3)).astype(np.float32)
    started = time.perf_counter()
    with pytest.raises(ValueError, match=r"extinction of 1\.68e\+07 per box length; mistyle renders extinctions up to"):
        mistyle.stylize(grid * 8.4e5, style, checkpoint=checkpoint)
    assert time.perf_counter() - started < 10.0


# ----------------------------------------------------------------------------- environment maps
def test_truncated_exr_files_are_refused_from_their_chunk_table(tmp_path):
    rng = np.random.default_rng(3)
    path = write_exr(tmp_path / "sky.exr", rng.random((48, 64, 3)).astype(np.float32))
    whole = path.read_bytes()
    for length in (3, 60, 340, len(whole) // 2, len(whole) - 1):
        cut = tmp_path / f"cut{length}.exr"
        cut.write_bytes(whole[:length])
        one_line_error(lambda cut=cut: read_exr(cut), cut.name)  # noqa: B023
    check_exr_layout(path)
    assert read_exr(path).shape == (48, 64, 3)


def test_an_environment_map_is_checked_when_loaded(tmp_path):
    sky = np.ones((16, 32, 3), np.float32)
    np.testing.assert_array_equal(load_envmap(write_exr(tmp_path / "sky.exr", sky)), sky)
    whole = (tmp_path / "sky.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(whole[: len(whole) // 2])
    one_line_error(lambda: load_envmap(tmp_path / "cut.exr"), "environment map", "cut.exr", "truncated")
    sky[2:4, 3:6] = np.nan
    sky[9, 9, 1] = np.inf
    write_exr(tmp_path / "holes.exr", sky)
    one_line_error(lambda: load_envmap(tmp_path / "holes.exr"), "holes.exr holds 6 NaN and 1 infinite pixels")
    loop = tmp_path / "loop.exr"
    os.symlink(loop, loop)
    one_line_error(lambda: load_envmap(loop), "symbolic link loop")
