"""The controller's collision guard: a command toward the user's head is slowed and
stopped at the clearance, judged on the simulator's truth; clear paths pass unchanged."""

from __future__ import annotations

import math

import numpy as np

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.quantize import step_rates
from manus.scene import default_scene
from manus.viapoints import parse_viapoints
from manus_stack.controlled import ControlledArm
from schemas.control import TrajectoryGoal
from schemas.planning import PlanRequest
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
        PlanRequest(path=parse_viapoints(HEAD_PATH, "head.txt"), start=UNFOLDED, speed_scaling=True)
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
