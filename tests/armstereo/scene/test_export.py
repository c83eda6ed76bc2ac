"""Outputs: the files, an MCAP whose messages decode to what the analysis found (also in the
TypeScript reader Foxglove uses), the top-down picture; re-analysis of the written MCAP."""

from __future__ import annotations

import io
import json
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from armstereo.scene import analyze_scene, load_cloud
from armstereo.scene.export import SCENE_FILES, analyze_points, write_scene_outputs
from armstereo.scene.heightmap import OCCUPIED
from armstereo.scene.synthetic import default_truth, scan

TS_DIR = Path(__file__).parents[2] / "ts_reader"


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    cloud = scan(default_truth(), spacing=0.002, noise=0.0003)
    analysis = analyze_scene(cloud)
    out = tmp_path_factory.mktemp("scene")
    return cloud, analysis, write_scene_outputs(analysis, cloud, out)


def _messages(path):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        msgs = {ch.topic: (schema.name, dec)
                for schema, ch, _, dec in reader.iter_decoded_messages()}
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    return msgs, meta


def test_every_file_is_written(written):
    _, analysis, paths = written
    assert set(paths) == set(SCENE_FILES)
    assert all(p.stat().st_size > 0 for p in paths.values())
    doc = json.loads(paths["scene.json"].read_text())
    assert len(doc["objects"]) == len(analysis.objects) == 4
    hm = np.load(paths["height_map.npz"])
    assert np.array_equal(hm["heights_m"], analysis.height_map.heights, equal_nan=True)


def test_mcap_holds_boxes_labels_plane_grid_and_voxels(written):
    _, analysis, paths = written
    msgs, meta = _messages(paths["scene.mcap"])
    assert {t: n for t, (n, _) in msgs.items()} == {
        "/points": "foxglove.PointCloud", "/scene/objects": "foxglove.SceneUpdate",
        "/scene/height_map": "foxglove.Grid", "/scene/occupancy": "foxglove.VoxelGrid"}
    update = msgs["/scene/objects"][1]
    ids = [e.id for e in update.entities]
    assert ids == ["plane"] + [f"object/{o.id}" for o in analysis.objects]
    for o, e in zip(analysis.objects, update.entities[1:], strict=True):
        cube = e.cubes[0]
        assert (cube.size.x, cube.size.y, cube.size.z) == pytest.approx(o.size_m, abs=1e-9)
        assert (cube.pose.position.x, cube.pose.position.y) == pytest.approx(o.center_m[:2])
        assert e.texts[0].text.startswith(f"#{o.id} ")
        assert e.frame_id == "base"
    grid = msgs["/scene/height_map"][1]
    rows, cols = analysis.height_map.heights.shape
    assert grid.column_count == cols and len(grid.data) == rows * grid.row_stride
    assert {f.name for f in grid.fields} == {"elevation", "red", "green", "blue", "alpha"}
    elev = np.frombuffer(grid.data, dtype=np.dtype({"names": ["e"], "formats": ["<f4"],
                                                     "offsets": [0], "itemsize": 8}))["e"]
    assert np.array_equal(elev.reshape(rows, cols), analysis.height_map.heights,
                          equal_nan=True)
    vox = msgs["/scene/occupancy"][1]
    nz, ny, nx = analysis.occupancy.grid.shape
    assert (vox.row_count, vox.column_count) == (ny, nx) and len(vox.data) == nz * vox.slice_stride
    occ = np.frombuffer(vox.data, dtype=np.int8)[::vox.cell_stride]
    assert np.sum(occ == OCCUPIED) == np.sum(analysis.occupancy.grid == OCCUPIED)
    assert meta["armstereo"]["kind"] == "scene_analysis"
    assert json.loads(meta["armstereo"]["scene"])["objects"][0]["points"] > 0


def test_written_mcap_can_be_analysed_again(written):
    _, analysis, paths = written
    again = analyze_scene(load_cloud(paths["scene.mcap"]))
    assert [o.points for o in again.objects] == [o.points for o in analysis.objects]


def test_top_down_picture_outlines_the_objects(written):
    _, analysis, paths = written
    img = cv2.imread(str(paths["scene_top.png"]))
    assert img is not None and img.shape[1] > 400
    green = (img[..., 1] > 200) & (img[..., 0] < 120) & (img[..., 2] < 120)
    assert green.sum() > 500  # the outlines


def test_typescript_reader_decodes_the_scene_mcap(written):
    node, npm = shutil.which("node"), shutil.which("npm")
    if not (node and npm):
        pytest.skip("node/npm not installed")
    if not (TS_DIR / "node_modules" / "@mcap" / "core").exists():
        done = subprocess.run([npm, "install", "--no-audit", "--no-fund"], cwd=TS_DIR,
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
    done = subprocess.run([node, "check.mjs", str(written[2]["scene.mcap"])], cwd=TS_DIR,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "/scene/objects  foxglove.SceneUpdate" in done.stdout and "OK" in done.stdout


def test_occupancy_npz_round_trips(written):
    _, analysis, paths = written
    data = np.load(io.BytesIO(paths["occupancy.npz"].read_bytes()))
    assert np.array_equal(data["occupancy"], analysis.occupancy.grid)


def test_analyze_points_writes_and_scores_an_in_memory_cloud(tmp_path):
    truth = default_truth()
    cloud = scan(truth, spacing=0.003)
    analysis, score = analyze_points(cloud.points, cloud.colors_bgr, tmp_path, source="demo",
                                     truth=truth)
    assert len(analysis.objects) == 4 and not score.missed and not score.phantoms
    assert json.loads((tmp_path / "scene_score.json").read_text())["true_objects"] == 4
    _, meta = _messages(tmp_path / "scene.mcap")
    assert "scene_truth" in meta["armstereo"]
