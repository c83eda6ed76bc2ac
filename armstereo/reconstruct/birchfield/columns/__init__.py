"""``column_smoothing``: the programme's costs smoothed along the columns first (:mod:`.vertical`),
then each row matched by the one-row kernels of :mod:`.rows`."""
