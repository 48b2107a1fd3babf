"""The fast validity check against the exact one (Coal): never valid where Coal finds a
clearance broken, bounds never above the exact margins, motions proven only where a
dense exact check finds them clear; attached bodies and the gripper's opening."""

from __future__ import annotations

import math

import numpy as np
import pytest

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, FOLDED_Q_DEG, UNFOLDED_Q_DEG
from manus.held import HeldBody, HeldError
from manus.scene import default_scene, parse_scene
from manus.validity import ValidityChecker, checker_for

MODEL = CollisionModel(default_scene(), DEFAULT_ARM)
FAST = checker_for(MODEL)
UNFOLDED = np.radians(UNFOLDED_Q_DEG)
FOLDED = np.radians(FOLDED_Q_DEG)


def random_configurations(n: int, seed: int) -> np.ndarray:
    """Uniform within the joint limits, and as many again near the unfolded pose (where
    the arm works: closer to the user, the chair and the table)."""
    rng = np.random.default_rng(seed)
    wide = rng.uniform(DEFAULT_ARM.lower_array, DEFAULT_ARM.upper_array, (n, 6))
    near = UNFOLDED + rng.normal(0.0, 0.6, (n, 6))
    return np.vstack((wide, near))


def exact_margins(Q: np.ndarray, model: CollisionModel = MODEL) -> np.ndarray:
    return np.array([model.clearance(q).margin for q in Q])


def test_never_valid_where_coal_finds_a_clearance_broken() -> None:
    Q = random_configurations(2500, seed=26)
    valid = FAST.is_valid_batch(Q)
    exact = exact_margins(Q)
    assert not np.any(valid & (exact < 0.0)), "the fast check called a violation free"
    assert 0.3 < valid.mean() < 0.9  # the sample holds both kinds
    bounds = FAST.margins_batch(Q)
    clear = exact >= 0.0
    assert np.all(bounds.tight[clear] <= exact[clear])
    # The same verdict from the boolean check, one by one and batched, and the bound.
    assert np.array_equal(valid, bounds.tight >= 0.0)
    assert [FAST.is_valid(q) for q in Q[:200]] == list(valid[:200])
    # Over-conservative rarely, by a few millimetres at most.
    wrong = clear & ~valid
    assert wrong.sum() < 0.1 * clear.sum()
    assert np.all(exact[wrong] < 0.025)


def test_the_tightest_check_names_what_coal_names_when_it_is_clear_cut() -> None:
    Q = random_configurations(300, seed=3)
    agree = 0
    for q in Q:
        exact = MODEL.clearance(q)
        bound = FAST.margins(q)
        assert bound.tight <= exact.margin or exact.margin < 0.0
        if exact.margin >= 0.0 and abs(bound.tight - exact.margin) < 1e-4:
            agree += 1
            assert (bound.check.body, bound.check.other) == (exact.check.body, exact.check.other)
    assert agree > 50


def test_per_body_margins_bound_coals_per_body_margins() -> None:
    Q = random_configurations(300, seed=5)
    moving = [MODEL.shapes[i].name for i in MODEL.moving]
    assert FAST.bodies == moving
    for q in Q:
        free, tight, _ = MODEL.pair_margins(q)
        if tight < 0.0:
            continue
        bound = FAST.margins(q).free
        for b, name in enumerate(moving):
            keep_in = min((m for m, c in MODEL.keep_in_margins() if c), default=math.inf)
            assert bound[b] <= max(free[b], keep_in) + 1e-12, name


def test_motions_are_proven_only_where_a_dense_exact_check_finds_them_clear() -> None:
    rng = np.random.default_rng(7)
    Q = random_configurations(400, seed=8)
    starts = Q[FAST.is_valid_batch(Q)]
    proven = refused = 0
    for a in starts[:60]:
        b = a + rng.uniform(-0.5, 0.5, 6)
        found = FAST.motion_valid(a, b)
        dense = exact_margins(a + np.linspace(0.0, 1.0, 101)[:, None] * (b - a))
        if found.ok:
            proven += 1
            assert found.fraction == 1.0
            assert dense.min() >= 0.0
        else:
            refused += 1
            assert 0.0 <= found.fraction < 1.0
            # Everything before where the proof stopped is clear.
            assert dense[: int(found.fraction * 100)].min(initial=math.inf) >= 0.0
    assert proven > 20 and refused > 0


def test_a_motion_into_the_table_stops_before_it() -> None:
    # Joint 3 from the unfolded pose: the wrist comes down onto the table.
    a = UNFOLDED.copy()
    b = a.copy()
    b[2] += 1.8
    end = MODEL.clearance(b)
    assert FAST.is_valid(a) and end.margin < 0.0 and end.check.other == "table"
    found = FAST.motion_valid(a, b)
    assert not found.ok and 0.0 < found.fraction < 1.0
    assert MODEL.clearance(a + found.fraction * (b - a)).margin >= 0.0
    assert FAST.motion_valid(a, a).ok


def test_a_held_object_counts_as_part_of_the_gripper() -> None:
    # A 400 mm rod held along the approach axis, reaching far past the fingers.
    rod = HeldBody("rod", "rod", "cylinder", (0.03, 0.4), (0.0, 0.0, 0.2), (0.0, 0.0, 0.0))
    model = MODEL.holding([rod])
    fast = checker_for(model)
    Q = random_configurations(500, seed=13)
    before = FAST.is_valid_batch(Q)
    after = fast.is_valid_batch(Q)
    assert fast.bodies[-1] == "rod" and len(fast.margins(UNFOLDED).free) == 7
    assert not np.any(after & ~before) and after.sum() < before.sum()
    rod_checks = {
        fast.check_of(*w)
        for w, ok in zip(fast.margins_batch(Q).which, after, strict=True)
        if not ok
    }
    assert any(c.body == "rod" for c in rod_checks)
    with pytest.raises(HeldError, match="'gripper': an arm body"):
        MODEL.holding([rod._replace(name="gripper")])


@pytest.mark.parametrize(
    "held",
    [
        HeldBody("cup", "cup", "cylinder", (0.035, 0.12), (0.0, 0.0, 0.0), (0.0, 0.0, 1.5708)),
        HeldBody("rod", "rod", "capsule", (0.02, 0.35), (0.0, 0.02, 0.0), (0.0, 0.0, 1.5708)),
        HeldBody("box", "box", "box", (0.08, 0.3, 0.05), (0.0, 0.0, -0.01), (0.3, 0.0, 0.0)),
    ],
    ids=lambda h: h.name,
)
def test_the_fast_check_stays_conservative_with_a_held_body(held: HeldBody) -> None:
    """Held bodies of each shape, checked against the arm's moving bodies too (its
    forearm, wrist, gripper motor): never valid where Coal (with the same held body)
    finds a clearance broken, no bound above Coal's margin, per body either."""
    model = MODEL.holding([held])
    fast = checker_for(model)
    Q = random_configurations(600, seed=29)
    valid = fast.is_valid_batch(Q)
    exact = exact_margins(Q, model)
    clear = exact >= 0.0
    assert not np.any(valid & ~clear), "the fast check called a violation free"
    assert np.all(fast.margins_batch(Q).tight[clear] <= exact[clear])
    assert (clear & ~valid).sum() < 0.1 * clear.sum()
    names = {fast.check_of(*w) for w in fast.margins_batch(Q[~valid]).which}
    assert {"forearm", "table", "head"} <= {c.other for c in names if c.body == held.name}
    for q in Q[clear][:150]:
        free, _, _ = model.pair_margins(q)  # the held body's mutual pairs halved, as here
        keep_in = min((m for m, _ in model.keep_in_margins()), default=math.inf)
        assert np.all(fast.margins(q).free <= np.maximum(free, keep_in) + 1e-12)


def test_motions_with_a_held_body_are_proven_only_where_a_dense_exact_check_finds_them_clear() -> (
    None
):
    """The held body and the forearm both move: their pair's margin is shared between
    them, so a proof of a motion that brings the held body to the forearm holds too."""
    rod = HeldBody("rod", "rod", "capsule", (0.02, 0.3), (0.0, 0.0, 0.05), (0.0, 1.5708, 0.0))
    model = MODEL.holding([rod])
    fast = checker_for(model)
    rng = np.random.default_rng(17)
    Q = random_configurations(300, seed=18)
    proven = 0
    for a in Q[fast.is_valid_batch(Q)][:50]:
        b = a + rng.uniform(-0.6, 0.6, 6)
        b[4] += rng.choice([-1.5, 1.5])  # the wrist swings the rod past the forearm
        found = fast.motion_valid(a, b)
        dense = exact_margins(a + np.linspace(0.0, 1.0, 101)[:, None] * (b - a), model)
        proven += found.ok
        assert dense[: int(found.fraction * 100) + found.ok].min(initial=math.inf) >= 0.0
    assert proven > 5


def test_the_gripper_opening_of_the_model_is_followed() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM, opening=0.0)
    fast = ValidityChecker(model)
    q = UNFOLDED
    closed = fast.margins(q).free[fast.bodies.index("gripper")]
    model.set_opening(DEFAULT_ARM.gripper_max)
    opened = fast.margins(q).free[fast.bodies.index("gripper")]
    assert opened < closed


def test_an_opening_prepared_ahead_changes_nothing_now_and_checks_as_one_built_then() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    fast = ValidityChecker(model)
    Q = random_configurations(50, 3)
    before = fast.margins_batch(Q).free
    fast.prepare(0.03)
    assert model.opening == DEFAULT_ARM.gripper_max
    assert np.array_equal(fast.margins_batch(Q).free, before)
    assert 0.03 in fast._by_opening  # built now, kept for when the opening is that
    model.set_opening(0.03)
    fresh = ValidityChecker(CollisionModel(default_scene(), DEFAULT_ARM, opening=0.03))
    assert np.array_equal(fast.margins_batch(Q).free, fresh.margins_batch(Q).free)
    assert np.array_equal(fast.levers(), fresh.levers())


def test_without_a_scene_only_the_arm_itself_is_checked() -> None:
    model = CollisionModel(None, DEFAULT_ARM)
    fast = ValidityChecker(model)
    assert fast.is_valid(UNFOLDED) and fast.is_valid(FOLDED)
    rng = np.random.default_rng(11)
    Q = rng.uniform(DEFAULT_ARM.lower_array, DEFAULT_ARM.upper_array, (400, 6))
    valid = fast.is_valid_batch(Q)
    assert not np.any(valid & (exact_margins(Q, model) < 0.0))
    assert {fast.check_of(0, o).cls for o in range(2)} == {"self"}


def test_zones_of_a_scene_file_are_checked() -> None:
    text = """
version: 1
mount: {xyz_mm: [0, 0, 1000]}
objects: []
zones:
  - {name: box, kind: keep_in, shape: box, size_mm: [1600, 1600, 1400], xyz_mm: [0, 0, 1000]}
  - {name: ball, kind: keep_out, shape: sphere, radius_mm: 100, xyz_mm: [500, 0, 1300],
     clearance_mm: 20, links: gripper}
"""
    model = CollisionModel(parse_scene(text, "zones.yaml"), DEFAULT_ARM)
    fast = ValidityChecker(model)
    Q = random_configurations(800, seed=12)
    valid = fast.is_valid_batch(Q)
    exact = exact_margins(Q, model)
    assert not np.any(valid & (exact < 0.0))
    names = {
        fast.check_of(*w).other
        for w, ok in zip(fast.margins_batch(Q).which, valid, strict=True)
        if not ok
    }
    assert {"ball", "keep_in box"} <= names
