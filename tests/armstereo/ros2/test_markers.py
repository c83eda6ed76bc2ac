"""The hand-written Marker CDR is byte for byte what rosbags serializes, and decodes with
mcap-ros2-support's decoder too."""

from __future__ import annotations

import numpy as np
from mcap_ros2._dynamic import generate_dynamic

from armstereo.ros2 import markers as M
from armstereo.ros2 import types as R
from armstereo.transforms import make_T, rot_x, rot_z


def _spec(n: int, seed: int = 0, **kw) -> M.MarkerSpec:
    rng = np.random.default_rng(seed)
    return M.MarkerSpec(kw.pop("ns", "object/3"), kw.pop("id", 7), kw.pop("type", M.TRIANGLE_LIST),
                        "base", 1_700_000_000_123_456_789,
                        pose=make_T(rot_z(0.3) @ rot_x(-1.0), [0.1, -0.2, 0.3]),
                        scale=(0.5, 0.25, 2.0), color=(0.1, 0.2, 0.3, 0.4),
                        points=rng.normal(size=(n, 3)), colors=rng.random((n, 4)), **kw)


def test_a_marker_is_what_rosbags_serializes():
    store = R.typestore("humble")
    for spec in (_spec(0), _spec(1), _spec(9, text="höhe 3 mm", frame_locked=True,
                                             lifetime_ns=2_500_000_001), _spec(5, ns="")):
        raw = M.encode_marker(spec)
        msg = store.deserialize_cdr(raw, R.MARKER)
        assert bytes(store.serialize_cdr(msg, R.MARKER)) == raw
        assert msg.ns == spec.ns and msg.text == spec.text and msg.id == spec.id
        assert np.array_equal([[p.x, p.y, p.z] for p in msg.points] or np.zeros((0, 3)),
                              spec.points)


def test_a_marker_array_decodes_with_the_second_reader():
    store = R.typestore("jazzy")
    specs = [_spec(4, seed=k, id=k) for k in range(3)] + [_spec(0, type=M.CUBE, id=9)]
    raw = M.encode_marker_array(specs)
    text = store.generate_msgdef(R.MARKER_ARRAY, ros_version=2)[0]
    decoded = generate_dynamic(R.MARKER_ARRAY, text)[R.MARKER_ARRAY](raw)
    assert [m.id for m in decoded.markers] == [0, 1, 2, 9]
    m = decoded.markers[1]
    assert np.allclose([[c.r, c.g, c.b, c.a] for c in m.colors], specs[1].colors)
    q = m.pose.orientation
    assert abs(q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2 - 1) < 1e-12
    assert (m.header.stamp.sec, m.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
