"""``armstereo stereo`` and ``armstereo eval``: files round-trip, scores match the library,
bad input gives one line and a non-zero exit code."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from armstereo.cli.main import main
from armstereo.evaluation.disparity import evaluate_disparity
from armstereo.io.disparity import read_disparity, write_disparity
from armstereo.reconstruct.stereo import birchfield
from tests.support import MIDDLEBURY

TSUKUBA = MIDDLEBURY / "tsukuba"
D0 = 6


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> tuple[Path, Path, np.ndarray, np.ndarray]:
    """A textured plane at disparity D0 as PNG files, plus the images."""
    rng = np.random.default_rng(11)
    noise = cv2.GaussianBlur(rng.standard_normal((50, 100 + D0, 3)).astype(np.float32),
                             (0, 0), 1.5)
    tex = np.clip(128 + 50 * noise / (3 * noise.std()), 0, 255).astype(np.uint8)
    left, right = tex[:, :100], tex[:, D0:]
    folder = tmp_path_factory.mktemp("pair")
    paths = folder / "left.png", folder / "right.png"
    for p, img in zip(paths, (left, right), strict=True):
        cv2.imwrite(str(p), img)
    return paths[0], paths[1], left, right


def run_cli(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("suffix, atol", [(".pfm", 0.0), (".png", 0.5 / 256)])
def test_stereo_writes_what_the_library_computes(pair, tmp_path, capsys, suffix, atol):
    left_path, right_path, left, right = pair
    out = tmp_path / f"disp{suffix}"
    code, text, _ = run_cli(capsys, "stereo", left_path, right_path, "--max-disparity", 15,
                            "--out", out, "--colorized", tmp_path / "view.png")
    assert code == 0 and str(out) in text
    disp = read_disparity(out)
    expected = birchfield(left, right, 15)
    np.testing.assert_array_equal(np.isnan(disp), np.isnan(expected))
    np.testing.assert_allclose(disp, expected, atol=atol, equal_nan=True)
    assert cv2.imread(str(tmp_path / "view.png")).shape[1] == left.shape[1]


def test_stereo_sgbm_and_options(pair, tmp_path, capsys):
    left_path, right_path, *_ = pair
    out = tmp_path / "sgbm.pfm"
    code, text, _ = run_cli(capsys, "stereo", left_path, right_path, "--max-disparity", 15,
                            "--out", out, "--method", "sgbm")
    assert code == 0 and text.startswith("sgbm:")
    disp = read_disparity(out)
    assert np.nanmedian(disp[:, 20:]) == pytest.approx(D0, abs=0.25)
    code, _, _ = run_cli(capsys, "stereo", left_path, right_path, "--max-disparity", 8,
                         "--min-disparity", 2, "--out", out, "--subpixel", "none",
                         "--color", "sum", "--threads", 1)
    assert code == 0
    disp = read_disparity(out)
    assert np.isnan(disp[:, :2]).all() and (disp[:, D0:] == D0).all()



def test_stereo_sgbm_flags_are_the_librarys_options(pair, tmp_path, capsys):
    """--sgbm-presmooth/--sgbm-shifts/--sgbm-mode give what SgbmOptions gives; a bad value is
    one line and exit 2; the Birchfield-Tomasi flags do not change an SGBM map."""
    from armstereo.reconstruct.sgbm import sgbm

    left_path, right_path, left, right = pair
    out = tmp_path / "sgbm.pfm"
    code, _, _ = run_cli(capsys, "stereo", left_path, right_path, "--max-disparity", 15,
                         "--out", out, "--method", "sgbm", "--sgbm-presmooth", 1,
                         "--sgbm-shifts", 4, "--sgbm-mode", "hh", "--subpixel", "none")
    assert code == 0
    got = read_disparity(out)
    expected = sgbm(cv2.imread(str(left_path)), cv2.imread(str(right_path)), 15,
                    presmooth=1.0, shifts=4, mode="hh")
    np.testing.assert_array_equal(got, expected)
    plain = sgbm(cv2.imread(str(left_path)), cv2.imread(str(right_path)), 15)
    assert not np.array_equal(np.nan_to_num(got), np.nan_to_num(plain))  # the flags did act
    for bad in (("--sgbm-shifts", 0), ("--sgbm-shifts", 40), ("--sgbm-presmooth", -1),
                ("--sgbm-mode", "fast")):
        code, _, err = run_cli(capsys, "stereo", left_path, right_path, "--max-disparity", 15,
                               "--out", out, "--method", "sgbm", *bad)
        assert code == 2 and bad[0] in err and len(err.strip().splitlines()) == 1


def test_stereo_photo_check_is_the_librarys(tmp_path, capsys):
    from tests.support.images import box_pair

    left, right = box_pair(3, 11, (50, 100, 20, 60))
    paths = tmp_path / "l.png", tmp_path / "r.png"
    for p, img in zip(paths, (left, right), strict=True):
        cv2.imwrite(str(p), img)
    out = tmp_path / "d.pfm"
    code, _, _ = run_cli(capsys, "stereo", *paths, "--max-disparity", 15, "--out", out,
                         "--photo-check", 4)
    assert code == 0
    np.testing.assert_array_equal(read_disparity(out), birchfield(left, right, 15, photo_check=4))
    code, _, err = run_cli(capsys, "stereo", *paths, "--max-disparity", 15, "--out", out,
                           "--photo-check", -1)
    assert code == 2 and "--photo-check" in err


def test_eval_round_trip_through_pfm_and_png(tmp_path, capsys):
    rng = np.random.default_rng(2)
    gt = rng.uniform(4, 30, (40, 60)).astype(np.float32)
    disp = gt.copy()
    disp[:10] += 1.5  # bad-1, not bad-2
    disp[10:15] -= 3.0  # bad-2
    disp[15:20] = np.nan  # invalid
    write_disparity(tmp_path / "gt.pfm", gt)
    expected = evaluate_disparity(disp, gt)
    for suffix in (".pfm", ".png"):
        write_disparity(tmp_path / f"disp{suffix}", disp)
        code, text, _ = run_cli(capsys, "eval", tmp_path / f"disp{suffix}", tmp_path / "gt.pfm",
                                "--json")
        assert code == 0
        scores = json.loads(text)
        assert scores["bad1"] == pytest.approx(20 / 40)
        assert scores["bad2"] == pytest.approx(10 / 40)
        assert scores["invalid"] == pytest.approx(5 / 40)
        assert scores["avg_error"] == pytest.approx(expected["avg_error"], abs=1e-3)
    code, text, _ = run_cli(capsys, "eval", tmp_path / "disp.pfm", tmp_path / "gt.pfm")
    assert code == 0
    assert "bad-2           25.00 %" in text and "invalid         12.50 %" in text
    # only the mask's white pixels count: rows 20.. are grey (128, "occluded") here
    mask = np.full(gt.shape, 255, np.uint8)
    mask[20:] = 128
    cv2.imwrite(str(tmp_path / "mask.png"), mask)
    code, text, _ = run_cli(capsys, "eval", tmp_path / "disp.pfm", tmp_path / "gt.pfm",
                            "--mask", tmp_path / "mask.png", "--json")
    scores = json.loads(text)
    assert (scores["bad1"], scores["bad2"], scores["invalid"]) == (1.0, 0.5, 0.25)
    assert scores["pixels"] == 20 * 60


def test_eval_reads_middlebury_ground_truth_with_its_scale_and_mask(tmp_path, capsys):
    gt = read_disparity(TSUKUBA / "groundtruth.png", scale=16)
    mask = cv2.imread(str(TSUKUBA / "nonocc.png"), cv2.IMREAD_GRAYSCALE) > 128
    disp = gt + np.where(np.arange(gt.shape[1]) % 4 == 0, 2.5, 0.0).astype(np.float32)
    write_disparity(tmp_path / "d.pfm", disp)
    expected = evaluate_disparity(disp, gt, mask, exclude_left=15)
    # the scale comes from meta.json beside the ground truth, or from --gt-scale
    for extra in ([], ["--gt-scale", 16]):
        code, text, _ = run_cli(capsys, "eval", tmp_path / "d.pfm", TSUKUBA / "groundtruth.png",
                                "--mask", TSUKUBA / "nonocc.png", "--exclude-left", 15,
                                "--json", *extra)
        assert code == 0
        assert json.loads(text)["bad2"] == pytest.approx(expected["bad2"])
        assert 0.2 < expected["bad2"] < 0.3
    # read at the wrong scale, nearly everything is bad: the scale matters
    code, text, _ = run_cli(capsys, "eval", tmp_path / "d.pfm", TSUKUBA / "groundtruth.png",
                            "--gt-scale", 1, "--json")
    assert json.loads(text)["bad2"] > 0.9


@pytest.mark.parametrize("argv, code, message", [
    (["stereo", "{L}", "{T}/imR.png", "--max-disparity", "15", "--out", "{o}/d.pfm"], 6,
     "image sizes differ"),
    (["stereo", "{L}", "{R}", "--max-disparity", "100", "--out", "{o}/d.pfm"], 6,
     "must be < the image width 100"),
    (["stereo", "{L}", "{R}", "--max-disparity", "0", "--out", "{o}/d.pfm"], 2,
     "argument --max-disparity: must be in 1..4096, got 0"),
    (["stereo", "{L}", "{R}", "--max-disparity", "15", "--out", "{o}/d.tiff"], 2,
     "use a .pfm or .png file"),
    (["stereo", "{o}/missing.png", "{R}", "--max-disparity", "15", "--out", "{o}/d.pfm"], 2,
     "no such file"),
    (["stereo", "{o}/junk.png", "{R}", "--max-disparity", "15", "--out", "{o}/d.pfm"], 2,
     "not a readable image"),
    (["eval", "{o}/missing.pfm", "{T}/groundtruth.png"], 2, "no such file"),
    (["eval", "{o}/small.pfm", "{T}/groundtruth.png"], 2, "the ground truth"),
    (["eval", "{o}/small.pfm", "{o}/small.pfm", "--mask", "{T}/nonocc.png"], 2,
     "mask"),
    (["eval", "{o}/small.pfm", "{o}/small.pfm", "--gt-scale", "0"], 2,
     "argument --gt-scale: must be > 0"),
])
def test_bad_input_gives_one_line_and_an_exit_code(pair, tmp_path, capsys, argv, code,
                                                   message):
    (tmp_path / "junk.png").write_bytes(b"not a png")
    write_disparity(tmp_path / "small.pfm", np.ones((5, 7), np.float32))
    names = dict(L=pair[0], R=pair[1], T=TSUKUBA, o=tmp_path)
    got, out, err = run_cli(capsys, *[a.format(**names) for a in argv])
    assert got == code
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"armstereo {argv[0]}: error:") and message in err
    assert not (tmp_path / "d.pfm").exists()


def test_console_entry_point_exit_code_and_message(pair, tmp_path):
    """The real process: exit status and a one-line message, no traceback."""
    proc = subprocess.run([sys.executable, "-m", "armstereo", "stereo", str(pair[0]),
                           str(TSUKUBA / "imR.png"), "--max-disparity", "8", "--out",
                           str(tmp_path / "d.pfm")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 6
    assert proc.stderr.strip().count("\n") == 0 and "image sizes differ" in proc.stderr
