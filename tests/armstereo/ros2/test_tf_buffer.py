"""The TF buffer: tf2's interpolation, chains through a common ancestor, and its refusals."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from armstereo.errors import RecordingError
from armstereo.ros2 import messages as msgs
from armstereo.ros2 import types as R
from armstereo.ros2.tf_buffer import TfBuffer
from armstereo.transforms import invert, make_T, rot_x, rot_z

STORE = R.typestore()


def _add(buf: TfBuffer, parent: str, child: str, T: np.ndarray, t_ns: int, static=False):
    tf = msgs.tf_message(STORE, [msgs.transform(STORE, T, parent, child, t_ns)])
    buf.add(tf, static=static, stamp_of=lambda h: R.stamp_ns(h.stamp))


def _tree() -> tuple[TfBuffer, np.ndarray, list[np.ndarray]]:
    buf = TfBuffer()
    T_bl_base = make_T(rot_z(np.pi), [0, 0, 0])
    _add(buf, "base_link", "base", T_bl_base, 0, static=True)
    flange = [make_T(rot_z(0.1 * k) @ rot_x(0.2 * k), [0.1 * k, 0.2, 0.3]) for k in range(3)]
    for k, T in enumerate(flange):
        _add(buf, "base_link", "tool0", T, k * 1_000_000_000)
    _add(buf, "tool0", "cam", make_T(rot_x(0.5), [0, 0.01, 0.02]), 0, static=True)
    buf.finish()
    return buf, T_bl_base, flange


def test_lookups_at_samples_and_between_them_are_tf2s():
    buf, T_bl_base, flange = _tree()
    T, ok = buf.lookup("base", "tool0", np.array([1_000_000_000]))
    assert ok.all() and np.abs(T[0] - invert(T_bl_base) @ flange[1]).max() < 1e-12
    T, ok = buf.lookup("base_link", "tool0", np.array([1_250_000_000]))
    assert np.allclose(T[0][:3, 3], 0.75 * flange[1][:3, 3] + 0.25 * flange[2][:3, 3])
    slerp = Slerp([0, 1], Rotation.from_matrix([flange[1][:3, :3], flange[2][:3, :3]]))
    assert np.allclose(T[0][:3, :3], slerp(0.25).as_matrix(), atol=1e-12)
    T, ok = buf.lookup("base", "cam", np.array([-1, 0, 2_000_000_000, 2_000_000_001]))
    assert ok.tolist() == [False, True, True, False]  # no extrapolation


def test_chain_problems_are_named():
    buf, _, _ = _tree()
    assert buf.chain_problem("base", "cam") is None
    assert "no frame camera_link" in buf.chain_problem("base", "camera_link")
    _add(buf, "camera_link", "optical", np.eye(4), 0, static=True)
    assert "optical's at camera_link" in buf.chain_problem("base", "optical")
    with pytest.raises(RecordingError, match="no TF chain"):
        buf.lookup("base", "optical", np.array([0]))


def test_stamps_back_in_time_and_two_parents_are_refused():
    buf = TfBuffer()
    _add(buf, "a", "b", np.eye(4), 10)
    _add(buf, "a", "b", np.eye(4), 5)
    with pytest.raises(RecordingError, match="go back in time"):
        buf.finish()
    buf = TfBuffer()
    _add(buf, "a", "b", np.eye(4), 10)
    _add(buf, "c", "b", np.eye(4), 20)
    with pytest.raises(RecordingError, match="two parents"):
        buf.finish()


def test_non_finite_transforms_are_rejected_not_used():
    buf = TfBuffer()
    tf = msgs.tf_message(STORE, [msgs.transform(STORE, np.eye(4), "a", "b", 0)])
    tf.transforms[0].transform.translation.x = float("nan")
    buf.add(tf, static=False, stamp_of=lambda h: R.stamp_ns(h.stamp))
    buf.finish()
    assert buf.rejected == 1 and "b" not in buf.frames
