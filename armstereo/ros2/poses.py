"""Where the camera was at any time of a bag: from its TF tree, or from joint states and a
kinematic model. Poses are 4x4 in ``base`` (metres); times integer nanoseconds."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from armstereo.errors import ConfigError, RecordingError
from armstereo.kinematics import ArmModel
from armstereo.ros2.tf_buffer import TfBuffer


class JointSeries:
    """Arm joint positions over time (rad, in ``names``' order) from JointState messages.

    A message's names match the arm's exactly or as ``<prefix><name>`` (the UR driver's
    ``tf_prefix``); messages without all six (a gripper's) are not the arm's and are skipped.
    Between two messages positions are interpolated linearly; outside them they are unknown.
    """

    def __init__(self, names: Sequence[str]) -> None:
        self.names = tuple(names)
        self._t: list[int] = []
        self._q: list[np.ndarray] = []
        self._order: dict[tuple[str, ...], list[int] | None] = {}
        self.t = np.zeros(0, np.int64)
        self.q = np.zeros((0, len(self.names)))

    def add(self, names: Sequence[str], positions: np.ndarray, stamp_ns: int) -> bool:
        """Add one message; False if it is not the arm's or its positions are unusable."""
        key = tuple(str(n) for n in names)
        if key not in self._order:
            self._order[key] = _match(self.names, key)
        order = self._order[key]
        pos = np.asarray(positions, dtype=float).reshape(-1)
        if order is None or len(pos) != len(key) or not np.all(np.isfinite(pos[order])):
            return False
        self._t.append(int(stamp_ns))
        self._q.append(pos[order])
        return True

    def finish(self, topic: str) -> None:
        t = np.asarray(self._t, dtype=np.int64)
        back = np.flatnonzero(np.diff(t) < 0)
        if back.size:
            k = int(back[0])
            raise RecordingError(f"{topic}: the stamps go back in time at message {k + 1} "
                                 f"({t[k + 1]} ns after {t[k]} ns); the bag's time stamps are "
                                 "out of order")
        keep = np.ones(len(t), bool)
        keep[1:] = np.diff(t) > 0
        self.t = t[keep]
        self.q = np.asarray(self._q, dtype=float).reshape(-1, len(self.names))[keep]

    def __len__(self) -> int:
        return len(self.t)

    def at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q (N, 6), valid (N,)) at ``times``."""
        times = np.asarray(times, dtype=np.int64).reshape(-1)
        if not len(self.t):
            return np.zeros((len(times), len(self.names))), np.zeros(len(times), bool)
        valid = (times >= self.t[0]) & (times <= self.t[-1])
        x = (times - self.t[0]).astype(float)
        xp = (self.t - self.t[0]).astype(float)
        q = np.stack([np.interp(x, xp, self.q[:, j]) for j in range(len(self.names))], axis=1)
        return q, valid


def _match(wanted: Sequence[str], names: Sequence[str]) -> list[int] | None:
    out = []
    for w in wanted:
        if w in names:
            out.append(names.index(w))
            continue
        hits = [k for k, n in enumerate(names) if n.endswith(w)]
        if len(hits) != 1:
            return None
        out.append(hits[0])
    return out


class TfPoses:
    """Camera poses from the TF tree: ``T_base_flange`` and ``T_flange_camera`` looked up
    between the given frames."""

    name = "tf"

    def __init__(self, tf: TfBuffer, base: str, flange: str, camera: str) -> None:
        for a, b in ((base, flange), (flange, camera)):
            problem = tf.chain_problem(a, b)
            if problem:
                raise RecordingError(problem)
        self.tf, self.base, self.flange, self.camera = tf, base, flange, camera

    def at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        T_bf, ok1 = self.tf.lookup(self.base, self.flange, times)
        T_fc, ok2 = self.tf.lookup(self.flange, self.camera, times)
        return T_bf, T_fc, ok1 & ok2


class JointPoses:
    """Camera poses from joint states: ``T_base_flange`` = the model's forward kinematics,
    ``T_flange_camera`` fixed (the mount, or TF's flange -> camera)."""

    name = "joints"

    def __init__(self, joints: JointSeries, model: ArmModel, T_flange_camera: np.ndarray) -> None:
        if not len(joints):
            raise ConfigError("the bag has no joint states of the arm (six joints named as "
                              f"{', '.join(model.joint_names)})")
        self.joints, self.model = joints, model
        self.T_flange_camera = np.asarray(T_flange_camera, dtype=float)

    def at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        q, valid = self.joints.at(times)
        T_bf = np.stack([self.model.flange_pose(qk) for qk in q]) if len(q) \
            else np.zeros((0, 4, 4))
        return T_bf, np.broadcast_to(self.T_flange_camera, T_bf.shape).copy(), valid
