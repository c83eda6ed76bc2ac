"""The GenTL producer the tests run against: ``viky.cti``, which the ``genicam`` package (a
test dependency) ships. It simulates three cameras (serials 0, 1, 2: a red, a green and a
blue bouncing ball on white), 100..800 x 100..800 pixels, RGBa8 or Mono8, streaming freely
at AcquisitionFrameRate (20 Hz): no exposure, gain, white balance, gamma or trigger features,
no buffer time stamps (docs/cameras.md)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def viky() -> str:
    import genicam

    path = Path(genicam.__file__).parent / "viky.cti"
    assert path.is_file(), f"the genicam package ships no viky.cti at {path}"
    return str(path)
