"""Numba kernels of the Birchfield-Tomasi matcher; the public API is :mod:`armstereo.stereo`.

Modules, in the order the matcher uses them:

- :mod:`.cost`: the sampling-insensitive dissimilarity and the intensity-variation flags;
- :mod:`.dp`: the scanline dynamic programme over match sequences and its decoding;
- :mod:`.matcher`: all rows of an image pair (on threads), masks and disparity window;
- :mod:`.postprocess`: the paper's propagation across scanlines and mode filters;
- :mod:`.refine`: options beyond the paper (subpixel, left-right check).

Everything here works in *doubled integer units* like Birchfield's reference code (twice each
intensity, sums of neighbour pairs instead of half-sums), so costs are exact integers.
"""
