"""Binary PLY writer and reader: header layout, byte order, colours, atomic writes."""

from __future__ import annotations

import os

import numpy as np
import pytest

from armstereo.errors import StereoError
from armstereo.io.ply import VERTEX_DTYPE, encode_ply, read_ply, write_ply

HEADER = (b"ply\nformat binary_little_endian 1.0\ncomment frame base\nelement vertex 3\n"
          b"property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
          b"property uchar green\nproperty uchar blue\nend_header\n")


def cloud(n: int = 3, seed: int = 0):
    rng = np.random.default_rng(seed)
    return (rng.normal(size=(n, 3)).astype(np.float32),
            rng.integers(0, 256, (n, 3), dtype=np.uint8))


def test_header_and_body_layout(tmp_path):
    pts, cols = cloud()
    path = write_ply(tmp_path / "c.ply", pts, cols, comment="frame base")
    data = path.read_bytes()
    assert data.startswith(HEADER)
    body = data[len(HEADER):]
    assert len(body) == 3 * 15 == 3 * VERTEX_DTYPE.itemsize
    first = np.frombuffer(body[:12], "<f4")
    assert np.array_equal(first, pts[0])
    assert tuple(body[12:15]) == (cols[0, 2], cols[0, 1], cols[0, 0])  # stored RGB


def test_round_trip(tmp_path):
    pts, cols = cloud(1000, seed=3)
    write_ply(tmp_path / "c.ply", pts, cols, comment="armstereo test")
    back = read_ply(tmp_path / "c.ply")
    assert np.array_equal(back.points, pts) and np.array_equal(back.colors_bgr, cols)
    assert back.comments == ("armstereo test",)


def test_empty_cloud_and_overwrite_leave_no_temporary_files(tmp_path):
    pts, cols = cloud()
    write_ply(tmp_path / "c.ply", pts, cols)
    write_ply(tmp_path / "c.ply", pts[:0], cols[:0])
    back = read_ply(tmp_path / "c.ply")
    assert back.points.shape == (0, 3) and back.colors_bgr.shape == (0, 3)
    assert [p.name for p in tmp_path.iterdir()] == ["c.ply"]


def test_float64_points_are_stored_as_float32():
    pts, cols = cloud()
    data = encode_ply(pts.astype(np.float64) + 1e-12, cols)
    assert b"property float x" in data and len(data) == len(HEADER) - len(b"comment frame "
                                                                          b"base\n") + 45


@pytest.mark.parametrize("pts,cols,match", [
    (np.zeros((3, 2)), np.zeros((3, 3), np.uint8), "points"),
    (np.zeros((3, 3)), np.zeros((3, 3), np.float32), "colors"),
    (np.zeros((3, 3)), np.zeros((2, 3), np.uint8), "colors"),
])
def test_bad_arrays_are_refused(pts, cols, match):
    with pytest.raises(StereoError, match=match):
        encode_ply(pts, cols)


def test_reader_refuses_what_it_cannot_read(tmp_path):
    pts, cols = cloud()
    data = encode_ply(pts, cols)
    (tmp_path / "short.ply").write_bytes(data[:-4])
    with pytest.raises(StereoError, match="truncated"):
        read_ply(tmp_path / "short.ply")
    (tmp_path / "ascii.ply").write_bytes(data.replace(b"binary_little_endian", b"ascii"))
    with pytest.raises(StereoError, match="binary_little_endian"):
        read_ply(tmp_path / "ascii.ply")
    (tmp_path / "x.ply").write_bytes(b"solid stl\n")
    with pytest.raises(StereoError, match="not a PLY"):
        read_ply(tmp_path / "x.ply")
    with pytest.raises(StereoError, match="one line"):
        encode_ply(pts, cols, comment="a\nb")


def test_written_files_get_the_umask_mode_not_a_private_one(tmp_path):
    # other users (a viewer, a web server) must be able to read the outputs like any saved file
    old = os.umask(0o022)
    try:
        path = write_ply(tmp_path / "c.ply", *cloud())
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o644
