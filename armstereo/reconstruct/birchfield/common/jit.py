"""``njit`` for the matcher's kernels: cached on disk where possible, compiled in memory if not.

numba's ``cache=True`` raises "no locator available" when neither the package's
``__pycache__`` nor the user's cache directory (``NUMBA_CACHE_DIR``, ``~/.cache``) is
writable, e.g. a read-only install with a read-only home; importing the matcher (and so every
CLI command) would then fail. This decorator falls back to ``cache=False`` for every kernel
and says so once: the commands still work, each process compiling what it uses.

The first run compiles the kernels (bench/coldstart.py measures it). What makes that slow with
numba, and is avoided on the default path: every array allocation type and every literal
argument value compiles a function of its own (allocate work arrays in Python; pass
``np.int64``/``np.bool_`` rather than bare constants to a kernel), a slice assignment compiles
a generic loop nest (write the loop), and every kernel gets wrappers for calls from Python
(none gets the C-callable one; ``inner=True`` leaves out the CPython one for kernels that
only other kernels call).
"""

from __future__ import annotations

import logging

import numba

log = logging.getLogger(__name__)

_cache_ok: bool | None = None  # None until the first kernel has tried


# A kernel that only other kernels call needs no CPython wrapper (argument unboxing, large
# for many arguments); no kernel needs the C-callable wrapper that numba compiles for every
# function by default (it serves ``cfunc``-style calls, which nothing here makes). Leaving
# them out shortens the first run's compile.
_INNER = dict(no_cpython_wrapper=True)
_NO_CFUNC = dict(no_cfunc_wrapper=True)


def njit(*args, inner: bool = False, **options):
    """``numba.njit`` with ``cache=True`` unless no cache location is writable.

    ``inner=True``: the kernel is called from other kernels only, never from Python.
    """
    options.update(_NO_CFUNC)
    if inner:
        options.update(_INNER)
    if args and callable(args[0]):
        return _compile(args[0], options)
    return lambda func: _compile(func, options)


def _compile(func, options):
    global _cache_ok
    if _cache_ok is not False and options.get("cache", False):
        try:
            dispatcher = numba.njit(**options)(func)
            _cache_ok = True
            return dispatcher
        except RuntimeError as err:  # numba: "cannot cache function ...: no locator available"
            if "no locator available" not in str(err):
                raise
            _cache_ok = False
            log.warning("no writable cache directory for the matcher's compiled kernels (set "
                        "NUMBA_CACHE_DIR to one); compiling them in memory, every run")
    return numba.njit(**dict(options, cache=False))(func)
