"""The stylize API and ``python -m mistyle.render_final``: outputs, reports and bad input."""

import json

import numpy as np
import pytest
import torch
from PIL import Image

import mistyle
import mistyle.stops
from mistyle.files import read_vol, write_vol
from mistyle.render_final import main


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory, tiny_checkpoint_factory):
    """An untrained tiny-config SKPN in the training checkpoint format."""
    return tiny_checkpoint_factory(tmp_path_factory.mktemp("ckpt") / "tiny.pt")


@pytest.fixture(scope="module")
def inputs(tmp_path_factory, blob_density):
    folder = tmp_path_factory.mktemp("inputs")
    write_vol(folder / "blob.vol", blob_density)
    rng = np.random.default_rng(0)
    Image.fromarray((rng.random((32, 32, 3)) * 255).astype(np.uint8)).save(folder / "style.png")
    Image.fromarray((rng.random((32, 32, 4)) * 255).astype(np.uint8), "RGBA").save(folder / "rgba.png")
    Image.fromarray((rng.random((32, 32)) * 255).astype(np.uint8), "L").save(folder / "grey.png")
    Image.fromarray((rng.random((32, 32)) * 65535).astype(np.uint16)).save(folder / "deep.png")
    Image.fromarray(np.zeros((1, 1, 3), np.uint8)).save(folder / "dot.png")
    Image.fromarray(np.full((8, 600, 3), 90, np.uint8)).save(folder / "sliver.png")  # 3 px high at 256 wide
    (folder / "notes.txt").write_text("not an image")
    (folder / "no_images").mkdir()
    np.save(folder / "nan.npy", np.full((8, 8, 8), np.nan, np.float32))
    np.save(folder / "negative.npy", -np.ones((8, 8, 8), np.float32))
    np.save(folder / "zeros.npy", np.zeros((8, 8, 8), np.float32))
    np.save(folder / "empty.npy", np.zeros((0, 8, 8), np.float32))
    np.save(folder / "huge.npy", np.full((8, 8, 8), 1e20, np.float32))
    (folder / "garbage.pt").write_bytes(b"\x00not a checkpoint")
    return folder


def test_stylize_api_any_shape_frames_and_sequences(mi, checkpoint, blob_density):
    style = np.random.default_rng(1).random((40, 30, 3)).astype(np.float32)
    albedo = mistyle.stylize(blob_density, style, checkpoint=checkpoint)
    assert albedo.shape == blob_density.shape + (3,) and albedo.dtype == np.float32
    assert 0 <= albedo.min() and albedo.max() <= 1
    odd = np.pad(blob_density, ((0, 1), (2, 0), (0, 3)))
    assert mistyle.stylize(odd, style, checkpoint=checkpoint).shape == odd.shape + (3,)
    frames = np.stack([blob_density, blob_density[::-1]])
    sequence = mistyle.stylize(frames, style, checkpoint=checkpoint)
    assert sequence.shape == frames.shape + (3,)
    np.testing.assert_allclose(sequence[0], albedo, atol=1e-6)  # frames are independent
    scaled = mistyle.stylize(blob_density, style, checkpoint=checkpoint, scale_structures=2.0)
    assert scaled.shape == albedo.shape and not np.allclose(scaled, albedo)


def test_render_api_path_traces_the_medium(mi, blob_density):
    albedo = np.full(blob_density.shape + (3,), 0.8, np.float32)
    raw = mistyle.render(blob_density, albedo, res=24, spp=8, denoise="none")
    assert raw.shape == (24, 24, 3) and raw.max() > 0.1 and raw[0, 0].max() == 0  # no medium, no light
    image = mistyle.render(blob_density, albedo, res=24, spp=8)  # denoised: the filter spreads a trace
    assert image.shape == (24, 24, 3) and image.max() > 0.1 and image[0, 0].max() < 0.01 * image.max()


@pytest.mark.parametrize("light", ["constant:2", "point:0,1.5,1.5:20", "area:4"])
def test_render_api_lights(mi, blob_density, light):
    albedo = np.full(blob_density.shape + (3,), 0.8, np.float32)
    image = mistyle.render(blob_density, albedo, res=16, spp=4, light=light)
    assert np.isfinite(image).all() and image.max() > 0


def test_environment_map_lights_the_side_it_is_bright_on(mi, blob_density, tmp_path):
    from mistyle.files import write_exr

    albedo = np.full(blob_density.shape + (3,), 0.8, np.float32)

    def top_over_bottom(bright_rows):
        sky = np.ones((8, 16, 3), np.float32)
        sky[bright_rows] = 6.0
        image = mistyle.render(
            blob_density, albedo, view=0.25, res=24, spp=32, light=f"envmap:{write_exr(tmp_path / 'sky.exr', sky)}"
        )
        luminance = image.mean(axis=-1)
        return luminance[:12].mean() / luminance[12:].mean()

    # Rows 0-3 of a latitude-longitude map are the upper hemisphere (+y, the image's top).
    assert top_over_bottom(slice(0, 4)) > 1.5 * top_over_bottom(slice(4, 8))


def test_render_final_turntable_writes_everything(mi, checkpoint, inputs, tmp_path):
    out = tmp_path / "out"
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(inputs / "blob.vol"),
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(out),
            "--res",
            "24",
            "--spp",
            "4",
            "--turntable",
            "3",
            "--refine",
            "1",
        ]
    )
    assert code == 0
    names = {p.name for p in out.iterdir()}
    assert {
        "albedo.vol",
        "albedo.npy",
        "report.json",
        "turntable.mp4",
        "turntable.gif",
        "turntable_0000.exr",
        "turntable_0002.png",
        "turntable_0001_network_layer.png",
        "sheet.png",
        "scene.xml",
        "density.vol",
        "albedo_refined.vol",
    } <= names
    report = json.loads((out / "report.json").read_text())
    for key in (
        "stylize_seconds",
        "render_seconds",
        "swd_final",
        "swd_layer",
        "rgb_swd",
        "patch_swd",
        "hue_coverage",
        "refine_seconds",
    ):
        assert key in report, key
    assert (out / "turntable.mp4").stat().st_size > 1000 and (out / "turntable.mp4").read_bytes()[4:8] == b"ftyp"
    assert np.load(out / "albedo.npy").shape == (16, 18, 20, 3)
    hidden = [p.name for p in out.iterdir() if p.name.startswith(".")]
    assert hidden == [".mistyle-manifest.json"]  # no temporary file left, only the record of what the run wrote


def given(checkpoint, density, style) -> list[str]:
    """The options naming a run's network and inputs."""
    return ["--checkpoint", str(checkpoint), "--density", str(density), "--style", str(style)]


def two_moving_frames(tmp_path, blob_density):
    """A folder of two frames: the density moved one voxel along x, with that velocity."""
    frames = tmp_path / "frames"
    frames.mkdir()
    for index in range(2):
        np.savez(
            frames / f"frame{index:04d}.npz",
            density=np.roll(blob_density, index, axis=2),
            velocity=np.tile(np.float32([1, 0, 0]), blob_density.shape + (1,)),
        )
    return frames


def test_render_final_sequence_with_velocity_reports_flicker(mi, checkpoint, inputs, tmp_path, blob_density):
    frames = two_moving_frames(tmp_path, blob_density)
    out = tmp_path / "out"
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(frames),
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(out),
            "--res",
            "16",
            "--spp",
            "2",
            "--coat",
            "dielectric:1.4",
            "--look-steps",
            "2",
        ]
    )
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert report["inputs"]["frames"] == 2 and report["temporal_flicker"] >= 0 and report["temporal_flicker_look"] >= 0
    assert report["inputs"]["refine_steps"] == 0  # a look instead: refined frames flicker
    assert report["look_key_frames"] == [0, 1]
    assert (out / "albedo_refined_frame0001.vol").is_file() and (out / "sequence.gif").is_file()
    chosen = tmp_path / "chosen"
    inputs_given = given(checkpoint, frames, inputs / "style.png")
    assert (
        main(
            [*inputs_given, "--out", str(chosen), "--res", "8", "--spp", "1", "--key-frames", "1", "--look-steps", "1"]
        )
        == 0
    )
    assert json.loads((chosen / "report.json").read_text())["look_key_frames"] == [1]


def test_the_default_outputs_look_fit_shows_its_progress(mi, checkpoint, inputs, tmp_path, monkeypatch, capsys):
    """A look's fit takes tens of seconds: the default output shows it as a bar, which the Blender
    add-on reads as lines (``MISTYLE_PROGRESS=lines``)."""
    from mistyle.progress import PROGRESS_ENV

    monkeypatch.setenv(PROGRESS_ENV, "lines")
    inputs_given = given(checkpoint, inputs / "blob.vol", inputs / "style.png")
    assert main([*inputs_given, "--out", str(tmp_path / "out"), "--res", "8", "--spp", "1", "--look-steps", "3"]) == 0
    assert "fitting a look: 100%" in capsys.readouterr().err


def test_a_sequence_that_starts_as_a_wisp_is_matched_on_a_frame_the_layer_sees(
    mi, checkpoint, inputs, tmp_path, blob_density
):
    frames = tmp_path / "frames"
    frames.mkdir()
    wisp = np.zeros_like(blob_density)
    wisp[6:8, 6:8, 6:8] = 1e-4  # a simulation's first frame: too thin to be seen
    for index, density in enumerate([wisp, blob_density, np.roll(blob_density, 1, axis=2)]):
        np.savez(frames / f"frame{index:04d}.npz", density=density)
    out = tmp_path / "out"
    inputs_given = given(checkpoint, frames, inputs / "style.png")
    assert main([*inputs_given, "--out", str(out), "--res", "16", "--spp", "2", "--look-steps", "2"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert any("1 of 3 image(s) see no medium" in note for note in report["notes"])  # the wisp is invisible
    assert not any("colour match" in note for note in report["notes"])  # the look's and the network's
    assert report["rgb_swd"] is not None and report["patch_swd"] is not None  # of the frames that see the medium


def test_refined_sequence_frames_start_from_the_warped_previous_frame(mi, checkpoint, inputs, tmp_path, blob_density):
    frames = two_moving_frames(tmp_path, blob_density)
    out = tmp_path / "out"
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(frames),
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(out),
            "--res",
            "16",
            "--spp",
            "2",
            "--refine",
            "2",
            "--refine-path",
            "0",
        ]
    )
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert report["inputs"]["refine_steps"] == 2 and report["temporal_flicker_refined"] >= 0
    assert all(np.isfinite(read_vol(out / f"albedo_refined_frame{index:04d}.vol")).all() for index in range(2))


def test_mesh_is_voxelized_and_coated(mi, checkpoint, inputs, tmp_path):
    from mistyle.data.mesh import icosphere, write_ply

    mesh = write_ply(tmp_path / "ball.ply", *icosphere(2))
    out = tmp_path / "out"
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--mesh",
            str(mesh),
            "--mesh-res",
            "12",
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(out),
            "--res",
            "16",
            "--spp",
            "2",
            "--coat",
            "dielectric:1.5",
            "--refine",
            "0",
        ]
    )
    assert code == 0
    assert (out / "coat_mesh.ply").is_file() and np.load(out / "albedo.npy").shape == (12, 12, 12, 3)
    assert json.loads((out / "report.json").read_text())["inputs"]["coat_ior"] == 1.5


def test_refine_through_the_layer_then_the_path_tracer(mi, checkpoint, inputs, tmp_path):
    out = tmp_path / "out"
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(inputs / "blob.vol"),
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(out),
            "--res",
            "16",
            "--spp",
            "2",
            "--refine",
            "2",
            "--refine-path",
            "1",
        ]
    )
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert report["refine_seconds"] > 0 and report["inputs"]["refine_path_steps"] == 1
    refined = read_vol(out / "albedo_refined.vol")
    assert refined.shape == (16, 18, 20, 3) and not np.allclose(refined, np.load(out / "albedo.npy"))


@pytest.mark.parametrize(
    "style, note", [("rgba.png", "alpha composited"), ("grey.png", "greyscale"), ("deep.png", "16-bit")]
)
def test_unusual_style_images_are_converted_with_a_note(mi, checkpoint, inputs, tmp_path, capsys, style, note):
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(inputs / "blob.vol"),
            "--style",
            str(inputs / style),
            "--out",
            str(tmp_path / "out"),
            "--res",
            "16",
            "--spp",
            "1",
            "--refine",
            "0",
        ]
    )
    assert code == 0 and note in capsys.readouterr().err


@pytest.mark.parametrize(
    "change, message",
    [
        ({"--style": "dot.png"}, "needs at least"),
        ({"--style": "sliver.png"}, "Crop it to a picture at most 32 times"),
        ({"--style": "notes.txt"}, "not a readable image"),
        ({"--style": "missing.png"}, "does not exist"),
        ({"--density": "nan.npy"}, "NaN"),
        ({"--density": "negative.npy"}, "negative"),
        ({"--density": "zeros.npy"}, "all zero"),
        ({"--density": "empty.npy"}, "empty"),
        ({"--checkpoint": "garbage.pt"}, "is not a mistyle checkpoint (not a file torch.save writes)"),
        ({"--light": "laser"}, "not a known light"),
        ({"--vgg-weights": "missing.pt"}, "--vgg-weights missing.pt does not exist"),
        ({"--light": "envmap:missing.exr"}, "does not exist"),
        ({"--density-scale": "-1"}, "--density-scale must lie in"),
        ({"--style": "no_images"}, "holds no images"),
        ({"--density": "huge.npy"}, "mistyle takes densities up to"),
        ({"--light": "constant:-5"}, "must be a finite number > 0"),
        ({"--light": "point:nan,0,0"}, "must be finite"),
        ({"--camera-distance": "0.1"}, "--camera-distance must lie in"),
        ({"--camera-distance": "0"}, "--camera-distance must lie in"),
        ({"--max-depth": "0"}, "--max-depth must be -1"),
        ({"--max-depth": "-5"}, "--max-depth must be -1"),
        ({"--view": "1.5"}, "--view is an orbit position"),
        ({"--coat": "dielectric:9"}, "index of refraction in (1, 4)"),
        ({"--bricks": "-1"}, "--bricks must lie in"),
        ({"--bricks": "4", "--coat": "dielectric:1.5"}, "--bricks needs one medium under --coat"),
    ],
)
def test_bad_input_is_a_clear_error_and_leaves_nothing(mi, checkpoint, inputs, tmp_path, capsys, change, message):
    arguments = {
        "--checkpoint": str(checkpoint),
        "--density": str(inputs / "blob.vol"),
        "--style": str(inputs / "style.png"),
    }
    arguments.update(
        {
            key: str(inputs / value) if key in ("--style", "--density", "--checkpoint") else value
            for key, value in change.items()
        }
    )
    out = tmp_path / "out"
    code = main(
        [item for pair in arguments.items() for item in pair] + ["--out", str(out), "--res", "16", "--spp", "1"]
    )
    error = capsys.readouterr().err
    assert code == 2 and message in error and "Traceback" not in error, error
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == []


def test_random_bad_option_values_give_one_clear_line_and_write_nothing(mi, checkpoint, inputs, tmp_path, capsys):
    rng = np.random.default_rng(7)
    bad = {
        "--spp": ["0", "-3", "100000000"],
        "--res": ["0", "4", "99999"],
        "--turntable": ["-1", "99999"],
        "--fps": ["0", "-2"],
        "--refine": ["-1", "1000000"],
        "--max-depth": ["0", "-2", "-100"],
        "--view": ["-0.1", "1", "nan", "inf"],
        "--camera-distance": ["0", "-2", "nan", "0.5", "1e9"],
        "--density-scale": ["0", "-1", "nan", "inf", "1e30"],
        "--scale-structures": ["0", "100", "nan"],
        "--working-size": ["-1", "8", "5000"],
        "--mesh-res": ["1", "99999"],
        "--light": ["constant:-1", "constant:nan", "point:1,2", "area:-4", "sun"],
        "--coat": ["dielectric:1", "dielectric:nan", "glass"],
    }
    for option in rng.permutation(list(bad)):
        value = str(rng.choice(bad[option]))
        out = tmp_path / "out"
        try:
            code = main(
                [
                    "--checkpoint",
                    str(checkpoint),
                    "--density",
                    str(inputs / "blob.vol"),
                    "--style",
                    str(inputs / "style.png"),
                    "--out",
                    str(out),
                    "--res",
                    "16",
                    "--spp",
                    "1",
                    option,
                    value,
                ]
            )
        except SystemExit as exit:  # argparse refuses values of the wrong type with its usage line
            code = exit.code
        error = capsys.readouterr().err
        assert code == 2 and "error:" in error and "Traceback" not in error, (option, value, error)
        assert not any(tmp_path.iterdir()), (option, value)


def test_an_interrupted_run_leaves_the_previous_output_untouched(mi, checkpoint, inputs, tmp_path, monkeypatch):
    from mistyle import job

    out = tmp_path / "out"
    arguments = [
        "--checkpoint",
        str(checkpoint),
        "--density",
        str(inputs / "blob.vol"),
        "--style",
        str(inputs / "style.png"),
        "--out",
        str(out),
        "--res",
        "16",
        "--spp",
        "1",
        "--refine",
        "0",
    ]
    assert main(arguments) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(job.run, "write_report", interrupted)
    assert main(arguments + ["--view", "0.5", "--overwrite"]) == 130
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no staging folder or lock left


def test_a_second_run_into_an_output_in_use_is_refused(mi, checkpoint, inputs, tmp_path, capsys, monkeypatch):
    """At once, before the network loads: the lock is taken when the output is written."""
    import mistyle.pipeline
    from mistyle.ownership import staged_directory

    def loaded(*args, **kwargs):
        raise AssertionError("the network was loaded for a run that is refused")

    monkeypatch.setattr(mistyle.pipeline, "Pipeline", loaded)
    out = tmp_path / "out"
    with staged_directory(out):
        code = main(
            [
                "--checkpoint",
                str(checkpoint),
                "--density",
                str(inputs / "blob.vol"),
                "--style",
                str(inputs / "style.png"),
                "--out",
                str(out),
                "--res",
                "16",
                "--spp",
                "1",
                "--refine",
                "0",
            ]
        )
        assert code == 2 and "Another mistyle run is writing to" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == [".mistyle-manifest.json"]  # the empty output, and nothing else


def test_checkpoint_from_another_config_is_refused(mi, checkpoint, inputs, tmp_path, capsys):
    payload = torch.load(checkpoint, weights_only=True)
    payload["config"]["model"]["widths"] = [4, 8, 8]
    other = tmp_path / "other.pt"
    torch.save(payload, other)
    code = main(
        [
            "--checkpoint",
            str(other),
            "--density",
            str(inputs / "blob.vol"),
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert code == 2 and "does not match" in capsys.readouterr().err


def test_unwritable_output_directory(mi, checkpoint, inputs, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(inputs / "blob.vol"),
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(blocker / "out"),
        ]
    )
    assert code == 2 and "Cannot write to the output directory" in capsys.readouterr().err


# ---------------------------------------------------------------------------- fitting artists' pipelines
FAST = ["--res", "16", "--spp", "1", "--refine", "0"]


def test_a_batch_writes_one_named_output_per_pair_and_an_index(mi, checkpoint, inputs, tmp_path, blob_density):
    styles = tmp_path / "styles"
    styles.mkdir()
    for name in ("wave", "night"):
        (styles / f"{name}.png").write_bytes((inputs / "style.png").read_bytes())
    (styles / "readme.txt").write_text("not a style")
    np.save(tmp_path / "ball.npy", blob_density[:, ::-1])
    out = tmp_path / "batch"
    arguments = [
        "--checkpoint",
        str(checkpoint),
        "--density",
        str(inputs / "blob.vol"),
        str(tmp_path / "ball.npy"),
        "--style",
        str(styles),
        "--out",
        str(out),
        *FAST,
    ]
    assert main(arguments) == 0
    folders = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert folders == ["ball__night", "ball__wave", "blob__night", "blob__wave"]
    index = (out / "index.html").read_text()
    for folder in folders:
        assert (out / folder / "sheet.png").is_file() and f"{folder}/sheet.png" in index
        report = json.loads((out / folder / "report.json").read_text())
        assert report["inputs"]["style"].endswith(f"{folder.split('__')[1]}.png")
    before = (out / "blob__wave" / "report.json").read_bytes()
    # A second run into existing outputs is refused before any work, and changes nothing.
    assert main(arguments) == 2
    assert (out / "blob__wave" / "report.json").read_bytes() == before
    assert main(arguments + ["--overwrite", "--view", "0.5"]) == 0
    assert json.loads((out / "blob__wave" / "report.json").read_text())["inputs"]["views"] == 1


def test_an_existing_output_is_refused_without_overwrite(mi, checkpoint, inputs, tmp_path, capsys):
    out = tmp_path / "out"
    arguments = [
        "--checkpoint",
        str(checkpoint),
        "--density",
        str(inputs / "blob.vol"),
        "--style",
        str(inputs / "style.png"),
        "--out",
        str(out),
        *FAST,
    ]
    assert main(arguments) == 0
    capsys.readouterr()
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert "already holds a render; pass --overwrite" in error and "Traceback" not in error


def test_mix_and_strength_from_the_command_line(mi, checkpoint, inputs, tmp_path):
    out = tmp_path / "mix"
    assert (
        main(
            [
                "--checkpoint",
                str(checkpoint),
                "--density",
                str(inputs / "blob.vol"),
                "--mix",
                f"{inputs / 'style.png'}:3",
                f"{inputs / 'rgba.png'}:1",
                "--strength",
                "0.5",
                "--out",
                str(out),
                "--res",
                "16",
                "--spp",
                "1",
            ]
        )
        == 0
    )
    report = json.loads((out / "report.json").read_text())
    assert (
        report["inputs"]["strength"] == 0.5
        and "0.75 x" in report["inputs"]["style"]
        and "0.25 x" in report["inputs"]["style"]
    )
    assert report["inputs"]["refine_steps"] == 0 and any("strength 0.5" in note for note in report["notes"])


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--mix", "style.png:1"], "--mix needs two or more"),
        (["--mix", "style.png:1", "rgba.png:x"], "--mix takes IMAGE:WEIGHT"),
        (["--mix", "style.png:0", "rgba.png:0"], "must not all be zero"),
        (["--style", "style.png", "--strength", "2"], "--strength must lie in [0, 1]"),
    ],
)
def test_bad_mix_or_strength_is_a_clear_error(mi, checkpoint, inputs, tmp_path, capsys, arguments, message):
    arguments = [str(inputs / a) if a.endswith(("png", "png:1", "png:0", "png:x")) else a for a in arguments]
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(inputs / "blob.vol"),
            *arguments,
            "--out",
            str(tmp_path / "out"),
            *FAST,
        ]
    )
    error = capsys.readouterr().err
    assert code == 2 and message in error and "Traceback" not in error, error
    assert not (tmp_path / "out").exists()


def test_the_written_scene_reproduces_the_final_render(mi, checkpoint, inputs, tmp_path):
    out = tmp_path / "out"
    assert (
        main(
            [
                "--checkpoint",
                str(checkpoint),
                "--density",
                str(inputs / "blob.vol"),
                "--style",
                str(inputs / "style.png"),
                "--out",
                str(out),
                "--res",
                "16",
                "--spp",
                "4",
                "--refine",
                "1",
                "--refine-path",
                "0",
                "--light",
                "constant:5",
                "--bricks",
                "0",
                "--denoise",
                "none",  # scene.xml reproduces the path tracer's image; denoising comes after it
            ]
        )
        == 0
    )  # scene.xml holds one medium (see scenes.export)
    from mistyle.files import read_exr

    scene = mi.load_file(str(out / "scene.xml"))
    np.testing.assert_allclose(np.array(mi.render(scene, sensor=0)), read_exr(out / "final.exr"), rtol=1e-4, atol=1e-5)
    assert 'filename" value="albedo_refined.vol"' in (out / "scene.xml").read_text()


def test_a_mesh_run_writes_the_voxelized_density_for_mitsuba(mi, checkpoint, inputs, tmp_path):
    from mistyle.data.mesh import icosphere, write_ply

    mesh = write_ply(tmp_path / "ball.ply", *icosphere(2))
    out = tmp_path / "out"
    assert (
        main(
            [
                "--checkpoint",
                str(checkpoint),
                "--mesh",
                str(mesh),
                "--mesh-res",
                "12",
                "--style",
                str(inputs / "style.png"),
                "--out",
                str(out),
                "--coat",
                "dielectric:1.5",
                *FAST,
            ]
        )
        == 0
    )
    assert read_vol(out / "density.vol").shape == (12, 12, 12) and read_vol(out / "density.vol").max() > 0.5
    assert mi.load_file(str(out / "scene.xml")) is not None  # the coat mesh is found beside the scene


def test_quiet_keeps_only_the_results_on_stdout(mi, checkpoint, inputs, tmp_path, capsys):
    assert (
        main(
            [
                "--checkpoint",
                str(checkpoint),
                "--density",
                str(inputs / "blob.vol"),
                "--style",
                str(inputs / "style.png"),
                "--out",
                str(tmp_path / "out"),
                "--quiet",
                *FAST,
            ]
        )
        == 0
    )
    captured = capsys.readouterr()
    summary, final = captured.out.splitlines()
    assert captured.err == "" and "rgb_swd" in json.loads(summary) and final.startswith("wrote ")


def test_vdb_in_and_out_keeps_the_transform_and_the_grids(mi, checkpoint, inputs, tmp_path, blob_density):
    from mistyle.files import vdb, vdb_layout

    try:
        vdb.vdb_interpreter()
    except vdb.VdbUnavailable as error:
        pytest.skip(str(error))
    matrix = np.diag([0.05, 0.05, 0.05, 1.0])
    matrix[:3, 3] = [1.0, -2.0, 0.5]
    transform = vdb.VdbTransform(matrix, (3, -4, 7))
    source = vdb.write_vdb(
        tmp_path / "houdini.vdb", transform, {"smoke": blob_density, "temperature": blob_density * 2}
    )
    out = tmp_path / "out"
    assert (
        main(
            [
                "--checkpoint",
                str(checkpoint),
                "--density",
                str(source),
                "--grid",
                "smoke",
                "--style",
                str(inputs / "style.png"),
                "--out",
                str(out),
                *FAST,
            ]
        )
        == 0
    )
    density, written, _ = vdb.read_vdb(out / "volume.vdb")
    np.testing.assert_array_equal(density, blob_density)
    np.testing.assert_array_equal(written.matrix, transform.matrix)
    assert written.index_min == transform.index_min
    albedo, _, _ = vdb.read_vdb(out / "volume.vdb", grid=vdb_layout.ALBEDO_GRID)
    expected = np.load(out / "albedo.npy") * (blob_density > 0)[..., None]
    np.testing.assert_array_equal(albedo, expected)


def test_vdb_with_two_float_grids_needs_grid(mi, checkpoint, inputs, tmp_path, blob_density, capsys):
    from mistyle.files import vdb

    try:
        vdb.vdb_interpreter()
    except vdb.VdbUnavailable as error:
        pytest.skip(str(error))
    source = vdb.write_vdb(
        tmp_path / "two.vdb",
        vdb.VdbTransform.for_medium_box(blob_density.shape),
        {"smoke": blob_density, "heat": blob_density},
    )
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(source),
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(tmp_path / "out"),
            *FAST,
        ]
    )
    error = capsys.readouterr().err
    assert code == 2 and "--grid" in error and "smoke" in error and "Traceback" not in error, error
    assert not (tmp_path / "out").exists()


def test_a_bad_style_late_in_a_batch_stops_it_before_any_output(mi, checkpoint, inputs, tmp_path, capsys):
    out = tmp_path / "batch"
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(inputs / "blob.vol"),
            "--style",
            str(inputs / "style.png"),
            str(inputs / "notes.txt"),
            "--out",
            str(out),
            *FAST,
        ]
    )
    error = capsys.readouterr().err
    assert code == 2 and "notes.txt is not a readable image" in error and not out.exists()


# ------------------------------------------------------------------ --overwrite replaces only mistyle's outputs
def test_overwrite_never_replaces_the_input_folder(mi, checkpoint, inputs, tmp_path, blob_density, capsys):
    frames = tmp_path / "frames"
    frames.mkdir()
    for index in range(2):
        write_vol(frames / f"frame_{index:04d}.vol", blob_density)
    before = sorted(p.name for p in frames.iterdir())
    arguments = ["--checkpoint", str(checkpoint), "--style", str(inputs / "style.png"), *FAST, "--overwrite"]
    assert main(["--density", str(frames), "--out", str(frames), *arguments]) == 2
    error = capsys.readouterr().err
    assert "is or holds the input" in error and "Traceback" not in error
    assert sorted(p.name for p in frames.iterdir()) == before
    # An --out that holds an input deeper down is refused too.
    assert main(["--density", str(frames / "frame_0000.vol"), "--out", str(tmp_path), *arguments]) == 2
    assert "is or holds the input" in capsys.readouterr().err and (frames / "frame_0000.vol").exists()
    # A style image in the output folder is an input as well.
    assert main(["--density", str(inputs / "blob.vol"), "--out", str(inputs), *arguments]) == 2
    assert "is or holds the input" in capsys.readouterr().err and (inputs / "style.png").exists()


def test_overwrite_refuses_a_folder_mistyle_did_not_write(mi, checkpoint, inputs, tmp_path, capsys):
    out = tmp_path / "photos"
    out.mkdir()
    (out / "holiday.jpg").write_bytes(b"precious")
    arguments = [
        "--checkpoint",
        str(checkpoint),
        "--density",
        str(inputs / "blob.vol"),
        "--style",
        str(inputs / "style.png"),
        "--out",
        str(out),
        *FAST,
    ]
    for extra in ([], ["--overwrite"]):
        assert main(arguments + extra) == 2
        assert "holds holiday.jpg: it has no manifest" in capsys.readouterr().err
        assert (out / "holiday.jpg").read_bytes() == b"precious"
    # A render is replaced with --overwrite, and only then.
    render = tmp_path / "render"
    arguments[arguments.index(str(out))] = str(render)
    assert main(arguments) == 0 and (render / "report.json").exists()
    assert main(arguments) == 2 and "pass --overwrite" in capsys.readouterr().err
    assert main(arguments + ["--overwrite"]) == 0


# ------------------------------------------------------------------ tiny, sparse and invisible media
def test_a_medium_of_a_few_voxels_is_refused_before_any_work(mi, checkpoint, inputs, tmp_path, capsys):
    density = np.zeros((32, 32, 32), np.float32)
    density[16, 16, 16] = 1.0
    with pytest.raises(ValueError, match="too little medium"):  # never NaN from the API
        mistyle.stylize(density, inputs / "style.png", checkpoint=checkpoint)
    write_vol(tmp_path / "dot.vol", density)
    out = tmp_path / "out"
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(tmp_path / "dot.vol"),
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(out),
            *FAST,
        ]
    )
    error = capsys.readouterr().err
    assert code == 2 and "density dot holds too little medium" in error and "NaN" not in error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dot.vol"]  # nothing written


def test_an_invisible_medium_is_refused_and_leaves_nothing(mi, checkpoint, inputs, tmp_path, capsys):
    density = np.zeros((32, 32, 32), np.float32)
    density[14:18, 14:18, 14:18] = 1e-4
    write_vol(tmp_path / "faint.vol", density)
    out = tmp_path / "out"
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            str(tmp_path / "faint.vol"),
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(out),
            *FAST,
        ]
    )
    assert code == 2  # not a black image reported as done: the cause, before any work
    assert "too thin to see" in capsys.readouterr().err and not out.exists()


# ------------------------------------------------------------------ interrupts and what they leave
@pytest.mark.parametrize(
    "signal_name, code, line",
    [
        ("SIGTERM", 143, "terminated: the output being written was removed; finished outputs are kept"),
        ("SIGINT", 130, "interrupted: the output being written was removed; finished outputs are kept"),
    ],
)
def test_a_signal_during_refinement_exits_in_one_line_and_leaves_nothing(
    checkpoint, inputs, tmp_path, signal_name, code, line
):
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "out"
    command = [
        sys.executable,
        "-m",
        "mistyle.render_final",
        "--checkpoint",
        str(checkpoint),
        "--density",
        str(inputs / "blob.vol"),
        "--style",
        str(inputs / "style.png"),
        "--out",
        str(out),
        "--res",
        "16",
        "--spp",
        "1",
        "--refine",
        "10000",
        "--quiet",
    ]
    # A test run started in the background (``pytest &``) has SIGINT ignored, and a child inherits that,
    # so Python would never see the Ctrl-C; a terminal's foreground process has the default action.
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.time() + 120
    while not list(tmp_path.glob(".out.partial-*")) and time.time() < deadline:
        time.sleep(0.2)
    assert list(tmp_path.glob(".out.partial-*")), "the run never started staging"
    time.sleep(1.0)
    process.send_signal(getattr(signal, signal_name))  # Ctrl-C is SIGINT
    _, error = process.communicate(timeout=120)
    assert process.returncode == code, error
    assert error.strip().splitlines() == [line]
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "handler, code, word",
    [(mistyle.stops.on_sigint, 130, "interrupted"), (mistyle.stops.on_sigterm, 143, "terminated")],
)
@pytest.mark.parametrize("chained", [True, False], ids=["caused-by-the-signal", "cause-lost"])
def test_a_signal_inside_dr_jits_custom_operation_still_stops_cleanly(
    monkeypatch, tmp_path, capsys, handler, code, word, chained
):
    """A Ctrl-C or SIGTERM that lands while Dr.Jit runs the fast layer's custom operation reaches Python as
    a RuntimeError (seen about once in ten runs of the test above), with the signal's exception as its
    cause or without it; the run stops as the signal asked all the same."""

    def run(args):
        try:
            handler(None, None)
        except BaseException as cause:
            error = RuntimeError("drjit.custom(<LayerOp>): error while performing a custom operation")
            raise error from (cause if chained else None)

    monkeypatch.setattr(mistyle.render_final, "run", run)
    argv = ["--density", "d.vol", "--style", "s.png", "--out", str(tmp_path / "out")]
    assert main(argv) == code
    assert capsys.readouterr().err.strip().startswith(f"{word}: the output being written was removed")


def test_an_error_without_a_signal_is_not_taken_for_one(monkeypatch, tmp_path):
    def run(args):
        raise RuntimeError("a bug")

    monkeypatch.setattr(mistyle.render_final, "run", run)
    with pytest.raises(RuntimeError, match="a bug"):
        main(["--density", "d.vol", "--style", "s.png", "--out", str(tmp_path / "out")])


def test_a_killed_runs_staging_folders_are_removed_by_the_next_run_and_a_live_ones_are_not(
    mi, checkpoint, inputs, tmp_path, capsys
):
    import os
    import subprocess
    import sys

    from mistyle.ownership import process_start, run_identity

    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    host = run_identity().split("-", 2)[2]
    dead = f"{int(ended.stdout)}-1-{host}"  # its pid, no longer running (or another process's now)
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        alive = f"{live.pid}-{process_start(live.pid)}-{host}"
        for name in (f".out.partial-{dead}-abc123", f".out.replaced-{dead}-def456", f".out.chunk-{alive}-ghi789"):
            (tmp_path / name / "x").mkdir(parents=True)
        (tmp_path / ".out.lock").write_text("")  # left by a SIGKILL: its process is gone, so its lock is free
        previous = os.umask(0o022)
        try:
            arguments = [
                "--checkpoint",
                str(checkpoint),
                "--density",
                str(inputs / "blob.vol"),
                "--style",
                str(inputs / "style.png"),
                "--out",
                str(tmp_path / "out"),
                *FAST,
            ]
            assert main(arguments) == 0
        finally:
            os.umask(previous)
    finally:
        live.kill()
        live.wait()
    assert "removed 2 unfinished staging folder(s)" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == [f".out.chunk-{alive}-ghi789", "out"]
    assert (tmp_path / "out").stat().st_mode & 0o777 == 0o755  # the umask's mode, not mkdtemp's 0700


def test_a_huge_style_is_reduced_at_decode_and_runs_in_little_memory(inputs, tmp_path):
    import resource
    import subprocess
    import sys

    from mistyle.files import MAX_STYLE_SIDE, load_style

    rng = np.random.default_rng(0)
    tile = Image.fromarray((rng.random((64, 64, 3)) * 255).astype(np.uint8))
    tile.resize((4096, 4096), Image.BICUBIC).save(tmp_path / "huge.jpg", quality=90)
    notes = []
    style = load_style(tmp_path / "huge.jpg", notes)
    assert max(style.shape[:2]) == MAX_STYLE_SIDE and any("decoded at" in note for note in notes)
    assert load_style(np.zeros((3000, 1000, 3), np.uint8)).shape == (MAX_STYLE_SIDE, 85, 3)

    def limit():  # 3 GB of address space: the full-size style alone was a 5 GB allocation
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

    command = [
        sys.executable,
        "-m",
        "mistyle.render_final",
        "--density",
        str(inputs / "blob.vol"),
        "--style",
        str(tmp_path / "huge.jpg"),
        "--out",
        str(tmp_path / "out"),
        *FAST,
        "--quiet",
    ]
    result = subprocess.run(command, capture_output=True, text=True, preexec_fn=limit, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]


def test_a_style_with_nan_says_so():
    from mistyle.files import load_style

    style = np.full((16, 16, 3), 0.5, np.float32)
    style[3, 4, 1] = np.nan
    with pytest.raises(ValueError, match="holds 1 NaN or infinite value"):
        load_style(style)


def test_a_batch_that_fails_late_keeps_an_index_and_resumes(mi, checkpoint, inputs, tmp_path, blob_density, capsys):
    styles = tmp_path / "styles"
    styles.mkdir()
    for name in ("wave", "night"):
        (styles / f"{name}.png").write_bytes((inputs / "style.png").read_bytes())
    dot = np.zeros((16, 16, 16), np.float32)
    dot[8, 8, 8] = 1.0  # too little medium: refused when its turn comes
    np.save(tmp_path / "late.npy", dot)
    out = tmp_path / "batch"
    arguments = [
        "--checkpoint",
        str(checkpoint),
        "--density",
        str(inputs / "blob.vol"),
        str(tmp_path / "late.npy"),
        "--style",
        str(styles),
        "--out",
        str(out),
        *FAST,
    ]

    def renders():
        return sorted(p.name for p in out.iterdir() if p.is_dir() and not p.name.startswith("."))

    assert main(arguments) == 2
    assert renders() == ["blob__night", "blob__wave"]
    assert "mistyle: 2 renders" in (out / "index.html").read_text()
    capsys.readouterr()
    assert main(arguments) == 2 and "--resume to keep it" in capsys.readouterr().err
    np.save(tmp_path / "late.npy", blob_density)  # the input fixed
    kept = (out / "blob__wave" / "report.json").read_bytes()
    assert main(arguments + ["--resume"]) == 0
    assert "2 of 4 output(s) already complete, kept" in capsys.readouterr().err
    assert renders() == ["blob__night", "blob__wave", "late__night", "late__wave"]
    assert (out / "blob__wave" / "report.json").read_bytes() == kept  # not made again
    # A subset made again keeps the index true to what is on disk.
    subset = [
        "--checkpoint",
        str(checkpoint),
        "--density",
        str(inputs / "blob.vol"),
        "--style",
        str(styles),
        "--out",
        str(out),
        *FAST,
        "--overwrite",
    ]
    assert main(subset) == 0
    index = (out / "index.html").read_text()
    assert "mistyle: 4 renders" in index and all(name in index for name in renders())


def test_messages_say_what_is_wrong(checkpoint, inputs, tmp_path, blob_density):
    from mistyle.files import load_density
    from mistyle.outputs import parse_mix_item

    with pytest.raises(ValueError, match="is a folder; a folder of frames is a sequence"):
        load_density(tmp_path)
    (tmp_path / "garbage.npy").write_bytes(
        b"\x93NUMPY\x01\x00v\x00{'descr': '|O', 'fortran_order': False, 'shape': (2,), }"
    )
    with pytest.raises(ValueError) as error:
        load_density(tmp_path / "garbage.npy")
    assert "pickle" not in str(error.value)
    with pytest.raises(ValueError, match="finite weights >= 0"):
        parse_mix_item("a.png:inf")
    from mistyle.scenes import LightSpec

    with pytest.raises(ValueError, match="The area light's strength must be a finite number > 0, got -1.0. Use"):
        LightSpec.parse("area:-1")
    for style in ([], [inputs / "style.png", inputs / "style.png"]):
        with pytest.raises(ValueError, match="not \\(style, weight\\) pairs"):
            mistyle.stylize(blob_density, style, checkpoint=checkpoint)
    write_vol(tmp_path / "blob.vol", blob_density)
    by_path = mistyle.stylize(str(tmp_path / "blob.vol"), inputs / "style.png", checkpoint=checkpoint)
    assert by_path.shape == blob_density.shape + (3,)


@pytest.fixture
def full_disk(tmp_path):
    """A 1 MB tmpfs: a real full disk (needs the right to mount; skipped without it)."""
    import subprocess

    mount = tmp_path / "small"
    mount.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here")
    yield mount
    subprocess.run(["umount", str(mount)], capture_output=True)


def test_a_full_disk_says_so_and_leaves_nothing(mi, checkpoint, inputs, full_disk, capsys):
    out = full_disk / "out"  # the 64^3 albedo alone (3 MB) does not fit
    code = main(
        [
            "--checkpoint",
            str(checkpoint),
            "--density",
            "examples/smoke_64.vol",
            "--style",
            str(inputs / "style.png"),
            "--out",
            str(out),
            *FAST,
        ]
    )
    error = capsys.readouterr().err
    assert code == 2 and f"The disk under {full_disk} is full" in error and "requested and" not in error
    assert list(full_disk.iterdir()) == []


def test_vdb_for_blender_is_z_up_and_says_what_it_holds(mi, checkpoint, inputs, tmp_path, blob_density):
    """--up z writes the medium box turned so that mistyle's up is world +z, with the metadata a DCC needs
    (Houdini's view: a fog-volume float 'density' and a vec3 'Cd'); reading it back turns nothing, and
    the same file read as Y-up is turned back upright for mistyle's renders."""
    from mistyle.files import vdb

    try:
        vdb.vdb_interpreter()
    except vdb.VdbUnavailable as error:
        pytest.skip(str(error))
    out = tmp_path / "out"
    arguments = ["--checkpoint", str(checkpoint), "--style", str(inputs / "style.png"), *FAST]
    assert main([*arguments, "--density", str(inputs / "blob.vol"), "--vdb", "--up", "z", "--out", str(out)]) == 0
    info = vdb.vdb_info(out / "volume.vdb")
    grids = {grid["name"]: grid for grid in info["grids"]}
    assert (grids["density"]["type"], grids["density"]["class"], grids["Cd"]["type"]) == (
        "float",
        "fog volume",
        "vec3s",
    )
    metadata = info["file_metadata"]
    assert metadata["mistyle_up_axis"] == "z" and metadata["mistyle_density_scale"] == 20.0
    assert metadata["mistyle_world_density_scale"] == 20.0  # the medium box's longest side is 1
    assert "single-scattering albedo" in metadata["mistyle_albedo"] and metadata["mistyle_version"]
    assert grids["density"]["metadata"]["mistyle_up_axis"] == "z"
    density, transform, _ = vdb.read_vdb(out / "volume.vdb")
    np.testing.assert_array_equal(density, blob_density)
    # Array axis y (mistyle's up) runs along world +z.
    assert np.allclose(transform.matrix[:3, 1] / np.linalg.norm(transform.matrix[:3, 1]), [0, 0, 1])
    again = tmp_path / "again"
    assert main([*arguments, "--density", str(out / "volume.vdb"), "--out", str(again)]) == 0
    assert vdb.vdb_info(again / "volume.vdb")["file_metadata"]["mistyle_up_axis"] == "z"  # what the file said
    np.testing.assert_array_equal(np.load(again / "albedo.npy"), np.load(out / "albedo.npy"))
    sideways = tmp_path / "sideways"
    assert main([*arguments, "--density", str(out / "volume.vdb"), "--up", "y", "--out", str(sideways)]) == 0
    turned, _, _ = vdb.read_vdb(sideways / "volume.vdb")
    assert turned.shape == (blob_density.shape[1], blob_density.shape[0], blob_density.shape[2])
