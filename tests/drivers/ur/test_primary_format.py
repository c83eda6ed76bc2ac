"""Decoding the primary interface (drivers.ur.primary_format) against byte streams a real UR
controller software sent (published in UR's client library tests; tests/data/ur_primary), and
against resized, unknown, truncated and malformed variants of them."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from armstereo.robot.dh import DHTable, fk, pose_difference
from armstereo.transforms import T_from_ur_pose
from drivers.ur.primary_format import (
    MAX_MESSAGE_BYTES,
    MessageSplitter,
    parse_robot_state,
    parse_version_message,
)
from tests.drivers.ur.primary_streams import (
    KINEMATICS_INFO,
    ROBOT_STATE,
    VERSION_MESSAGE,
    kinematics_payload,
    replaced,
    robot_state,
    subpackages,
)

# The values UR's test asserts for these bytes (tests/data/ur_primary/README.md).
PUBLISHED_A = (0, -0.425, -0.3922, 0, 0, 0)
PUBLISHED_D = (0.1625, 0, 0, 0.1333, 0.0997, 0.0996)
PUBLISHED_ALPHA = (1.570796327, 0, 0, 1.570796327, -1.570796327, 0)
WIRE_ORDER = [(0, 47), (1, 251), (4, 101), (5, 225), (9, 53), (3, 75), (2, 37), (6, 445),
              (7, 61), (8, 9), (10, 43), (11, 26), (12, 8)]


def body(message: bytes) -> bytes:
    return message[5:]


def test_captured_robot_state_gives_the_published_table():
    (kind, content), = MessageSplitter().feed(ROBOT_STATE)
    assert kind == 16 and len(content) == 1386 - 5
    state = parse_robot_state(content)
    assert state.valid and state.subpackages == WIRE_ORDER and state.notes == []
    k = state.kinematics
    assert k.checksums == (4294967295,) * 6
    assert k.theta == (0.0,) * 6
    assert k.a == PUBLISHED_A and k.d == PUBLISHED_D and k.alpha == PUBLISHED_ALPHA
    assert k.calibration_status == 0 and k.extra_bytes == 0


def test_captured_state_is_self_consistent():
    # DH FK of the message's own joints with its own table is its own TCP pose: checks the
    # decoder, the DH convention and the base frame at once.
    state = parse_robot_state(body(ROBOT_STATE))
    k = state.kinematics
    table = DHTable("ur5e", k.theta, k.a, k.d, k.alpha)
    np.testing.assert_allclose(state.joints, [-1.6007, -1.7271, -2.2030, -0.8080, 1.5951,
                                              -0.0310], atol=5e-5)
    np.testing.assert_array_equal(state.tcp_offset, np.zeros(6))
    lin, ang = pose_difference(fk(table, state.joints), T_from_ur_pose(state.tcp_pose))
    assert lin < 1e-12 and ang < 1e-12


def test_captured_version_message_gives_the_published_version():
    (kind, content), = MessageSplitter().feed(VERSION_MESSAGE)
    assert kind == 20
    v = parse_version_message(content)
    assert (v.project, v.major, v.minor, v.bugfix, v.build) == ("URControl", 5, 24, 0, 0)
    assert v.build_date == "04-10-2025, 00:25:33"
    assert str(v) == "5.24.0.0"


@pytest.mark.parametrize("chunk", [1, 3, 7, 64, 1391, 5000])
def test_messages_split_anywhere_and_glued_together(chunk):
    stream = VERSION_MESSAGE + ROBOT_STATE + VERSION_MESSAGE + ROBOT_STATE
    splitter, got = MessageSplitter(), []
    for i in range(0, len(stream), chunk):
        got += splitter.feed(stream[i:i + chunk])
    assert [k for k, _ in got] == [20, 16, 20, 16]
    assert got[1][1] == body(ROBOT_STATE) and splitter.pending == (0, None)


def test_incomplete_message_is_held_not_returned():
    splitter = MessageSplitter()
    assert splitter.feed(ROBOT_STATE[:700]) == []
    assert splitter.pending == (700, 1386)


@pytest.mark.parametrize("size", [0, 4, -1, MAX_MESSAGE_BYTES + 1])
def test_impossible_message_size_stops_the_splitter(size):
    splitter = MessageSplitter()
    assert splitter.feed(struct.pack(">iB", size, 16) + bytes(20)) == []
    assert "out of step" in splitter.error
    assert splitter.feed(ROBOT_STATE) == []  # nothing after that is trusted


def test_longer_kinematics_info_is_read_and_its_extra_ignored():
    state = parse_robot_state(body(replaced(KINEMATICS_INFO, kinematics_payload() + bytes(10))))
    assert state.valid and state.kinematics.extra_bytes == 10
    assert state.kinematics.d == PUBLISHED_D and state.kinematics.calibration_status == 0


@pytest.mark.parametrize("length", [0, 4, 219])
def test_short_kinematics_info_is_skipped(length):
    state = parse_robot_state(body(replaced(KINEMATICS_INFO, kinematics_payload()[:length])))
    assert state.valid and state.kinematics is None and state.short_kinematics == 1
    assert state.joints is not None  # the rest of the message is still read


def test_unknown_and_resized_subpackages_are_skipped_by_length():
    parts = subpackages()
    parts[0] = (0, parts[0][1] + bytes(13))       # ROBOT_MODE_DATA grown by a newer version
    parts[2] = (4, parts[2][1][:48])              # CARTESIAN_INFO without the TCP offset
    parts.insert(3, (77, b"\x01" * 30))           # unknown sub-type before the table
    parts.append((200, b""))                      # and an empty one at the end
    state = parse_robot_state(body(robot_state(parts)))
    assert state.valid and state.kinematics.a == PUBLISHED_A
    assert state.tcp_pose is not None and state.tcp_offset is None
    assert [k for k, _ in state.subpackages] == [0, 1, 4, 77, 5, 9, 3, 2, 6, 7, 8, 10, 11, 12,
                                                 200]


def test_state_without_kinematics_info():
    state = parse_robot_state(body(replaced(KINEMATICS_INFO, None)))
    assert state.valid and state.kinematics is None and len(state.subpackages) == 12


@pytest.mark.parametrize("damage", ["overlong", "too_small", "stray"])
def test_malformed_state_is_not_used_at_all(damage):
    content = bytearray(body(ROBOT_STATE))
    if damage == "overlong":  # the table's size runs past the end of the message
        struct.pack_into(">i", content, 47 + 251 + 101, 5000)
    elif damage == "too_small":
        struct.pack_into(">i", content, 47 + 251 + 101, 3)
    else:
        content += b"\x00\x00"
    state = parse_robot_state(bytes(content))
    assert not state.valid and state.kinematics is None and state.joints is None
    assert "malformed" in state.notes[-1]


def test_other_robot_messages_and_broken_version_messages():
    key_message = struct.pack(">QbB", 0, -2, 7) + bytes(12)
    assert parse_version_message(key_message) is None
    broken = bytearray(body(VERSION_MESSAGE))
    broken[10] = 100  # project name longer than the message
    with pytest.raises(ValueError, match="does not fit"):
        parse_version_message(bytes(broken))
    with pytest.raises(ValueError, match="shorter"):
        parse_version_message(b"\x00" * 5)
