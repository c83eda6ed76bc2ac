"""The headless mesh picture: pixels land where the pinhole puts them, near hides far."""

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.fusion.mesh import Mesh
from armstereo.fusion.render import framing_camera, mesh_picture, render_mesh

K = np.array([[100.0, 0.0, 49.5], [0.0, 100.0, 39.5], [0.0, 0.0, 1.0]])
SIZE = (100, 80)


def square(z: float, half: float, bgr) -> Mesh:
    """A square facing the camera at the origin (camera = base frame), ``half`` m wide."""
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    return Mesh(v, np.array([[0, 1, 2], [0, 2, 3]]), np.tile(np.array(bgr, np.uint8), (4, 1)))


def merge(*meshes: Mesh) -> Mesh:
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return Mesh(np.vstack([m.vertices for m in meshes]),
                np.vstack([m.faces + o for m, o in zip(meshes, offsets, strict=True)]),
                np.vstack([m.colors for m in meshes]))


def test_a_square_covers_exactly_its_projection():
    # half 0.1 m at 1 m: +-10 px around the principal point (49.5, 39.5)
    image = render_mesh(square(1.0, 0.1, (0, 0, 200)), np.eye(4), K, SIZE, "color")
    drawn = np.any(image != 255, axis=2)
    rows, cols = np.nonzero(drawn)
    assert (cols.min(), cols.max(), rows.min(), rows.max()) == (40, 59, 30, 49)
    assert image[39, 49, 2] > image[39, 49, 0]  # red stays red (BGR), only shaded


def test_the_nearer_surface_hides_the_farther_whatever_the_order():
    near, far = square(1.0, 0.05, (0, 200, 0)), square(2.0, 0.8, (200, 0, 0))
    for mesh in (merge(near, far), merge(far, near)):
        image = render_mesh(mesh, np.eye(4), K, SIZE, "color")
        assert image[39, 49, 1] > 0 and image[39, 49, 0] == 0  # green in the middle
        assert image[39, 20, 0] > 0 and image[39, 20, 1] == 0  # blue around it


def test_framing_fills_the_picture_and_styles():
    mesh = merge(square(0.0, 0.2, (120, 120, 120)), square(0.05, 0.05, (0, 0, 255)))
    T, K_fit = framing_camera(mesh, SIZE)
    image = render_mesh(mesh, T, K_fit, SIZE, "shape")
    rows, cols = np.nonzero(np.any(image != 255, axis=2))
    assert cols.min() <= 8 and cols.max() >= SIZE[0] - 9  # spans the width up to the margin
    assert rows.min() >= 0 and rows.max() <= SIZE[1] - 1
    assert mesh_picture(mesh, SIZE).shape == (SIZE[1], 2 * SIZE[0], 3)
    with pytest.raises(ConfigError, match="style"):
        render_mesh(mesh, T, K_fit, SIZE, "wireframe")
    with pytest.raises(ConfigError, match="empty"):
        framing_camera(Mesh.empty(), SIZE)
