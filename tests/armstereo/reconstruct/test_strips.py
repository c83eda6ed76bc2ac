"""Row strips: they cover the image once, in order, and run on the pool's threads."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import pytest

from armstereo.reconstruct.strips import MIN_STRIP_ROWS, each_strip, row_strips, thread_pool


@pytest.mark.parametrize("height", [1, MIN_STRIP_ROWS - 1, MIN_STRIP_ROWS * 2, 288, 481])
@pytest.mark.parametrize("threads", [1, 2, 3, 8])
def test_strips_cover_the_rows_once(height, threads):
    strips = row_strips(height, threads)
    assert strips[0][0] == 0 and strips[-1][1] == height
    assert all(b == c for (_, b), (c, _) in zip(strips[:-1], strips[1:], strict=True))
    assert 1 <= len(strips) <= threads
    assert len(strips) == 1 or min(b - a for a, b in strips) >= MIN_STRIP_ROWS


def test_each_strip_returns_in_strip_order_and_uses_the_pool():
    strips = row_strips(200, 4)
    names = {}

    def job(first, stop, scale):
        names[first] = threading.current_thread().name
        return scale * first + stop

    with thread_pool(len(strips)) as pool:
        assert isinstance(pool, ThreadPoolExecutor)
        got = each_strip(pool, strips, job, 10)
    assert got == [10 * a + b for a, b in strips]
    assert names[0] == threading.current_thread().name  # the first strip: the caller's
    assert {names[a] for a, _ in strips[1:]} != {threading.current_thread().name}


def test_one_strip_needs_no_pool():
    strips = row_strips(20, 4)
    with thread_pool(len(strips)) as pool:
        assert pool is None
        assert each_strip(pool, strips, lambda a, b: (a, b)) == [(0, 20)]
