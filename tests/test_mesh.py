"""Mesh voxelization: analytic sphere volume, aspect, soft edges, and bad meshes."""

import numpy as np
import pytest

from mistyle.data.mesh import check_closed, icosphere, load_mesh, voxelize, write_ply


@pytest.fixture(scope="module")
def sphere_ply(tmp_path_factory):
    vertices, faces = icosphere(4)
    return write_ply(tmp_path_factory.mktemp("mesh") / "sphere.ply", vertices, faces)


def test_sphere_volume_within_two_percent_at_64(mi, sphere_ply):
    vertices, faces = load_mesh(sphere_ply)
    density = voxelize(vertices, faces, resolution=64, margin=0.1)
    assert density.shape == (64, 64, 64)
    radius = 0.5 * (1 - 2 * 0.1)  # box units: the sphere spans 80% of the box
    volume = density.sum() / 64**3
    assert abs(volume / (4 / 3 * np.pi * radius**3) - 1) < 0.02


def test_obj_files_load_too(mi, tmp_path):
    vertices, faces = icosphere(1)
    lines = [f"v {x} {y} {z}" for x, y, z in vertices] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path = tmp_path / "ball.obj"
    path.write_text("\n".join(lines) + "\n")
    loaded_vertices, loaded_faces = load_mesh(path)
    assert loaded_faces.shape == faces.shape
    assert voxelize(loaded_vertices, loaded_faces, resolution=16).sum() > 0


def test_elongated_mesh_keeps_its_aspect_and_soft_edges_are_fractional(mi):
    vertices, faces = icosphere(2)
    vertices = vertices * np.array([1.0, 0.5, 0.25])  # long along x
    density = voxelize(vertices, faces, resolution=32, margin=0.0, supersample=2)
    assert density.shape == (8, 16, 32)  # (Z, Y, X)
    assert 0 < ((density > 0) & (density < 1)).sum()
    assert density.max() == 1.0 and density[0, 0, 0] == 0.0


def test_open_and_empty_meshes_are_refused(mi):
    vertices, faces = icosphere(1)
    with pytest.raises(ValueError, match="not watertight"):
        voxelize(vertices, faces[1:], resolution=8)
    with pytest.raises(ValueError, match="no triangles"):
        check_closed(np.zeros((0, 3), dtype=int))


def test_unreadable_mesh_files_give_clear_errors(mi, tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        load_mesh(tmp_path / "missing.ply")
    with pytest.raises(ValueError, match=".ply or .obj"):
        load_mesh(tmp_path / "mesh.stl")
    broken = tmp_path / "broken.ply"
    broken.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n")
    with pytest.raises(ValueError, match="Cannot read the mesh"):
        load_mesh(broken)


def test_mesh_cli_writes_a_vol_file(mi, tmp_path, sphere_ply):
    from mistyle.data.__main__ import main as data_cli
    from mistyle.files import load_density

    assert data_cli(["mesh", "--mesh", str(sphere_ply), "--res", "16", "--out", str(tmp_path / "ball.vol")]) == 0
    assert load_density(tmp_path / "ball.vol").shape == (16, 16, 16)
    assert data_cli(["mesh", "--mesh", str(tmp_path / "none.ply"), "--out", str(tmp_path / "x.vol")]) == 2


def test_data_commands_that_cannot_write_say_so_in_one_line(mi, tmp_path, capsys):
    from mistyle.data.__main__ import main as data_cli

    (tmp_path / "a_file").write_text("not a folder")
    for command in (["mesh", "--res", "8", "--out", str(tmp_path / "a_file" / "ball.vol")],
                    ["styles", "--out", str(tmp_path / "a_file" / "styles")]):  # fmt: skip
        assert data_cli(command) == 2
        error = capsys.readouterr().err
        assert error.startswith("error: ") and error.count("\n") == 1 and "Traceback" not in error, error
        assert "a_file" in error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]
