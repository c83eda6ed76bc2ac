"""Benchmark: the two pure-Python ROS 2 libraries side by side, and the bridge's own steps.

    .venv/bin/python -m bench.ros2 [--repeats 5] [--quick] [--out bench/results/ros2.md]

Side by side in one process, alternating A B A B per repeat (medians quoted):

- CDR encode and decode of what a bag holds: ``tf2_msgs/TFMessage`` (seven transforms, what
  robot_state_publisher sends for a UR arm at 500 Hz), ``sensor_msgs/JointState`` and a
  640x480 ``bgr8`` ``sensor_msgs/Image``; rosbags (typestore ``serialize_cdr`` /
  ``deserialize_cdr``) against mcap-ros2-support (its dynamic encoder / decoder from the
  definition text);
- a fused mesh as one ``visualization_msgs/Marker`` TRIANGLE_LIST: rosbags message objects,
  mcap-ros2-support from dicts, and armstereo's numpy CDR (``armstereo.ros2.markers``);
- ``armstereo export`` of the sample recording and the ``armstereo import`` of that bag.

Prints a markdown table (time per message or per call).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from mcap_ros2._dynamic import generate_dynamic, serialize_dynamic

from armstereo.ros2 import markers as M
from armstereo.ros2 import messages as msgs
from armstereo.ros2 import types as R
from armstereo.ros2.export import export_recording
from armstereo.ros2.importer import ImportOptions, import_bag
from armstereo.transforms import make_T, rot_x, rot_z
from bench.harness import command_line, machine_note, timed, write_report

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "recordings" / "sample.mcap"


def _timed(fn, n: int) -> float:
    """Mean seconds per call over ``n`` calls."""
    return timed(lambda: [fn() for _ in range(n)])[1] / n


def _as_dict(obj):
    """A rosbags message as nested dicts/lists (what mcap-ros2-support encodes)."""
    if isinstance(obj, np.ndarray):
        return obj.tobytes() if obj.dtype == np.uint8 else obj.tolist()
    if isinstance(obj, list):
        return [_as_dict(v) for v in obj]
    if hasattr(obj, "__dataclass_fields__"):
        return {k: _as_dict(getattr(obj, k)) for k in obj.__dataclass_fields__
                if k != "__msgtype__"}
    return obj


def samples(store) -> dict[str, tuple[str, object]]:
    tfs = [msgs.transform(store, make_T(rot_z(0.1 * k) @ rot_x(0.2), [0.1 * k, 0.2, 0.3]),
                          f"link{k}", f"link{k + 1}", 1_700_000_000_000_000_000)
           for k in range(7)]
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, (480, 640, 3), dtype=np.uint8)
    return {
        "TFMessage (7 transforms)": (R.TF_MESSAGE, msgs.tf_message(store, tfs)),
        "JointState (6 joints)": (R.JOINT_STATE, msgs.joint_state(
            store, [f"j{k}" for k in range(6)], rng.normal(size=6), 1)),
        "Image 640x480 bgr8": (R.IMAGE, msgs.image(store, image, 1, "camera_optical")),
    }


def _codec_times(store, msgtype: str, msg, repeats: int, n: int) -> list[float]:
    """Median s per message: rosbags encode, mcap-ros2 encode, rosbags decode, mcap-ros2
    decode, alternating per repeat."""
    text = store.generate_msgdef(msgtype, ros_version=2)[0]
    encode = serialize_dynamic(msgtype, text)[msgtype]
    decode = generate_dynamic(msgtype, text)[msgtype]
    as_dict = _as_dict(msg)
    raw = bytes(store.serialize_cdr(msg, msgtype))
    assert bytes(encode(as_dict)) == raw  # both write the same bytes
    steps = [lambda: store.serialize_cdr(msg, msgtype), lambda: encode(as_dict),
             lambda: store.deserialize_cdr(raw, msgtype), lambda: decode(raw)]
    times: list[list[float]] = [[] for _ in steps]
    for _ in range(repeats):
        for k, step in enumerate(steps):
            times[k].append(_timed(step, n))
    return [statistics.median(t) for t in times]


def codec_rows(repeats: int, quick: bool) -> list[tuple]:
    store = R.typestore("humble")
    rows = []
    for label, (msgtype, msg) in samples(store).items():
        n = 20 if quick else (200 if "Image" not in label else 50)
        rows.append((label, *_codec_times(store, msgtype, msg, repeats, n)))
    return rows


def mesh_rows(repeats: int, quick: bool) -> list[tuple]:
    store = R.typestore("humble")
    n = 60_000 if quick else 600_000  # triangle-list points: three per face of a fused mesh
    rng = np.random.default_rng(1)
    pts, cols = rng.normal(size=(n, 3)), rng.random((n, 4)).astype(np.float32)
    spec = M.MarkerSpec("mesh", 0, M.TRIANGLE_LIST, "base", 1, points=pts, colors=cols)
    raw = M.encode_marker(spec)
    msg = store.deserialize_cdr(raw, R.MARKER)
    text = store.generate_msgdef(R.MARKER, ros_version=2)[0]
    encode = serialize_dynamic(R.MARKER, text)[R.MARKER]
    as_dict = _as_dict(msg)
    types = store.types

    def rosbags_objects():
        P, C = types["geometry_msgs/msg/Point"], types["std_msgs/msg/ColorRGBA"]
        built = type(msg)(**{**{k: getattr(msg, k) for k in msg.__dataclass_fields__
                                if k != "__msgtype__"},
                             "points": [P(x=float(a), y=float(b), z=float(c)) for a, b, c in pts],
                             "colors": [C(r=float(r), g=float(g), b=float(b), a=float(a))
                                        for r, g, b, a in cols]})
        return store.serialize_cdr(built, R.MARKER)

    times = {k: [] for k in ("numpy", "rosbags", "mcap_ros2")}
    for _ in range(max(1, repeats // 2)):
        times["numpy"].append(_timed(lambda: M.encode_marker(spec), 3))
        times["rosbags"].append(_timed(rosbags_objects, 1))
        times["mcap_ros2"].append(_timed(lambda: encode(as_dict), 1))
    assert bytes(encode(as_dict)) == raw
    return [(f"Marker TRIANGLE_LIST, {n} points", *(statistics.median(v)
                                                    for v in times.values()))]


def bridge_rows(repeats: int) -> list[tuple]:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        ex, im = [], []
        for k in range(repeats):
            bag = Path(tmp) / f"bag{k}"
            t0 = time.perf_counter()
            export_recording(SAMPLE, bag)
            ex.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            import_bag(bag, Path(tmp) / f"r{k}.mcap", ImportOptions(image_topic="/camera/image"))
            im.append(time.perf_counter() - t0)
        rows.append(("export sample.mcap (2 views 640x480)", statistics.median(ex)))
        rows.append(("import of that bag", statistics.median(im)))
    return rows


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="fewer messages, a small mesh")
    ap.add_argument("--out", type=Path, default=None, help="also write the tables here")
    args = ap.parse_args(argv)
    lines = ["| message | rosbags encode | mcap-ros2 encode | rosbags decode | mcap-ros2 decode |",
             "|---|---|---|---|---|"]
    for label, *t in codec_rows(args.repeats, args.quick):
        lines.append(f"| {label} | " + " | ".join(f"{v * 1e6:.0f} us" for v in t) + " |")
    lines += ["", "| mesh marker | numpy CDR (armstereo) | rosbags objects | mcap-ros2 dicts |",
              "|---|---|---|---|"]
    for label, *t in mesh_rows(args.repeats, args.quick):
        lines.append(f"| {label} | " + " | ".join(f"{v:.3f} s" for v in t) + " |")
    lines += ["", "| bridge step | median wall |", "|---|---|"]
    for label, t in bridge_rows(args.repeats):
        lines.append(f"| {label} | {t:.3f} s |")
    lines += ["", f"`{command_line('bench.ros2', argv)}`; {machine_note()}"]
    write_report("\n".join(lines) + "\n", args.out)


if __name__ == "__main__":
    main()
