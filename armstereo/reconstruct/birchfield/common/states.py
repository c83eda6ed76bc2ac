"""What every solver shares: the pixel states of a matched row and the programme's constants.

All in the doubled integer units of :mod:`.cost` (twice each intensity).
"""

from __future__ import annotations

from armstereo.reconstruct.birchfield.common.cost import INF

C0 = 600  # reference code's start offset; keeps costs positive, does not change the optimum
NO_VARIATION_PENALTY = 1000  # doubled units, as in the reference code: effectively forbids

# The state of each left pixel after matching (uint8 maps)
MATCHED = 0  # left pixel matched
OCCLUDED = 1  # left pixel skipped by a left occlusion (seen only in the left image)
BORDER = 2  # valid left pixel without a possible partner (outside the window or the other view)
INVALID = 3  # left pixel outside its validity mask

# The float32 solvers' exactness (paper/dp_exact.py, the window path, the column pass)
VALID_BELOW = INF // 2  # real path costs stay far below this; sums involving INF stay above
EXACT_BELOW = 1 << 24  # float32 holds every integer below this exactly
MAX_PIXEL_COST = 510  # doubled units: the largest dissimilarity of one channel
