"""What every route of the matcher shares: cost, pixel states and constants, one row's set-up
and decoding, ``njit`` and inline ``min``/``max``."""
