"""Readings of a UR controller's receive interface for :class:`drivers.ur.arm.URArm`: joints and
TCP pose from one RTDE package, the safety state, and the wait for fresh packages (the state
right after a move can be one period stale). A part of ``URArm``, kept beside it."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from armstereo.errors import ArmstereoError, ConnectionLost, HardwareError, NotConnected
from drivers.ur.safety import ControllerState

FRESH_POLL_S = 0.001        # polling period while waiting for new RTDE packages
FRESH_PACKAGES = 2          # packages that must arrive after a call before its reading


class Sample(NamedTuple):
    """One consistent RTDE reading: controller time (s), joints (rad), TCP pose (UR 6-vector)."""

    controller_time: float
    q: np.ndarray
    tcp_pose: np.ndarray


class Readings:
    """Receive-interface readings of :class:`~drivers.ur.arm.URArm` (see the module doc)."""

    def _rr_get(self, getter: str):
        """A receive-interface getter; ur_rtde's errors become HardwareError."""
        if self._rr is None:
            raise NotConnected(f"{self.name}: not connected; call connect() first")
        try:
            return getattr(self._rr, getter)()
        except ArmstereoError:
            raise
        except Exception as err:
            raise HardwareError(f"UR controller at {self.host}: {getter} failed: "
                                f"{one_line(err)}") from err

    def _read_state(self) -> ControllerState:
        return ControllerState(int(self._rr_get("getSafetyStatusBits")),
                               int(self._rr_get("getSafetyMode")),
                               int(self._rr_get("getRobotMode")),
                               int(self._rr_get("getRuntimeState")))

    def _read_sample(self) -> Sample:
        """Latest joints and TCP pose with the timestamp of the package they came from."""
        for _ in range(3):  # re-read if a new package landed between the getters
            t0 = self._rr_get("getTimestamp")
            q = self._rr_get("getActualQ")
            pose = self._rr_get("getActualTCPPose")
            t1 = self._rr_get("getTimestamp")
            if t0 == t1:
                break
        q, pose = np.asarray(q, dtype=float), np.asarray(pose, dtype=float)
        if q.shape != (6,) or pose.shape != (6,) or not np.all(np.isfinite(np.r_[q, pose])):
            raise HardwareError(f"UR controller at {self.host} sent invalid state: q={q.tolist()}, "
                                f"TCP pose={pose.tolist()}")
        return Sample(float(t1), q, pose)

    def _fresh_sample(self) -> Sample:
        self._wait_fresh()
        return self._read_sample()

    def _wait_fresh(self, packages: int = FRESH_PACKAGES) -> None:
        """Block until ``packages`` new RTDE packages arrived after this call began."""
        watch = DataWatch(self)
        while watch.changes < packages:
            self.clock.sleep(FRESH_POLL_S)
            if not self._rr_get("isConnected"):
                raise ConnectionLost(f"lost the RTDE connection to UR controller at {self.host}")
            watch.check()


class DataWatch:
    """Counts new RTDE packages (timestamp changes); ConnectionLost when none came for the
    arm's ``data_timeout`` (ur_rtde itself notices only after 2.5 s, and only on EOF or silence
    of its own thread)."""

    def __init__(self, arm: Readings):
        self.arm = arm
        self.last = arm._rr_get("getTimestamp")
        self.since = arm.clock.now()
        self.changes = 0

    def check(self) -> None:
        t, now = self.arm._rr_get("getTimestamp"), self.arm.clock.now()
        if t != self.last:
            self.last, self.since, self.changes = t, now, self.changes + 1
        elif now - self.since > self.arm.data_timeout:
            raise ConnectionLost(f"no new RTDE data from UR controller at {self.arm.host} for "
                                 f"{self.arm.data_timeout:g} s (link lost?)")


def one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__
