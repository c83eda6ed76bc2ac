"""Numba kernels of the Birchfield-Tomasi matcher; the public API is
:mod:`armstereo.reconstruct.stereo`.

Modules, in the order the matcher uses them:

- :mod:`.cost`: the sampling-insensitive dissimilarity and the intensity-variation flags;
- :mod:`.dp_exact`: the scanline dynamic programme over match sequences, solved exactly (the
  default);
- :mod:`.dp_pruned`: the reference code's pruned search of the same programme, its decoding and
  the constants both solvers share;
- :mod:`.matcher`: all rows of an image pair (on threads), masks and disparity window, for
  the paper's single-pixel costs;
- :mod:`.aggregate`: the default matcher on window-summed costs with slant steps: per-row
  geometry, penalties and rewards for the whole image in numpy (:mod:`.blocks`), then
  :mod:`.lanes` (blocks of rows in lockstep, rows as the SIMD axis via :mod:`.simd`;
  :mod:`.fused`: its forward pass as one IR loop per right pixel, for one-column windows);
- :mod:`.minmax`: ``min``/``max`` emitted inline (the builtins compile a function per type
  pair: cold start);
- :mod:`.rows`: the same programme one row at a time, used by :mod:`.vertical` (the
  ``column_smoothing`` option: costs smoothed along the columns first);
- :mod:`.postprocess`: the paper's propagation across scanlines and mode filters;
- :mod:`.refine`: options beyond the paper (subpixel, left-right check).

Everything here works in *doubled integer units* like Birchfield's reference code (twice each
intensity, sums of neighbour pairs instead of half-sums), so costs are exact integers.
"""
