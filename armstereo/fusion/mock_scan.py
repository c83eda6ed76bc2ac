"""Record a planned multi-view scan on the mock arm and mock camera (tests, benchmarks, demo).

The mock backends come from the backend registry, so this module never imports a driver. For
each kept viewpoint of a :class:`~armstereo.capture.scan_plan.ScanPlan`, in tour order: a joint
move to the left view's joints, grab, then a straight camera move by the baseline to the right
view, grab, and a pair event. Poses are forward kinematics of the arm's actual joints, as in
capture. The recording's metadata carries the scene's exact geometry under ``scene_truth``
(JSON of :class:`~armstereo.evaluation.scene_truth.SceneTruth`) and each pair's viewpoint under
``scan_viewpoints`` (JSON list), so ``fuse`` can score the model.

This is a simulation helper, not the ``scan`` command: it builds its own mock arm and camera
and runs no pre-flight beyond what the plan checked.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from armstereo import backends
from armstereo.capture.run import model_metadata
from armstereo.capture.scan_plan import ScanPlan
from armstereo.errors import ConfigError
from armstereo.kinematics import ArmModel
from armstereo.recording import RecordingWriter

log = logging.getLogger(__name__)

METADATA_SCENE_TRUTH = "scene_truth"
METADATA_VIEWPOINTS = "scan_viewpoints"
JOINT_SPEED = 0.5  # rad/s: simulated time only
JOINT_ACCELERATION = 1.0
LINEAR_SPEED = 0.05  # m/s
LINEAR_ACCELERATION = 0.25
SETTLE_S = 0.2


@dataclass(frozen=True)
class MockScanResult:
    """What :func:`record_mock_scan` wrote: the file, pair count and the scene's truth JSON."""

    path: Path
    pairs: int
    scene_truth_json: str


def record_mock_scan(out: str | Path, plan: ScanPlan, model: ArmModel, *,
                     camera_noise: float = 0.0, joint_noise: float = 0.0, seed: int = 0,
                     scene=None, progress: Callable[[str], None] | None = None
                     ) -> MockScanResult:
    """Shoot every viewpoint of ``plan`` with the mock backends into the recording ``out``.

    ``scene`` is a mock scene (default: the mock camera's table scene); ``camera_noise`` is
    the sensor noise in grey levels, ``joint_noise`` the arm's repeatability in rad.
    Raises ConfigError for an empty plan.
    """
    if not plan.views:
        raise ConfigError("the scan plan keeps no viewpoint: nothing to record")
    out = Path(out)
    arm_config = backends.arm_config("mock", joint_noise=joint_noise, seed=seed,
                                     q0=tuple(plan.q_start))
    camera_config = backends.camera_config("mock", noise=camera_noise, seed=seed, scene=scene)
    with backends.build_arm("mock", arm_config, model) as arm:
        camera = backends.build_camera("mock", camera_config, model, arm)
        truth = camera.recording_metadata()["scene_truth"]
        with camera, RecordingWriter(out, metadata=_metadata(model, plan, truth, camera_noise,
                                                             joint_noise)) as writer:
            writer.write_calibration(camera.intrinsics, arm.clock.now_ns())
            for k, view in enumerate(plan.views):
                if progress is not None:
                    progress(f"viewpoint {view.index} ({k + 1}/{len(plan.views)})")
                arm.move_joints(view.q_left, JOINT_SPEED, JOINT_ACCELERATION)
                left = _shoot(arm, camera, model, writer, 2 * k)
                arm.move_linear(model.flange_pose_for_camera(view.T_base_right), LINEAR_SPEED,
                                LINEAR_ACCELERATION)
                right = _shoot(arm, camera, model, writer, 2 * k + 1)
                writer.write_pair(k, 2 * k, 2 * k + 1, plan.baseline,
                                  float(np.linalg.norm(right - left)), "x")
            arm.move_joints(plan.q_start, JOINT_SPEED, JOINT_ACCELERATION)
    return MockScanResult(out, len(plan.views), truth)


def _shoot(arm, camera, model: ArmModel, writer: RecordingWriter, view: int) -> np.ndarray:
    """Settle, grab and record one view; returns the camera position (base, m)."""
    arm.wait_until_steady()
    arm.clock.sleep(SETTLE_S)
    frame = camera.grab()
    q = arm.joint_positions()
    T_base_flange = model.flange_pose(q)
    writer.write_view(view, frame, q, model.joint_names, T_base_flange,
                      model.mount.T_flange_camera, settle_s=SETTLE_S)
    return (T_base_flange @ model.mount.T_flange_camera)[:3, 3]


def _metadata(model: ArmModel, plan: ScanPlan, truth_json: str, camera_noise: float,
              joint_noise: float) -> dict[str, str]:
    viewpoints = [{"pair": k, "viewpoint": v.index, "azimuth_deg": round(v.azimuth_deg, 6),
                   "elevation_deg": round(v.elevation_deg, 6), "roll_deg": v.roll_deg}
                  for k, v in enumerate(plan.views)]
    return {**model_metadata(model), "arm": "mock", "camera": "mock", "kind": "scan",
            "source": "armstereo.fusion.mock_scan", "views": str(plan.layout),
            "target_m": ",".join(f"{v:.6g}" for v in plan.target),
            "radius_m": repr(plan.radius), "elevation_deg": repr(plan.elevation_deg),
            "baseline_m": repr(plan.baseline), "pairs": str(len(plan.views)),
            "camera_noise": repr(camera_noise), "joint_noise_rad": repr(joint_noise),
            METADATA_SCENE_TRUTH: truth_json, METADATA_VIEWPOINTS: json.dumps(viewpoints)}
