"""Looks (``mistyle.look``): fitted once, saved, loaded, applied to any frame; chunked renders merge, also
on a two-worker Dask cluster (``mistyle.farm``)."""

import json
import re

import numpy as np
import pytest
import torch
from PIL import Image

from mistyle.farm import frame_chunks
from mistyle.farm import main as farm_main
from mistyle.files import read_vol, write_vol
from mistyle.look import LOOK_VERSION, Look, LookSettings, default_key_frames, diverged, fit_look, parse_key_frames
from mistyle.ownership import MANIFEST_FILE
from mistyle.render_final import main
from mistyle.stylizer import Stylizer

STEPS = 3


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory, tiny_checkpoint_factory):
    return tiny_checkpoint_factory(tmp_path_factory.mktemp("ckpt") / "tiny.pt")


@pytest.fixture(scope="module")
def stylizer(checkpoint):
    return Stylizer(checkpoint)


@pytest.fixture(scope="module")
def style():
    rng = np.random.default_rng(0)
    return np.repeat(np.repeat(rng.random((8, 8, 3)), 4, axis=0), 4, axis=1).astype(np.float32)


def moving_frames(blob_density, count=4):
    return [np.roll(blob_density, shift, axis=2) for shift in range(count)]


@pytest.fixture(scope="module")
def look(stylizer, blob_density, style):
    return fit_look(stylizer, moving_frames(blob_density), style, settings=LookSettings(steps=STEPS))


def test_key_frames_default_to_first_middle_last_and_parse_checked():
    assert default_key_frames(1) == [0] and default_key_frames(2) == [0, 1] and default_key_frames(9) == [0, 4, 8]
    assert parse_key_frames("4, 0,4", 5) == [0, 4]
    for text, message in (("a,b", "comma-separated"), ("", "names no frame"), ("0,9", "outside")):
        with pytest.raises(ValueError, match=message):
            parse_key_frames(text, 5)


def test_a_look_fitted_again_is_the_same_bit_for_bit(look, stylizer, blob_density, style):
    """The fast layer's gradient is summed in one order (``backend.ordered_sums``): fitting again, as the
    preview does for the final render, gives the same look."""
    again = fit_look(stylizer, moving_frames(blob_density), style, settings=LookSettings(steps=STEPS))
    np.testing.assert_array_equal(again.apply(blob_density), look.apply(blob_density))


def test_a_fit_changes_the_network_and_a_saved_look_stylizes_as_the_fitted_one(
    look, stylizer, blob_density, style, tmp_path
):
    initial = stylizer.kernels(style)
    tuned = look.kernels.sites[3]["gamma"]
    assert not torch.equal(tuned, initial.sites[3]["gamma"])  # the fit moved the head's kernel
    assert look.meta["key_frames"] == [0, 1, 3] and np.isfinite(look.meta["final_loss"])
    albedo = look.stylize(blob_density)
    assert albedo.shape == blob_density.shape + (3,) and np.isfinite(albedo).all()
    assert 0 <= albedo.min() and albedo.max() <= 1
    path = look.save(tmp_path / "any name.mylook")
    assert path.stat().st_size < 2 << 20  # small beside a frame: the texture is at most 64^3 x 3 halves (1.5 MiB)
    loaded = Look.load(path, stylizer=stylizer)
    np.testing.assert_array_equal(loaded.stylize(blob_density), albedo)
    np.testing.assert_array_equal(loaded.thumbnail, look.thumbnail)
    assert loaded.density_scale == look.density_scale


def test_a_texture_only_look_leaves_the_network_as_it_was(stylizer, blob_density, style):
    """LookSettings.fixed_stage "logits": the head's logits are computed once, and the look keeps the
    network's kernels and convolutions; only its texture moves."""
    settings = LookSettings(steps=STEPS, tune_sites=(), tune_decoder=())
    assert settings.fixed_stage == "logits" and LookSettings().fixed_stage == "body"
    assert LookSettings(tune_sites=()).fixed_stage == "site" and LookSettings(tune_sites=(2, 3)).fixed_stage is None
    textured = fit_look(stylizer, [blob_density], style, settings=settings)
    initial = stylizer.kernels(style).without_noise()
    for site, kernel in initial.sites.items():
        for key, value in kernel.items():
            assert torch.equal(textured.kernels.sites[site][key], value)
    assert textured.decoder == {} and textured.texture.abs().max() > 0
    untextured = fit_look(
        stylizer,
        [blob_density],
        style,
        settings=LookSettings(steps=0, tune_sites=(), tune_decoder=()),
    )
    assert not np.allclose(textured.stylize(blob_density), untextured.stylize(blob_density))
    with pytest.raises(ValueError, match="must fit something"):
        LookSettings(tune_sites=(), tune_decoder=(), texture_side=0)


def test_the_fit_folds_the_head_and_fits_what_the_plain_head_fits(stylizer, blob_density, style, monkeypatch):
    """The default fit (``fixed_stage`` "body") computes the head as one convolution
    (``SKPN.folded_head_logits``); it must step as the plain head would (in float32: where the hardware
    has bfloat16 the fit runs it in that, which ``tests/test_skpn.py`` bounds)."""
    from mistyle.model import skpn
    from mistyle.model.skpn import SKPN

    monkeypatch.setattr(skpn, "inference_precision", lambda device: "fp32")
    settings = LookSettings(steps=STEPS)
    calls = []
    folded_head_logits = SKPN.folded_head_logits
    monkeypatch.setattr(SKPN, "folded_head_logits", lambda *a: calls.append(1) or folded_head_logits(*a))
    folded = fit_look(stylizer, [blob_density], style, settings=settings)
    assert len(calls) >= STEPS
    monkeypatch.setattr(SKPN, "folds_head", staticmethod(lambda kernels: False))
    plain = fit_look(stylizer, [blob_density], style, settings=settings)
    for key, value in plain.kernels.sites[3].items():
        torch.testing.assert_close(folded.kernels.sites[3][key], value, rtol=1e-3, atol=1e-5)
    np.testing.assert_allclose(folded.network_albedo(blob_density), plain.network_albedo(blob_density), atol=1e-4)


def test_a_texture_is_stretched_over_the_crop_as_trilinear_interpolation_would():
    """``stretch_texture`` (three small matrix products) gives what ``F.interpolate`` of the whole grid,
    cut to the crop window and padded to the head's grid, gives, and the same gradient."""
    import torch.nn.functional as F

    from mistyle.look import stretch_texture

    texture = torch.randn(3, 5, 4, 6, generator=torch.Generator().manual_seed(2))
    frame = {"size": (13, 10, 16), "window": (slice(4, 12), slice(0, 10), slice(2, 15))}
    padded = (8, 12, 16)
    weights = torch.randn((3,) + padded, generator=torch.Generator().manual_seed(3))

    def by_interpolation(values):
        whole = F.interpolate(values[None], size=frame["size"], mode="trilinear", align_corners=False)[0]
        cut = whole[(slice(None), *frame["window"])]
        return F.pad(cut, [p for n, m in reversed(list(zip(cut.shape[1:], padded))) for p in (0, m - n)])

    expected, leaf = by_interpolation(texture), texture.clone().requires_grad_()
    stretched = stretch_texture(leaf, frame, padded)
    torch.testing.assert_close(stretched, expected, rtol=1e-5, atol=1e-6)
    (stretched * weights).sum().backward()
    reference = texture.clone().requires_grad_()
    (by_interpolation(reference) * weights).sum().backward()
    torch.testing.assert_close(leaf.grad, reference.grad, rtol=1e-5, atol=1e-5)
    uncropped = {"size": (13, 10, 16), "window": None}
    torch.testing.assert_close(
        stretch_texture(texture, uncropped, (13, 10, 16)),
        F.interpolate(texture[None], size=(13, 10, 16), mode="trilinear", align_corners=False)[0],
        rtol=1e-5,
        atol=1e-6,
    )


def test_a_look_a_study_fitted_with_noise_fields_is_refused_in_one_line(look, tmp_path):
    """Noise fields were a study's arm (``LookSettings.noise_channels``, removed): a look file that has them,
    intact, is refused with the fix rather than applied without them."""
    from mistyle.look.fitted import PAYLOAD_DIGEST_KEY, payload_digest

    path = look.save(tmp_path / "ours.look")
    record = torch.load(path, weights_only=True)
    record["noise_weight"] = torch.zeros(3, 8)
    record["meta"] = {**record["meta"], "noise_channels": 8}
    record[PAYLOAD_DIGEST_KEY] = payload_digest(record)
    studied = tmp_path / "studied.look"
    torch.save(record, studied)
    with pytest.raises(ValueError, match=r"noise fields, which only a study fitted.*fit it again with --save-look"):
        Look.load(studied, stylizer=look.stylizer)


def test_frames_are_stylized_each_on_its_own(look, blob_density):
    frames = moving_frames(blob_density, 3)
    together = look.stylize(np.stack(frames))
    for frame, albedo in zip(frames, together):
        np.testing.assert_array_equal(look.stylize(frame), albedo)


def test_other_density_scales_and_sizes_get_a_note(look, blob_density):
    notes = []
    look.stylize(blob_density, density_scale=look.density_scale * 2, notes=notes)
    assert any("density scale" in note for note in notes)
    notes = []
    big = np.zeros((48, 48, 48), np.float32)
    big[8:40, 8:40, 8:40] = 1.0
    look.stylize(big, notes=notes)
    assert any("voxels across" in note for note in notes)


def test_damaged_foreign_and_mismatched_looks_are_one_clear_error(look, stylizer, tmp_path, tiny_checkpoint_factory):
    path = look.save(tmp_path / "good.look")
    (tmp_path / "garbage.look").write_bytes(b"\x00\x01 not a look")
    (tmp_path / "truncated.look").write_bytes(path.read_bytes()[:200])
    torch.save({"format": "mistyle-look", "version": LOOK_VERSION + 1}, tmp_path / "future.look")
    torch.save({"weights": torch.zeros(3)}, tmp_path / "foreign.look")
    torch.save({"format": "mistyle-look", "version": LOOK_VERSION, "meta": {}}, tmp_path / "hollow.look")
    cases = {
        "garbage.look": "is not a mistyle look \\(the file is not one --save-look writes\\)",
        "truncated.look": "not a readable mistyle look",
        "future.look": f"format version {LOOK_VERSION + 1}",
        "foreign.look": "is not a mistyle look",
        "hollow.look": "damaged mistyle look",
        "missing.look": "does not exist",
    }
    for name, message in cases.items():
        with pytest.raises(ValueError, match=message) as error:
            Look.load(tmp_path / name, stylizer=stylizer)
        assert "\n" not in str(error.value)
    other = Stylizer(tiny_checkpoint_factory(tmp_path / "other.pt", seed=1))
    with pytest.raises(ValueError, match="fitted with the network tiny.pt"):
        Look.load(path, stylizer=other)


def _rewritten(source, target, change):
    """``target``: the look record of ``source`` after ``change(record)``, saved as torch saves it."""
    record = torch.load(source, map_location="cpu", weights_only=True)
    change(record)
    torch.save(record, target)
    return target


def test_a_look_with_changed_bytes_is_refused_by_its_digest(look, stylizer, tmp_path):
    """torch keeps no checksum: 500 changed bytes of a tensor load as other numbers, which fail late (NaN
    albedos, blamed on the density or the light). The digest recorded at save finds them."""
    import zipfile

    path = look.save(tmp_path / "good.look")
    raw = path.read_bytes()
    with zipfile.ZipFile(path) as archive:
        member = max((i for i in archive.infolist() if "/data/" in i.filename), key=lambda i: i.file_size)
    start = member.header_offset + 30 + len(member.filename) + len(member.extra)
    damaged = bytearray(raw)
    damaged[start : start + min(500, member.file_size)] = b"\x7f" * min(500, member.file_size)
    (tmp_path / "changed.look").write_bytes(bytes(damaged))
    with pytest.raises(ValueError, match="changed.look is a damaged mistyle look .*SHA-256 recorded") as error:
        Look.load(tmp_path / "changed.look", stylizer=stylizer)
    assert "\n" not in str(error.value)


def test_looks_with_nan_huge_or_misshapen_tensors_are_refused_when_loaded(look, stylizer, tmp_path):
    """Looks saved before the digest was recorded still load, and every look is checked for finite values of
    a sane size and for the shapes the network takes, with or without a digest."""
    from mistyle.look import MAX_LOOK_VALUE, PAYLOAD_DIGEST_KEY, payload_digest

    path = look.save(tmp_path / "good.look")

    def legacy(record):
        del record[PAYLOAD_DIGEST_KEY]

    old = _rewritten(path, tmp_path / "old.look", legacy)
    np.testing.assert_array_equal(Look.load(old, stylizer=stylizer).thumbnail, look.thumbnail)

    def poison(record):
        record["kernels"]["3"]["gamma"][0, :3] = float("nan")
        record[PAYLOAD_DIGEST_KEY] = payload_digest(record)  # a digest does not make a value sane

    def huge(record):
        legacy(record)
        record["decoder"]["2.weight"] *= 10 * MAX_LOOK_VALUE

    def misshapen(record):
        legacy(record)
        record["kernels"]["3"]["beta"] = record["kernels"]["3"]["beta"][:, :-1].clone()

    def unmonotone(record):
        legacy(record)
        record["colour_match"]["shown_levels"] = record["colour_match"]["shown_levels"].flip(0)

    cases = {
        poison: "tensor kernels/3/gamma (1, 8) holds 3 NaN or infinite values",
        huge: "tensor decoder/2.weight holds values up to",
        misshapen: "kernels 3/beta (1, 7) do not have the shapes the network gives",
        unmonotone: "response does not increase",
    }
    for change, message in cases.items():
        bad = _rewritten(path, tmp_path / f"{change.__name__}.look", change)
        with pytest.raises(
            ValueError, match=f"{change.__name__}.look is a damaged mistyle look .*{re.escape(message)}"
        ):
            Look.load(bad, stylizer=stylizer)


def test_a_fit_that_ends_above_its_start_keeps_its_lowest_loss_values(stylizer, blob_density, style):
    assert not diverged([2.0, 1.5, 1.2, 1.1]) and diverged([2.0, 2.8, 2.4, 2.5]) and not diverged([1.0])
    notes, losses = [], []
    wild = LookSettings(steps=12, lr=5.0, texture_lr=5.0)  # steps this large throw the head to its bounds
    look = fit_look(
        stylizer, [blob_density], style, settings=wild, notes=notes, progress=lambda *a: losses.append(a[2])
    )
    assert min(losses) == losses[0] and np.mean(losses[-6:]) > losses[0]
    assert any("diverged" in note and "at step 1 of 12" in note for note in notes)
    # Its lowest loss was at the start: the look is the look of no step at all.
    start = fit_look(stylizer, [blob_density], style, settings=LookSettings(steps=0))
    assert np.array_equal(look.apply(blob_density), start.apply(blob_density))
    notes.clear()
    fit_look(stylizer, [blob_density], style, settings=LookSettings(steps=12), notes=notes)
    assert not any("diverged" in note for note in notes)


# ---------------------------------------------------------------------------- the command line
@pytest.fixture(scope="module")
def sequence(tmp_path_factory, blob_density):
    folder = tmp_path_factory.mktemp("sequence")
    frames = folder / "frames"
    frames.mkdir()
    for index, frame in enumerate(moving_frames(blob_density)):
        write_vol(frames / f"smoke_{index:03d}.vol", frame)
    rng = np.random.default_rng(1)
    Image.fromarray((rng.random((32, 32, 3)) * 255).astype(np.uint8)).save(folder / "style.png")
    return folder


def render(checkpoint, *arguments):
    return main(["--checkpoint", str(checkpoint), "--res", "16", "--spp", "2", "--quiet", *map(str, arguments)])


def files_of(folder):
    """The files of a render, but its report and manifest (their times differ from run to run)."""
    assert (folder / MANIFEST_FILE).is_file()
    skipped = ("report.json", MANIFEST_FILE)
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file() and p.name not in skipped}


def test_a_look_saved_once_renders_chunks_that_merge_into_the_single_run(checkpoint, sequence, look, tmp_path, capsys):
    frames, style = sequence / "frames", sequence / "style.png"
    wave = tmp_path / "wave.look"
    args = ["--density", frames, "--style", style, "--save-look", wave, "--key-frames", "0,3", "--look-steps", STEPS]
    assert render(checkpoint, *args) == 0
    assert wave.is_file() and not (tmp_path / "out").exists()

    whole, chunked = tmp_path / "whole", tmp_path / "chunked"
    assert render(checkpoint, "--density", frames, "--look", wave, "--out", whole) == 0
    assert render(checkpoint, "--density", frames, "--look", wave, "--out", chunked, "--frames", "2-3") == 0
    assert render(checkpoint, "--density", frames, "--look", wave, "--out", chunked, "--frames", "0-1") == 0
    assert files_of(whole) == files_of(chunked)
    assert "sequence_0003.exr" in files_of(whole) and "albedo_frame0000.npy" in files_of(whole)
    one, two = (json.loads((folder / "report.json").read_text()) for folder in (whole, chunked))
    assert one["frames"] == two["frames"] and list(two["frames"]) == ["0000", "0001", "0002", "0003"]
    assert [chunk["frames"] for chunk in two["chunks"]] == [[0, 1], [2, 3]]
    assert two["inputs"]["frames_in_sequence"] == 4 and two["rgb_swd"] == pytest.approx(one["rgb_swd"])

    # Rendering a chunk again replaces only its frames.
    kept = (chunked / "sequence_0000.exr").stat().st_mtime_ns
    assert render(checkpoint, "--density", frames, "--look", wave, "--out", chunked, "--frames", "3") == 0
    assert (chunked / "sequence_0000.exr").stat().st_mtime_ns == kept
    assert files_of(whole) == files_of(chunked)

    # A chunk of another look is refused, and leaves the folder as it was.
    other = look.save(tmp_path / "other.look")
    capsys.readouterr()
    assert render(checkpoint, "--density", frames, "--look", other, "--out", chunked, "--frames", "0") == 2
    assert "holds frames of another look" in capsys.readouterr().err
    assert files_of(whole) == files_of(chunked)


def test_a_sequence_starting_empty_renders_every_frame_and_its_chunks_merge(checkpoint, sequence, tmp_path):
    """A simulation's cache whose first frames are empty (its emitter starts later): the command renders
    every frame, the empty ones as they are, and a chunk of empty frames (a farm's first) renders too."""
    frames = tmp_path / "frames"
    frames.mkdir()
    for index, source in enumerate(sorted((sequence / "frames").iterdir())):
        density = read_vol(source)
        write_vol(frames / f"smoke_{index + 2:03d}.vol", density)
    for index in range(2):
        write_vol(frames / f"smoke_{index:03d}.vol", np.zeros_like(density))
    wave = tmp_path / "wave.look"
    args = ["--density", frames, "--style", sequence / "style.png", "--save-look", wave, "--look-steps", STEPS]
    assert render(checkpoint, *args) == 0
    assert Look.load(wave, checkpoint=checkpoint).meta["key_frames"] == [2, 3, 5]  # first, middle, last with medium
    whole, chunked = tmp_path / "whole", tmp_path / "chunked"
    assert render(checkpoint, "--density", frames, "--look", wave, "--out", whole) == 0
    for chunk in ("0-1", "2-5"):
        assert render(checkpoint, "--density", frames, "--look", wave, "--out", chunked, "--frames", chunk) == 0
    assert files_of(whole) == files_of(chunked)
    report = json.loads((whole / "report.json").read_text())
    assert len(report["frames"]) == 6 and any("0-1 hold no medium" in note for note in report["notes"])
    assert np.all(np.load(whole / "albedo_frame0000.npy") == 0.5)


def test_a_looks_texture_travels_with_the_frames_velocities(look, blob_density):
    # The blob moves four voxels a frame along x through a wider box. The network is shift-equivariant
    # by four voxels (its crop's corner is rounded to four), so all that would not follow the blob is
    # the look's texture, fixed over the box unless it is carried by the velocities.
    wide = np.pad(blob_density, ((0, 0), (0, 0), (8, 28)))
    frames = [np.roll(wide, 4 * t, axis=2) for t in range(5)]
    velocities = [np.broadcast_to(np.float32([4, 0, 0]), wide.shape + (3,)) for _ in frames]
    carried, fixed = look.stylize(frames, velocities=velocities), look.stylize(frames)
    assert np.array_equal(carried[0], fixed[0])

    def change(albedos):  # each frame against the first moved with the blob, where the blob is
        inside = [np.roll(wide > 0.05, 4 * t, axis=2) for t in range(5)]
        return max(np.abs(albedos[t] - np.roll(albedos[0], 4 * t, axis=2))[inside[t]].max() for t in range(1, 5))

    assert change(carried) < 0.01 and change(fixed) > 0.1  # carried: up to rounding in the warps
    with pytest.raises(ValueError, match="one velocity per frame"):
        look.stylize(frames, velocities=velocities[:2])


def test_chunks_of_a_sequence_with_velocities_merge_into_the_single_run(checkpoint, look, blob_density, tmp_path):
    """A chunk's texture follows the velocities of the frames before it, as the whole run's does."""
    frames = tmp_path / "frames"
    frames.mkdir()
    velocity = np.broadcast_to(np.float32([1, 0, 0]), blob_density.shape + (3,))
    for index, frame in enumerate(moving_frames(blob_density, 10)):
        np.savez(frames / f"smoke_{index:03d}.npz", density=frame, velocity=velocity)
    wave = look.save(tmp_path / "wave.look")
    whole, chunked = tmp_path / "whole", tmp_path / "chunked"
    assert render(checkpoint, "--density", frames, "--look", wave, "--out", whole) == 0
    for chunk in ("9", "0-8"):
        assert render(checkpoint, "--density", frames, "--look", wave, "--out", chunked, "--frames", chunk) == 0
    assert files_of(whole) == files_of(chunked)


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--look", "{look}", "--strength", "0.5", "--out", "{out}"], "full strength"),
        (["--look", "{look}", "--look-steps", "5", "--out", "{out}"], "--look applies a look already fitted"),
        (["--look", "{look}", "--resume", "--overwrite", "--out", "{out}"], "give one of the two"),
        (["--style", "{style}", "--key-frames", "0", "--refine", "0", "--out", "{out}"], "leave out"),
        (["--look", "{look}", "--frames", "5-9", "--out", "{out}"], "outside"),
        (["--style", "{style}", "--frames", "0-1", "--out", "{out}"], "renders chunks from a look"),
        (["--look", "{look}", "--frames", "b-a", "--out", "{out}"], "--frames takes A-B"),
        (["--look", "{garbage}", "--out", "{out}"], "is not a mistyle look (the file is not one --save-look writes)"),
        (["--style", "{style}", "--save-look", "{out}/missing/x.look"], "folder does not exist"),
        (["--style", "{style}"], "--out is required"),
    ],
)
def test_bad_look_options_are_one_clear_line(checkpoint, sequence, look, tmp_path, capsys, arguments, message):
    good = look.save(tmp_path / "good.look")
    (tmp_path / "garbage.look").write_bytes(b"nope")
    values = dict(look=good, garbage=tmp_path / "garbage.look", style=sequence / "style.png", out=tmp_path / "out")
    code = render(checkpoint, "--density", sequence / "frames", *[a.format(**values) for a in arguments])
    error = capsys.readouterr().err
    assert code == 2 and message in error and len(error.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------- the farm
def test_frame_chunks_cover_the_range_once():
    assert frame_chunks(10, 4) == [(0, 3), (4, 7), (8, 9)]
    assert frame_chunks(10, 3, (2, 6)) == [(2, 4), (5, 6)]
    with pytest.raises(ValueError, match="outside"):
        frame_chunks(4, 2, (3, 5))
    with pytest.raises(ValueError, match="at least 1"):
        frame_chunks(4, 0)


def test_a_two_worker_cluster_renders_what_one_process_renders(tmp_path, blob_density, tiny_checkpoint_factory):
    from PIL import Image

    checkpoint = tiny_checkpoint_factory(tmp_path / "tiny.pt")
    frames = tmp_path / "frames"
    frames.mkdir()
    for index, frame in enumerate(moving_frames(blob_density, 5)):
        write_vol(frames / f"f_{index:02d}.vol", frame)
    Image.fromarray((np.random.default_rng(2).random((32, 32, 3)) * 255).astype(np.uint8)).save(tmp_path / "s.png")
    options = ["--checkpoint", str(checkpoint), "--res", "16", "--spp", "2", "--quiet"]
    look = tmp_path / "s.look"
    fit = ["--density", frames, "--style", tmp_path / "s.png", "--save-look", look, "--look-steps", "2"]
    assert main([*map(str, fit), *options]) == 0
    single = tmp_path / "single"
    # One torch thread, as each worker has (dask gives a one-thread worker OMP_NUM_THREADS=1): on some CPUs
    # (AMX) oneDNN's convolutions round differently with another thread count, by about 1e-4 in albedo.
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        assert main(["--density", str(frames), "--look", str(look), "--out", str(single), *options]) == 0
    finally:
        torch.set_num_threads(threads)

    farmed = tmp_path / "farmed"
    argv = ["--local-workers", "2", "--density", str(frames), "--look", str(look), "--out", str(farmed)]
    assert farm_main([*argv, "--chunk", "2", "--", *options]) == 0
    assert files_of(single) == files_of(farmed)


def test_a_look_renders_a_single_frame_file_and_the_api_fits_one(checkpoint, sequence, look, tmp_path):
    import mistyle

    path = look.save(tmp_path / "a.look")
    out = tmp_path / "single"
    assert render(checkpoint, "--density", sequence / "frames" / "smoke_001.vol", "--look", path, "--out", out) == 0
    report = json.loads((out / "report.json").read_text())
    assert (out / "final.exr").is_file() and report["inputs"]["refine_steps"] == 0

    fitted = mistyle.fit_look(
        sequence / "frames",
        sequence / "style.png",
        key_frames=[1],
        checkpoint=checkpoint,
        settings=LookSettings(steps=1),
    )
    assert fitted.meta["key_frames"] == [1] and fitted.meta["style"] == "style.png"
