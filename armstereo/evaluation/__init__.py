"""Scoring against ground truth: disparity maps (Middlebury style), depth maps (the mock
camera's exact depth) and scene geometry (the mock scene's exact primitives)."""
