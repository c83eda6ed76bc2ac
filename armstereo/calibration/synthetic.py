"""Simulated calibration sessions with a known truth, for tests, benchmarks and the mock.

The truth: a camera mount (hand-eye and intrinsics) that differs from the arm model's nominal
one, a board lying in front of the start camera, and an arm whose real kinematics differ from
the nominal model that reports its poses (see ARM_ERROR_PROFILES).
Views come from :func:`plan_calibration_views` with the nominal mount, as a real session's
would. Observations are either the exactly projected corners plus Gaussian pixel noise, or
corners detected in rendered images.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from armstereo.calibration.board import Board, Detection, detect_board, render_board_view
from armstereo.calibration.poses import exp6
from armstereo.calibration.views import ViewPlanSettings, plan_calibration_views
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.robot.arm_model import ArmModel, ready_configuration
from armstereo.transforms import invert, make_T, rot_x, rot_z
from robot_models.generate_urdfs import SPECS


@dataclass(frozen=True)
class ArmError:
    """How far the arm really is from what forward kinematics of its joints reports.

    Systematic: the real arm's DH parameters differ from the nominal model's (Gaussian per
    parameter: lengths a and d, twists alpha, joint zero offsets theta), drawn once per
    session, so the pose error changes smoothly with the joints, as a real arm's does. Random:
    per view, Gaussian per axis in the flange frame (repeatability). All sigmas; metres, rad.
    """

    length_m: float = 0.0
    twist_rad: float = 0.0
    offset_rad: float = 0.0
    repeat_m: float = 0.0
    repeat_rad: float = 0.0


# "ideal": the arm is where its joints say.
# "ur_like": a UR arm whose poses come from its *calibrated* kinematics (the controller's own
# factory calibration): what remains is the calibration's residual (about 0.1-0.3 mm and a
# hundredth of a degree, varying with the joints) plus repeatability (UR: +-0.03 mm).
# "nominal_kinematics": the same arm's poses from the *nominal* model: its factory calibration
# differs from nominal by UR-typical amounts, 1-3 mm and 0.1-0.6 deg at the flange, of which
# a few tenths of a millimetre and a few hundredths of a degree change across a calibration
# orbit (the constant part is absorbed into the hand-eye and the board pose).
ARM_ERROR_PROFILES = {
    "ideal": ArmError(),
    "ur_like": ArmError(length_m=0.0001, twist_rad=0.0002, offset_rad=0.0002,
                        repeat_m=0.00003, repeat_rad=math.radians(0.001)),
    "nominal_kinematics": ArmError(length_m=0.0005, twist_rad=0.002, offset_rad=0.001,
                                   repeat_m=0.00003, repeat_rad=math.radians(0.001)),
}


class TrueArm:
    """Forward kinematics of a real arm: the nominal UR DH table of ``model_name`` perturbed
    by ``error`` (drawn from ``rng``); ``flange_pose(q)`` is where the flange really is."""

    def __init__(self, model_name: str, error: ArmError, rng: np.random.Generator):
        specs = {s.name: s for s in SPECS}
        if model_name not in specs:
            raise ConfigError(f"no DH table for robot {model_name!r}; known: "
                              f"{', '.join(specs)}")
        rows = np.array(specs[model_name].dh_rows())  # (a, d, alpha) per joint
        self.a = rows[:, 0] + rng.normal(size=6) * error.length_m
        self.d = rows[:, 1] + rng.normal(size=6) * error.length_m
        self.alpha = rows[:, 2] + rng.normal(size=6) * error.twist_rad
        self.theta = rng.normal(size=6) * error.offset_rad
        self.error = error
        self._rng = rng

    def flange_pose(self, q: np.ndarray) -> np.ndarray:
        """T_base_flange of joints q (rad): standard DH, Rz(q + theta) Tz(d) Tx(a) Rx(alpha)."""
        T = np.eye(4)
        for i in range(6):
            T = T @ make_T(rot_z(q[i] + self.theta[i]), [0.0, 0.0, self.d[i]]) @ make_T(
                rot_x(self.alpha[i]), [self.a[i], 0.0, 0.0])
        return T

    def with_repeatability(self, T: np.ndarray) -> np.ndarray:
        e = self.error
        return T @ exp6(np.concatenate([self._rng.normal(size=3) * e.repeat_rad,
                                        self._rng.normal(size=3) * e.repeat_m]))


@dataclass
class SyntheticSession:
    """A simulated session: what the calibrator gets and the truth to grade it with."""

    board: Board
    true_mount: CameraMount
    nominal_mount: CameraMount
    T_base_board: np.ndarray
    joints: list[np.ndarray]
    T_base_flange_reported: list[np.ndarray]
    T_base_flange_true: list[np.ndarray]
    detections: list[Detection | None]
    images: list[np.ndarray] | None = None

    @property
    def T_camera_board_true(self) -> list[np.ndarray]:
        X = self.true_mount.T_flange_camera
        return [invert(F @ X) @ self.T_base_board for F in self.T_base_flange_true]


def perturbed_mount(nominal: CameraMount, rng: np.random.Generator, *,
                    translation_m: float = 0.005, rotation_deg: float = 2.0,
                    focal_rel: float = 0.02, principal_px: float = 6.0,
                    k1: float = -0.08, k2: float = 0.05) -> CameraMount:
    """A 'true' mount near the nominal one: hand-eye off by about ``translation_m`` and
    ``rotation_deg``, focal length by ``focal_rel``, principal point by ``principal_px``,
    plus radial distortion (k1, k2)."""
    def unit(v):
        return v / np.linalg.norm(v)

    xi = np.concatenate([unit(rng.normal(size=3)) * math.radians(rotation_deg),
                         unit(rng.normal(size=3)) * translation_m])
    X = nominal.T_flange_camera @ exp6(xi)
    intr = nominal.intrinsics
    K = intr.K.copy()
    K[0, 0] *= 1 + focal_rel
    K[1, 1] *= 1 + focal_rel * 1.001  # square pixels are not exact either
    K[:2, 2] += rng.normal(size=2) * principal_px / math.sqrt(2)
    dist = np.array([k1, k2, 0.0, 0.0, 0.0])
    return CameraMount("true_" + nominal.name, X, Intrinsics(intr.width, intr.height, K, dist))


def simulate_session(model: ArmModel, board: Board, *, n_views: int = 15,
                     arm_error: str | ArmError = "ur_like", pixel_noise: float = 0.3,
                     seed: int = 0, render: bool = False, image_noise: float = 1.0,
                     board_distance_m: float = 0.45,
                     settings: ViewPlanSettings | None = None,
                     joints: Sequence[np.ndarray] | None = None,
                     supersample: int = 2) -> SyntheticSession:
    """Simulate a calibration session of ``model`` (which carries the *nominal* mount).

    The board lies ``board_distance_m`` in front of the camera at the model's ready
    configuration (or at ``joints[0]``); the views are planned with ``settings`` (default:
    ``n_views`` views) unless ``joints`` (rad, one vector per view) are given.
    ``pixel_noise`` (px, per coordinate) is added to projected corners when ``render`` is
    False; with ``render`` the corners are detected in rendered grey images with
    ``image_noise`` grey levels of sensor noise and ``supersample`` squared rays per pixel
    (slower: a few tenths of a second per view).
    """
    if model.mount is None:
        raise ConfigError("simulate_session needs a model with a (nominal) mount")
    if isinstance(arm_error, str):
        if arm_error not in ARM_ERROR_PROFILES:
            raise ConfigError(f"arm error profile must be one of "
                              f"{', '.join(ARM_ERROR_PROFILES)}, not {arm_error!r}")
        arm_error = ARM_ERROR_PROFILES[arm_error]
    rng = np.random.default_rng(seed)
    arm = TrueArm(model.name, arm_error, np.random.default_rng([seed, 1]))
    true_mount = perturbed_mount(model.mount, rng)
    q0 = ready_configuration(model.name) if joints is None else np.asarray(joints[0], float)
    # The board lies roughly square to the start camera's view, slightly turned and offset.
    T0_cam_true = arm.flange_pose(q0) @ true_mount.T_flange_camera
    R_cb = rot_z(rng.uniform(-0.3, 0.3)) @ rot_x(rng.uniform(-0.1, 0.1))
    t_cb = np.array([rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), board_distance_m])
    T_cb0 = make_T(R_cb, t_cb - R_cb @ board.center)
    T_base_board = T0_cam_true @ T_cb0
    # The planner sees the board with the nominal mount (as a real session would).
    T_cb_nominal = invert(model.camera_pose(q0)) @ T_base_board
    if joints is None:
        plan = plan_calibration_views(model, q0, board, T_camera_board_start=T_cb_nominal,
                                      settings=settings or ViewPlanSettings(n_views=n_views))
        joints = [v.q for v in plan.views]
    joints = [np.asarray(q, dtype=float) for q in joints]
    reported = [model.flange_pose(q) for q in joints]
    true = [arm.with_repeatability(arm.flange_pose(q)) for q in joints]
    X, intr = true_mount.T_flange_camera, true_mount.intrinsics
    detections, images = [], [] if render else None
    for k, F in enumerate(true):
        T_cb = invert(F @ X) @ T_base_board
        if render:
            img = render_board_view(board, intr, T_cb, noise_sigma=image_noise,
                                    seed=seed * 1000 + k, supersample=supersample)
            images.append(img)
            detections.append(detect_board(img, board))
        else:
            detections.append(observe_board(board, intr, T_cb, pixel_noise, rng))
    return SyntheticSession(board, true_mount, model.mount, T_base_board, joints, reported, true,
                            detections, images)


def observe_board(board: Board, intr: Intrinsics, T_cb: np.ndarray, noise: float,
                  rng: np.random.Generator) -> Detection | None:
    """The board's corners projected from ``T_cb`` (board in camera_optical) plus Gaussian
    noise (px per coordinate); None if any corner leaves the image (as a detector would)."""
    obj = board.object_points
    rvec = cv2.Rodrigues(np.ascontiguousarray(T_cb[:3, :3]))[0]
    uv, _ = cv2.projectPoints(obj, rvec, T_cb[:3, 3], intr.K, intr.dist)
    uv = uv.reshape(-1, 2) + rng.normal(size=(len(obj), 2)) * noise
    inside = ((uv[:, 0] >= 0) & (uv[:, 0] <= intr.width - 1) & (uv[:, 1] >= 0)
              & (uv[:, 1] <= intr.height - 1))
    if not inside.all():
        return None
    return Detection(np.arange(len(obj)), uv, obj.copy())
