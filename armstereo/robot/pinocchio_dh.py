"""A Pinocchio model of a UR arm built straight from a DH table (no URDF, no roll-pitch-yaw).

The model has the same shape as the bundled URDFs, so :class:`armstereo.robot.arm_model.ArmModel`
uses it unchanged: root ``base_link``, fixed frame ``base`` (``base_link`` turned 180 deg about
z), six revolute joints about their local z named as in the URDFs, and frame ``tool0`` = DH frame
6. FK from ``base`` to ``tool0`` equals :func:`armstereo.robot.dh.fk` of the table (to rounding).

Where the joint frames sit. A DH frame may lie far from the physical joint: a calibrated table
puts the frames of nearly parallel joints hundreds of metres away along their axes. A joint's
frame can slide freely along its own axis (a rotation about z commutes with a shift along z),
so each joint frame is slid to the point of its axis nearest that joint's nominal position,
and the next placement takes the shift back. FK is unchanged; the placements stay within
millimetres of the nominal ones, which keeps IK's reach bound meaningful and the numbers sane.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from armstereo.errors import ConfigError
from armstereo.robot.dh import N_JOINTS, DHTable, frames, nominal_table
from robot_models.generate_urdfs import JOINTS, LINKS, POSITION_LIMIT, SPECS

BASE_FRAME = "base"
FLANGE_FRAME = "tool0"
ROOT_LINK = "base_link"
_SPECS = {spec.name: spec for spec in SPECS}


def build_model(table: DHTable) -> pin.Model:
    """Pinocchio model of ``table``'s arm; joint limits, speeds and efforts are those of the
    table's UR model (as in its URDF). Raises ConfigError if the model is not a bundled one."""
    spec = _SPECS.get(table.model)
    if spec is None:
        raise ConfigError(f"no joint limits for robot {table.model!r}: a DH table needs a model "
                          f"name among {', '.join(_SPECS)}")
    placements, T_flange = joint_placements(table)
    model = pin.Model()
    model.name = table.model
    T_root_base = _rz(math.pi)
    base = model.addFrame(pin.Frame(BASE_FRAME, 0, 0, pin.SE3(T_root_base),
                                    pin.FrameType.OP_FRAME))
    parent, frame = 0, base
    for i in range(N_JOINTS):
        M = T_root_base @ placements[0] if i == 0 else placements[i]
        limit = POSITION_LIMIT[i]
        parent = model.addJoint(parent, pin.JointModelRZ(), pin.SE3(M), JOINTS[i],
                                np.array([float(spec.effort_nm[i])]),
                                np.array([math.radians(spec.speed_deg_s[i])]),
                                np.array([-limit]), np.array([limit]))
        joint_frame = model.addJointFrame(parent, frame)
        frame = model.addBodyFrame(LINKS[i + 1], parent, pin.SE3.Identity(), joint_frame)
    model.addFrame(pin.Frame(FLANGE_FRAME, parent, frame, pin.SE3(T_flange),
                             pin.FrameType.OP_FRAME))
    return model


def joint_placements(table: DHTable) -> tuple[list[np.ndarray], np.ndarray]:
    """Placement of each joint frame in its parent's (joint 1: in ``base``) and of ``tool0`` in
    joint 6's frame, as 4x4 arrays, with the joint frames slid along their axes to their
    nominal places (see the module docstring)."""
    slide = _slides(table)
    rows = table.rows()  # theta, a, d, alpha
    placements = [_rz(rows[0, 0])]  # joint 1: base z is its axis, no slide
    for k in range(1, N_JOINTS):
        _, a, d, alpha = rows[k - 1]
        placements.append(_tz(d - slide[k - 1]) @ _tx(a) @ _rx(alpha) @ _tz(slide[k])
                          @ _rz(rows[k, 0]))
    _, a, d, alpha = rows[N_JOINTS - 1]
    return placements, _tz(d - slide[N_JOINTS - 1]) @ _tx(a) @ _rx(alpha)


def _slides(table: DHTable) -> np.ndarray:
    """Shift (m) of joint k+1's frame along its axis (the z of DH frame k), k = 0..5, that
    brings it nearest to where the nominal model has it at q = 0 (0 for joint 1)."""
    F = frames(table, np.zeros(N_JOINTS))
    N = frames(nominal_table(table.model), np.zeros(N_JOINTS))
    slide = np.zeros(N_JOINTS)
    for k in range(1, N_JOINTS):
        slide[k] = float((N[k, :3, 3] - F[k, :3, 3]) @ F[k, :3, 2])
    return slide


def _rz(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def _rx(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    T = np.eye(4)
    T[1:3, 1:3] = [[c, -s], [s, c]]
    return T


def _tz(d: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = d
    return T


def _tx(a: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = a
    return T
