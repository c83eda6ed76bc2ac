"""armstereo check: verdicts on mock recordings, JSON keys, one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from armstereo.cli.main import main
from tests.armstereo.epipolar.mock_views import (
    FORWARD_5MM,
    LATERAL,
    TILTED,
    YAW_1DEG,
    record_pair,
)

SAMPLE = Path(__file__).resolve().parents[3] / "recordings" / "sample.mcap"


def run_json(capsys, *args) -> dict:
    assert main(["check", *map(str, args), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_the_sample_recording_is_ok(capsys):
    doc = run_json(capsys, SAMPLE)
    assert [p["pair"] for p in doc["pairs"]] == [0]
    pair = doc["pairs"][0]
    assert pair["verdict"] == "ok"
    assert pair["median_sampson_px"] < 0.2
    assert pair["motion"]["kind"] == "lateral"


def test_text_output(capsys):
    assert main(["check", str(SAMPLE), "--pair", "0"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("pair 0: ok: median Sampson distance")


def test_one_degree_yaw_of_the_true_mount_is_reported_and_explained(tmp_path, capsys):
    rec = record_pair(tmp_path / "yaw.mcap", LATERAL, YAW_1DEG)
    pair = run_json(capsys, rec)["pairs"][0]
    assert pair["verdict"] == "miscalibrated"
    assert pair["correction"]["rotation_deg"][1] == pytest.approx(1.0, abs=0.15)
    assert any("further right" in s for s in pair["correction"]["description"])
    assert main(["check", str(rec)]) == 0
    text = capsys.readouterr().out
    assert "pair 0: miscalibrated" in text and "further right than the mount says" in text


def test_five_millimetres_of_the_true_mount_on_a_tilted_pair(tmp_path, capsys):
    rec = record_pair(tmp_path / "fwd.mcap", TILTED, FORWARD_5MM)
    pair = run_json(capsys, rec)["pairs"][0]
    assert pair["verdict"] == "miscalibrated"
    assert pair["median_sampson_px"] > 1.0
    assert pair["correction"]["translation_mm"][2] == pytest.approx(5.0, abs=1.0)


@pytest.mark.parametrize("args, code, text", [
    (["nothere.mcap"], 2, "no such file"),
    ([str(SAMPLE), "--pair", "7"], 2, "--pair 7 is not in"),
    ([str(SAMPLE), "--pair", "x"], 2, "pair number"),
    ([str(SAMPLE), "--threshold", "0"], 2, "--threshold"),
])
def test_bad_input_is_one_line_with_an_exit_code(capsys, args, code, text):
    assert main(["check", *args]) == code
    err = capsys.readouterr().err.strip()
    assert text in err and "\n" not in err and err.startswith("armstereo check: error:")


def test_a_file_that_is_not_a_recording_exits_5(tmp_path, capsys):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file")
    assert main(["check", str(bad)]) == 5
    assert "not an MCAP file" in capsys.readouterr().err


def test_check_warns_when_the_mock_shot_the_two_views_at_different_exposures(tmp_path, capsys):
    """The realistic mock changes exposure and white balance between views (as a camera left
    in auto does) and says so per frame; the ideal one reports nothing, so check is silent."""
    for profile in ("realistic", "ideal"):
        out = tmp_path / f"{profile}.mcap"
        assert main(["-q", "capture", "--mock-profile", profile, "--out", str(out)]) == 0
        capsys.readouterr()
        settings = run_json(capsys, out)["pairs"][0]["camera_settings"]
        if profile == "ideal":
            assert settings == {"left": None, "right": None, "differences": [], "warnings": []}
            continue
        assert set(settings["left"]) == {"exposure", "balance_ratio"}
        assert [d["what"] for d in settings["differences"]] == ["brightness", "white balance"]
        assert any("differ in brightness" in w for w in settings["warnings"])
        assert main(["check", str(out)]) == 0
        assert "warning: views 0 and 1: the two views differ in" in capsys.readouterr().out
