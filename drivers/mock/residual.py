"""What a controller's calibrated kinematics leave of a UR arm's pose error.

A factory calibration fits a DH table to the arm; the gears, the links' elasticity and the
encoders' own errors are not in any DH table. What remains is a flange pose error of about a
tenth of a millimetre that changes smoothly with the joints, plus repeatability: a fresh small
error after every move. The mock arm's physical flange pose is its kinematics' pose composed
with both (:meth:`drivers.mock.arm.MockArm.true_flange_pose`); the controller knows neither.
"""

from __future__ import annotations

import math

import numpy as np

from armstereo.transforms import make_T, rotvec_to_matrix
from drivers.mock.profile import TAG_REPEAT, TAG_RESIDUAL, ArmResidual, rng_for

# Cycles per joint revolution of the error. A strain-wave gear's transmission error repeats
# twice per turn of its wave generator, which turns about a hundred times per joint turn; these
# lower stand-ins already make views a few tenths of a radian apart see unrelated errors.
HARMONICS = (7, 11, 13)


class PoseResidual:
    """``at(q)``: the 4x4 ``T_flange_trueflange`` of joints ``q`` (rad), a seeded smooth
    function of the joints: per joint a sum of harmonics ``sin(k q_j)``, ``cos(k q_j)`` (k in
    HARMONICS: a gear's transmission error repeats many times per joint turn), one
    standard deviation ``errors.rotation_rad`` / ``translation_m`` per axis over the joint
    space. ``moved()`` draws the repeatability error of the next stop."""

    def __init__(self, errors: ArmResidual, seed: int):
        self.errors = errors
        rng = rng_for(seed, TAG_RESIDUAL)
        n = 6 * len(HARMONICS)  # always drawn: each source keeps its draws
        self._a = rng.standard_normal((n, 6))
        self._b = rng.standard_normal((n, 6))
        self._k = np.repeat(np.asarray(HARMONICS, dtype=float)[None, :], 6, axis=0).ravel()
        self._joint = np.repeat(np.arange(6), len(HARMONICS))
        self._repeat_rng = rng_for(seed, TAG_REPEAT)
        self._scale = np.array([errors.rotation_rad] * 3 + [errors.translation_m] * 3)
        self._repeat = np.zeros(6)

    def moved(self) -> None:
        """A move ended: the arm stops a little off where it stopped last time."""
        unit = self._repeat_rng.standard_normal(6)
        e = self.errors
        self._repeat = np.array([e.repeat_rad] * 3 + [e.repeat_m] * 3) * unit

    def at(self, q: np.ndarray) -> np.ndarray:
        arg = self._k * np.asarray(q, dtype=float)[self._joint]
        # each term (a sin + b cos) has unit variance per axis; n of them / sqrt n
        xi = (np.sin(arg) @ self._a + np.cos(arg) @ self._b) / math.sqrt(len(arg))
        e = self._scale * xi + self._repeat
        return make_T(rotvec_to_matrix(e[:3]), e[3:])
