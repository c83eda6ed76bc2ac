"""The command line behaves like a Unix filter: a reader that goes away ends it quietly."""

import subprocess
import sys

import pytest

from tests.support import SAMPLE_RECORDING


@pytest.mark.parametrize("argv", [["inspect", str(SAMPLE_RECORDING), "--json"],
                                  ["capture", "--help"]])
def test_closed_pipe_ends_quietly_with_exit_0(argv):
    proc = subprocess.Popen([sys.executable, "-m", "armstereo", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    # The reader leaves before the first line is written (what `| head -1` does to a command
    # that is still working), so every write meets a closed pipe.
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=60) == 0
    assert err == b""
