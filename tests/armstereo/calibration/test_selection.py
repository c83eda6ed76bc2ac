"""Choosing the hand-eye by leave-one-out prediction: the refinement unless a closed form
predicts clearly better, and only when the arm's poses limit the fit."""

from __future__ import annotations

import numpy as np

from armstereo.calibration.selection import REFINED, SELECTION_MARGIN, Candidate, choose


def _candidate(name: str, median_px: float) -> Candidate:
    eye = np.eye(4)
    return Candidate(name, eye, eye, np.full(9, median_px), np.zeros(3), np.zeros(3),
                     np.zeros(9))


def test_a_clearly_better_closed_form_wins():
    chosen = choose([_candidate(REFINED, 2.0), _candidate("park", 1.7),
                     _candidate("daniilidis", 1.6)])
    assert chosen.name == "daniilidis"


def test_a_near_tie_keeps_the_refinement():
    just_better = 2.0 * (1 - SELECTION_MARGIN) + 1e-6
    assert choose([_candidate(REFINED, 2.0), _candidate("park", just_better)]).name == REFINED


def test_the_refinement_is_kept_when_it_predicts_best():
    assert choose([_candidate(REFINED, 0.4), _candidate("tsai", 0.6)]).name == REFINED
