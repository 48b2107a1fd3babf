"""Property tests: whatever text or path comes in, only documented errors come out."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from manus.config import UNFOLDED_Q_DEG
from manus.trajectory import JointTrajectory
from manus.viapoints import ViaPointError, parse_viapoints
from schemas.planning import (
    INTERPOLATIONS,
    PLAN_ERROR_REASONS,
    PlanReply,
    PlanRequest,
    ViaPointPath,
)
from services.planner.core import PlannerCore

CORE = PlannerCore()
UNFOLDED = [math.radians(q) for q in UNFOLDED_Q_DEG]


def _plan_text(text: str, start: list[float], interpolation: str, scaling: bool) -> None:
    try:
        path = parse_viapoints(text, "fuzz.txt")
    except ViaPointError as exc:
        assert str(exc).startswith("fuzz.txt") and "\n" not in str(exc)
        return
    request = PlanRequest(
        ViaPointPath(path=path, interpolation=interpolation, speed_scaling=scaling), start=start
    )
    reply = CORE.plan(request)
    _check_reply(reply, len(path.via_points))
    assert PlanReply.decode(reply.encode()) == reply  # always a valid message


def _check_reply(reply: PlanReply, n: int) -> None:
    if not reply.ok:
        assert reply.error is not None and reply.trajectory is None
        assert reply.error.reason in PLAN_ERROR_REASONS
        assert reply.error.message and "\n" not in reply.error.message
        return
    traj = reply.trajectory
    assert traj is not None and len(traj.times) == n
    assert np.isfinite(np.array(traj.positions)).all()
    JointTrajectory(traj)


@given(st.text(max_size=400), st.sampled_from(INTERPOLATIONS), st.booleans())
def test_random_text(text: str, interpolation: str, scaling: bool) -> None:
    _plan_text(text, UNFOLDED, interpolation, scaling)


def _cell(values: st.SearchStrategy[float]) -> st.SearchStrategy[str]:
    return values.map(lambda v: f"{v:.3f}")


POSITION = _cell(st.floats(-250.0, 250.0))
RATE = _cell(st.sampled_from([0.0, 0.0, 0.0, 15.0, -40.0]))
ANGLE = st.one_of(st.just("0"), _cell(st.floats(-45.0, 45.0)))
BROKEN = st.sampled_from(["nan", "1e9", "x", "1,5", "-inf", "3"])


@st.composite
def via_point_text(draw: st.DrawFn) -> str:
    """Mostly well-formed files with plausible values; now and then one broken cell."""
    n = draw(st.integers(1, 6))
    lines = ["0 0 0 0 0 0 0 0 0 0 0 0 0 0"]
    t = 0.0
    for _ in range(n):
        t += draw(st.sampled_from([0.0, 0.001, 0.3, 1.0, 4.0]))
        cells = [draw(POSITION) for _ in range(3)] + [draw(RATE) for _ in range(3)]
        cells += [draw(ANGLE) for _ in range(3)] + [draw(RATE) for _ in range(3)]
        cells += [f"{t:g}", draw(st.sampled_from(["0", "1", "2", "2"]))]
        if draw(st.integers(0, 9)) == 0:
            cells[draw(st.integers(0, 13))] = draw(BROKEN)
        lines.append(" ".join(cells))
    return "\n".join(lines)


@given(
    via_point_text(),
    st.lists(st.floats(-math.pi, math.pi), min_size=6, max_size=6),
    st.sampled_from(INTERPOLATIONS),
    st.booleans(),
)
def test_random_paths_and_starts(
    text: str, start: list[float], interpolation: str, scaling: bool
) -> None:
    _plan_text(text, start, interpolation, scaling)


@given(via_point_text(), st.sampled_from(INTERPOLATIONS))
def test_random_paths_from_the_unfolded_pose(text: str, interpolation: str) -> None:
    _plan_text(text, UNFOLDED, interpolation, True)
