"""The forward pass of :mod:`.lanes` for one-column windows, each step one loop in registers.

:func:`.lanes.lane_forward` computes a right pixel's node costs in passes over the disparity
indices ``k`` (BT dissimilarities of every row into a scratch array, the window's vertical
sums, the mask), then runs the programme's step in another pass. Each pass stores what the
next one loads, and the step's running minimum over ``k`` lives in memory (numba's arrays may
alias, so LLVM keeps it there): about 110 instructions per node of 8 lanes
(bench/results/dp_lanes.md). Here one loop over ``k``, written as LLVM IR, does all of it per
node: the BT vectors of the block's rows, their window sums by shifting across the two
vectors (no store and reload), the division and mask, the node cost's store for the
backtrack, and the step, with the running minimum in a register.

The operations and their order per lane are those of :mod:`.lanes` (same float32 results, bit
for bit: the sums are of integers below float32's exact range, and every ``min``/``max`` is
the same comparison and select), so the paths are the same. Used for windows one column wide
with 1 or 3 rows (``rx == 0``, ``ry <= 1``: the default ``(1, 3)`` and the paper's
``(1, 1)``); wider windows keep :func:`.lanes.lane_forward`, which compiles only when used.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

from armstereo.reconstruct.birchfield.common.cost import INF
from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.minmax import max2, min2
from armstereo.reconstruct.birchfield.window.lanes import ACTIVE, R0, U1, X0, start_lane
from armstereo.reconstruct.birchfield.window.simd import LANES, vfloor, vmax, vmin

FUSED_MAX_RY = 1  # window rows 2 ry + 1 handled here (one intrinsic pair per ry is compiled)

_F32 = ir.FloatType()
_VEC = ir.VectorType(_F32, LANES)
_I32 = ir.IntType(32)


@njit(cache=True, nogil=True, fastmath=True)
def lane_forward_column(row0, ry, dmin, q, geo, x_begin, x_end, pen_l, rew, pen_r, slant,
                        costs, phi, rbest, run):
    """:func:`.lanes.lane_forward` for ``rx == 0``, ``0 <= ry <= FUSED_MAX_RY`` and
    ``dmin >= 0``: same arguments (less ``rx``), same results."""
    nd = phi.shape[1] - 2
    inf = np.float32(INF)
    bounds, col, lims, ring, d = costs
    for lane in range(LANES):  # float32 copies, for comparing in float32 vectors
        lims[0, lane] = geo[X0, lane]
        lims[1, lane] = geo[U1, lane]
    iq = np.float32(1.0 / q)
    divided = np.int64(q != 1)
    arrays = (bounds, phi, pen_l, rew, pen_r, rbest, d, lims)
    if ry == 0:
        _costs_ry0(arrays, (x_begin, row0, dmin, divided), (slant, iq))
    else:
        _costs_ry1(arrays, (x_begin, row0, dmin, divided), (slant, iq))
    for u in range(x_begin, x_end + nd):
        for lane in range(LANES):
            rbest[u, lane] = inf
    first, last = x_end, x_begin - 1  # the right pixels where some lane starts
    for lane in range(LANES):
        if geo[ACTIVE, lane]:
            first = min2(first, geo[R0, lane])
            last = max2(last, geo[R0, lane])
    for x in range(x_begin, x_end):
        if first <= x <= last:
            for lane in range(LANES):
                if geo[ACTIVE, lane] and geo[R0, lane] == x:
                    start_lane(d[x], lane, phi[x], phi[x + 1], rbest[x:x + nd])
        if x + 1 < x_end:
            if ry == 0:
                _step_ry0(arrays, (x + 1, row0, dmin, divided), (slant, iq))
            else:
                _step_ry1(arrays, (x + 1, row0, dmin, divided), (slant, iq))


def _column_kernel(ry: int, step: bool):
    """Intrinsic ``f(arrays, ints, floats)``: node costs of right pixel ``xc`` into
    ``d[xc]`` (window of ``2 ry + 1`` rows, one column) and, if ``step``, the programme's
    step into ``phi[xc + 1]`` (:func:`.lanes._node_costs` then :func:`.lanes._step`).

    ``arrays``: ``(bounds, phi, pen_l, rew, pen_r, rbest, d, lims)`` as :mod:`.lanes` names
    them (C-contiguous float32); ``ints``: ``(xc, j0, dmin, divided)`` (``j0``: the block's
    first column in ``bounds``; ``divided``: costs are divided by ``q``); ``floats``:
    ``(slant, 1 / q)``. Indices are not checked (the caller's geometry bounds them)."""
    nv = -(-(LANES + 2 * ry) // LANES)  # BT vectors per node: the block's rows and window

    def typer(typingctx, arrays, ints, floats):
        ok = (isinstance(arrays, types.BaseTuple) and len(arrays) == 8
              and all(isinstance(t, types.Array) and t.dtype == types.float32
                      and t.layout == "C" for t in arrays)
              and isinstance(ints, types.BaseTuple) and len(ints) == 4
              and all(isinstance(t, types.Integer) for t in ints)
              and isinstance(floats, types.BaseTuple) and len(floats) == 2
              and all(t == types.float32 for t in floats))
        if not ok:
            raise TypeError(f"fused column step: bad arguments {arrays}, {ints}, {floats}")

        def codegen(context, b, sig, args):
            _emit(context, b, sig, args, ry, nv, step)
            return context.get_dummy_value()

        return types.none(arrays, ints, floats), codegen

    typer.__name__ = f"_{'step' if step else 'costs'}_ry{ry}"
    return intrinsic(typer)


def _emit(context, b, sig, args, ry, nv, step):
    """The IR of one :func:`_column_kernel` call (see there)."""
    arr_types, int_types, _ = sig.args
    arrs = [context.make_array(t)(context, b, b.extract_value(args[0], i))
            for i, t in enumerate(arr_types)]
    intp = context.get_value_type(types.intp)
    xc, j0, dmin, divided = (context.cast(b, b.extract_value(args[1], i), t, types.intp)
                             for i, t in enumerate(int_types))
    slant, iq = (_splat(b, b.extract_value(args[2], i)) for i in range(2))
    bounds, phi, pen_l, rew, pen_r, rbest, d, lims = range(8)

    def ptr(i, *idx):
        a, t = arrs[i], arr_types[i]
        idx = [v if isinstance(v, ir.Value) else ir.Constant(intp, v) for v in idx]
        p = cgutils.get_item_pointer2(context, b, a.data, cgutils.unpack_tuple(b, a.shape),
                                      cgutils.unpack_tuple(b, a.strides), t.layout, idx,
                                      wraparound=False)
        return b.bitcast(p, _VEC.as_pointer())

    def load(p):
        return b.load(p, align=4)

    def rows(i, u):  # the nv vectors of the block's rows at bounds[i, u]
        return [load(ptr(bounds, i, u, b.add(j0, ir.Constant(intp, LANES * h))))
                for h in range(nv)]

    zero = ir.Constant(_VEC, [0.0] * LANES)
    inf = ir.Constant(_VEC, [float(INF)] * LANES)
    last = b.sub(cgutils.unpack_tuple(b, arrs[bounds].shape)[1], ir.Constant(intp, 1))
    rv, rmin, rmax = rows(3, xc), rows(4, xc), rows(5, xc)
    x0, u1 = load(ptr(lims, 0, 0)), load(ptr(lims, 1, 0))
    is_divided = b.icmp_signed("!=", divided, ir.Constant(intp, 0))
    u_f = cgutils.alloca_once_value(b, _splat(b, b.sitofp(xc, _F32)))  # float32(xc + k)
    if step:
        xp = b.sub(xc, ir.Constant(intp, 1))
        pr = load(ptr(pen_r, xp, 0))
        run = cgutils.alloca_once_value(b, inf)  # promoted to a register by LLVM
    nd = cgutils.unpack_tuple(b, arrs[d].shape)[1]
    with cgutils.for_range(b, nd, intp=intp) as loop:
        k = loop.index
        u = b.add(b.add(xc, dmin), k)
        u = b.select(b.icmp_signed("<", last, u), last, u)  # min2(W - 1, xc + dmin + k)
        lv, lmin, lmax = rows(0, u), rows(1, u), rows(2, u)
        bt = []
        for h in range(nv):  # lanes._bt
            d_l = vmax(b, zero, vmax(b, b.fsub(lv[h], rmax[h]), b.fsub(rmin[h], lv[h])))
            d_r = vmax(b, zero, vmax(b, b.fsub(rv[h], lmax[h]), b.fsub(lmin[h], rv[h])))
            bt.append(vmin(b, d_l, d_r))
        cost = bt[0]
        for t in range(1, 2 * ry + 1):  # lanes._vertical_sums: rows t .. t + LANES - 1
            cost = b.fadd(cost, _shifted(b, bt, t))
        before = b.block
        with b.if_then(is_divided):  # lanes._mask_divided (a branch LLVM unswitches)
            divided_cost = vfloor(b, b.fmul(cost, iq))
            after_division = b.block
        merged = b.phi(_VEC)
        merged.add_incoming(divided_cost, after_division)
        merged.add_incoming(cost, before)
        uf = b.load(u_f)
        ok = b.and_(b.fcmp_ordered("<=", x0, uf), b.fcmp_ordered("<", uf, u1))
        dk = b.select(ok, merged, inf)  # lanes._mask
        b.store(dk, ptr(d, xc, k, 0), align=4)
        b.store(b.fadd(uf, ir.Constant(_VEC, [1.0] * LANES)), u_f)
        if step:  # lanes._step, lanes._node_update
            k1, k2 = b.add(k, ir.Constant(intp, 1)), b.add(k, ir.Constant(intp, 2))
            c0, c1 = load(ptr(phi, xc, k, 0)), load(ptr(phi, xc, k1, 0))
            p2 = load(ptr(phi, xp, k2, 0))
            uk = b.add(xc, k)
            pl, rw = load(ptr(pen_l, uk, 0)), load(ptr(rew, uk, 0))
            rb_p = ptr(rbest, b.add(xp, k), 0)
            rb, r = load(rb_p), b.load(run)
            a = b.fadd(r, pl)
            jump = b.fadd(vmin(b, c0, p2), slant)
            best = vmin(b, vmin(b, c1, a), vmin(b, rb, jump))
            b.store(vmin(b, rb, b.fadd(c1, pr)), rb_p, align=4)
            b.store(vmin(b, r, c1), run)
            b.store(vmin(b, b.fsub(b.fadd(best, dk), rw), inf), ptr(phi, b.add(xc, ir.Constant(
                intp, 1)), k1, 0), align=4)


def _splat(b, x):
    """``x`` (float32) in every lane."""
    one = b.insert_element(ir.Constant(_VEC, ir.Undefined), x, ir.Constant(_I32, 0))
    return b.shuffle_vector(one, ir.Constant(_VEC, ir.Undefined),
                            ir.Constant(ir.VectorType(_I32, LANES), [0] * LANES))


def _shifted(b, vecs, t):
    """Rows ``t .. t + LANES - 1`` of the rows held in ``vecs`` (LANES each)."""
    h, s = divmod(t, LANES)
    if s == 0:
        return vecs[h]
    return b.shuffle_vector(vecs[h], vecs[h + 1],
                            ir.Constant(ir.VectorType(_I32, LANES), list(range(s, s + LANES))))


_costs_ry0 = _column_kernel(0, False)
_costs_ry1 = _column_kernel(1, False)
_step_ry0 = _column_kernel(0, True)
_step_ry1 = _column_kernel(1, True)
