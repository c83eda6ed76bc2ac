"""The arm model's old home, kept for scripts that import it from here: everything about a UR
arm's kinematics now lives in :mod:`armstereo.robot` (the model with FK and IK in
:mod:`armstereo.robot.arm_model`). Names only: nothing is defined here."""

from armstereo.robot.arm_model import (
    BASE_FRAME,
    FLANGE_FRAME,
    JOINT_LIMITS,
    JOINT_NAMES,
    MAX_STEP_RAD,
    MODEL_NAMES,
    MODELS_DIR,
    NO_CONVERGENCE,
    SINGULAR,
    SINGULAR_SIGMA,
    UNREACHABLE,
    ArmModel,
    ready_configuration,
)

__all__ = [
    "BASE_FRAME", "FLANGE_FRAME", "JOINT_LIMITS", "JOINT_NAMES", "MAX_STEP_RAD", "MODELS_DIR",
    "MODEL_NAMES", "NO_CONVERGENCE", "SINGULAR", "SINGULAR_SIGMA", "UNREACHABLE", "ArmModel",
    "ready_configuration",
]
