"""Mock camera: renders the synthetic scene from wherever the arm has put the camera.

It pairs with any arm backend: ``pose_source`` returns ``T_base_camera`` (camera_optical in the
controller's base frame), normally ``lambda: model.camera_pose(arm.joint_positions())``, i.e.
forward kinematics of the arm's *actual* joints at exposure. Each frame carries the exact
ground-truth z-depth (metres, float32, NaN = nothing hit).

With a mock profile (:mod:`drivers.mock.profile`) the camera differs from what it reports:
:attr:`MockCamera.intrinsics` are the mount file's (what the software believes), while frames
are rendered with ``true_intrinsics`` from the TRUE camera pose (the arm's physical flange and
the camera's true hand-eye transform), and the profile's image effects are applied. The ground
truth depth is the true depth of what each delivered pixel shows.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.clock import Clock, SimClock
from armstereo.devices import Arm, Camera, Frame
from armstereo.errors import CameraTimeout, ConfigError
from armstereo.photometric.vignetting import Vignetting
from drivers.mock.cell import cell_camera, true_intrinsics, true_mount
from drivers.mock.faults import FaultPlan
from drivers.mock.imaging import apply_effects, view_gains
from drivers.mock.profile import TAG_IMAGE, ImageEffects, MockProfile, rng_for
from drivers.mock.render import Scene
from drivers.mock.scene import default_table_scene

if TYPE_CHECKING:
    from armstereo.kinematics import ArmModel
    from drivers.mock.config import MockCameraConfig

log = logging.getLogger(__name__)

__all__ = ["DEFAULT_FRAME_PERIOD_S", "MockCamera", "true_intrinsics", "true_mount"]

DEFAULT_FRAME_PERIOD_S = 1 / 30  # a grab waits for the next exposure


class MockCamera(Camera):
    """A camera that ray-casts ``scene`` (default: :func:`default_table_scene`).

    ``noise_sigma`` adds seeded Gaussian sensor noise (grey levels, per channel) to each frame;
    ``faults`` may time out a given grab (``camera-timeout@N``). Each grab advances ``clock``
    by ``frame_period`` (the wait for the next exposure) and stamps the frame at its exposure.
    """

    def __init__(self, intrinsics: Intrinsics, pose_source: Callable[[], np.ndarray], *,
                 scene: Scene | None = None, clock: Clock | None = None,
                 noise_sigma: float = 0.0, seed: int = 0, faults: FaultPlan | None = None,
                 supersample: int = 2, frame_period: float = DEFAULT_FRAME_PERIOD_S,
                 name: str = "mock camera", true_intrinsics: Intrinsics | None = None,
                 effects: ImageEffects | None = None, truth: dict | None = None,
                 vignetting: Vignetting | None = None):
        if not isinstance(intrinsics, Intrinsics):
            raise ConfigError(f"{name}: intrinsics must be an Intrinsics, got "
                              f"{type(intrinsics).__name__}")
        if not callable(pose_source):
            raise ConfigError(f"{name}: pose_source must be a callable returning T_base_camera")
        if not (math.isfinite(noise_sigma) and noise_sigma >= 0):
            raise ConfigError(f"{name}: noise_sigma must be >= 0 grey levels, got {noise_sigma}")
        if not (math.isfinite(frame_period) and frame_period >= 0):
            raise ConfigError(f"{name}: frame_period must be >= 0 s, got {frame_period}")
        self._intrinsics = intrinsics
        self.true_intrinsics = intrinsics if true_intrinsics is None else true_intrinsics
        if self.true_intrinsics.size != intrinsics.size:
            raise ConfigError(f"{name}: true intrinsics are {self.true_intrinsics.size}, the "
                              f"reported ones {intrinsics.size}")
        self.effects = ImageEffects() if effects is None else effects
        self.vignetting = vignetting  # the lens's own fall-off (None: effects' default)
        self._truth = dict(truth or {})
        self._effects_rng = rng_for(seed, TAG_IMAGE)
        self._pose_source = pose_source
        self.scene = default_table_scene() if scene is None else scene
        self.clock = SimClock() if clock is None else clock
        self.noise_sigma = float(noise_sigma)
        self.faults = faults if faults is not None else FaultPlan()
        self.supersample = supersample
        self.frame_period = float(frame_period)
        self.name = name
        self.grabs = 0  # grabs attempted since construction (fault counter, 1-based)
        self._rng = np.random.default_rng(seed)
        self._connected = False
        self._last_depth: np.ndarray | None = None

    @classmethod
    def from_config(cls, config: MockCameraConfig, model: ArmModel, arm: Arm) -> MockCamera:
        """The registry's constructor, on the arm's clock. Renders from where the flange is:
        the mock arm's true flange pose, a real controller's reported one, or else forward
        kinematics of the arm's actual joints through ``model``; then through the camera's
        true hand-eye transform (the mount's, with the profile's error and
        ``config.hand_eye_offset``) and true intrinsics. With ``config.board`` the scene is
        the table cleared for that calibration board (:mod:`drivers.mock.board`). The true
        camera is the cell's (:func:`drivers.mock.cell.cell_camera`)."""
        profile: MockProfile = config.profile
        cell = cell_camera(profile, config.seed, model.mount, reference=config.truth_mount,
                           offset=config.hand_eye_offset)
        T_flange_true, true_intr = cell.mount.T_flange_camera, cell.mount.intrinsics
        flange = _flange_source(arm, model)
        scene = config.scene
        if scene is None:
            from drivers.mock.desk import scene_for

            scene = scene_for(profile.scene, config.seed)
        if config.board is not None:
            from drivers.mock.board import calibration_scene

            scene = calibration_scene(config.board, scene, config.seed, profile.board)
        return cls(model.mount.intrinsics, lambda: flange() @ T_flange_true, scene=scene,
                   clock=arm.clock, noise_sigma=config.noise, seed=config.seed,
                   faults=config.fault_plan, true_intrinsics=true_intr,
                   effects=profile.image,
                   truth=cell.truth(profile, config.seed, config.hand_eye_offset),
                   vignetting=cell.vignetting)

    def connect(self) -> None:
        """Open the (simulated) device; raises NotConnected if it is already open."""
        self._require_not_connected()
        self._connected = True

    def close(self) -> None:
        self._connected = False

    @property
    def intrinsics(self) -> Intrinsics:
        return self._intrinsics

    def recording_metadata(self) -> dict[str, str]:
        """The scene's exact geometry (``scene_truth``, JSON; see
        :mod:`armstereo.evaluation.scene_truth`), for scoring reconstructions; with a mock
        profile also ``mock_camera_truth`` (JSON: profile name, the TRUE ``T_flange_camera``,
        ``K`` and ``dist``, the hand-eye offset asked for, the vignetting, the cell), for
        error analysis, and ``mock_cell`` (which cell: ``realistic seed 0``)."""
        out = {"scene_truth": self.scene.truth().to_json()}
        if self._truth:
            import json

            out["mock_camera_truth"] = json.dumps(self._truth)
            if "cell" in self._truth:
                out["mock_cell"] = self._truth["cell"]
        return out

    @property
    def ground_truth_depth(self) -> np.ndarray | None:
        """z-depth (H, W) float32 metres of the last frame delivered, NaN = nothing hit."""
        return self._last_depth

    def grab(self, timeout: float = 2.0) -> Frame:
        """Render a frame from the current camera pose.

        Raises CameraTimeout (naming the camera) for an injected ``camera-timeout`` after
        waiting ``timeout`` seconds on the clock, NotConnected when not connected.
        """
        self._require_connected()
        if not (math.isfinite(timeout) and timeout > 0):
            raise ConfigError(f"{self.name}: grab timeout must be > 0 s, got {timeout}")
        self.grabs += 1
        fault = self.faults.grab_fault(self.grabs)
        if fault is not None and fault.name == "camera-timeout":
            log.info("%s: injecting %s", self.name, fault)
            self.clock.sleep(timeout)
            raise CameraTimeout(f"{self.name}: no frame within {timeout:g} s timeout "
                                f"(grab {self.grabs}, injected {fault.name})")
        self.clock.sleep(self.frame_period)
        stamp = self.clock.now_ns()
        image, depth = self.scene.render(self._pose_source(), self.true_intrinsics,
                                         supersample=self.supersample)
        gains = view_gains(self.effects, self._effects_rng) if self.effects.any else None
        image = apply_effects(image, self.effects, self._effects_rng, gains,
                              vignetting=self.vignetting)
        if self.noise_sigma > 0:
            noisy = image + self._rng.normal(0.0, self.noise_sigma, image.shape)
            image = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
        self._last_depth = depth
        return Frame(image=image, timestamp_ns=stamp, depth=depth,
                     settings=reported_settings(self.effects, gains), device_frame=self.grabs)


def reported_settings(effects: ImageEffects, gains: np.ndarray | None) -> dict | None:
    """What the simulated camera reports of a frame's exposure and white balance (None when
    its profile varies neither): ``gains`` (B, G, R) as a camera states them, an exposure
    relative to nominal (the green channel's gain) and ``balance_ratio`` [red, green, blue]
    normalised to green = 1, as GenICam cameras keep it."""
    if gains is None or (effects.exposure_rel <= 0 and effects.white_balance_rel <= 0):
        return None
    b, g, r = (float(x) for x in gains)
    return {"exposure": g, "balance_ratio": [r / g, 1.0, b / g]}


def _flange_source(arm: Arm, model: ArmModel) -> Callable[[], np.ndarray]:
    """Where the flange really is: the mock arm's physical pose, a controller's report, or
    (any other arm) forward kinematics of its actual joints through ``model``."""
    for method in ("true_flange_pose", "controller_flange_pose"):
        source = getattr(arm, method, None)
        if callable(source):
            return source
    return lambda: model.flange_pose(arm.joint_positions())
