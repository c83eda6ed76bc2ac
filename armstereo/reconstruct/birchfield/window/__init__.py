"""The default route: the scanline programme on window-summed costs with slant steps, 8 rows at a
time in SIMD lanes (:mod:`.aggregate` -> :mod:`.blocks` -> :mod:`.fused` / :mod:`.lanes`)."""
