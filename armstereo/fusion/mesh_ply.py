"""Binary little-endian PLY triangle meshes (vertices xyz float32 + red green blue uchar, faces
as ``uchar``-counted ``int`` index lists): the layout MeshLab, Open3D, CloudCompare and Blender
read::

    ply
    format binary_little_endian 1.0
    comment armstereo fused mesh, frame base, metres
    element vertex N
    property float x
    property float y
    property float z
    property uchar red
    property uchar green
    property uchar blue
    element face M
    property list uchar int vertex_indices
    end_header

Colours are BGR in memory (the project's order) and RGB in the file. Writes are atomic.
(Point clouds without faces are :mod:`armstereo.io.ply`'s; this module adds the face element.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from armstereo.errors import StereoError
from armstereo.fusion.mesh import Mesh
from armstereo.io.files import write_bytes_atomic
from armstereo.io.ply import VERTEX_DTYPE

FACE_DTYPE = np.dtype([("n", "u1"), ("i0", "<i4"), ("i1", "<i4"), ("i2", "<i4")])
_HEADER_END = b"end_header\n"


def encode_mesh_ply(mesh: Mesh, *, comment: str = "") -> bytes:
    """The bytes of a binary PLY of ``mesh`` (vertices in metres, colours BGR in memory)."""
    if "\n" in comment:
        raise StereoError("a PLY comment must be one line")
    vertices = np.empty(len(mesh.vertices), dtype=VERTEX_DTYPE)
    for i, axis in enumerate("xyz"):
        vertices[axis] = mesh.vertices[:, i]
    vertices["red"], vertices["green"], vertices["blue"] = (
        mesh.colors[:, 2], mesh.colors[:, 1], mesh.colors[:, 0])
    faces = np.empty(len(mesh.faces), dtype=FACE_DTYPE)
    faces["n"] = 3
    faces["i0"], faces["i1"], faces["i2"] = mesh.faces[:, 0], mesh.faces[:, 1], mesh.faces[:, 2]
    header = ["ply", "format binary_little_endian 1.0"]
    header += [f"comment {comment}"] if comment else []
    header += [f"element vertex {len(vertices)}"]
    header += [f"property float {a}" for a in "xyz"]
    header += [f"property uchar {c}" for c in ("red", "green", "blue")]
    header += [f"element face {len(faces)}", "property list uchar int vertex_indices",
               "end_header"]
    return ("\n".join(header) + "\n").encode("ascii") + vertices.tobytes() + faces.tobytes()


def write_mesh_ply(path: str | Path, mesh: Mesh, *, comment: str = "") -> Path:
    """Write ``mesh`` as a binary PLY atomically; returns the path."""
    return write_bytes_atomic(path, encode_mesh_ply(mesh, comment=comment))


def read_mesh_ply(path: str | Path) -> Mesh:
    """Read a mesh written by :func:`write_mesh_ply` (exactly that layout; StereoError
    otherwise)."""
    data = Path(path).read_bytes()
    end = data.find(_HEADER_END)
    if not data.startswith(b"ply\n") or end < 0:
        raise StereoError(f"{path}: not a PLY file")
    lines = [ln for ln in data[:end].decode("ascii").splitlines()
             if not ln.startswith("comment")]
    counts = {w[1]: int(w[2]) for w in (ln.split() for ln in lines) if w[0] == "element"}
    expected = encode_mesh_ply(Mesh.empty()).decode("ascii", "replace").splitlines()
    layout = [ln for ln in expected if not ln.startswith(("element", "comment"))]
    if [ln for ln in lines if not ln.startswith("element")] + ["end_header"] != layout \
            or set(counts) != {"vertex", "face"}:
        raise StereoError(f"{path}: not the armstereo mesh PLY layout")
    body = data[end + len(_HEADER_END):]
    nv, nf = counts["vertex"], counts["face"]
    need = nv * VERTEX_DTYPE.itemsize + nf * FACE_DTYPE.itemsize
    if len(body) < need:
        raise StereoError(f"{path}: truncated ({len(body)} of {need} body bytes)")
    v = np.frombuffer(body, dtype=VERTEX_DTYPE, count=nv)
    f = np.frombuffer(body, dtype=FACE_DTYPE, count=nf, offset=nv * VERTEX_DTYPE.itemsize)
    if nf and np.any(f["n"] != 3):
        raise StereoError(f"{path}: only triangles are supported")
    return Mesh(np.stack([v["x"], v["y"], v["z"]], axis=1),
                np.stack([f["i0"], f["i1"], f["i2"]], axis=1),
                np.stack([v["blue"], v["green"], v["red"]], axis=1).astype(np.uint8))
