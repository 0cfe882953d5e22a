"""scene.xml + density.vol + albedo.vol: the path-traced scene as files Mitsuba opens and renders alike."""

import numpy as np
import pytest

from mistyle.files import read_vol, write_exr
from mistyle.scenes import CameraPath, LightSpec, MediumBox
from mistyle.scenes.export import scene_xml, write_scene_files
from mistyle.scenes.pathtraced import pathtraced_scene


def _vol_bbox(path):
    import struct

    return np.array(struct.unpack_from("<6f", path.read_bytes(), 24)).reshape(2, 3)


@pytest.mark.parametrize("light", ["constant:6", "point:0.5,1.5,1.0:20", "area:5", "envmap"])
def test_the_xml_scene_renders_as_the_dictionary_does(mi, blob_density, tmp_path, light):
    rng = np.random.default_rng(0)
    albedo = rng.uniform(0.2, 0.95, blob_density.shape + (3,)).astype(np.float32)
    if light == "envmap":
        sky = np.ones((8, 16, 3), np.float32) * np.linspace(0.5, 3.0, 16)[None, :, None]
        light = f"envmap:{write_exr(tmp_path / 'sky.exr', sky)}:2"
    spec = LightSpec.parse(light)
    views = CameraPath(distance=1.7).turntable(2, offset=0.1)
    options = dict(res=24, spp=8, max_depth=-1, density_scale=30.0, light=spec)
    folder = tmp_path / "assets"
    folder.mkdir()
    paths = write_scene_files(folder, blob_density, albedo, views, **options)
    from_files = mi.load_file(str(paths["scene"]))
    from_dict = mi.load_dict(pathtraced_scene(blob_density, albedo, views, **options))
    for index in range(len(views)):
        a = np.array(mi.render(from_files, sensor=index))
        b = np.array(mi.render(from_dict, sensor=index))
        assert a.mean() > 1e-3
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(read_vol(paths["density"]), blob_density)
    np.testing.assert_array_equal(read_vol(paths["albedo"]), albedo)
    box = MediumBox(blob_density.shape)
    np.testing.assert_allclose(_vol_bbox(paths["albedo"]), [box.bbox_min, box.bbox_max], rtol=1e-6)
    np.testing.assert_allclose(_vol_bbox(paths["density"]), [box.bbox_min, box.bbox_max], rtol=1e-6)
    if spec.kind == "envmap":
        assert (folder / "sky.exr").is_file() and 'sky.exr"' in paths["scene"].read_text()


def test_grids_left_in_memory_are_refused(mi, blob_density):
    scene = pathtraced_scene(
        blob_density,
        np.full(blob_density.shape + (3,), 0.5, np.float32),
        [CameraPath().view(0.0)],
        res=8,
        density_scale=10.0,
    )
    with pytest.raises(ValueError, match="Cannot write the scene entry 'grid'"):
        scene_xml(scene)
