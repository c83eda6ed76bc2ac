"""Two-argument ``min``/``max`` for the kernels, emitted in place: no function of their own.

numba implements the builtins ``min`` and ``max`` as overloads: each pair of argument types a
kernel uses (``int64, int64``, ``Literal[int](0), int64``, ``float32, float32`` ...) compiles a
small function of its own, through numba's whole pipeline and LLVM's, which the first run
pays for (bench/results/coldstart.md). :func:`min2`/:func:`max2` are intrinsics instead: their
IR goes straight into the calling kernel. They compute what the builtins compute for two
arguments: both cast to the unified type, then ``y if y < x else x`` (``y if y > x else
x``), so results are bit for bit the same.
"""

from __future__ import annotations

import operator

from numba.core import types
from numba.core.errors import TypingError
from numba.core.typing import signature
from numba.extending import intrinsic


def _minmax(cmp):
    def typer(typingctx, x, y):
        if not all(isinstance(t, (types.Number, types.Boolean)) for t in (x, y)):
            raise TypingError(f"min2/max2 take two numbers, got {x}, {y}")
        ty = typingctx.unify_types(x, y)
        if ty is None:
            raise TypingError(f"min2/max2: {x} and {y} have no common type")

        def codegen(context, builder, sig, args):
            (tx, ty_), (vx, vy) = sig.args, args
            rt = sig.return_type
            vx = context.cast(builder, vx, tx, rt)
            vy = context.cast(builder, vy, ty_, rt)
            pred = context.get_function(cmp, signature(types.boolean, rt, rt))(builder,
                                                                               (vy, vx))
            return builder.select(pred, vy, vx)

        return signature(ty, x, y), codegen

    return typer


def _named(typer, name: str):
    typer.__name__ = name
    return intrinsic(typer)


min2 = _named(_minmax(operator.lt), "min2")
min2.__doc__ = "``min(x, y)`` of two numbers, as numba's builtin computes it (module doc)."
max2 = _named(_minmax(operator.gt), "max2")
max2.__doc__ = "``max(x, y)`` of two numbers, as numba's builtin computes it (module doc)."
