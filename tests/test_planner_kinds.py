"""The planner's seam: one planner per kind of motion, knots that say what they are, and
the resume of a paused plan by the planner that made it."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path as FilePath

import numpy as np
import pytest

from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.kinematics import jacobian
from manus.trajectory import JointTrajectory
from manus.viapoints import load_path, parse_viapoints
from schemas.motion import MOTIONS
from schemas.planning import (
    KnotKind,
    PlanReply,
    PlanRequest,
    PlanResume,
    Trajectory,
    ViaPointPath,
)
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.planner import Planner
from services.planner.registry import PLANNERS

ROOT = FilePath(__file__).resolve().parent.parent
UNFOLDED = [math.radians(q) for q in UNFOLDED_Q_DEG]
SQUARE = ViaPointPath(path=load_path(ROOT / "paths" / "thesis_square.txt"))
CORE = PlannerCore(PlannerConfig(scene="none"))


def plan(motion: ViaPointPath, start: list[float], resume: PlanResume | None = None) -> PlanReply:
    return CORE.plan(PlanRequest(motion, start=start, preview_dt=0.0, resume=resume))


def trajectory(reply: PlanReply) -> Trajectory:
    assert reply.ok and reply.trajectory is not None, reply.error
    return reply.trajectory


def at(traj: Trajectory, t: float) -> list[float]:
    """Where the arm is at trajectory time ``t`` (as if it stopped there)."""
    return JointTrajectory(traj).position(t)


def test_every_kind_declared_is_served_and_only_those() -> None:
    assert set(PLANNERS) == set(MOTIONS.members.values())
    assert all(issubclass(planner, Planner) for planner in PLANNERS.values())
    assert set(CORE.planners) == set(PLANNERS)


def test_a_path_s_knots_are_its_via_points_the_first_being_the_start() -> None:
    traj = trajectory(plan(SQUARE, UNFOLDED))
    n = len(SQUARE.path.via_points)
    assert traj.knot_kinds == ["start", *["via_point"] * (n - 1)]
    assert traj.via_indices == list(range(n))
    assert traj.via_lines == [vp.line for vp in SQUARE.path.via_points]
    assert [traj.knot_kind(i) for i in (0, 1)] == [KnotKind.START, KnotKind.VIA_POINT]
    # A trajectory made before knots said what they were: knot i is via point i.
    legacy = dataclasses.replace(traj, knot_kinds=[], via_indices=[])
    assert [legacy.knot_kind(i) for i in range(n)] == traj.knot_kinds
    assert [legacy.via_index(i) for i in range(n)] == traj.via_indices


def test_resume_plans_the_via_points_not_reached_at_their_planned_pace() -> None:
    first = trajectory(plan(SQUARE, UNFOLDED))
    assert first.time_scale == 1.0
    reached = 5.0
    rest = trajectory(plan(SQUARE, at(first, reached), PlanResume(first, reached)))
    left = [i for i, t in enumerate(first.times) if t > reached]
    assert rest.knot_kinds == ["start", *["via_point"] * len(left)]
    assert rest.via_indices == [-1, *left]
    assert rest.via_lines == [0, *(first.via_lines[i] for i in left)]
    lead = PlannerConfig().resume_lead_s
    planned = [0.0, *(first.times[i] - reached + lead for i in left)]
    assert rest.times == pytest.approx([t * rest.time_scale for t in planned], abs=1e-12)
    # The same configurations as planned (the arm stopped on the plan: the same IK branch).
    planned_q = np.array([first.positions[i] for i in left])
    np.testing.assert_allclose(rest.positions[1:], planned_q, rtol=0.0, atol=1e-9)
    assert rest.velocities[0] == [0.0] * 6 and rest.velocities[-1] == [0.0] * 6


def test_a_resumed_plan_ends_as_the_plan_did_and_pauses_again() -> None:
    text = (
        "0 0 0 0 0 0 0 0 0 0 0 0 0 2\n0 40 0 0 0 0 0 0 0 0 0 0 2 2\n"
        "0 40 40 0 0 0 0 0 0 0 0 0 4 2\n0 40 40 0 10 0 0 0 0 2 0 0 6 2\n"
    )
    motion = ViaPointPath(path=parse_viapoints(text, "moving.txt"))
    first = trajectory(plan(motion, UNFOLDED))
    rest = trajectory(plan(motion, at(first, 1.0), PlanResume(first, 1.0)))
    assert rest.time_scale == 1.0
    twist = jacobian(np.array(rest.positions[-1]), DEFAULT_ARM) @ np.array(rest.velocities[-1])
    expected = jacobian(np.array(first.positions[-1]), DEFAULT_ARM) @ np.array(first.velocities[-1])
    assert twist == pytest.approx(expected, abs=1e-12)
    assert twist[1] == pytest.approx(0.010, abs=1e-12)
    # Paused again: the via points keep their indices in the file.
    assert rest.via_indices == [-1, 1, 2, 3] and rest.times[2] < 4.0 < rest.times[3]
    again = trajectory(plan(motion, at(rest, 4.0), PlanResume(rest, 4.0)))
    assert again.via_indices == [-1, 3]
    assert again.via_lines == [0, 4]


def test_resume_keeps_only_via_points_not_a_planner_s_waypoints() -> None:
    first = trajectory(plan(SQUARE, UNFOLDED))
    kinds = list(first.knot_kinds)
    indices = list(first.via_indices)
    kinds[6], indices[6] = "waypoint", -1  # as if the planner had chosen knot 6
    marked = dataclasses.replace(first, knot_kinds=kinds, via_indices=indices)
    rest = trajectory(plan(SQUARE, at(first, 3.0), PlanResume(marked, 3.0)))
    left = [i for i, t in enumerate(first.times) if t > 3.0 and i != 6]
    assert rest.via_indices == [-1, *left]


def test_nothing_left_or_a_malformed_plan_is_refused_by_name() -> None:
    first = trajectory(plan(SQUARE, UNFOLDED))
    end = first.times[-1]
    reply = plan(SQUARE, first.positions[-1], PlanResume(first, end))
    assert reply.error is not None and reply.error.reason == "invalid"
    assert "thesis_square.txt (resumed at t = 19.20 s): nothing is left" in reply.error.message
    for broken in (
        dataclasses.replace(first, times=[1.0, *first.times[1:]]),
        dataclasses.replace(first, via_indices=[0, 1]),
        dataclasses.replace(first, positions=[row[:5] for row in first.positions]),
    ):
        reply = plan(SQUARE, UNFOLDED, PlanResume(broken, 2.0))
        assert reply.error is not None and reply.error.reason == "invalid", broken
        assert "the paused trajectory" in reply.error.message


def test_a_resumed_plan_s_refusal_names_the_via_point_of_the_file() -> None:
    first = trajectory(plan(SQUARE, UNFOLDED))
    moved = at(first, 5.0)
    moved[0] += math.radians(100.0)  # the user turned the base far away meanwhile
    reply = plan(SQUARE, moved, PlanResume(first, 5.0))
    assert reply.error is not None and reply.error.reason == "branch", reply.error
    nxt = next(i for i, t in enumerate(first.times) if t > 5.0)
    assert (reply.error.via_point, reply.error.line) == (nxt, first.via_lines[nxt])
    where = f"thesis_square.txt (resumed at t = 5.00 s) line {first.via_lines[nxt]} (via point"
    assert f"{where} {nxt}): joint 1 would jump 100.3 deg" in reply.error.message
