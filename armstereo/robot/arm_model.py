"""Kinematics of UR arms in the controller's ``base`` frame: FK, flange Jacobian, IK, limits.

Every pose crosses this module's boundary as a 4x4 float64 array ``T_base_x`` in the frame the
UR controller reports (``getActualTCPPose`` with a zero TCP), not the URDF root ``base_link``
(which is ``base`` turned 180 deg about z). Pinocchio does the work; ``pin.SE3`` stays inside.

The Pinocchio model of a URDF is built once per process; every :class:`ArmModel` owns its own
``Data`` workspace, so one instance must not be shared between threads.

Example::

    arm = ArmModel.load("ur5e", mount="default_wrist_camera")
    q = ready_configuration("ur5e")
    T_base_flange = arm.flange_pose(q)
    q2 = arm.ik(T_base_flange @ make_T(np.eye(3), [0.05, 0, 0]), q, margin=0.1)
"""

from __future__ import annotations

import functools
import hashlib
import logging
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from armstereo.errors import ConfigError, IKError, JointLimitError
from armstereo.mount import CameraMount
from armstereo.transforms import as_rigid, invert, nearest_rotation
from robot_models import MODELS_DIR

log = logging.getLogger(__name__)

JOINT_NAMES = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
               "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")
MODEL_NAMES = ("ur3e", "ur5e", "ur10e", "ur16e", "ur5")
BASE_FRAME = "base"
FLANGE_FRAME = "tool0"

# IK reasons carried by IKError.reason.
NO_CONVERGENCE = "no_convergence"
JOINT_LIMITS = "joint_limits"
SINGULAR = "singular"
UNREACHABLE = "unreachable"

MAX_STEP_RAD = 0.2  # largest joint change per IK step: keeps DLS from jumping branches
SINGULAR_SIGMA = 1e-3  # sigma_min (mixed m/rad units) below which a failed IK is called singular
_DAMPING_START, _DAMPING_MIN, _DAMPING_MAX = 1e-6, 1e-12, 1e2

# Flange pointing straight down (tool0 z = -base z), upper arm vertical, forearm horizontal,
# wrist 2 at -90 deg: the classic UR "ready" pose, far from the shoulder, elbow and wrist
# singularities. See ready_configuration() for where this puts the flange.
_READY_Q = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])
_READY = dict.fromkeys(MODEL_NAMES, _READY_Q)


def ready_configuration(name: str) -> np.ndarray:
    """Joint vector (rad) of a bundled model with the flange pointing straight down.

    tool0 z is -base z, tool0 x is +base y; the flange sits in front of the robot on the -x side
    of the base frame. For the UR5e the flange is at (-0.492, -0.133, 0.488) m in ``base``
    (UR5: (-0.487, -0.109, 0.432); UR10e: (-0.691, -0.174, 0.677); UR16e: (-0.480, -0.174,
    0.543); UR3e: (-0.299, -0.131, 0.303)). Meant as the IK seed for "camera above the table
    looking down". Raises ConfigError for a name not in MODEL_NAMES.
    """
    key = str(name).lower()
    if key not in _READY:
        raise ConfigError(f"no ready configuration for robot {name!r}; known: "
                          f"{', '.join(MODEL_NAMES)}")
    return _READY[key].copy()


class _IKResult(NamedTuple):
    q: np.ndarray
    converged: bool
    iterations: int
    error: np.ndarray  # 6-vector log6 error in the flange frame (m, rad)


class ArmModel:
    """A UR arm's kinematics (and optionally its wrist camera mount), in the ``base`` frame.

    Attributes: ``name``, ``urdf_path``, ``urdf_sha256`` (of the URDF file's bytes), ``mount``
    (CameraMount or None), ``joint_names``, ``lower``/``upper`` (rad) and ``velocity_limits``
    (rad/s), each a read-only (6,) array from the URDF.
    """

    def __init__(self, name: str, urdf_path: Path, mount: CameraMount | None = None):
        self.name = name
        self.urdf_path = Path(urdf_path)
        self.urdf_sha256 = hashlib.sha256(self.urdf_path.read_bytes()).hexdigest()
        self.mount = mount
        self._setup_from_model(_build_model(str(self.urdf_path.resolve()), self.urdf_sha256))

    @classmethod
    def load(cls, name_or_path: str | Path,
             mount: CameraMount | str | Path | None = None) -> ArmModel:
        """Load a bundled model by name (case-insensitive, one of MODEL_NAMES) or a URDF path.

        ``mount`` is a CameraMount, a mount name or file (see armstereo.mount), or None (then
        camera_pose raises). A custom URDF needs six joints and frames ``base`` and ``tool0``.
        Raises ConfigError for an unknown name, an unreadable URDF or a bad mount.
        """
        name, path = _resolve_urdf(name_or_path)
        if mount is not None and not isinstance(mount, CameraMount):
            mount = CameraMount.load(mount)
        return cls(name, path, mount)

    def __repr__(self) -> str:
        mount = self.mount.name if self.mount else None
        return f"ArmModel(name={self.name!r}, urdf={str(self.urdf_path)!r}, mount={mount!r})"

    # ---- forward kinematics -------------------------------------------------------------
    def flange_pose(self, q: ArrayLike) -> np.ndarray:
        """T_base_flange (4x4, m) of joint vector ``q`` (rad): UR's DH forward kinematics."""
        return (self._base_M_world * self._world_M_flange(self._as_q(q))).homogeneous

    def camera_pose(self, q: ArrayLike) -> np.ndarray:
        """T_base_camera (camera_optical in base) = flange_pose(q) @ mount.T_flange_camera."""
        return self.flange_pose(q) @ self._require_mount().T_flange_camera

    def flange_pose_for_camera(self, T_base_camera: np.ndarray) -> np.ndarray:
        """T_base_flange that puts the camera at ``T_base_camera`` (inverse of camera_pose)."""
        T = _as_pose(T_base_camera, "T_base_camera")
        return T @ invert(self._require_mount().T_flange_camera)

    def jacobian(self, q: ArrayLike) -> np.ndarray:
        """6x6 flange Jacobian: rows (v; w) of tool0's origin in base axes, per joint rad/s."""
        J = pin.computeFrameJacobian(self._model, self._data, self._as_q(q), self._flange_id,
                                     pin.LOCAL_WORLD_ALIGNED)
        return self._twist_base_world @ J

    def sigma_min(self, q: ArrayLike) -> float:
        """Smallest singular value of jacobian(q); near 0 at a singularity (mixed m/rad units)."""
        return float(np.linalg.svd(self.jacobian(q), compute_uv=False)[-1])

    # ---- joint limits -------------------------------------------------------------------
    def check_limits(self, q: ArrayLike, margin: float = 0.0) -> None:
        """Raise JointLimitError naming the first joint outside [lower + margin, upper - margin]."""
        problem = self._limit_violation(self._as_q(q), _as_margin(margin))
        if problem:
            raise JointLimitError(problem)

    def within_limits(self, q: ArrayLike, margin: float = 0.0) -> bool:
        """True if every joint is inside [lower + margin, upper - margin] (rad)."""
        return self._limit_violation(self._as_q(q), _as_margin(margin)) is None

    def _limit_violation(self, q: np.ndarray, margin: float) -> str | None:
        bad = (q < self.lower + margin) | (q > self.upper - margin)
        if not bad.any():
            return None
        i = int(np.argmax(bad))
        text = (f"{self.joint_names[i]} = {q[i]:.2f} rad is outside "
                f"[{self.lower[i]:.2f}, {self.upper[i]:.2f}]")
        return text + (f" - margin {margin:.2f}" if margin else "")

    # ---- inverse kinematics -------------------------------------------------------------
    def ik(self, T_base_flange: np.ndarray, q_seed: ArrayLike, *, margin: float = 0.0,
           tol: float = 1e-9, max_iter: int = 200) -> np.ndarray:
        """Joint vector (rad) reaching ``T_base_flange`` on the seed's branch.

        Damped least squares on the log6 pose error from ``q_seed``; each joint of the result
        is taken to the equivalent angle (mod 2 pi) nearest the seed. A solution outside
        [lower + margin, upper - margin] is refused, never clipped. ``tol`` bounds the norm of
        the 6-vector error (m and rad). Raises IKError with ``reason`` one of "unreachable",
        "no_convergence", "singular", "joint_limits"; ConfigError for malformed input.
        """
        target = self._world_M_base * pin.SE3(_as_pose(T_base_flange, "T_base_flange"))
        seed, margin = self._as_q(q_seed, "q_seed"), _as_margin(margin)
        self._check_reach(target)
        result = self._solve(target, seed, tol, max_iter)
        if not result.converged:
            raise self._failure(result)
        q = _nearest_turn(result.q, seed)
        problem = self._limit_violation(q, margin)
        if problem:
            raise IKError(f"IK solution has {problem}", reason=JOINT_LIMITS)
        return q

    def _solve(self, target: pin.SE3, q: np.ndarray, tol: float, max_iter: int) -> _IKResult:
        """Levenberg-Marquardt style DLS: shrink damping on progress, grow it on a bad step."""
        damping = _DAMPING_START
        err, J = self._residual(target, q)
        for it in range(max_iter):
            if np.linalg.norm(err) < tol:
                return _IKResult(q, True, it, err)
            dq = np.linalg.solve(J.T @ J + damping * np.eye(6), -J.T @ err)
            dq *= min(1.0, MAX_STEP_RAD / max(np.abs(dq).max(), 1e-300))
            err_new, J_new = self._residual(target, q + dq)
            if np.linalg.norm(err_new) < np.linalg.norm(err):
                q, err, J = q + dq, err_new, J_new
                damping = max(damping * 0.3, _DAMPING_MIN)
            else:
                damping = min(damping * 10.0, _DAMPING_MAX)
        return _IKResult(q, bool(np.linalg.norm(err) < tol), max_iter, err)

    def _residual(self, target: pin.SE3, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """log6 error (flange frame) from the pose at q to the target, and its Jacobian in q."""
        flange_M_target = self._world_M_flange(q).actInv(target)
        err = pin.log6(flange_M_target).vector
        J_local = pin.computeFrameJacobian(self._model, self._data, q, self._flange_id,
                                           pin.LOCAL)
        return err, -pin.Jlog6(flange_M_target.inverse()) @ J_local

    def _check_reach(self, target: pin.SE3) -> None:
        dist = float(np.linalg.norm(target.translation - self._reach.center))
        if dist > self._reach.radius:
            raise IKError(f"target flange is {dist:.2f} m from the {self.name}'s first joint, "
                          f"beyond its reach bound of {self._reach.radius:.2f} m",
                          reason=UNREACHABLE)

    def _failure(self, result: _IKResult) -> IKError:
        pos, rot = np.linalg.norm(result.error[:3]), np.linalg.norm(result.error[3:])
        sigma = self.sigma_min(result.q)
        left = f"{pos * 1000:.2f} mm / {np.degrees(rot):.3f} deg left after {result.iterations} " \
               "iterations"
        log.debug("IK failed at q=%s: %s, sigma_min %.2e", np.round(result.q, 4), left, sigma)
        if sigma < SINGULAR_SIGMA:
            return IKError(f"IK stuck at a singular configuration (sigma_min {sigma:.1e}); "
                           f"{left}", reason=SINGULAR)
        return IKError(f"IK did not converge: {left}", reason=NO_CONVERGENCE)

    # ---- helpers ------------------------------------------------------------------------
    def _world_M_flange(self, q: np.ndarray) -> pin.SE3:
        pin.framesForwardKinematics(self._model, self._data, q)
        return self._data.oMf[self._flange_id]

    def _require_mount(self) -> CameraMount:
        if self.mount is None:
            raise ConfigError(f"robot model {self.name} has no camera mount; "
                              "load it with ArmModel.load(..., mount=NAME_OR_FILE)")
        return self.mount

    def _as_q(self, q: ArrayLike, what: str = "q") -> np.ndarray:
        arr = np.asarray(q, dtype=float)
        if arr.shape != (self._model.nq,):
            raise ConfigError(f"{what} must be {self._model.nq} joint angles (rad), "
                              f"got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ConfigError(f"{what} has non-finite joint angles: {arr.tolist()}")
        return arr.copy()

    # ---- models built from a DH table (e.g. the controller's calibrated one) ----------------
    # The DHTable a model was built from by from_dh; None for a model loaded from a URDF.
    dh = None

    @classmethod
    def from_dh(cls, table, mount: CameraMount | str | Path | None = None) -> ArmModel:
        """A model whose FK is ``table``'s DH FK (an ``armstereo.robot.dh.DHTable``, typically
        the controller's calibrated table), with the joint limits of ``table.model``'s URDF.

        ``urdf_path`` is None and ``urdf_sha256`` holds ``table.sha256`` (what identifies these
        kinematics); ``dh`` is the table. ``mount`` as in :meth:`load`. Raises ConfigError for a
        table of an unknown model or a bad mount.
        """
        from armstereo.robot.pinocchio_dh import build_model

        if mount is not None and not isinstance(mount, CameraMount):
            mount = CameraMount.load(mount)
        self = cls.__new__(cls)
        self.name, self.urdf_path, self.urdf_sha256 = table.model, None, table.sha256
        self.mount, self.dh = mount, table
        self._setup_from_model(build_model(table))
        return self

    def _setup_from_model(self, model: pin.Model) -> None:
        """Everything derived from the Pinocchio model: workspace, frames, limits, reach."""
        self._model = model
        self._data = self._model.createData()
        self._flange_id = self._model.getFrameId(FLANGE_FRAME)
        base_id = self._model.getFrameId(BASE_FRAME)
        pin.framesForwardKinematics(self._model, self._data, pin.neutral(self._model))
        self._world_M_base = self._data.oMf[base_id].copy()  # fixed: base hangs off the root
        self._base_M_world = self._world_M_base.inverse()
        R = self._base_M_world.rotation
        self._twist_base_world = np.block([[R, np.zeros((3, 3))], [np.zeros((3, 3)), R]])
        self.joint_names = tuple(self._model.names[1:])
        self.lower = _frozen(self._model.lowerPositionLimit)
        self.upper = _frozen(self._model.upperPositionLimit)
        self.velocity_limits = _frozen(self._model.velocityLimit)
        self._reach = _reach_bound(self._model, self._flange_id)


class _Reach(NamedTuple):
    center: np.ndarray  # shoulder point in the URDF root frame (m)
    radius: float  # no flange position is farther than this from ``center`` (m)


def _reach_bound(model: pin.Model, flange_id: int) -> _Reach:
    """A sure upper bound on the flange's distance from the shoulder: the sum of the offsets."""
    placements = [model.jointPlacements[j].translation for j in range(2, model.njoints)]
    placements.append(model.frames[flange_id].placement.translation)
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    center = data.oMi[1].translation.copy()
    return _Reach(center, float(sum(np.linalg.norm(t) for t in placements)))


def _nearest_turn(q: np.ndarray, seed: np.ndarray) -> np.ndarray:
    """Shift each joint by whole turns to the equivalent angle nearest the seed (|q - seed| <= pi).

    Never looks further for a turn that would fit the limits: that would be a full extra turn of
    the joint (and of the camera cable), so such a solution is refused instead.
    """
    return q - 2 * np.pi * np.round((q - seed) / (2 * np.pi))


@functools.lru_cache(maxsize=16)
def _build_model(path: str, sha256: str) -> pin.Model:
    """Pinocchio model of a URDF, built once per file content (sha256 is the cache key)."""
    try:
        model = pin.buildModelFromUrdf(path)
    except (RuntimeError, ValueError) as err:
        raise ConfigError(f"cannot load URDF {path}: {str(err).splitlines()[0]}") from None
    missing = [f for f in (BASE_FRAME, FLANGE_FRAME) if not model.existFrame(f)]
    if not missing and model.frames[model.getFrameId(BASE_FRAME)].parentJoint != 0:
        raise ConfigError(f"URDF {path}: frame {BASE_FRAME!r} must be fixed to the root link")
    if missing or model.nq != 6 or model.nv != 6:
        raise ConfigError(f"URDF {path} is not a 6-joint arm with frames {BASE_FRAME!r} and "
                          f"{FLANGE_FRAME!r} (nq={model.nq}, missing frames: {missing})")
    return model


def _resolve_urdf(name_or_path: str | Path) -> tuple[str, Path]:
    key = str(name_or_path).lower()
    if key in MODEL_NAMES:
        return key, MODELS_DIR / f"{key}.urdf"
    path = Path(name_or_path)
    if path.suffix == ".urdf" and path.is_file():
        return path.stem, path
    raise ConfigError(f"unknown robot model {str(name_or_path)!r}; known models: "
                      f"{', '.join(MODEL_NAMES)} (or the path of a .urdf file)")


def _as_pose(T, what: str) -> np.ndarray:
    """Validate a 4x4 rigid transform and snap its rotation exactly onto SO(3) (Pinocchio's
    log map expects a clean rotation)."""
    T = as_rigid(T, what)
    T[:3, :3] = nearest_rotation(T[:3, :3])
    return T


def _as_margin(margin: float) -> float:
    m = float(margin)
    if not np.isfinite(m) or m < 0:
        raise ConfigError(f"joint limit margin must be >= 0 rad, got {margin}")
    return m


def _frozen(a: np.ndarray) -> np.ndarray:
    out = np.array(a, dtype=float)
    out.setflags(write=False)
    return out
