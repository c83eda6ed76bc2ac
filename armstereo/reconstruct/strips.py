"""Row strips of an image processed side by side on a few threads.

The steps before and after matching are mostly row-local (a window a few rows high at most):
each strip of rows reads the rows its windows reach beyond it (a halo) and writes only its
own rows, so strips can run at the same time and give the same map as one pass over the
image. OpenCV and most numpy operations on whole rows release the GIL, so Python threads are
enough, but only while each call has real work: a step made of dozens of small calls keeps
the threads waiting on each other between them (such a step is better one kernel, as the
consensus median's counts are). The threads live for one call, like the matcher's.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext

MIN_STRIP_ROWS = 32  # fewer rows per strip: the thread hand-offs cost more than they save


def row_strips(height: int, threads: int) -> list[tuple[int, int]]:
    """Up to ``threads`` strips ``(first, stop)`` of about equal height covering ``0 ..
    height - 1``, each at least MIN_STRIP_ROWS high (one strip when the image is lower)."""
    n = max(1, min(threads, height // MIN_STRIP_ROWS))
    cuts = [round(i * height / n) for i in range(n + 1)]
    return list(zip(cuts[:-1], cuts[1:], strict=True))


def each_strip(pool: ThreadPoolExecutor | None, strips: list[tuple[int, int]],
               func: Callable, *args) -> list:
    """``[func(first, stop, *args) for each strip]``: the first strip on the calling thread,
    the others on ``pool``'s (the strips must write disjoint rows)."""
    if pool is None or len(strips) == 1:
        return [func(first, stop, *args) for first, stop in strips]
    jobs = [pool.submit(func, first, stop, *args) for first, stop in strips[1:]]
    return [func(*strips[0], *args)] + [job.result() for job in jobs]


def thread_pool(threads: int):
    """Context manager: a pool of ``threads - 1`` threads for :func:`each_strip` (the calling
    thread is the other one) and the matcher, or None for one thread. One pool serves a whole
    call: starting a thread costs about 0.1 ms."""
    return ThreadPoolExecutor(threads - 1) if threads > 1 else nullcontext()
