"""Numba kernels of the Birchfield-Tomasi matcher, grouped by the route a call takes; the
public API is :mod:`armstereo.reconstruct.stereo` (``birchfield()``, ``BirchfieldOptions``).

Which kernels a call runs (``armstereo.reconstruct.stereo._match`` picks the route):

- the default, and every grey ``search="exact"`` call (any ``cost_window``, with or without
  ``slant_penalty``; ``BirchfieldOptions.paper()`` too, on a 1x1 window): :mod:`.window`,
  :func:`.window.aggregate.match_image_aggregated` -> :func:`.window.blocks.block_setup` (every
  block's geometry, penalties and rewards) -> :func:`.window.fused.lane_forward_column` (the
  forward pass of one-column windows; :func:`.window.lanes.lane_forward` for wider ones) ->
  :func:`.window.lanes.lane_backtrack`: 8 rows per block in SIMD lanes (:mod:`.window.simd`);
- ``column_smoothing=(p1, p2)``: :mod:`.columns`, :func:`.columns.vertical.match_image_vertical`
  on the one-row kernels of :mod:`.columns.rows`;
- colour costs on a colour pair (``color="sum"``/``"max"``) or ``search="pruned"``: the paper's
  reference solvers, :mod:`.paper`: :func:`.paper.matcher.match_image` ->
  :func:`.paper.dp_exact.scanline_dp_exact` (exact) or :func:`.paper.dp_pruned.scanline_dp`
  (the reference code's pruned search; unpruned, the tests' oracle);
- ``postprocess="paper"``, after any route: :func:`.paper.postprocess.postprocess`.

Shared by every route (:mod:`.common`): the sampling-insensitive dissimilarity and the
intensity-variation flags (:mod:`.common.cost`), the pixel states and the programme's constants
(:mod:`.common.states`), one row's valid runs, geometry and decoding (:mod:`.common.scanline`),
``njit`` with its cache fallback (:mod:`.common.jit`) and inline ``min``/``max``
(:mod:`.common.minmax`). After matching, :mod:`.refine` holds the kernels of the sub-pixel
steps, the left-right check and the row test of flat and hidden pixels.

Everything here works in *doubled integer units* like Birchfield's reference code (twice each
intensity, sums of neighbour pairs instead of half-sums), so costs are exact integers.
"""
