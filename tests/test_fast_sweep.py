"""The fast sweep (the sweep's first try) and the guard's compiled anchor: what they prove
holds on a dense exact check, what they report is Coal's, and what they cannot prove they
hand back."""

from __future__ import annotations

import math

import numpy as np
import pytest

from manus.advancement import Advancement
from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.fast_sweep import fast_sweep
from manus.scene import default_scene
from manus.sweep import STEP_M, TOLERANCE_M
from manus.validity import checker_for
from services.planner.spline import PiecewisePolynomial

MODEL = CollisionModel(default_scene(), DEFAULT_ARM)
UNFOLDED = np.radians(UNFOLDED_Q_DEG)


def random_paths(count: int, seed: int) -> list[PiecewisePolynomial]:
    """Seeded joint-space cubic paths from the unfolded pose, 1-3 moves of up to 60 deg
    per joint, 2 s each (many pass near the scene, some through)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        n = int(rng.integers(1, 4))
        q = UNFOLDED + np.vstack(
            (np.zeros(6), np.cumsum(np.radians(rng.uniform(-60, 60, (n, 6))), axis=0))
        )
        out.append(PiecewisePolynomial.hermite(np.arange(n + 1) * 2.0, q, np.zeros_like(q)))
    return out


def test_a_proof_holds_on_a_dense_exact_check_and_reports_coals_clearance() -> None:
    proven = handed_back = 0
    for curve in random_paths(24, seed=41):
        ex = curve.extremes(1)
        peaks = np.maximum(-ex.low, ex.high)
        proof = fast_sweep(
            MODEL, curve.times, peaks, curve.evaluate, step=STEP_M, tolerance=TOLERANCE_M
        )
        dense = curve.evaluate(np.arange(0.0, curve.duration + 1e-9, 0.004))
        lowest = min(MODEL.clearance(q).margin for q in dense)
        if proof is None:
            handed_back += 1
            continue
        proven += 1
        assert lowest >= 0.0
        worst = proof.worst
        # Coal's per-body queries and its one query differ by ~1e-7 (GJK warm starts).
        assert MODEL.clearance(worst.q).margin == pytest.approx(worst.margin, abs=1e-6)
        assert lowest - 0.001 <= worst.margin <= lowest + TOLERANCE_M
        assert 1 <= proof.exact <= proof.checked
    assert proven >= 8 and handed_back >= 1


def test_a_path_into_the_table_is_handed_back_to_the_exact_sweep() -> None:
    b = UNFOLDED.copy()
    b[2] += 1.8  # the wrist comes down onto the table
    q = np.vstack((UNFOLDED, b))
    curve = PiecewisePolynomial.hermite(np.array([0.0, 4.0]), q, np.zeros_like(q))
    ex = curve.extremes(1)
    peaks = np.maximum(-ex.low, ex.high)
    assert (
        fast_sweep(MODEL, curve.times, peaks, curve.evaluate, step=STEP_M, tolerance=TOLERANCE_M)
        is None
    )


def test_the_anchor_proves_only_boxes_a_dense_exact_check_finds_clear() -> None:
    advance = Advancement(checker_for(MODEL))
    assert not advance.proven(UNFOLDED)  # no anchor yet
    rng = np.random.default_rng(5)
    proved = 0
    for _ in range(40):
        origin = UNFOLDED + rng.normal(0.0, 0.4, 6)
        advance.anchor_fast(origin)
        reach = rng.uniform(0.0, 0.15)
        corner = origin + rng.uniform(-reach, reach, 6)
        if not advance.proven(origin, corner):
            continue
        proved += 1
        inside = origin + rng.uniform(0.0, 1.0, (30, 6)) * (corner - origin)
        assert min(MODEL.clearance(q).margin for q in inside) >= 0.0
    assert proved >= 10
    advance.forget()
    assert advance.margin == -math.inf and not advance.proven(UNFOLDED)


def test_an_exact_anchor_takes_coals_margins() -> None:
    advance = Advancement(checker_for(MODEL))
    probe = MODEL.probe(UNFOLDED)
    advance.anchor(UNFOLDED, probe.free, probe.reach, probe.best.margin)
    assert advance.margin == probe.best.margin
    assert advance.proven(UNFOLDED, UNFOLDED + 1e-4)
    assert not advance.proven(UNFOLDED, UNFOLDED + 1.0)
