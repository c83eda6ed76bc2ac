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
from numba.core import cgutils, types
from numba.extending import intrinsic

LANES = 8  # rows per block: one AVX2 register of float32; 16 measured slower (cache)

_VEC = ir.VectorType(ir.FloatType(), LANES)


def vmin(b: ir.IRBuilder, x, y):
    """Lane-wise ``min(x, y)`` as numba compiles it: ``y if y < x else x``."""
    return b.select(b.fcmp_ordered("<", y, x), y, x)


def vmax(b: ir.IRBuilder, x, y):
    """Lane-wise ``max(x, y)`` as numba compiles it: ``y if y > x else x``."""
    return b.select(b.fcmp_ordered(">", y, x), y, x)


def vfloor(b: ir.IRBuilder, x):
    """Lane-wise ``np.floor(x)`` (LLVM's ``floor``, as numba's for a float32)."""
    fn = cgutils.get_or_insert_function(b.module, ir.FunctionType(_VEC, [_VEC]),
                                        f"llvm.floor.v{LANES}f32")
    return b.call(fn, [x])


def lanewise(fn):
    """Intrinsic ``kernel(rows, scalars)`` from ``fn(b, *vectors) -> {index: vector}``.

    ``rows``: a tuple of rows of LANES float32 each, every one either a contiguous float32
    array (its first LANES elements) or a tuple ``(array, i, ..., j)`` of a C-contiguous
    float32 array and one index per dimension (elements ``[i, ..., j .. j + LANES - 1]``,
    indices not checked, not wrapped: a slice would cost more than the work here).
    ``scalars``: a tuple of float32 values. ``fn`` gets the IR builder, then one vector per row
    followed by one broadcast vector per scalar, and returns the new contents of rows by their
    index in ``rows``.
    """
    def typer(typingctx, rows, scalars):
        for t in rows:
            _check_row(t)
        if any(t != types.float32 for t in scalars):
            raise TypeError(f"lanewise scalars must be float32, got {scalars}")

        def codegen(context, b, sig, args):
            row_types, scalar_types = sig.args
            ptrs = [b.bitcast(_row_pointer(context, b, t, b.extract_value(args[0], i)),
                              _VEC.as_pointer()) for i, t in enumerate(row_types)]
            vecs = [b.load(p, align=4) for p in ptrs]
            vecs += [_broadcast(b, b.extract_value(args[1], i)) for i in range(len(scalar_types))]
            for i, v in fn(b, *vecs).items():
                b.store(v, ptrs[i], align=4)
            return context.get_dummy_value()

        return types.none(rows, scalars), codegen

    typer.__name__ = fn.__name__
    return intrinsic(typer)


def _check_row(t) -> None:
    arr = t[0] if isinstance(t, types.BaseTuple) else t
    ok = isinstance(arr, types.Array) and arr.dtype == types.float32 and arr.layout == "C"
    if isinstance(t, types.BaseTuple):
        ok = ok and len(t) == arr.ndim + 1 and all(isinstance(i, types.Integer) for i in t[1:])
    if not ok:
        raise TypeError(f"a lanewise row is a C-contiguous float32 array, or one with an index "
                        f"per dimension; got {t}")


def _row_pointer(context, b, t, value):
    """Pointer to the first float of a row (see :func:`lanewise`)."""
    if not isinstance(t, types.BaseTuple):
        return context.make_array(t)(context, b, value).data
    arr_t = t[0]
    arr = context.make_array(arr_t)(context, b, b.extract_value(value, 0))
    idx = [context.cast(b, b.extract_value(value, i + 1), t[i + 1], types.intp)
           for i in range(arr_t.ndim)]
    return cgutils.get_item_pointer2(context, b, arr.data, cgutils.unpack_tuple(b, arr.shape),
                                     cgutils.unpack_tuple(b, arr.strides), arr_t.layout, idx,
                                     wraparound=False)


def _broadcast(b, x):
    one = b.insert_element(ir.Constant(_VEC, ir.Undefined), x, ir.Constant(ir.IntType(32), 0))
    return b.shuffle_vector(one, ir.Constant(_VEC, ir.Undefined),
                            ir.Constant(ir.VectorType(ir.IntType(32), LANES), [0] * LANES))
