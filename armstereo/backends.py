"""The backend registry: arm and camera backends by name, each with its own config dataclass.

This is the one place in ``armstereo`` that reaches into ``drivers``, and only lazily, by name:
importing armstereo never imports a vendor SDK or a mock. Each backend lives in
``drivers/<name>/`` with a ``config.py`` holding a keyword-only dataclass that validates itself
(``MockArmConfig``, ``URArmConfig``, ``MockCameraConfig``, ``OpenCVCameraConfig``). The fields'
metadata (made with :func:`armstereo.flags.option`) are the backend's command-line flags, so a
backend's flags are written once, beside its driver.

Names used on the command line: arms ``mock`` and ``ur``; cameras ``mock`` and
``opencv:<index, path or pipeline>``.
"""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from armstereo.errors import ConfigError
from armstereo.flags import option  # noqa: F401  (re-exported: the name's old home)

if TYPE_CHECKING:
    import numpy as np

    from armstereo.devices import Arm, Camera
    from armstereo.robot.arm_model import ArmModel


@dataclass(frozen=True)
class Backend:
    """Where a backend lives: ``module`` holds the driver class and ``config_module`` its
    config dataclass (imported only when the backend is used)."""

    kind: str  # "arm" or "camera"
    name: str
    module: str
    driver: str
    config_module: str
    config: str
    description: str


ARMS: dict[str, Backend] = {
    "mock": Backend("arm", "mock", "drivers.mock.arm", "MockArm", "drivers.mock.config",
                    "MockArmConfig", "simulated UR arm (the default; no hardware)"),
    "ur": Backend("arm", "ur", "drivers.ur.arm", "URArm", "drivers.ur.config", "URArmConfig",
                  "Universal Robots arm through ur_rtde"),
}
CAMERAS: dict[str, Backend] = {
    "mock": Backend("camera", "mock", "drivers.mock.camera", "MockCamera", "drivers.mock.config",
                    "MockCameraConfig", "ray-cast camera on the mock scene (the default)"),
    "opencv": Backend("camera", "opencv", "drivers.opencv.camera", "OpenCVCamera",
                      "drivers.opencv.config", "OpenCVCameraConfig",
                      "USB or GStreamer camera through OpenCV (opencv:<index, path or pipeline>)"),
}
ARM_NAMES = tuple(ARMS)


def arm_backend(name: str) -> Backend:
    """The arm backend called ``name``, or ConfigError listing the known ones."""
    if name not in ARMS:
        raise ConfigError(f"unknown arm {name!r}; choose one of: {', '.join(ARMS)}")
    return ARMS[name]


def camera_backend(spec: str) -> tuple[Backend, str]:
    """(backend, device) for a camera spec ``mock`` or ``opencv:<device>``."""
    name, _, device = spec.partition(":")
    if name not in CAMERAS or (name == "opencv") != bool(device.strip()):
        raise ConfigError(f"unknown camera {spec!r}; use 'mock' or 'opencv:<index or path>'")
    return CAMERAS[name], device.strip()


def config_class(backend: Backend) -> type:
    """The backend's config dataclass (imports its ``config`` module, never its driver)."""
    return getattr(importlib.import_module(backend.config_module), backend.config)


def flag_fields(backend: Backend) -> list[dataclasses.Field]:
    """The config fields of ``backend`` that are command-line flags."""
    return [f for f in dataclasses.fields(config_class(backend)) if "flag" in f.metadata]


def build_arm(name: str, config: Any, model: ArmModel) -> Arm:
    """An unconnected arm of backend ``name`` built from its config (the caller connects it,
    best with ``with``)."""
    backend = arm_backend(name)
    _check_config(backend, config)
    return getattr(importlib.import_module(backend.module), backend.driver).from_config(
        config, model)


def build_camera(spec: str, config: Any, model: ArmModel, arm: Arm) -> Camera:
    """An unconnected camera for ``spec`` built from its config. Cameras share the arm's clock;
    the mock camera renders from the arm's actual joints through ``model``."""
    backend, _ = camera_backend(spec)
    _check_config(backend, config)
    return getattr(importlib.import_module(backend.module), backend.driver).from_config(
        config, model, arm)


def _check_config(backend: Backend, config: Any) -> None:
    cls = config_class(backend)
    if not isinstance(config, cls):
        raise ConfigError(f"the {backend.name} {backend.kind} needs a {cls.__name__}, got "
                          f"{type(config).__name__}")


# -- the mock world ---------------------------------------------------------------------------
# Applications that run on the mock (demo, sweep) need its scenes and the arm poses those scenes
# are laid out for; they get them here, so they too never import ``drivers``.


def mock_start_joints(model: ArmModel, layout: str = "table") -> np.ndarray:
    """Joints at which the mock scene ``layout`` (``table``: camera looking down at the table,
    ``horizontal``: camera looking across it) is in view; ConfigError if the arm cannot."""
    return importlib.import_module("drivers.mock.start_poses").start_joints(model, layout)


def mock_table_scene(seed: int = 0):
    """The demo's table scene (a ``drivers.mock.scene.Scene``) with textures from ``seed``."""
    return importlib.import_module("drivers.mock.scene").default_table_scene(seed)


def mock_target_scene(distances, T_base_camera, intrinsics, *, max_baseline: float,
                      seed: int = 0):
    """Planar targets at ``distances`` in front of the camera at ``T_base_camera`` (base
    frame), each staying in view for baselines up to ``max_baseline`` along camera x; returns
    a ``drivers.mock.scene.TargetScene`` (scene + targets with their pixel boxes)."""
    scene = importlib.import_module("drivers.mock.scene")
    return scene.planar_target_scene(distances, T_base_camera, intrinsics,
                                     max_baseline=max_baseline, seed=seed)


def mock_profile_names() -> tuple[str, ...]:
    """The mock backends' named error profiles (``--mock-profile``), ``ideal`` first."""
    return importlib.import_module("drivers.mock.profile").PROFILE_NAMES


def arm_config(name: str, **values: Any) -> Any:
    """A config for arm backend ``name`` from keyword values (validated by the dataclass)."""
    return _make_config(arm_backend(name), values)


def camera_config(spec: str, **values: Any) -> Any:
    """A config for camera ``spec``; an ``opencv:<device>`` spec fills in the device."""
    backend, device = camera_backend(spec)
    if device:
        values = {**values, "device": device}
    return _make_config(backend, values)


def _make_config(backend: Backend, values: dict[str, Any]) -> Any:
    cls = config_class(backend)
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise ConfigError(f"the {backend.name} {backend.kind} has no option "
                          f"{', '.join(unknown)} (it has: {', '.join(sorted(known))})")
    return cls(**values)


# -- what a UR controller knows about itself ---------------------------------------------------


def read_ur_kinematics(host: str, model: str | None = None, **kwargs: Any):
    """The controller's calibrated DH table from its read-only primary interface, or the
    nominal table with warnings (``drivers.ur.primary.ArmKinematics``); see
    :func:`drivers.ur.primary.read_arm_kinematics` for ``port`` and ``timeout``."""
    primary = importlib.import_module("drivers.ur.primary")
    return primary.read_arm_kinematics(host, model, **kwargs)


# -- optional extras: ecosystem bridges installed with ``pip install armstereo[name]`` ------------


@dataclass(frozen=True)
class Extra:
    """An optional extra: the pip extra's name, the modules it brings and what needs them."""

    name: str
    modules: tuple[str, ...]
    purpose: str


EXTRAS: dict[str, Extra] = {
    "ros2": Extra("ros2", ("rosbags",), "ROS 2 bags (armstereo export --to ros2, "
                  "armstereo import)"),
}


def require_extra(name: str) -> None:
    """Import the modules of extra ``name``, or raise ConfigError in one line saying how to
    install it (``pip install 'armstereo[name]'``)."""
    extra = EXTRAS[name]
    for module in extra.modules:
        try:
            importlib.import_module(module)
        except ImportError as err:
            raise ConfigError(f"{extra.purpose} need(s) the optional '{name}' extra "
                              f"({module} is not installed): pip install 'armstereo[{name}]'"
                              ) from err
