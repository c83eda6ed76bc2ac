"""Command-line flags of the arm and camera backends, generated from their config dataclasses.

Every backend flag is declared once, on its config field (:func:`armstereo.flags.option`).
Flags are parsed with no default, so we know which ones the user gave; a flag given for a
backend that is not selected is an error ("--exposure applies to --camera opencv only"),
never silently ignored.
"""

from __future__ import annotations

import argparse
from dataclasses import MISSING, dataclass
from typing import Any

from armstereo import backends
from armstereo.errors import ConfigError
from armstereo.robot.arm_model import MODEL_NAMES

_DEST = "backend_flag:"  # argparse dest prefix of generated flags


@dataclass(frozen=True)
class BackendChoice:
    """The arm and camera a command will build, with their validated configs."""

    arm: str
    arm_config: Any
    camera: str
    camera_config: Any


def add_backend_flags(p: argparse.ArgumentParser, *, arms: tuple[str, ...] = backends.ARM_NAMES,
                      defaults: dict[str, Any] | None = None) -> None:
    """Add --arm, --camera, --robot, --mount and every backend's own flags to ``p``.

    ``defaults`` overrides a config field's default for this command (by field name); the help
    text shows the default that applies.
    """
    defaults = defaults or {}
    p.add_argument("--arm", choices=arms, default="mock", help="arm backend (default mock)")
    p.add_argument("--camera", default="mock", help="mock or opencv:<index-or-path>")
    p.add_argument("--robot", default="ur5e",
                   help=f"arm model: {', '.join(MODEL_NAMES)}, a URDF file or a model file "
                   "saved by robot-info --save")
    p.add_argument("--mount", default=None, help="camera mount file (default: bundled mount)")
    seen: set[str] = set()
    for backend in _backends(arms):
        group = p.add_argument_group(f"{backend.name} {backend.kind}: {backend.description}")
        for f in backends.flag_fields(backend):
            flag = f.metadata["flag"]
            if flag in seen:
                continue
            seen.add(flag)
            default = defaults.get(f.name, f.default)
            shown = "" if default in (None, (), False, MISSING) else f" (default {default})"
            kwargs = dict(f.metadata["argparse"])
            if kwargs.get("action") not in ("store_true", "store_false"):
                kwargs.setdefault("metavar", flag.lstrip("-").replace("-", "_").upper())
            group.add_argument(flag, dest=_DEST + flag, default=argparse.SUPPRESS,
                               help=f.metadata["help"] + shown, **kwargs)


def backend_choice(args: argparse.Namespace, *,
                   defaults: dict[str, Any] | None = None,
                   fixed: dict[str, dict[str, Any]] | None = None) -> BackendChoice:
    """Validated configs for ``args.arm`` and ``args.camera``.

    ``fixed`` adds values a command sets itself, per backend kind (``{"arm": {"layout":
    "horizontal"}}``). Raises ConfigError for a flag that no selected backend takes.
    """
    defaults, fixed = defaults or {}, fixed or {}
    arm = backends.arm_backend(args.arm)
    camera, _ = backends.camera_backend(args.camera)
    given = {k[len(_DEST):]: v for k, v in vars(args).items() if k.startswith(_DEST)}
    selected = (arm, camera)
    for flag in given:
        if not any(flag == f.metadata["flag"] for b in selected for f in backends.flag_fields(b)):
            raise ConfigError(f"{flag} applies to {_owners(flag)} only, not to --arm "
                              f"{args.arm} --camera {args.camera}")
    arm_config = backends.arm_config(args.arm, **_values(arm, given, defaults),
                                     **fixed.get("arm", {}))
    camera_config = backends.camera_config(args.camera, **_values(camera, given, defaults),
                                           **fixed.get("camera", {}))
    _check_faults(given.get("--inject-fault", ()), (arm_config, camera_config))
    return BackendChoice(args.arm, arm_config, args.camera, camera_config)


def _backends(arms: tuple[str, ...]) -> list[backends.Backend]:
    return [backends.ARMS[a] for a in arms] + list(backends.CAMERAS.values())


def _values(backend: backends.Backend, given: dict[str, Any],
            defaults: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for f in backends.flag_fields(backend):
        if f.metadata["flag"] in given:
            out[f.name] = given[f.metadata["flag"]]
        elif f.name in defaults:
            out[f.name] = defaults[f.name]
    return out


def _owners(flag: str) -> str:
    owners = [f"--{b.kind} {b.name}" for b in _backends(backends.ARM_NAMES)
              if any(f.metadata["flag"] == flag for f in backends.flag_fields(b))]
    return " or ".join(owners)


def _check_faults(specs, configs) -> None:
    """Every injected fault must have a selected backend that injects it (arm faults need the
    mock arm, camera faults the mock camera)."""
    for spec in specs:
        for item in str(spec).split(","):
            name = item.split("@")[0].strip()
            if not any(getattr(c, "injects", lambda _: False)(name) for c in configs):
                raise ConfigError(f"--inject-fault {item.strip()} needs a mock backend that "
                                  "injects it (arm faults: --arm mock; camera-timeout: "
                                  "--camera mock)")
