"""Goals run as tasks in lock-step: the sequencer, the planner (goal planning), the
controller, the bridge and the simulator cores; safety judged on the simulator's truth.

The issue's goal (base frame x 560, y 100, z -150 mm, the gripper level, 110 mm above the
table in front of the user) is reached from the unfolded pose with every clearance kept
on the simulator's true joint angles; a refused goal moves nothing.
"""

from __future__ import annotations

import math

import numpy as np

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM
from manus.kinematics import fk
from manus.scene import default_scene
from manus_stack.task_lockstep import TaskLockStep
from schemas.control import TrajectoryGoal
from schemas.sequencing import Task
from services.sequencer.taskfile import parse_task_text
from services.simulator.config import SimConfig

ISSUE_GOAL = "reach = {pose = [560, 100, -150, 0, 90, 0]}"


def task(*steps: str) -> Task:
    return parse_task_text("".join(f"[[step]]\n{s}\n" for s in steps), source="test.toml")


def run_judged(rig: TaskLockStep, limit_s: float = 60.0) -> tuple[float, str, int]:
    """Run the task to its end; the smallest true margin (the exact model on the
    simulator's true angles, every 20 ms) [m], that check in words, and the contacts."""
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    worst, what = math.inf, ""
    end = rig.ls.t_ns + round(limit_s * 1e9)
    while rig.seq.busy and rig.ls.t_ns < end:
        rig.ls.run_for(0.02)
        found = model.clearance(np.array(rig.ls.sim.truth().q_true))
        if found.margin < worst:
            worst, what = found.margin, found.describe()
    return worst, what, rig.ls.sim.truth().contacts


def test_the_issue_goal_is_reached_with_every_clearance_kept_on_the_truth() -> None:
    rig = TaskLockStep(SimConfig(start_pose="unfolded"))
    rig.start_arm()
    reply = rig.submit(task(ISSUE_GOAL))
    assert reply.accepted, reply.errors
    worst, what, contacts = run_judged(rig)
    assert rig.seq.state == "succeeded", rig.seq.reason
    assert contacts == 0
    assert worst >= 0.0, what
    final = rig.ls.sim.truth()
    assert np.linalg.norm(np.array(final.xyz) - [0.560, 0.100, -0.150]) < 0.003
    goal = next(r for r in rig.requests if isinstance(r, TrajectoryGoal))
    assert goal.trajectory.knot_kinds[0] == "start" and goal.trajectory.knot_kinds[-1] == "goal"


def test_a_paused_goal_is_planned_again_and_still_ends_at_the_goal() -> None:
    rig = TaskLockStep(SimConfig(start_pose="unfolded"))
    rig.start_arm()
    assert rig.submit(task('reach = "drink"')).accepted
    rig.ls.run_for(3.0)
    assert rig.control("pause").ok
    rig.run_until_event("paused")
    assert rig.control("resume").ok
    worst, what, contacts = run_judged(rig)
    assert rig.seq.state == "succeeded", rig.seq.reason
    assert contacts == 0 and worst >= 0.0, what
    goals = [r for r in rig.requests if isinstance(r, TrajectoryGoal)]
    assert len(goals) == 2
    drink = np.radians([-13, -92, -39, -80, -102, -48])
    assert np.abs(np.array(goals[1].trajectory.positions[-1]) - drink).max() < 1e-9
    reached = fk(rig.ls.sim.truth().q_true, DEFAULT_ARM)[:3, 3]
    assert np.linalg.norm(reached - fk(drink, DEFAULT_ARM)[:3, 3]) < 0.005


def test_a_goal_from_the_folded_pose_is_not_stopped_by_the_guard_near_the_shoulder() -> None:
    # Folded, the gripper's motor is 20 mm from the shoulder (10 mm needed): the guard's
    # slow zone. The trajectory's first counts, slowed, must not all become zero.
    rig = TaskLockStep(SimConfig(start_pose="folded"))
    rig.start_arm()
    assert rig.submit(task('reach = "home"')).accepted
    worst, what, contacts = run_judged(rig)
    assert rig.seq.state == "succeeded", rig.seq.reason
    assert contacts == 0 and worst >= 0.0, what


def test_a_goal_that_cannot_be_reached_is_refused_and_nothing_moves() -> None:
    rig = TaskLockStep(SimConfig(start_pose="unfolded"))
    rig.start_arm()
    reply = rig.submit(task("reach = {pose = [600, 100, -240, 0, 180, 0]}", 'reach = "kitchen"'))
    assert not reply.accepted
    assert "goal_collision" in reply.errors[0] and "table" in reply.errors[0]
    assert "test.toml:2: step 1 (reach)" in reply.errors[0]
    assert "not planned: its start is unknown" in reply.errors[1]
    reply = rig.submit(task('reach = "kitchen"'), task_id="u")
    assert not reply.accepted
    assert "planner refused (invalid): unknown named pose 'kitchen'" in reply.errors[0]
    assert not any(isinstance(r, TrajectoryGoal) for r in rig.requests)
