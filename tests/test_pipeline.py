"""The pipeline is the product: ``mistyle.stylize``, ``mistyle.Pipeline`` and ``mistyle-render`` give the
same albedo for the same inputs, bit for bit."""

import json

import drjit as dr
import numpy as np
import pytest

import mistyle
from mistyle.files import read_vol, write_vol
from mistyle.pipeline import Pipeline, PipelineSettings, RenderSettings
from mistyle.render_final import main, parser, settings_from

STYLE = "examples/style_marble.png"
RENDER = ["--res", "16", "--spp", "1", "--quiet"]


@pytest.fixture
def one_thread():
    """Dr.Jit on one thread: its parallel scatter-add (the fast layer's backward pass) sums in the order
    threads finish, so a refinement is bit-reproducible only on one thread."""
    threads = dr.thread_count()
    dr.set_thread_count(1)
    yield
    dr.set_thread_count(threads)


@pytest.fixture(scope="module")
def density_file(tmp_path_factory, blob_density):
    path = tmp_path_factory.mktemp("pipeline") / "blob.vol"
    write_vol(path, blob_density)
    return path


def render_cli(tmp_path, density_file, *options):
    out = tmp_path / "out"
    assert main(["--density", str(density_file), "--style", STYLE, "--out", str(out), *RENDER, *options]) == 0
    return out


def test_stylize_is_the_commands_feed_forward_albedo(mi, tmp_path, density_file):
    out = render_cli(tmp_path, density_file, "--refine", "0")
    assert np.array_equal(mistyle.stylize(read_vol(density_file), STYLE), np.load(out / "albedo.npy"))
    assert np.array_equal(read_vol(out / "albedo.vol"), np.load(out / "albedo.npy"))


def test_pipeline_gives_the_commands_refined_albedo_bit_for_bit(mi, tmp_path, density_file, one_thread):
    out = render_cli(tmp_path, density_file, "--refine", "3", "--refine-path", "1")
    stylized = Pipeline(PipelineSettings(refine_steps=3, refine_path_steps=1)).stylize(read_vol(density_file), STYLE)
    assert stylized.refined and stylized.refinement.layer_steps == 3 and stylized.refinement.path_steps == 1
    assert np.array_equal(stylized.albedos[0], read_vol(out / "albedo_refined.vol"))
    assert np.array_equal(stylized.network[0], np.load(out / "albedo.npy"))


def test_stylize_refine_runs_the_commands_default_settings():
    args = parser().parse_args(["--density", "d.vol", "--style", STYLE, "--out", "o"])
    assert settings_from(args) == PipelineSettings()  # the command's defaults are the pipeline's defaults
    pipeline = Pipeline()
    assert pipeline.fits_look()  # a frame, or a sequence's key frames, get a look fitted on them
    unmatched = Pipeline(PipelineSettings(colour_match=False), stylizer=pipeline.stylizer)
    refinement = unmatched.refinement()
    assert not unmatched.fits_look() and refinement.layer_steps > 0 and refinement.path_steps > 0
    for named in ({"refine_steps": 0}, {"refine_path_steps": 2}, {"strength": 0.5}):
        assert not Pipeline(PipelineSettings(**named), stylizer=pipeline.stylizer).fits_look()


def test_stylize_refine_is_the_commands_default_output(mi, tmp_path, density_file, one_thread):
    out = render_cli(tmp_path, density_file)
    report = json.loads((out / "report.json").read_text())
    assert report["look_seconds"] > 0 and report["inputs"]["refine_steps"] == 0
    density = read_vol(density_file)
    assert np.array_equal(mistyle.stylize(density, STYLE, refine=True), read_vol(out / "albedo_refined.vol"))


def test_a_sequence_by_default_is_stylized_by_one_look_fitted_on_its_key_frames(mi, tmp_path, blob_density, one_thread):
    frames = tmp_path / "frames"
    frames.mkdir()
    sequence = np.stack([np.roll(blob_density, index, axis=2) for index in range(4)])
    for index, density in enumerate(sequence):
        np.savez(frames / f"frame{index:04d}.npz", density=density)
    out = render_cli(tmp_path, frames, "--look-steps", "2")
    report = json.loads((out / "report.json").read_text())
    assert report["look_seconds"] > 0 and report["inputs"]["refine_steps"] == 0
    assert report["temporal_flicker_look_unwarped"] >= 0 and report["temporal_flicker_unwarped"] >= 0
    look = Pipeline(PipelineSettings(look_steps=2)).fit_look(sequence, STYLE)
    assert look.meta["key_frames"] == [0, 1, 3]  # the first, middle and last: frame 2 is not fitted on
    for index, density in enumerate(sequence):
        assert np.array_equal(look.stylize(density), read_vol(out / f"albedo_refined_frame{index:04d}.vol"))
    # `--refine 0` keeps the feed-forward network's frames, as before.
    feed_forward = render_cli(tmp_path / "ff", frames, "--refine", "0")
    assert "look_seconds" not in json.loads((feed_forward / "report.json").read_text())
    assert not (feed_forward / "albedo_refined_frame0000.vol").exists()


def test_a_sequences_frames_before_its_emitter_starts_are_rendered_as_they_are(mi, blob_density, one_thread):
    """Frames with too little medium to stylize (a simulation before its emitter starts, its first puff of
    three voxels) hold the grey ``EMPTY_FRAME_ALBEDO`` and are path traced; the others are stylized as they
    would be without them, bit for bit: the network, its colour match and the look on their key frames."""
    from mistyle.stylizer import EMPTY_FRAME_ALBEDO

    empty = np.zeros_like(blob_density)
    speck = empty.copy()
    speck[8, 8, 8:11] = 1.0
    smoke = [np.roll(blob_density, index, axis=2) for index in range(3)]
    pipeline = Pipeline(PipelineSettings(look_steps=2, render=RenderSettings(res=16, spp=1, denoise="none")))
    notes = []
    stylized = pipeline.stylize([empty, speck, *smoke], STYLE, notes=notes)
    alone = pipeline.stylize(smoke, STYLE)
    assert stylized.look.meta["key_frames"] == [2, 3, 4]
    assert any(note.startswith("frame(s) 0-1 hold no medium to stylize") for note in notes)
    for index in range(2):
        assert np.all(stylized.network[index] == EMPTY_FRAME_ALBEDO)
        assert np.all(stylized.albedos[index] == EMPTY_FRAME_ALBEDO)
    for index in range(3):
        assert np.array_equal(stylized.network[2 + index], alone.network[index])
        assert np.array_equal(stylized.albedos[2 + index], alone.albedos[index])
    assert stylized.report["temporal_flicker_look_unwarped"] == alone.report["temporal_flicker_look_unwarped"]
    images, _ = pipeline.path_trace(stylized.frames, stylized.albedos, notes=notes)
    assert images[0].max() == 0 and images[2].max() > 0
    assert not [note for note in notes if "shows no medium" in note]  # the empty frames are said once
    applied = stylized.look.stylize([empty, *smoke])
    assert np.all(applied[0] == EMPTY_FRAME_ALBEDO) and np.array_equal(applied[1], alone.albedos[0])
    with pytest.raises(ValueError, match=r"Key frame\(s\) 1 hold too little medium to fit a look on; frames 2-4"):
        pipeline.fit_look([empty, speck, *smoke], STYLE, key_frames=[1, 3])


def test_the_feed_forward_colour_match_renders_at_the_settings_scale_and_orbit(mi, blob_density):
    """``mistyle-render --density-scale 40 --refine 0`` colour-matches the medium as it renders at 40."""
    settings = PipelineSettings(refine_steps=0, density_scale=40.0, camera_distance=2.2)
    pipeline = Pipeline(settings)
    albedo = pipeline.stylize(blob_density, STYLE).albedos[0]
    stylizer = pipeline.stylizer
    assert np.array_equal(albedo, stylizer(blob_density, STYLE, density_scale=40.0, camera_distance=2.2))
    assert not np.array_equal(albedo, stylizer(blob_density, STYLE))  # the checkpoint's 20 and 1.7 differ


def test_refinement_rule():
    pipeline = Pipeline()
    default = Pipeline(PipelineSettings(colour_match=False), stylizer=pipeline.stylizer).refinement(1)
    assert (pipeline.refinement(1).layer_steps, pipeline.refinement(1).path_steps) == (0, 0)  # a look instead
    assert (pipeline.refinement(3).layer_steps, pipeline.refinement(3).path_steps) == (0, 0)  # sequences
    weakened = Pipeline(PipelineSettings(strength=0.5), stylizer=pipeline.stylizer).refinement(1)
    assert (weakened.layer_steps, weakened.path_steps) == (0, 0)
    layer_only = Pipeline(PipelineSettings(refine_steps=0), stylizer=pipeline.stylizer).refinement(1)
    assert (layer_only.layer_steps, layer_only.path_steps) == (0, 0)
    named = Pipeline(PipelineSettings(refine_steps=5, refine_path_steps=2), stylizer=pipeline.stylizer).refinement(3)
    assert (named.layer_steps, named.path_steps) == (5, 2) and named.tv_weight == default.tv_weight


@pytest.mark.parametrize(
    "change, message",
    [({"strength": 2.0}, "strength"), ({"refine_steps": -1}, "refine_steps"), ({"device": "tpu"}, "device")],
)
def test_settings_refuse_bad_values(change, message):
    with pytest.raises(ValueError, match=message):
        PipelineSettings(**change)


def test_pipeline_refuses_empty_and_mismatched_frames(blob_density):
    pipeline = Pipeline()
    with pytest.raises(ValueError, match="all zero"):
        pipeline.frames(np.zeros((8, 8, 8), np.float32))
    empty = np.zeros_like(blob_density)
    speck = empty.copy()
    speck[4, 4, 4:7] = 1.0  # three voxels: too few to stylize
    with pytest.raises(
        ValueError, match=r"None of the sequence's 3 frames holds medium enough.*frame\(s\) 1 hold fewer"
    ):
        pipeline.frames([empty, speck, empty])
    assert pipeline.frames([empty, speck], chunk=True).holding == []  # frames of a longer sequence
    with pytest.raises(ValueError, match="one grid size"):
        pipeline.frames([blob_density, blob_density[:8]])
    with pytest.raises(ValueError, match="one velocity per frame"):
        pipeline.frames([blob_density, blob_density], velocities=[np.zeros(blob_density.shape + (3,))])


def test_passes_replay_their_kernels_and_give_the_traced_passes_bit_for_bit(mi, blob_density, monkeypatch):
    """A render in passes (a stop waits for one pass) traces Mitsuba's integrator for the first passes of
    each size only and replays the recorded kernels after (``dr.freeze``): the same image as tracing each
    pass, with pass ``n`` of ``P`` seeded ``(seed + view) * P + n``."""
    from mistyle.pathtrace import render_passes
    from mistyle.scenes import CameraPath, pathtraced_scene

    albedo = np.full(blob_density.shape + (3,), 0.6, np.float32)
    views = [CameraPath(distance=2.0).view(0.1), CameraPath(distance=2.0).view(0.6)]
    scene = mi.load_dict(pathtraced_scene(blob_density, albedo, views, res=16, density_scale=20.0, spp=20))
    passes = [3] * 4 + [2] * 4
    traced = sum(
        np.array(mi.render(scene, sensor=1, spp=count, seed=(5 + 1) * len(passes) + number), np.float64) * count
        for number, count in enumerate(passes)
    )
    calls = []
    render = mi.render
    monkeypatch.setattr(mi, "render", lambda *args, **kwargs: calls.append(kwargs["spp"]) or render(*args, **kwargs))
    image = render_passes(scene, 1, passes, seed=5)
    assert len(calls) < len(passes)  # replayed, not traced again
    np.testing.assert_array_equal(image, (traced / sum(passes)).astype(np.float32))
