"""The grid, box and camera conventions, each checked against Mitsuba itself."""

import numpy as np
import pytest

from mistyle.files import read_vol, write_vol
from mistyle.integrators import layer_scene, prepare_density
from mistyle.scenes import (
    CameraPath,
    MediumBox,
    View,
    heterogeneous_medium,
    split_views,
)

SHAPE = (8, 10, 12)  # (Z, Y, X)


def hot_voxel_grid():
    grid = np.zeros(SHAPE, dtype=np.float32)
    grid[7, 5, 2] = 1.0  # voxel (x=2, y=5, z=7)
    return grid


def test_box_keeps_aspect_with_longest_side_one():
    box = MediumBox(SHAPE)
    np.testing.assert_allclose(box.extent, [1.0, 10 / 12, 8 / 12])
    np.testing.assert_allclose(box.bbox_min, -box.bbox_max)
    assert box.voxel_size == pytest.approx(1 / 12)
    np.testing.assert_allclose(box.voxel_centre(2, 5, 7), box.voxel_centres()[7, 5, 2])
    np.testing.assert_allclose(box.world_to_unit(box.voxel_centre(2, 5, 7)), [2.5 / 12, 5.5 / 10, 7.5 / 8])


def test_texture_lookup_at_voxel_centre_reads_arr_z_y_x(mi):
    box = MediumBox(SHAPE)
    texture = mi.Texture3f(mi.TensorXf(hot_voxel_grid()[..., None]))
    unit = box.world_to_unit(box.voxel_centre(2, 5, 7))
    assert texture.eval(mi.Point3f(*map(float, unit)))[0][0] == pytest.approx(1.0)
    # Its neighbour along x is half a voxel away from any other centre: exactly zero there.
    unit_neighbour = box.world_to_unit(box.voxel_centre(3, 5, 7))
    assert texture.eval(mi.Point3f(*map(float, unit_neighbour)))[0][0] == pytest.approx(0.0)


def test_field_support_bounds_where_the_interpolated_field_is_non_zero(mi):
    grid = hot_voxel_grid()
    grid[0, 9, 11] = 1.0  # a corner voxel: the clamped edge carries it to the faces
    box = MediumBox(SHAPE)
    low, high = box.field_support(grid > 0)
    texture = mi.Texture3f(mi.TensorXf(grid[..., None]))
    # A lattice of 4 points per voxel and axis, off the voxel faces and centres.
    axes = [(np.arange(4 * n) + 0.37) / (4 * n) for n in SHAPE[::-1]]
    unit = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    values = np.asarray(texture.eval(mi.Point3f(*(mi.Float(unit[:, i]) for i in range(3))))[0])
    world = box.bbox_min + unit * box.extent
    inside = np.all((world >= low) & (world <= high), axis=1)
    assert values[~inside].max() == 0.0 and values[inside].max() > 0
    # Tight: the non-zero points come within a lattice step of every side of the support.
    seen = world[values > 0]
    step = box.voxel_size / 4
    assert np.all(seen.min(axis=0) - low < step) and np.all(high - seen.max(axis=0) < step)
    np.testing.assert_allclose(high, box.bbox_max)  # the corner voxel reaches the box's faces
    np.testing.assert_allclose(low, box.bbox_min + np.array([1.5, 4.5, -0.5]).clip(0) * box.voxel_size)
    empty_low, empty_high = box.field_support(np.zeros(SHAPE, bool))
    np.testing.assert_array_equal(empty_low, box.bbox_min)
    np.testing.assert_array_equal(empty_high, box.bbox_max)
    with pytest.raises(ValueError, match="does not match"):
        box.field_support(np.ones((2, 2, 2), bool))


def test_gridvolume_of_path_tracer_reads_arr_z_y_x(mi):
    import drjit as dr

    medium_dict = heterogeneous_medium(hot_voxel_grid(), 1.0, np.full(SHAPE + (3,), 0.5, np.float32))
    volume = mi.load_dict(medium_dict["sigma_t"])
    interaction = dr.zeros(mi.Interaction3f)
    interaction.p = mi.Point3f(*map(float, MediumBox(SHAPE).voxel_centre(2, 5, 7)))
    assert volume.eval_1(interaction)[0] == pytest.approx(1.0)


def test_cube_shape_spans_the_box(mi):
    from mistyle.scenes import medium_cube

    box = MediumBox(SHAPE)
    cube = medium_cube(np.ones(SHAPE, np.float32), 1.0, np.ones(SHAPE + (3,), np.float32))
    scene = mi.load_dict({"type": "scene", "box": cube})
    for axis in range(3):
        direction = np.zeros(3)
        direction[axis] = 1.0
        ray = mi.Ray3f(mi.Point3f(*map(float, -5 * direction)), mi.Vector3f(*map(float, direction)))
        hit = scene.ray_intersect(ray)
        assert hit.p.numpy()[axis][0] == pytest.approx(box.bbox_min[axis], abs=1e-5)


@pytest.mark.parametrize("channels", [1, 3])
def test_vol_files_round_trip_through_mitsubas_own_reader_and_writer(mi, tmp_path, channels):
    grid = np.random.default_rng(0).random(SHAPE + (channels,)).astype(np.float32)
    expected = grid[..., 0] if channels == 1 else grid
    path = write_vol(tmp_path / "grid.vol", grid, bbox_min=(-0.5, -0.4, -0.3), bbox_max=(0.5, 0.4, 0.3))
    np.testing.assert_array_equal(read_vol(path), expected)
    np.testing.assert_array_equal(np.array(mi.VolumeGrid(str(path))).reshape(grid.shape), grid)
    mi.VolumeGrid(grid).write(str(tmp_path / "mitsuba.vol"))
    np.testing.assert_array_equal(read_vol(tmp_path / "mitsuba.vol"), expected)


def test_image_orientation_plus_x_right_plus_y_up(mi):
    """Seen from +z, a bright x>0, y>0 octant lands in the image's top-right quadrant."""
    shape = (16, 16, 16)
    density = np.full(shape, 0.5, np.float32)
    albedo = np.full(shape + (3,), 0.05, np.float32)
    albedo[:, 8:, 8:] = 1.0  # y >= 0 and x >= 0
    prepared = prepare_density(density, 4.0)
    view = View(origin=(0.0, 0.0, 3.0))
    image = split_views(mi.render(mi.load_dict(layer_scene(prepared, albedo, [view], res=32))), 1)[0].mean(-1)
    quadrants = {"top_right": image[:16, 16:], "top_left": image[:16, :16], "bottom_right": image[16:, 16:]}
    assert quadrants["top_right"].mean() > 4 * quadrants["top_left"].mean()
    assert quadrants["top_right"].mean() > 4 * quadrants["bottom_right"].mean()


def test_split_views_layout():
    film = np.arange(2 * 3 * 4 * 3, dtype=np.float32).reshape(2, 3 * 4, 3)
    views = split_views(film, 3)
    assert views.shape == (3, 2, 4, 3)
    np.testing.assert_array_equal(views[1], film[:, 4:8])


def test_camera_path_views_look_at_the_box():
    path = CameraPath()
    for view in path.turntable(8) + path.sample(8, np.random.default_rng(0)) + path.held_out(2):
        assert np.linalg.norm(view.origin) == pytest.approx(path.distance)
    with pytest.raises(ValueError):
        View(origin=(0.0, 2.0, 0.0), up=(0.0, 1.0, 0.0))  # looking straight down its up vector


def test_stratified_views_are_evenly_spaced_from_a_random_offset():
    path = CameraPath()
    azimuths = []
    for seed in range(50):
        views = path.sample_stratified(3, np.random.default_rng(seed))
        angles = sorted(np.arctan2(view.origin[0], view.origin[2]) % (2 * np.pi) for view in views)
        gaps = np.diff(angles + [angles[0] + 2 * np.pi])
        np.testing.assert_allclose(gaps, 2 * np.pi / 3, atol=1e-9)
        azimuths.append(angles[0])
    assert 0 < min(azimuths) and max(azimuths) < 2 * np.pi / 3 and np.std(azimuths) > 0.3


def test_torch_reference_camera_matches_mitsuba_rays(mi):
    from mistyle.reference_torch import camera_rays
    from mistyle.scenes.cameras import sensor_dict

    view = CameraPath().view(0.3)
    sensor = mi.load_dict(sensor_dict(view, 6, 4))
    origins, directions = camera_rays([view], 4, 6)
    for row, col in [(0, 0), (3, 5), (2, 1)]:
        ray, _ = sensor.sample_ray(0.0, 0.0, mi.Point2f((col + 0.5) / 6, (row + 0.5) / 4), mi.Point2f(0.5))
        np.testing.assert_allclose(np.array(ray.d)[:, 0], directions[0, row, col].numpy(), atol=1e-6)
        # Mitsuba starts rays on the near clip plane: same line, same direction.
        offset = np.array(ray.o)[:, 0] - origins[0, row, col].numpy()
        np.testing.assert_allclose(np.cross(offset, directions[0, row, col].numpy()), 0.0, atol=1e-6)


# Parameters and fields whose defaults are conventions: they must name the constant, not repeat its value.
CONVENTION_DEFAULTS = {
    "density_scale": "DEFAULT_DENSITY_SCALE",
    "directions": "LS_DIRECTIONS",
    "radiance": "DEFAULT_ENV_RADIANCE",
    "camera_distance": "ORBIT_DISTANCE",
    "layer_steps_per_ray": "LAYER_MARCH_STEPS",
}


def literal_convention_defaults():
    """``(file, line, name)`` of every literal number given as the default of a convention's parameter,
    dataclass field or ``--option`` in the package (``conventions.py`` itself excepted)."""
    import ast
    from pathlib import Path

    import mistyle

    root = Path(mistyle.__file__).parent
    found = []
    for path in root.rglob("*.py"):
        if path.name == "conventions.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            pairs = []
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                positional = node.args.posonlyargs + node.args.args
                pairs += list(
                    zip([a.arg for a in positional[len(positional) - len(node.args.defaults) :]], node.args.defaults)
                )
                pairs += [(a.arg, d) for a, d in zip(node.args.kwonlyargs, node.args.kw_defaults) if d is not None]
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value is not None:
                pairs.append((node.target.id, node.value))
            elif isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument" and node.args:
                option = node.args[0].value if isinstance(node.args[0], ast.Constant) else ""
                default = next((k.value for k in node.keywords if k.arg == "default"), None)
                if isinstance(option, str) and default is not None:
                    pairs.append((option.lstrip("-").replace("-", "_"), default))
            found += [
                (path.name, value.lineno, name)
                for name, value in pairs
                if name in CONVENTION_DEFAULTS
                and isinstance(value, ast.Constant)
                and isinstance(value.value, (int, float))
                and not isinstance(value.value, bool)
            ]
    return found


def test_convention_defaults_name_their_constant():
    assert literal_convention_defaults() == [], f"use the constants of mistyle.conventions ({CONVENTION_DEFAULTS})"


def test_default_orbit_and_march_are_the_shipped_networks():
    """An image framed by default (``mistyle.render(view=...)``, a ``CameraPath``, a fit's settings) is
    framed as ``mistyle-render`` frames it: at the orbit the bundled network was trained on and records."""
    import inspect

    import mistyle
    from mistyle.fit import FitSettings, RefineSettings
    from mistyle.look import LookSettings
    from mistyle.model.config import RenderConfig
    from mistyle.pipeline import Pipeline

    shipped = Pipeline().config.render
    assert inspect.signature(mistyle.render).parameters["camera_distance"].default == shipped.camera_distance
    for distance in (CameraPath().distance, FitSettings().camera_distance, RefineSettings().camera_distance):
        assert distance == shipped.camera_distance
    assert RenderConfig().camera_distance == shipped.camera_distance
    for steps in (RenderConfig().steps, LookSettings().layer_steps_per_ray, RefineSettings().layer_steps_per_ray):
        assert steps == shipped.steps
