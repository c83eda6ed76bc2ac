"""Helpers shared by the tests: paths to test data, random geometry, synthetic images."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]  # the repository
DATA = ROOT / "tests" / "data"
MIDDLEBURY = DATA / "middlebury"
SAMPLE_RECORDING = ROOT / "recordings" / "sample.mcap"
