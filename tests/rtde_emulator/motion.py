"""Trajectories of the emulated arm: a 1-D speed profile along a joint or Cartesian path.

moveJ interpolates the joints linearly (the leading joint follows the trapezoid, rad); moveL
interpolates the TCP pose linearly in position and by the shortest rotation (the position
follows the trapezoid, m; a pure rotation uses its angle) with inverse kinematics every
``LINEAR_STEP_M`` along the path and linear joint interpolation in between. Stops are a constant
deceleration along the same path, as stopL/stopJ do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from armstereo.robot.arm_model import ArmModel
from armstereo.transforms import invert, matrix_to_rotvec, rotvec_to_matrix

LINEAR_STEP_M = 0.001  # IK sample spacing along a moveL path (error in between: micrometres)


@dataclass(frozen=True)
class _Segment:
    """Constant acceleration ``a`` from time ``t0`` (position s0, speed v0) to ``t1``."""

    t0: float
    s0: float
    v0: float
    a: float
    t1: float

    def at(self, t: float) -> tuple[float, float]:
        tau = min(max(t - self.t0, 0.0), self.t1 - self.t0)
        return self.s0 + self.v0 * tau + 0.5 * self.a * tau * tau, self.v0 + self.a * tau


class Profile:
    """Path position s(t) >= 0 and speed, rest to rest, ending exactly at ``end``."""

    def __init__(self, segments: list[_Segment], end: float):
        self.segments = segments
        self.end = end
        self.duration = segments[-1].t1 if segments else 0.0

    @classmethod
    def trapezoid(cls, length: float, speed: float, acceleration: float) -> Profile:
        """Accelerate, cruise at ``speed``, decelerate (triangular if too short to cruise)."""
        if length <= 0.0:
            return cls([], 0.0)
        v = min(speed, math.sqrt(length * acceleration))
        t_acc = v / acceleration
        t_cruise = (length - v * t_acc) / v
        t1, t2 = t_acc, t_acc + t_cruise
        s1 = 0.5 * v * t_acc
        return cls([_Segment(0.0, 0.0, 0.0, acceleration, t1),
                    _Segment(t1, s1, v, 0.0, t2),
                    _Segment(t2, s1 + v * t_cruise, v, -acceleration, t2 + t_acc)], length)

    def at(self, t: float) -> tuple[float, float]:
        """(position, speed) at time ``t``; at rest at ``end`` after the last segment."""
        if not self.segments or t >= self.duration:
            return self.end, 0.0
        for seg in self.segments:
            if t <= seg.t1:
                s, v = seg.at(t)
                return min(s, self.end), v
        return self.end, 0.0

    def brake(self, t: float, deceleration: float) -> Profile:
        """From the state at ``t``, decelerate at ``deceleration`` to rest on the same path
        (``inf``: at rest at once)."""
        s, v = self.at(t)
        if v <= 0.0 or deceleration <= 0.0 or math.isinf(deceleration):
            return Profile([_Segment(t, s, 0.0, 0.0, t)], s)
        t_stop = v / deceleration
        end = min(self.end, s + 0.5 * v * t_stop)
        return Profile([_Segment(t, s, v, -deceleration, t + t_stop)], end)


class JointPath:
    """Straight line in joint space; length = travel of the leading joint (rad)."""

    def __init__(self, q_from: np.ndarray, q_to: np.ndarray):
        self.q_from = np.asarray(q_from, dtype=float)
        self.q_to = np.asarray(q_to, dtype=float)
        self.length = float(np.max(np.abs(self.q_to - self.q_from)))

    def joints(self, s: float) -> np.ndarray:
        if self.length <= 0.0:
            return self.q_to.copy()
        return self.q_from + (self.q_to - self.q_from) * min(s / self.length, 1.0)


class LinearPath:
    """Straight TCP line from the current pose to ``T_base_tcp_goal`` with TCP ``T_flange_tcp``.

    The goal is solved first (raises IKError if unreachable); the joints along the way come
    from IK samples warm-started one from the next.
    """

    def __init__(self, model: ArmModel, q_from: np.ndarray, T_flange_tcp: np.ndarray,
                 T_base_tcp_goal: np.ndarray):
        self.model = model
        self.T_tcp_flange = invert(T_flange_tcp)
        self.T0 = model.flange_pose(q_from) @ T_flange_tcp
        self.T1 = np.asarray(T_base_tcp_goal, dtype=float)
        self.dp = self.T1[:3, 3] - self.T0[:3, 3]
        self.rotvec = matrix_to_rotvec(self.T0[:3, :3].T @ self.T1[:3, :3])
        distance, angle = float(np.linalg.norm(self.dp)), float(np.linalg.norm(self.rotvec))
        self.length = distance if distance > 1e-7 else angle
        self.q_to = model.ik(self.T1 @ self.T_tcp_flange, q_from)
        self._s = [0.0]
        self._q = [np.asarray(q_from, dtype=float)]

    def pose(self, s: float) -> np.ndarray:
        """T_base_tcp at path position ``s``."""
        f = 1.0 if self.length <= 0.0 else min(s / self.length, 1.0)
        T = np.eye(4)
        T[:3, :3] = self.T0[:3, :3] @ rotvec_to_matrix(f * self.rotvec)
        T[:3, 3] = self.T0[:3, 3] + f * self.dp
        return T

    def joints(self, s: float) -> np.ndarray:
        if self.length <= 0.0:
            return self.q_to.copy()
        s = min(max(s, 0.0), self.length)
        while self._s[-1] < s:
            nxt = min(self._s[-1] + LINEAR_STEP_M, self.length)
            q = (self.model.ik(self.pose(nxt) @ self.T_tcp_flange, self._q[-1])
                 if nxt < self.length else self.q_to)
            self._s.append(nxt)
            self._q.append(q)
        k = int(np.searchsorted(self._s, s))
        if k == 0:
            return self._q[0].copy()
        s0, s1 = self._s[k - 1], self._s[k]
        f = (s - s0) / (s1 - s0) if s1 > s0 else 1.0
        return self._q[k - 1] + f * (self._q[k] - self._q[k - 1])


class Motion:
    """One move in progress: a path, its profile and the move's own clock ``tau`` (s), which
    runs at the speed-slider fraction."""

    def __init__(self, kind: str, path: JointPath | LinearPath, speed: float,
                 acceleration: float, *, asynchronous: bool, number: int):
        self.kind = kind
        self.path = path
        self.profile = Profile.trapezoid(path.length, speed, acceleration)
        self.asynchronous = asynchronous
        self.number = number  # 1-based count of moves since the emulator started
        self.tau = 0.0
        self.braking = False

    def advance(self, dt: float) -> np.ndarray:
        """Move on by ``dt`` seconds of motion time; the joints there."""
        self.tau += dt
        return self.path.joints(self.profile.at(self.tau)[0])

    @property
    def finished(self) -> bool:
        return self.tau >= self.profile.duration

    @property
    def fraction(self) -> float:
        """Share of the commanded path covered so far (0..1)."""
        length = self.path.length
        return 1.0 if length <= 0.0 else self.profile.at(self.tau)[0] / length

    def brake(self, deceleration: float) -> None:
        """Decelerate to rest along the path from now on."""
        self.profile = self.profile.brake(self.tau, deceleration)
        self.braking = True
