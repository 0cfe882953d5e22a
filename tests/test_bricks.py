"""The bricked medium (``scenes.bricks``): the same field, the same image in expectation, faster."""

import drjit as dr
import numpy as np
import pytest

from mistyle.data.procedural import colour_noise_albedo
from mistyle.scenes import CameraPath, LightSpec, pathtraced_scene
from mistyle.scenes.bricks import brick_levels, bricked_media
from mistyle.scenes.medium import heterogeneous_medium


def sparse_smoke() -> np.ndarray:
    """A dense core and a thin, far wisp in a mostly empty 24 x 20 x 16 box."""
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5 for n in (24, 20, 16)), indexing="ij")
    core = 2.0 * np.exp(-((z - 8) ** 2 + (y - 8) ** 2 + (x - 8) ** 2) / 6.0)
    wisp = 0.15 * np.exp(-((z - 19) ** 2 / 4.0 + (y - 14) ** 2 / 2.0 + (x - 6) ** 2 / 20.0))
    density = core + wisp
    density[density < 0.01] = 0.0
    return density.astype(np.float32)


def test_levels_leave_empty_bricks_out_and_sort_by_peak():
    density = np.zeros((16, 16, 16), np.float32)
    density[2, 2, 2] = 1.0  # brick (0, 0, 0)
    density[12, 12, 12] = 0.2  # brick (1, 1, 1): peak 1/5 of the maximum -> level 2
    level, edges = brick_levels(density, brick=8, levels=4)
    assert [e.tolist() for e in edges] == [[0, 8, 16]] * 3
    assert level[0, 0, 0] == 0 and level[1, 1, 1] == 2
    assert (level == -1).sum() == 6
    # The halo: a voxel on a brick's face makes the neighbouring brick non-empty too.
    density[7, 2, 2] = 1.0
    level, _ = brick_levels(density, brick=8, levels=4)
    assert level[1, 0, 0] == 0
    assert (brick_levels(np.zeros((8, 8, 8), np.float32), 4, 2)[0] == -1).all()
    with pytest.raises(ValueError, match="brick"):
        brick_levels(density, brick=0, levels=2)
    with pytest.raises(ValueError, match="levels"):
        brick_levels(density, brick=4, levels=0)


def test_brick_peaks_are_each_bricks_maximum_with_its_halo():
    """Against a brick-by-brick reference, on a grid no brick size divides."""
    density = sparse_smoke()
    for brick in (3, 5, 8, 24):
        level, edges = brick_levels(density, brick=brick, levels=3)
        top = density.max()
        for position in np.ndindex(level.shape):
            window = tuple(
                slice(max(int(edges[a][position[a]]) - 1, 0), int(edges[a][position[a] + 1]) + 1) for a in range(3)
            )
            peak = density[window].max()
            expected = -1 if peak == 0 else min(int(np.floor(np.log2(top / peak))), 2)
            assert level[position] == expected, (brick, position)


def test_a_brick_larger_than_the_grid_is_one_brick_in_the_grids_memory():
    """Padding the grid to whole bricks would take 512 GiB for --bricks 4096 on a 16^3 grid (8 GB for 1000);
    any brick of the grid's longest side or more is the whole grid as one brick."""
    import time

    density = np.zeros((16, 16, 12), np.float32)
    density[3:9, 4:10, 2:6] = 1.0
    whole = brick_levels(density, brick=16, levels=4)
    started = time.perf_counter()
    for brick in (17, 1000, 4096, 10**30):
        level, edges = brick_levels(density, brick=brick, levels=4)
        assert level.tolist() == whole[0].tolist() == [[[0]]]
        assert [e.tolist() for e in edges] == [[0, 16], [0, 16], [0, 12]]
    assert time.perf_counter() - started < 1.0


def test_every_level_returns_the_whole_mediums_field_inside_its_bricks(mi):
    density = sparse_smoke()
    albedo = colour_noise_albedo(density.shape, seed=1)
    whole = mi.load_dict(heterogeneous_medium(density, 10.0, albedo))
    level, edges = brick_levels(density, brick=4, levels=3)
    media = {}  # level -> medium, read off the face meshes' names: brick_faces_{inside}_{outside}
    for name, mesh in bricked_media(density, 10.0, albedo, brick=4, levels=3).items():
        inside, outside = name.split("_")[-2:]
        for region, medium in ((inside, mesh.interior_medium()), (outside, mesh.exterior_medium())):
            assert (region == "vacuum") == (medium is None)
            if medium is not None:
                assert media.setdefault(int(region), medium) is medium
    assert sorted(media) == np.unique(level[level >= 0]).tolist() and len(media) > 1
    rng = np.random.default_rng(0)
    voxel = 1.0 / max(density.shape)
    bbox_min = -0.5 * np.array(density.shape[::-1]) * voxel
    checked = 0
    for position in zip(*np.nonzero(level >= 0)):
        medium = media[level[position]]
        lo = np.array([edges[a][position[a]] for a in range(3)])[::-1]
        hi = np.array([edges[a][position[a] + 1] for a in range(3)])[::-1]
        points = bbox_min + (lo + rng.random((16, 3)) * (hi - lo)) * voxel
        mei = dr.zeros(mi.MediumInteraction3f, 16)
        mei.p = mi.Point3f(*(mi.Float(points[:, i]) for i in range(3)))
        sigma_s, _, sigma_t = whole.get_scattering_coefficients(mei)
        got_s, got_n, got_t = medium.get_scattering_coefficients(mei)  # sigma_n: the level's majorant - sigma_t
        np.testing.assert_allclose(np.asarray(got_s), np.asarray(sigma_s), rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(np.asarray(got_t), np.asarray(sigma_t), rtol=1e-5, atol=1e-5)
        assert np.asarray(got_n).min() >= 0.0
        checked += 1
    assert checked == (level >= 0).sum() > 4


def mean_difference_z(
    mi, density, albedo, view, res, density_scale, bricks, spp, seed, light: str = "constant"
) -> tuple[float, float]:
    """``(z, mean)``: the bricked render's mean minus one medium's over its standard error (two seeds each,
    the noise measured from the seed pairs), and the plain render's mean."""

    def renders(brick):
        scene = mi.load_dict(
            pathtraced_scene(
                density,
                albedo,
                [CameraPath().view(view)],
                res=res,
                density_scale=density_scale,
                bricks=brick,
                light=LightSpec.parse(light),
            )
        )
        return [np.asarray(mi.render(scene, spp=spp, seed=s))[..., :3] for s in (seed, 1000 * seed)]

    plain, bricked = renders(0), renders(bricks)
    variance = sum(np.mean((a - b) ** 2) / 2 for a, b in (plain, bricked)) / 2
    difference = np.mean(bricked[0] + bricked[1] - plain[0] - plain[1]) / 2
    return float(difference / np.sqrt(variance / plain[0].size)), float(np.mean(plain))


@pytest.mark.parametrize("light", ["constant", "point:1.5,1.2,0.5:100", "area:50"])
def test_bricks_render_the_same_image_as_one_medium(mi, light):
    density = sparse_smoke()
    z, mean = mean_difference_z(
        mi,
        density,
        colour_noise_albedo(density.shape, seed=1),
        0.1,
        res=24,
        density_scale=10.0,
        bricks=4,
        spp=256,
        seed=3,
        light=light,
    )
    assert abs(z) < 4.0 and mean > 0.01


def test_thin_medium_through_face_meshes_matches_the_box(mi):
    """A thin, homogeneous box split into bricks of two levels: through ``rectangle`` shapes, volpath was
    ~1% too bright here (z > 6 at this sample count); the face meshes must agree with the cube."""
    density = np.full((16, 16, 16), 0.2, np.float32)
    density[8:] = 0.05  # a second level above
    albedo = np.full(density.shape + (3,), 0.8, np.float32)
    z, _ = mean_difference_z(mi, density, albedo, 0.0625, res=16, density_scale=20.0, bricks=8, spp=1024, seed=5)
    assert abs(z) < 4.0


def test_bricks_refuse_a_coat_and_prbvolpath(mi):
    density = sparse_smoke()
    albedo = np.full(density.shape + (3,), 0.5, np.float32)
    views = [CameraPath().view(0.1)]
    with pytest.raises(ValueError, match="coat"):
        pathtraced_scene(density, albedo, views, res=8, density_scale=10.0, bricks=4, coat_ior=1.5)
    with pytest.raises(ValueError, match="prbvolpath"):
        pathtraced_scene(density, albedo, views, res=8, density_scale=10.0, bricks=4, integrator="prbvolpath")
