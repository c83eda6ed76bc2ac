"""Hostile bytes never crash the bag reader: damaged MCAP and sqlite3 storage and metadata.yaml
end in an ArmstereoError (one line on the command line) or a usable import, nothing else.

Seeded: the same damage every run, so a failure reproduces (print the case to replay it)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from armstereo.errors import ArmstereoError
from armstereo.ros2.importer import ImportOptions, import_bag
from tests.armstereo.ros2 import tiny as T
from tests.support.ros2_bags import as_sqlite3_bag

# mcap: chunks with CRCs (damage mostly fails a checksum); plain: no CRC, no compression (damage
# reaches the CDR decoder and the message checks); db3: the sqlite3 file; yaml: metadata.yaml.
CASES = {"mcap": 40, "plain": 80, "db3": 30, "yaml": 20}


def damage(data: bytes, rng: np.random.Generator) -> bytes:
    """One random kind of damage: flipped bytes, an overwritten span, a cut, a repeat."""
    b = bytearray(data)
    kind = rng.integers(4)
    if kind == 0:
        for i in rng.integers(0, len(b), rng.integers(1, 9)):
            b[i] ^= 1 << int(rng.integers(8))
    elif kind == 1:
        start = int(rng.integers(0, len(b)))
        span = rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8).tobytes()
        b[start:start + len(span)] = span
    elif kind == 2:
        del b[int(rng.integers(0, len(b))):]
    else:
        start = int(rng.integers(0, len(b)))
        b[start:start] = b[start:start + int(rng.integers(1, 200))]
    return bytes(b)


def _try(bag, out) -> str:
    try:
        import_bag(bag, out, ImportOptions(image_topic=T.IMAGE))
    except ArmstereoError as err:
        assert "\n" not in str(err)
        return type(err).__name__
    return "ok"


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    folder = tmp_path_factory.mktemp("clean")
    mcap = T.tiny().write(folder / "tiny.mcap")
    plain = T.tiny().write(folder / "plain.mcap", plain=True)
    db = as_sqlite3_bag(mcap, folder / "tiny_db")
    return {"mcap": mcap, "plain": plain, "db3": db, "yaml": db}


@pytest.mark.parametrize("target", list(CASES))
@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # numpy formatting absurd numbers
def test_damaged_bags_end_in_one_line_errors(clean, tmp_path, target):
    rng = np.random.default_rng(list(b"ros2" + target.encode()))
    outcomes: dict[str, int] = {}
    for case in range(CASES[target]):
        out = tmp_path / f"rec{case}.mcap"
        if target in ("mcap", "plain"):
            bag = tmp_path / f"{case}.mcap"
            bag.write_bytes(damage(clean[target].read_bytes(), rng))
        else:
            bag = tmp_path / f"bag{case}"
            shutil.copytree(clean[target], bag)
            victim = next(bag.glob("*.db3")) if target == "db3" else bag / "metadata.yaml"
            victim.write_bytes(damage(victim.read_bytes(), rng))
        try:
            kind = _try(bag, out)
        except Exception as err:  # noqa: BLE001 - this is what the test is about
            pytest.fail(f"{target} case {case}: {type(err).__name__}: {err}")
        outcomes[kind] = outcomes.get(kind, 0) + 1
    assert sum(outcomes.values()) == CASES[target]
    assert set(outcomes) - {"ok"}, outcomes  # the damage did reach the reader


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_damaged_recordings_export_or_end_in_one_line_errors(tmp_path):
    """The export's reader (armstereo's recording reader, then mcap's) on damaged captures."""
    from armstereo.ros2.export import export_recording
    from tests.support import SAMPLE_RECORDING

    data = SAMPLE_RECORDING.read_bytes()
    rng = np.random.default_rng(list(b"export"))
    for case in range(20):
        src = tmp_path / f"{case}.mcap"
        src.write_bytes(damage(data, rng))
        try:
            export_recording(src, tmp_path / f"bag{case}")
        except ArmstereoError as err:
            assert "\n" not in str(err)
        except Exception as err:  # noqa: BLE001
            pytest.fail(f"export case {case}: {type(err).__name__}: {err}")
