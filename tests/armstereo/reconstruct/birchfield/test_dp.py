"""The scanline dynamic programme (docs/birchfield-tomasi.md §4-5; oracles §10.2).

The oracle enumerates every match sequence of tiny scanlines and prices each one from the
model's definition (one occlusion penalty per disparity jump, a reward per match, occlusions
only next to an intensity variation, start at right pixel 0, end at the last left pixel).
"""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.reconstruct.birchfield.common.cost import (
    INF,
    dissimilarity_table,
    row_bounds,
    variation_flags,
)
from armstereo.reconstruct.birchfield.common.scanline import decode_matches
from armstereo.reconstruct.birchfield.common.states import (
    BORDER,
    C0,
    MATCHED,
    NO_VARIATION_PENALTY,
    OCCLUDED,
)
from armstereo.reconstruct.birchfield.paper.dp_exact import scanline_dp_exact
from armstereo.reconstruct.birchfield.paper.dp_pruned import scanline_dp

OCC, REW = 50, 10  # doubled units: the paper's 25 and 5


class Scanline:
    """A left/right row pair with everything the programmes need (window 0 .. nd - 1)."""

    def __init__(self, left, right, nd, occ=OCC):
        self.occ = occ
        self.left = np.asarray(left, np.uint8)
        self.right = np.asarray(right, np.uint8)
        self.n = len(left)
        self.nd = nd
        self.lb = row_bounds(self.left)
        self.rb = row_bounds(self.right)
        self.gl = np.zeros(self.n, np.bool_)
        self.gr = np.zeros(self.n, np.bool_)
        variation_flags(self.left[:, None], 0, self.n, 0, self.n, 5, True, self.gl, 0)
        variation_flags(self.right[:, None], 0, self.n, 0, self.n, 5, False, self.gr, 0)
        self.dis = np.empty((self.n, nd), np.int32)
        dissimilarity_table(*self.lb, *self.rb, 0, False, self.dis)

    def exact(self):
        match = np.empty(self.n, np.int32)
        phi = np.empty((self.n, self.nd), np.float32)
        cost = scanline_dp_exact(*self.lb, *self.rb, 0, False, self.gl, self.gr, self.occ, REW, phi,
                                 match)
        return cost, match

    def search(self, prune):
        match = np.empty(self.n, np.int32)
        cost = scanline_dp(self.dis, self.gl, self.gr, self.occ, REW, prune,
                           np.empty((self.n, self.nd), np.int32),
                           np.empty((self.n, self.nd), np.int16), match)
        return cost, match

    def d(self, xl, xr):
        return int(self.dis[xr, xl - xr])

    def sequence_cost(self, seq):
        """Price a match sequence [(xL, xR), ...] from the model; None if it is not one."""
        if not seq or seq[0][1] != 0 or seq[-1][0] != self.n - 1:
            return None
        cost = C0 + self.d(*seq[0])
        for (xl0, xr0), (xl1, xr1) in zip(seq, seq[1:], strict=False):
            if xl1 <= xl0 or xr1 <= xr0 or not 0 <= xl1 - xr1 < self.nd:
                return None
            if xl1 == xl0 + 1 and xr1 == xr0 + 1:
                step = 0
            elif xr1 == xr0 + 1:  # left pixels skipped: a left occlusion
                step = self.occ + (0 if self.gl[xl1] else NO_VARIATION_PENALTY)
            elif xl1 == xl0 + 1:  # right pixels skipped: a right occlusion
                step = self.occ + (0 if self.gr[xr0] else NO_VARIATION_PENALTY)
            else:
                return None  # both skip: not a match sequence of the model
            cost += step + self.d(xl1, xr1) - REW
        return cost

    def brute_force(self):
        """Least cost over all match sequences (exhaustive)."""
        best = INF

        def grow(seq):
            nonlocal best
            cost = self.sequence_cost(seq)
            if cost is not None:
                best = min(best, cost)
            xl, xr = seq[-1]
            for xl1 in range(xl + 1, self.n):
                for xr1 in range(xr + 1, xl1 + 1):
                    if xl1 - xr1 < self.nd and (xl1 == xl + 1 or xr1 == xr + 1):
                        grow(seq + [(xl1, xr1)])

        for k in range(min(self.nd, self.n)):
            grow([(k, 0)])
        return best


def sequence_of(match):
    return [(x, int(y)) for x, y in enumerate(match) if y >= 0]


def _tiny_scanlines(count):
    """Random tiny two-plane pairs (a foreground run in front of a background), strong texture;
    a low occlusion penalty for half of them so that occlusions are common."""
    rng = np.random.default_rng(1234)
    for i in range(count):
        n = int(rng.integers(5, 9))
        nd = int(rng.integers(2, 5))  # disparities 0 .. nd - 1 <= 3
        d_bg, d_fg = int(rng.integers(0, nd - 1)), nd - 1
        bg = rng.integers(0, 256, n + nd)
        fg = rng.integers(0, 256, n + nd)
        a = int(rng.integers(0, n - 1))
        b = min(n, a + int(rng.integers(1, 4)))
        x = np.arange(n)
        left = np.where((x >= a) & (x < b), fg[x], bg[x])
        in_fg = (x + d_fg >= a) & (x + d_fg < b)
        right = np.where(in_fg, fg[x + d_fg], bg[x + d_bg])
        yield Scanline(left, right, nd, occ=OCC if i % 2 else 4)


@pytest.mark.parametrize("line", list(_tiny_scanlines(80)))
def test_optimum_equals_brute_force_on_tiny_scanlines(line):
    best = line.brute_force()
    exact_cost, exact_match = line.exact()
    full_cost, _ = line.search(prune=False)
    pruned_cost, pruned_match = line.search(prune=True)
    assert exact_cost == best
    assert full_cost == best
    assert pruned_cost >= best  # the reference pruning is a heuristic
    # the returned sequences are valid and cost what the programmes say
    assert line.sequence_cost(sequence_of(exact_match)) == exact_cost
    assert line.sequence_cost(sequence_of(pruned_match)) == pruned_cost


def _two_plane_row(seed, n=90, d_bg=4, d_fg=11, fg=(35, 60)):
    """Band-limited row pair: background at d_bg, a foreground segment at d_fg."""
    rng = np.random.default_rng(seed)
    tex = np.convolve(rng.normal(0, 60, 400), np.ones(3) / 3, mode="same") + 128
    bg, fgt = tex[:200], tex[200:]
    x = np.arange(n)
    left = np.where((x >= fg[0]) & (x < fg[1]), fgt[x], bg[x])
    xr_fg = x + d_fg  # the foreground covers right pixels fg[0]-d_fg .. fg[1]-d_fg-1
    covered = (xr_fg >= fg[0]) & (xr_fg < fg[1])
    right = np.where(covered, fgt[np.clip(xr_fg, 0, 199)], bg[np.clip(x + d_bg, 0, 199)])
    return np.clip(left, 0, 255).astype(np.uint8), np.clip(right, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("seed", range(8))
def test_match_sequence_invariants(seed):
    left, right = _two_plane_row(seed)
    line = Scanline(left, right, 16)
    cost, match = line.exact()
    seq = sequence_of(match)
    xl = np.array([p[0] for p in seq])
    xr = np.array([p[1] for p in seq])
    assert (np.diff(xl) > 0).all() and (np.diff(xr) > 0).all()
    assert ((xl - xr >= 0) & (xl - xr < 16)).all()
    assert line.sequence_cost(seq) == cost
    for (xl0, xr0), (xl1, xr1) in zip(seq, seq[1:], strict=False):
        if xl1 > xl0 + 1:
            assert line.gl[xl1], "left occlusion away from an intensity variation"
        if xr1 > xr0 + 1:
            assert line.gr[xr0], "right occlusion away from an intensity variation"


@pytest.mark.parametrize("seed", range(5))
def test_two_planes_recovered_with_the_occlusion_strip_where_geometry_says(seed):
    left, right = _two_plane_row(seed)
    line = Scanline(left, right, 16)
    _, match = line.exact()
    disp = np.empty(line.n, np.int32)
    state = np.empty(line.n, np.uint8)
    decode_matches(match, disp, state)
    assert (disp[40:56] == 11).all()  # foreground interior
    assert (disp[15:25] == 4).all() and (disp[68:85] == 4).all()  # background interiors
    occluded = np.flatnonzero(state == OCCLUDED)
    # left-only strip: d_fg - d_bg = 7 pixels just left of the foreground (x = 28 .. 34)
    assert abs(len(occluded) - 7) <= 1
    assert 26 <= occluded.min() and occluded.max() <= 35


@pytest.mark.parametrize("seed", range(5))
def test_constant_disparity_recovered_except_the_border_strip(seed):
    rng = np.random.default_rng(seed)
    tex = np.convolve(rng.normal(0, 50, 140), np.ones(3) / 3, mode="same") + 128
    tex = np.clip(tex, 0, 255).astype(np.uint8)
    d0 = 9
    line = Scanline(tex[:120], tex[d0:d0 + 120], 16)  # left(x) = right(x - d0)
    _, match = line.exact()
    disp = np.empty(line.n, np.int32)
    state = np.empty(line.n, np.uint8)
    decode_matches(match, disp, state)
    assert (disp == d0).all()
    assert (state[:d0] == BORDER).all() and (state[d0:] == MATCHED).all()


def test_flat_rows_give_disparity_zero():
    line = Scanline(np.full(30, 77), np.full(30, 77), 8)
    cost, match = line.exact()
    assert (match == np.arange(30)).all()
    assert cost == C0 - REW * 29


def test_decode_hand_case():
    # left pixels 0..1 before the first match; 4..5 skipped by a left occlusion (k 1 -> 3)
    match = np.array([-1, -1, 1, 2, -1, -1, 3, 4], np.int32)
    disp = np.empty(8, np.int32)
    state = np.empty(8, np.uint8)
    decode_matches(match, disp, state)
    assert disp.tolist() == [1, 1, 1, 1, 1, 1, 3, 3]
    assert state.tolist() == [BORDER, BORDER, MATCHED, MATCHED, OCCLUDED, OCCLUDED, MATCHED,
                              MATCHED]
