"""Compile the matcher ahead of time, in another process, while something else runs.

The Birchfield-Tomasi matcher is numba code cached on disk (``cache=True``): the first run
after a fresh install compiles it, which takes several seconds of one core; every later run
loads it from the cache in a fraction of a second. A command that has other work to do first
(the demo calibrates the camera before it matches) can start :func:`start` at the beginning:
a child process matches a small synthetic pair of the same types, which compiles and caches
the same code on the other core, and :func:`wait` before the first real match lets the cache
be read instead of compiled again. Nothing depends on it: if the child fails or is slow, the
match compiles as it always did.

Run as ``python -m armstereo.reconstruct.warmup [OPTIONS_JSON]``.
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys

import numpy as np

log = logging.getLogger(__name__)

WAIT_TIMEOUT_S = 60.0  # never wait longer than compiling in-process would take


def warm_up(options: dict | None = None) -> None:
    """Match a 160 x 120 BGR pair (same types as a rectified recording) with ``options``."""
    from armstereo.reconstruct.stereo import compute_disparity

    rng = np.random.default_rng(0)
    base = rng.integers(0, 256, (120, 176, 3)).astype(np.uint8)
    left, right = base[:, 16:].copy(), base[:, 8:-8].copy()  # right = left shifted by 8 px
    mask = np.ones(left.shape[:2], dtype=bool)
    compute_disparity(left, right, 16, method="birchfield", min_disparity=0, left_mask=mask,
                      right_mask=mask, **(options or {}))


def start(method: str, options: dict | None = None) -> subprocess.Popen | None:
    """Start compiling the matcher of ``method`` in a child process (None for a matcher
    without compiled code, or when the child cannot start)."""
    if method != "birchfield":
        return None
    try:
        return subprocess.Popen([sys.executable, "-m", "armstereo.reconstruct.warmup",
                                 json.dumps(options or {})], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                env=dict(os.environ))
    except OSError as err:  # no second process: compile in-process as usual
        log.debug("matcher warm-up not started: %s", err)
        return None


def wait(child: subprocess.Popen | None) -> None:
    """Wait until the child has compiled (or give up after WAIT_TIMEOUT_S and stop it)."""
    if child is None:
        return
    try:
        child.wait(timeout=WAIT_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        child.kill()
        child.wait()


if __name__ == "__main__":  # pragma: no cover - the child process
    warm_up(json.loads(sys.argv[1]) if len(sys.argv) > 1 else None)
