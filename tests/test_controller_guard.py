"""The controller's collision guard: a command toward the user's head is slowed and
stopped at the clearance, judged on the simulator's truth; clear paths pass unchanged."""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest

from manus.clearance import Probe
from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, FOLDED_Q_DEG, UNFOLDED_Q_DEG
from manus.kinematics import gripper_position
from manus.quantize import step_rates
from manus.scene import default_scene
from manus.viapoints import parse_viapoints
from manus_stack.controlled import ControlledArm
from schemas.control import TrajectoryGoal
from schemas.planning import PlanRequest, ViaPointPath
from services.controller.guard import Guard
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.simulator.config import SimConfig

UNFOLDED = [math.radians(v) for v in UNFOLDED_Q_DEG]
HEAD_PATH = """\
0 0 0 0 0 0 0 0 0 0 0 0 0 2
-289 157 15 0 0 0 0 0 0 0 0 0 3 2
-289 158 15 0 0 0 0 0 0 0 0 0 6 2
"""
"""From the unfolded pose to the centre of the default user's head."""


def head_distance(model: CollisionModel, q: list[float]) -> float:
    """Smallest distance [m] from any arm body to the head (with its 50 mm included)."""
    margins = model.margins(np.asarray(q))
    rows = [k for k, c in enumerate(model.checks) if c.other == "head"]
    return float(min(margins[k] + model.checks[k].required for k in rows))


def test_a_trajectory_into_the_head_is_stopped_at_the_clearance() -> None:
    # A planner without the scene plans it; the controller's guard must stop it.
    blind = PlannerCore(PlannerConfig(scene="none"))
    reply = blind.plan(
        PlanRequest(
            ViaPointPath(path=parse_viapoints(HEAD_PATH, "head.txt"), speed_scaling=True),
            start=UNFOLDED,
        )
    )
    assert reply.trajectory is not None
    arm = ControlledArm(SimConfig(start_pose="unfolded"))
    arm.start()
    assert arm.submit(TrajectoryGoal(goal_id="head", trajectory=reply.trajectory)).accepted
    model = CollisionModel(default_scene(), DEFAULT_ARM, opening=arm.ls.sim.truth().gripper)
    closest = math.inf
    for _ in range(200):  # 12 s
        arm.ls.run_for(0.06)
        truth = arm.ls.sim.truth()
        closest = min(closest, head_distance(model, truth.q_true))
        if arm.results("head"):
            break
    result = arm.results("head")[0]
    assert result.status == "aborted"
    assert result.reason.startswith("collision guard stopped: ")
    assert "from head (person: needs 50 mm)" in result.reason
    assert result.clearance is not None and result.clearance.other == "head"
    arm.ls.run_for(1.0)  # the arm has come to rest: nothing moves any more
    truth = arm.ls.sim.truth()
    # how far from the path's end it stopped (the head's centre): where it stands now,
    # within the run-out after the stop and the encoders' counts
    end = gripper_position(reply.trajectory.positions[-1], DEFAULT_ARM)
    stood = gripper_position(truth.q_true, DEFAULT_ARM)
    assert result.final_error == pytest.approx(math.dist(stood, end), abs=0.005)
    assert result.final_error > 0.05
    closest = min(closest, head_distance(model, truth.q_true))
    assert truth.contacts == 0
    # The truth never came within the person clearance (50 mm), and it stopped near it.
    assert 0.05 <= closest < 0.08
    feedback = [m for _, s, m in arm.ls.messages if s == "controller/feedback"]
    assert any(getattr(fb, "guard", "").startswith("slowed to ") for fb in feedback)


def test_clear_paths_pass_unchanged_and_mostly_without_distances() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    guard = Guard(model)
    q = list(UNFOLDED)
    counts = np.array([2, -1, 0, 3, 0, 0])
    for _ in range(50):
        verdict = guard.filter(q, step_rates(counts.tolist()), counts, 0.0)
        assert verdict.scale == 1.0 and verdict.reason == ""
        assert (verdict.counts == counts).all()
        q = list(np.asarray(q) + np.radians([0.6, 0.3, 0.0, 0.9, 0.0, 0.0]) * 0.1)
    assert guard.computed < 20


def test_idle_costs_nothing() -> None:
    guard = Guard(CollisionModel(default_scene(), DEFAULT_ARM))
    zero = np.zeros(6, dtype=np.int64)
    verdict = guard.filter(UNFOLDED, [0.0] * 6, zero, 0.0)
    assert verdict.scale == 1.0 and verdict.reason == "" and verdict.clearance is None
    assert (verdict.counts == zero).all()
    assert guard.computed == 0


def ahead(q: np.ndarray, counts: np.ndarray, guard: Guard) -> np.ndarray:
    """Where ``counts`` take the arm from ``q`` (nothing in flight): a cycle and the
    run-out [rad]."""
    rate = np.array(step_rates(counts.tolist()))
    return np.asarray(q + rate * (guard.cycle_s + guard.runout_s))


def smallest_margin(model: CollisionModel, q0: np.ndarray, q1: np.ndarray) -> float:
    """The exact model's smallest margin at 41 configurations from ``q0`` to ``q1`` [m]."""
    return min(model.clearance(q0 + s * (q1 - q0)).margin for s in np.linspace(0.0, 1.0, 41))


def test_a_slowed_motion_keeps_one_count_where_it_is_proven_clear() -> None:
    # Folded, the gripper's motor is 20 mm from the shoulder (10 mm needed): inside the
    # slow zone, a closing motion is slowed to a third; one count times a third is none.
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    guard = Guard(model)
    q = np.radians(FOLDED_Q_DEG)
    counts = np.array([0, -1, -1, 0, 0, 0])
    verdict = guard.filter(list(q), [0.0] * 6, counts, model.opening)
    assert verdict.reason.startswith("slowed to 0.3"), verdict.reason
    assert (verdict.counts == counts).all()
    assert smallest_margin(model, q, ahead(q, verdict.counts, guard)) >= 0.0


def test_what_the_guard_lets_through_keeps_the_clearance_near_the_head() -> None:
    # 1.5 mm from the head's clearance: every command of at most one count per joint;
    # what passes (slowed or not) must keep the clearance all along, on the exact model,
    # and the commands that would break it are stopped.
    blind = PlannerCore(PlannerConfig(scene="none"))
    reply = blind.plan(
        PlanRequest(
            ViaPointPath(path=parse_viapoints(HEAD_PATH, "head.txt"), speed_scaling=True),
            start=UNFOLDED,
        )
    )
    assert reply.trajectory is not None
    path = np.array(reply.trajectory.positions)
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    k = next(k for k in range(len(path)) if model.clearance(path[k]).margin < 0.002)
    a, b = path[k - 1], path[k]
    lo, hi = 0.0, 1.0
    for _ in range(30):  # where the margin is 1.5 mm
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if model.clearance(a + mid * (b - a)).margin > 0.0015 else (lo, mid)
    q = a + lo * (b - a)
    guard = Guard(model)
    stopped = passed = 0
    for row in itertools.product((-1, 0, 1), repeat=6):
        counts = np.array(row)
        if not counts.any():
            continue
        guard.advance.forget()  # each command decided afresh, as the first of a motion
        verdict = guard.filter(list(q), [0.0] * 6, counts, model.opening)
        if verdict.counts.any():
            passed += 1
            assert smallest_margin(model, q, ahead(q, verdict.counts, guard)) >= 0.0
        else:
            stopped += 1
            assert verdict.reason.startswith("stopped: ")
    assert stopped > 0 and passed > 0


class _Counted(CollisionModel):
    """The collision model, counting the exact distances it computes."""

    probes = 0

    def probe(self, q: np.ndarray, time: float = 0.0, **kw: Any) -> Probe:
        self.probes += 1
        return super().probe(q, time, **kw)


class _CoalAhead(Guard):
    """The guard as it was: Coal's margins ahead of every exact anchor."""

    def _bounds_pass(self, q_next: np.ndarray, q_end: np.ndarray, now: float) -> bool:
        return False


def test_the_fast_bounds_ahead_decide_as_coals_margins_would() -> None:
    # Seeded walks of commands from the unfolded pose, drifting toward poses about it and
    # toward the folded one (into the slow zone and the stops): every verdict the same.
    fast, exact = _Counted(default_scene(), DEFAULT_ARM), _Counted(default_scene(), DEFAULT_ARM)
    slowed = 0
    for seed in range(4):
        guard, coal = Guard(fast), _CoalAhead(exact)
        rng = np.random.default_rng(seed)
        q, applied = np.radians(UNFOLDED_Q_DEG), [0.0] * 6
        goal = np.radians(FOLDED_Q_DEG) if seed % 2 else q + rng.normal(0.0, 1.0, 6)
        for _ in range(150):
            drift = np.round((goal - q) * 8.0) + rng.integers(-3, 4, 6)
            counts = np.clip(drift, -6, 6).astype(np.int64)
            got = guard.filter(list(q), applied, counts, 0.05)
            want = coal.filter(list(q), applied, counts, 0.05)
            assert (got.counts == want.counts).all() and got.reason == want.reason
            assert got.scale == want.scale
            assert (got.clearance is None) == (want.clearance is None)
            if got.clearance is not None and want.clearance is not None:
                assert got.clearance.margin == want.clearance.margin
                assert got.clearance.check == want.clearance.check
            slowed += got.scale < 1.0
            applied = step_rates(got.counts.tolist())
            q = q + np.array(applied) * guard.cycle_s
        assert guard.computed == coal.computed
    assert slowed > 0
    assert fast.probes < exact.probes  # the bounds decided some, with fewer exact distances
