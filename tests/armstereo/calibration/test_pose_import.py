"""Pose files from other tools: every format reads to the same flange poses, and every
malformed file is a one-line error naming the file and the line (a seeded fuzz)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from armstereo.calibration.pose_import import flange_pose, read_poses
from armstereo.calibration.poses import exp6, rotvec
from armstereo.errors import ConfigError

RNG = np.random.default_rng(0)
FLANGES = [exp6(np.r_[RNG.normal(size=3) * 0.6, RNG.uniform(-0.6, 0.6, 3)]) for _ in range(4)]
JOINTS = [RNG.uniform(-3, 3, 6) for _ in range(4)]


def _tcp(T) -> list[float]:
    return [*T[:3, 3].tolist(), *rotvec(T[:3, :3]).tolist()]


def _files() -> dict[str, str]:
    """The same four poses in each supported layout (file name -> text)."""
    rows = [_tcp(T) for T in FLANGES]
    num = lambda v: ",".join(repr(float(x)) for x in v)  # noqa: E731
    mats = [T.reshape(-1).tolist() for T in FLANGES]
    return {
        "tcp.csv": "image,x,y,z,rx,ry,rz\n" + "".join(f"v{k}.png,{num(r)}\n"
                                                        for k, r in enumerate(rows)),
        "tcp_plain.csv": "# x y z rx ry rz, as getActualTCPPose\n"
                         + "".join(" ".join(repr(x) for x in r) + "\n" for r in rows),
        "tcp_semicolon.csv": "".join(";".join(repr(x) for x in r) + "\n" for r in rows),
        "tcp.json": json.dumps([{"image": f"v{k}.png", "tcp": r} for k, r in enumerate(rows)],
                               indent=1),
        "tcp.yaml": "poses:\n" + "".join(
            f"  - image: v{k}.png\n    tcp: {{x: {r[0]!r}, y: {r[1]!r}, z: {r[2]!r}, "
            f"rx: {r[3]!r}, ry: {r[4]!r}, rz: {r[5]!r}}}\n" for k, r in enumerate(rows)),
        "matrix.csv": "".join(num(m) + "\n" for m in mats),
        "matrix.json": json.dumps({"poses": [{"T_base_flange": T.tolist()} for T in FLANGES]},
                                  indent=2),
        "matrix.yaml": "".join(f"- {T[:3].reshape(-1).tolist()}\n" for T in FLANGES),
        "joints.csv": "q1,q2,q3,q4,q5,q6\n" + "".join(num(q) + "\n" for q in JOINTS),
        "joints.yaml": "".join(f"- joints: {q.tolist()}\n" for q in JOINTS),
    }


@pytest.mark.parametrize("name", sorted(_files()))
def test_every_layout_reads_to_the_same_poses(tmp_path, name):
    path = tmp_path / name
    path.write_text(_files()[name])
    pf = read_poses(path)
    assert len(pf.records) == 4
    if name.startswith("joints"):
        assert pf.kind == "joints"
        for r, q in zip(pf.records, JOINTS, strict=True):
            np.testing.assert_allclose(r.values, q, atol=1e-12)
        return
    assert pf.kind == ("tcp" if name.startswith("tcp") else "matrix")
    for r, T in zip(pf.records, FLANGES, strict=True):
        np.testing.assert_allclose(flange_pose(r), T, atol=1e-12)
    assert pf.named == (name in ("tcp.csv", "tcp.json", "tcp.yaml"))


def test_six_numbers_are_joints_when_a_robot_is_named(tmp_path):
    path = tmp_path / "q.csv"
    path.write_text("".join(",".join(repr(float(x)) for x in q) + "\n" for q in JOINTS))
    assert read_poses(path, joints_expected=True).kind == "joints"
    assert read_poses(path, "joints").kind == "joints"


def test_a_tcp_offset_is_taken_off(tmp_path):
    T_flange_tcp = exp6([0.0, 0.0, 0.3, 0.0, 0.0, 0.12])
    path = tmp_path / "p.csv"
    path.write_text("".join(",".join(repr(x) for x in _tcp(T @ T_flange_tcp)) + "\n"
                            for T in FLANGES))
    for r, T in zip(read_poses(path).records, FLANGES, strict=True):
        np.testing.assert_allclose(flange_pose(r, T_flange_tcp), T, atol=1e-12)


@pytest.mark.parametrize(("text", "line", "match"), [
    ("image,x,y,z,rx,ry,rz\na.png,0.1,0.2,0.3,0,0,0\nb.png,0.1,0.2,0.3,0,0\n", 3, "fields"),
    ("0.1,0.2,0.3,0,0,0\n0.1,0.2,abc,0,0,0\n", 2, "'abc' is not a number"),
    ("100,200,300,0,0,0\n", 1, "millimetres"),
    ("0.1,0.2,0.3,90,0,0\n", 1, "degrees"),
    ("0.1,0.2,0.3,0,0\n", 1, "5 numbers"),
    ("1,0,0,0,0,2,0,0,0,0,1,0,0,0,0,1\n", 1, "no rotation"),
    ("1,0,0,0,0,1,0,0,0,0,1,0,0,0,1,1\n", 1, "last row"),
    ("a.png,0.1,0.2,0.3,0,0,0\na.png,0.1,0.2,0.3,0,0,0\n", 2, "already has a pose"),
    ("0.1,0.2,0.3,0,0,0\n1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1\n", 1, "mixes pose kinds"),
    ("# nothing here\n", 1, "no poses"),
])
def test_malformed_csv_names_file_and_line(tmp_path, text, line, match):
    path = tmp_path / "poses.csv"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match) as info:
        read_poses(path)
    assert str(info.value).startswith(f"{path}:{line}: ")


def test_malformed_json_and_yaml_name_the_line(tmp_path):
    bad_json = tmp_path / "p.json"
    bad_json.write_text('[\n {"tcp": [0.1, 0.2, 0.3, 0, 0, 0]},\n {"tcp": [0.1, 0.2]}\n]\n')
    with pytest.raises(ConfigError, match=r"p\.json:3: a TCP pose is 6 numbers"):
        read_poses(bad_json)
    broken = tmp_path / "q.json"
    broken.write_text('[\n [0.1, 0.2, 0.3, 0, 0, 0],\n [0.1, 0.2 0.3]\n]\n')
    with pytest.raises(ConfigError, match=r"q\.json:3: not valid JSON"):
        read_poses(broken)
    yml = tmp_path / "p.yaml"
    yml.write_text("- tcp: [0.1, 0.2, 0.3, 0, 0, 0]\n- tcp: [0.1, 0.2, 0.3, 0, 0, 0\n")
    with pytest.raises(ConfigError, match=r"p\.yaml:\d+: not valid YAML"):
        read_poses(yml)
    nothing = tmp_path / "n.yaml"
    nothing.write_text("- {image: a.png}\n")
    with pytest.raises(ConfigError, match=r"n\.yaml:1: the entry has none of"):
        read_poses(nothing)


_LINE = re.compile(r"^(?P<path>.+):(?P<line>\d+): \S")


def _mutate(text: str, rng: np.random.Generator) -> str:
    """One random edit of the kinds a broken export makes."""
    kind = rng.integers(8)
    pos = int(rng.integers(len(text) + 1))
    if kind == 0:  # delete a stretch
        return text[:pos] + text[pos + int(rng.integers(1, 12)):]
    if kind == 1:  # insert junk
        junk = rng.choice(["abc", ",", ";", "nan", "inf", "]", "{", ":", "\t", "1e999",
                           "'", '"', "-", "\n", "\x00", "é", "- ", "#"])
        return text[:pos] + str(junk) + text[pos:]
    if kind == 2:  # cut the file short
        return text[:pos]
    if kind == 3:  # a line twice
        lines = text.splitlines(keepends=True)
        k = int(rng.integers(len(lines)))
        return "".join(lines[:k + 1] + lines[k:])
    if kind == 4:  # a number in millimetres or degrees
        return re.sub(r"-?\d+\.\d+", lambda m: str(float(m.group()) * 1000), text, count=1)
    if kind == 5:  # a line dropped
        lines = text.splitlines(keepends=True)
        del lines[int(rng.integers(len(lines)))]
        return "".join(lines)
    if kind == 6:  # swap two characters
        if len(text) < 2:
            return text
        p = min(pos, len(text) - 2)
        return text[:p] + text[p + 1] + text[p] + text[p + 2:]
    return text.replace(",", " , ", int(rng.integers(1, 4)))


def test_fuzz_every_malformed_pose_file_is_one_line_naming_file_and_line(tmp_path):
    rng = np.random.default_rng(2024)
    files = _files()
    refused = 0
    for trial in range(400):
        name = sorted(files)[trial % len(files)]
        text = files[name]
        for _ in range(int(rng.integers(1, 4))):
            text = _mutate(text, rng)
        path = tmp_path / f"{trial}_{name}"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        try:
            read_poses(path)
        except ConfigError as err:
            msg = str(err)
            m = _LINE.match(msg)
            assert m and "\n" not in msg, (name, text, msg)
            assert m.group("path") == str(path)
            assert 1 <= int(m.group("line")) <= max(1, text.count("\n") + 1), (text, msg)
            refused += 1
    assert refused > 150  # the fuzz really broke most files
