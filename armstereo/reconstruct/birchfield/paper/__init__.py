"""The paper's reference solvers on single-pixel costs: the exact (:mod:`.dp_exact`) and the
pruned (:mod:`.dp_pruned`) programme, their rows (:mod:`.matcher`: colour costs and
``search="pruned"``) and the paper's postprocessing across scanlines (:mod:`.postprocess`)."""
