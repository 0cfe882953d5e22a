"""Procedural densities: range, determinism, and where their density sits."""

import numpy as np

from mistyle.data.mesh import icosphere
from mistyle.data.procedural import (
    noise_filled_level_set,
    pyroclastic_sphere,
    sphere_sdf,
    spot_noise,
    torus_sdf,
)
from mistyle.scenes import MediumBox


def test_pyroclastic_sphere_is_deterministic_and_bounded():
    a, b = pyroclastic_sphere((16, 20, 24), seed=4), pyroclastic_sphere((16, 20, 24), seed=4)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (16, 20, 24) and 0 <= a.min() and a.max() <= 1 and a.max() > 0.5
    assert not np.array_equal(a, pyroclastic_sphere((16, 20, 24), seed=5))


def test_noise_filled_level_set_stays_inside_its_surface():
    sdf = torus_sdf((24, 24, 24))
    density = noise_filled_level_set(sdf, seed=1)
    assert density[sdf >= 0].max() == 0
    assert density[sdf < -0.03].mean() > 0.2  # the inside is filled (noise varies it)
    assert density[sdf < -0.03].std() > 0.05


def test_spot_noise_forms_a_shell_near_the_surface():
    vertices, faces = icosphere(2)
    density = spot_noise(vertices, faces, resolution=24, impulses=400, margin=0.1, seed=3)
    assert density.shape == (24, 24, 24) and 0 <= density.min() and density.max() <= 1
    radius = 0.4  # the unit sphere fitted into the box with a 10% margin
    distance = np.linalg.norm(MediumBox(density.shape).voxel_centres(), axis=-1)
    dense = density > 0.2
    assert dense.sum() > 50
    assert np.all(np.abs(distance[dense] - radius) < 0.12)  # a shell, not a filled ball
    assert density[distance < 0.15].max() < 0.05
    np.testing.assert_array_equal(density, spot_noise(vertices, faces, resolution=24, impulses=400, margin=0.1, seed=3))


def test_sphere_sdf_sign():
    sdf = sphere_sdf((9, 9, 9), radius=0.3)
    assert sdf[4, 4, 4] < 0 < sdf[0, 0, 0]
