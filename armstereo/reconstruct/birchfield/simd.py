"""Explicit SIMD over the :data:`LANES` rows of a block, for the kernels of :mod:`.lanes`.

LLVM vectorises a loop over the lanes only where it can prove that the arrays written do not
overlap the arrays read; numba's arrays carry no such information, so a loop of 16 lanes is
unrolled into scalar code, or vectorised behind run-time overlap checks that cost as much as
the work. :func:`lanewise` instead turns a function of whole vectors into a numba intrinsic:
every array argument is loaded as one ``<LANES x float>`` vector, scalars are broadcast, and
the results are stored back, with exactly the scalar code's float32 operations per lane (the
same results, bit for bit: :func:`vmin` is the comparison-and-select of numba's ``min``, and
additions are plain IEEE additions).
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

LANES = 16  # rows per block: one AVX-512 register of float32 (two AVX2 ones)

_VEC = ir.VectorType(ir.FloatType(), LANES)


def vmin(b: ir.IRBuilder, x, y):
    """Lane-wise ``min(x, y)`` as numba compiles it: ``y if y < x else x``."""
    return b.select(b.fcmp_ordered("<", y, x), y, x)


def vmax(b: ir.IRBuilder, x, y):
    """Lane-wise ``max(x, y)`` as numba compiles it: ``y if y > x else x``."""
    return b.select(b.fcmp_ordered(">", y, x), y, x)


def lanewise(fn):
    """Intrinsic ``kernel(rows, scalars)`` from ``fn(b, *vectors) -> {index: vector}``.

    ``rows``: a tuple of 1-D contiguous float32 arrays of at least LANES elements (lanes
    ``0 .. LANES - 1`` from the first); ``scalars``: a tuple of float32 values. ``fn`` gets
    the IR builder, then one vector per row followed by one broadcast vector per scalar, and
    returns the new contents of rows by their index in ``rows``.
    """
    def typer(typingctx, rows, scalars):
        for t in rows:
            if not (isinstance(t, types.Array) and t.ndim == 1 and t.layout == "C"
                    and t.dtype == types.float32):
                raise TypeError(f"lanewise rows must be 1-D contiguous float32, got {t}")
        if any(t != types.float32 for t in scalars):
            raise TypeError(f"lanewise scalars must be float32, got {scalars}")

        def codegen(context, b, sig, args):
            row_types, scalar_types = sig.args
            ptrs = []
            for i, t in enumerate(row_types):
                arr = context.make_array(t)(context, b, b.extract_value(args[0], i))
                ptrs.append(b.bitcast(arr.data, _VEC.as_pointer()))
            vecs = [b.load(p, align=4) for p in ptrs]
            for i in range(len(scalar_types)):
                one = b.insert_element(ir.Constant(_VEC, ir.Undefined),
                                       b.extract_value(args[1], i), ir.Constant(ir.IntType(32), 0))
                vecs.append(b.shuffle_vector(one, ir.Constant(_VEC, ir.Undefined),
                                             ir.Constant(ir.VectorType(ir.IntType(32), LANES),
                                                         [0] * LANES)))
            for i, v in fn(b, *vecs).items():
                b.store(v, ptrs[i], align=4)
            return context.get_dummy_value()

        return types.none(rows, scalars), codegen

    typer.__name__ = fn.__name__
    return intrinsic(typer)
