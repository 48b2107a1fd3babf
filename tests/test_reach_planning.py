"""Goal planning through the planner core: the search (OMPL), its determinism, the
refusals, straight Cartesian lines, resuming, and the live view's drawing of a plan."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.kinematics import fk
from manus.sweep import straight_motion_problem
from schemas.goals import JointGoal, LineFrame, LineMotion, NamedGoal, PoseGoal, Search
from schemas.motion import Motion
from schemas.planning import PlanReply, PlanRequest, PlanResume
from services.planner.core import PlannerCore
from services.viewer.core import ViewerCore

CORE = PlannerCore()
UNFOLDED = [math.radians(v) for v in UNFOLDED_Q_DEG]
LEVEL = [0.0, math.pi / 2, 0.0]


def plan(motion: Motion, start: list[float] | None = None, **kw: object) -> PlanReply:
    return CORE.plan(PlanRequest(motion, start=start or UNFOLDED, preview_dt=0.0, **kw))  # type: ignore[arg-type]


def planned(motion: Motion, start: list[float] | None = None) -> PlanReply:
    reply = plan(motion, start)
    assert reply.ok and reply.trajectory is not None, reply.error
    return reply


def test_the_issue_goal_is_planned_with_the_clearances_kept() -> None:
    reply = planned(PoseGoal(xyz=[0.56, 0.10, -0.15], ypr=LEVEL))
    traj = reply.trajectory
    assert traj is not None and traj.clearance is not None
    assert traj.clearance.distance >= traj.clearance.required
    assert traj.knot_kinds[0] == "start" and traj.knot_kinds[-1] == "goal"
    np.testing.assert_allclose(traj.positions[0], UNFOLDED)
    end = fk(np.array(traj.positions[-1]), DEFAULT_ARM)
    np.testing.assert_allclose(end[:3, 3], [0.56, 0.10, -0.15], atol=1e-9)
    np.testing.assert_allclose(end[:3, 2], [1.0, 0.0, 0.0], atol=1e-9)  # level, forward
    # Within half the joints' speed limits (the default speed), starting and ending at rest.
    v = np.abs(np.array(traj.velocities))
    assert v.max() <= 0.5 * max(DEFAULT_ARM.max_speed) + 1e-9
    assert not v[0].any() and not v[-1].any()


def test_a_goal_around_something_is_searched_for_and_every_motion_is_clear() -> None:
    goal = PoseGoal(xyz=[0.70, 0.10, -0.16], ypr=LEVEL)
    traj = planned(goal).trajectory
    assert traj is not None and "RRTConnect (seed 1" in traj.notes[0]
    assert CORE.collision is not None
    knots = np.array(traj.positions)
    assert len(knots) >= 3
    for a, b in itertools.pairwise(knots):
        assert straight_motion_problem(CORE.collision, a, b, "segment") is None


def test_the_same_request_gives_the_same_plan_and_seeds_differ() -> None:
    goal = PoseGoal(xyz=[0.70, 0.10, -0.16], ypr=LEVEL)
    first = plan(goal).encode()
    plan(PoseGoal(xyz=[0.6, 0.1, -0.16], ypr=[0.0, math.pi, 0.0]))  # something in between
    assert plan(goal).encode() == first
    other = PoseGoal(xyz=goal.xyz, ypr=goal.ypr, search=Search(seed=7))
    assert plan(other).encode() != first


def test_a_search_out_of_budget_says_how_far_it_got() -> None:
    start = planned(PoseGoal(xyz=[0.56, 0.10, -0.15], ypr=LEVEL)).trajectory
    assert start is not None
    goal = PoseGoal(
        xyz=[-0.02, 0.12, -0.31], ypr=[math.pi, 3 * math.pi / 4, 0.0], search=Search(budget=3)
    )
    reply = plan(goal, start.positions[-1])
    assert reply.error is not None and reply.error.reason == "no_path", reply.error
    message = reply.error.message
    assert "no collision-free path found in 3 iterations of RRTConnect (seed 1;" in message
    assert "the closest it came:" in message and "mm from its goal" in message


def test_refusals_name_the_reason_and_a_start_too_close_is_refused() -> None:
    reply = plan(NamedGoal(name="kitchen"))
    assert reply.error is not None and reply.error.reason == "invalid"
    reply = plan(PoseGoal(xyz=[0.6, 0.1, -0.24], ypr=[0.0, math.pi, 0.0]))
    assert reply.error is not None and reply.error.reason == "goal_collision"
    inside = [0.0, math.radians(66), math.radians(-18), 0.0, math.radians(60), 0.0]
    reply = plan(JointGoal(joints=UNFOLDED), start=inside)
    assert reply.error is not None
    assert reply.error.reason == "collision" and "already too close" in reply.error.message


def test_an_approach_is_a_straight_line_along_the_gripper_axis() -> None:
    start = planned(PoseGoal(xyz=[0.56, 0.10, -0.15], ypr=LEVEL)).trajectory
    assert start is not None
    q0 = start.positions[-1]
    traj = planned(LineMotion(xyz=[0.0, 0.0, 0.04], frame=LineFrame.TOOL), q0).trajectory
    assert traj is not None
    xyz = np.array(traj.via_xyz)
    np.testing.assert_allclose(xyz[:, 1:], [[0.10, -0.15]] * len(xyz), atol=1e-9)
    assert xyz[-1, 0] == pytest.approx(0.60) and np.all(np.diff(xyz[:, 0]) > 0.0)
    assert np.linalg.norm(np.diff(xyz, axis=0), axis=1).max() <= 0.002 + 1e-9
    # Paused half way, the line goes on to the same end.
    resume = PlanResume(trajectory=traj, reached=traj.times[-1] / 2)
    middle = traj.positions[len(traj.positions) // 2]
    rest = plan(LineMotion(xyz=[0.0, 0.0, 0.04], frame=LineFrame.TOOL), middle, resume=resume)
    assert rest.trajectory is not None
    np.testing.assert_allclose(rest.trajectory.via_xyz[-1], xyz[-1], atol=1e-9)


@pytest.mark.parametrize(
    ("end", "reason", "words"),
    [
        ([0.56, 0.10, -0.23], "collision", "at 35 mm of 80 mm the gripper"),
        ([0.90, 0.10, -0.15], "singular", "crosses the wrist singularity"),
    ],
)
def test_a_line_that_cannot_be_followed_is_refused_naming_where(
    end: list[float], reason: str, words: str
) -> None:
    start = planned(PoseGoal(xyz=[0.56, 0.10, -0.15], ypr=LEVEL)).trajectory
    assert start is not None
    reply = plan(LineMotion(xyz=end), start.positions[-1])
    assert reply.error is not None and reply.error.reason == reason, reply.error
    assert words in reply.error.message


def test_a_line_below_the_work_area_is_refused_where_it_reaches_its_edge() -> None:
    start = planned(PoseGoal(xyz=[0.21, 0.12, -0.34], ypr=[0.0, math.pi, 0.0])).trajectory
    assert start is not None
    reply = plan(LineMotion(xyz=[0.21, 0.12, -0.40]), start.positions[-1])
    assert reply.error is not None and reply.error.reason == "zone"
    assert "of 60 mm the line reaches the edge of the arm's own work area" in reply.error.message
    assert "work area's floor (z -350 mm)" in reply.error.message


def test_a_line_out_of_reach_is_refused_where_it_leaves_it() -> None:
    reply = plan(LineMotion(xyz=[0.2078, 0.105, 0.9]))
    assert reply.error is not None and reply.error.reason == "unreachable"
    assert "at 513 mm of 700 mm: the line leaves the arm's reach" in reply.error.message


def test_the_live_view_draws_a_goal_plan_before_it_runs() -> None:
    reply = planned(NamedGoal(name="drink"))
    viewer = ViewerCore()
    out = viewer.on_sample("manus/trace/planner/plan/reply", reply.encode(), 1_000)
    assert [o.topic for o in out] == ["manus/viz/planned"]
    assert viewer.stats.bad_payloads == {}
