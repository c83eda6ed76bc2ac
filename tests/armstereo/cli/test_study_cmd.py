"""armstereo study epipolar: files, repeatability, option errors."""

from __future__ import annotations

import csv

import pytest

from armstereo.cli.main import main


def test_small_study_writes_markdown_csv_and_plot(tmp_path, capsys):
    assert main(["study", "epipolar", "--trials", "1", "--points", "40",
                 "--out", str(tmp_path)]) == 0
    assert "study.md" in capsys.readouterr().out
    rows = list(csv.DictReader(open(tmp_path / "study.csv")))
    assert len(rows) == 2 * 4 * 2 * 7  # scenes x motions x noise levels x methods
    assert {r["method"] for r in rows} == {"8point", "ransac", "lmeds", "mlesac", "mapsac",
                                           "magsac", "gold"}
    assert (tmp_path / "study.png").read_bytes()[:4] == b"\x89PNG"
    assert "## mean truth error, noise 0.5 px" in (tmp_path / "study.md").read_text()


@pytest.mark.parametrize("args, text", [
    (["--noise", "-1"], "--noise"),
    (["--trials", "0"], "--trials"),
    (["--outliers", "0.95"], "--outliers"),
    (["--points", "5"], "--points"),
])
def test_bad_options_exit_2(tmp_path, capsys, args, text):
    assert main(["study", "epipolar", *args, "--out", str(tmp_path)]) == 2
    assert text in capsys.readouterr().err


def test_unknown_study_is_an_argparse_error(capsys):
    assert main(["study", "sweep"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "invalid choice: 'sweep'" in err[0]
