"""Random but seeded rotations and poses for geometry tests."""

from __future__ import annotations

import numpy as np

from armstereo.transforms import matrix_from_quaternion_xyzw, rotvec_to_matrix


def random_rotation(rng: np.random.Generator, max_deg: float | None = None) -> np.ndarray:
    """A random 3x3 rotation: uniform over SO(3), or about a random axis by at most
    ``max_deg`` degrees."""
    if max_deg is None:
        q = rng.normal(size=4)
        return matrix_from_quaternion_xyzw(q / np.linalg.norm(q))
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    return rotvec_to_matrix(axis * np.radians(rng.uniform(0.0, max_deg)))
