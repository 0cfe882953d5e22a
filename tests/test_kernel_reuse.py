"""A sequence's frames reuse one scene and its kernels (issue #51, item 1): ``pathtrace.SceneCache``.

Each new frame of a sequence used to compile the path tracer's kernel anew (each level's medium was
cropped to its bricks, and the crop's bounds were literals in the kernel). Now a frame of the same
structure updates the kept scene's data and renders with the kernels compiled for the first frame,
bit for bit as a scene loaded anew for it.
"""

import drjit as dr
import numpy as np
import pytest

from mistyle import pathtrace
from mistyle.data.procedural import colour_noise_albedo
from mistyle.scenes import CameraPath
from mistyle.scenes.bricks import brick_levels, present_levels

BIG_KERNEL_OPS = 500
"""IR operations above which a kernel is a render's (the path tracer's is thousands); a first update
compiles two small kernels of its own once (the albedo's copy into its texture, the camera's new
projection: under 100 each)."""


def blob_frames(count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` frames ``(density (16, 16, 24), albedo)`` of a blob moving one 4-voxel brick along x a
    frame: the same levels present, the face meshes' vertices new."""
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5 for n in (16, 16, 24)), indexing="ij")
    frames = []
    for index in range(count):
        centre = 6.0 + 4.0 * index
        core = 3.0 * np.exp(-((z - 8) ** 2 + (y - 8) ** 2 + (x - centre) ** 2) / 5.0)
        wisp = 0.3 * np.exp(-((z - 12) ** 2 / 3.0 + (y - 4) ** 2 / 2.0 + (x - centre) ** 2 / 3.0))
        density = np.where(core + wisp > 0.02, core + wisp, 0.0).astype(np.float32)
        frames.append((density, colour_noise_albedo(density.shape, seed=index)))
    return frames


def trace(frame, view, options):
    (image,), _ = pathtrace.path_trace(*frame, [view], **options)
    return image


def new_kernels(seen: set) -> list[dict]:
    """Kernels launched since the last call whose hash this process had not launched before."""
    launched = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    new = [k for k in launched if k["hash"] not in seen]
    seen.update(k["hash"] for k in launched)
    return new


@pytest.mark.parametrize(
    "options",
    [
        {"bricks": 4, "spp": 4},  # one launch a view
        {"bricks": 4, "spp": 6, "max_pass_samples": 16 * 16 * 2},  # three frozen passes
        {"bricks": 0, "spp": 4},  # one medium in the box
    ],
    ids=["bricks", "bricks-frozen-passes", "one-medium"],
)
def test_later_frames_compile_nothing_and_render_as_a_fresh_scene(mi, options):
    options = {"res": 16, "density_scale": 20.0, **options}
    frames = blob_frames(3)
    if options["bricks"]:
        levels = {present_levels(brick_levels(density, 4, 4)[0]) for density, _ in frames}
        assert len(levels) == 1 and len(next(iter(levels))) > 1  # one structure, several media
    views = CameraPath().turntable(3)
    pathtrace.release_scenes()
    builds, updates = pathtrace.SCENES.builds, pathtrace.SCENES.updates
    seen: set = set()
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        dr.kernel_history()
        kept = [trace(frames[0], views[0], options)]
        first = new_kernels(seen)
        render_pass = pathtrace.SCENES.kept.render_pass
        kept.append(trace(frames[1], views[1], options))
        second = new_kernels(seen)
        kept.append(trace(frames[2], views[2], options))
        third = new_kernels(seen)
    assert any(k["operation_count"] > BIG_KERNEL_OPS for k in first) or not first  # compiled, or cached earlier
    assert [k["operation_count"] for k in second if k["operation_count"] > BIG_KERNEL_OPS] == []
    assert third == []
    assert (pathtrace.SCENES.builds - builds, pathtrace.SCENES.updates - updates) == (1, 2)
    assert pathtrace.SCENES.kept.render_pass is render_pass  # the frozen pass, kept with its scene
    for frame, view, image in zip(frames, views, kept):
        pathtrace.release_scenes()
        fresh = trace(frame, view, options)
        assert image.mean() > 1e-3
        np.testing.assert_array_equal(image, fresh)


def test_another_structure_loads_a_new_scene(mi):
    """Another grid shape, or bricks whose levels differ, is another kernel: a new scene, not an update."""
    (density, albedo), _ = blob_frames(2)
    view = CameraPath().view(0.1)
    options = {"res": 8, "spp": 1, "density_scale": 20.0, "bricks": 4}
    pathtrace.release_scenes()
    builds = pathtrace.SCENES.builds
    trace((density, albedo), view, options)
    trace((density[:, :, :20].copy(), albedo[:, :, :20].copy()), view, options)
    thin = np.where(density > 0.5 * density.max(), density, 0.0).astype(np.float32)  # one level only
    assert present_levels(brick_levels(thin, 4, 4)[0]) != present_levels(brick_levels(density, 4, 4)[0])
    trace((thin, albedo), view, options)
    assert pathtrace.SCENES.builds - builds == 3
    pathtrace.release_scenes()
    assert pathtrace.SCENES.kept is None


def test_a_large_grids_scene_is_not_kept_past_its_frames(mi, monkeypatch):
    """A sequence's frames share the kept scene within one ``Pipeline.path_trace``; a grid larger than
    ``KEPT_SCENE_VOXELS`` has its scene freed after them (at 512^3 it holds about 7 GB), a smaller one's
    is kept for the next call."""
    from mistyle.pipeline import Pipeline, PipelineSettings, RenderSettings

    pipeline = Pipeline(PipelineSettings(render=RenderSettings(res=16, spp=1, denoise="none")))
    (density, albedo), (moved, moved_albedo) = blob_frames(2)
    frames = pipeline.frames([density, moved])
    pathtrace.release_scenes()
    builds, updates = pathtrace.SCENES.builds, pathtrace.SCENES.updates
    pipeline.path_trace(frames, [albedo, moved_albedo])
    assert pathtrace.SCENES.kept is not None
    monkeypatch.setattr(pathtrace, "KEPT_SCENE_VOXELS", density.size - 1)
    pipeline.path_trace(frames, [albedo, moved_albedo])
    assert pathtrace.SCENES.kept is None
    assert (pathtrace.SCENES.builds - builds, pathtrace.SCENES.updates - updates) == (1, 3)  # kept until then
    pipeline.path_trace(frames, [albedo, moved_albedo])
    assert (pathtrace.SCENES.builds - builds, pathtrace.SCENES.updates - updates) == (2, 4)  # built anew


def test_the_fast_layers_later_frames_launch_only_the_first_frames_kernels(mi):
    """The layer's Ls grid and image of a blob moving through its box: a new frame's arrays reach Dr.Jit
    aligned (``backend.lanes``) and its march box as data, so no kernel differs from the first frame's."""
    import torch

    from mistyle.bridge_torch import render_views
    from mistyle.integrators import prepare_density

    frames = blob_frames(3)
    views = CameraPath().turntable(3)
    seen: set = set()
    launched = []
    boxes = set()
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        dr.kernel_history()
        for (density, albedo), view in zip(frames, views):
            prepared = prepare_density(density, 20.0)
            boxes.add(tuple(np.concatenate(prepared.march_bounds)))
            with torch.no_grad():
                image = render_views(torch.from_numpy(albedo).permute(3, 0, 1, 2).contiguous(), prepared, [view], 16)
            assert float(image.mean()) > 1e-3
            launched.append(new_kernels(seen))
    assert len(boxes) == 3  # the medium's box moves
    assert launched[0] and launched[1:] == [[], []]
