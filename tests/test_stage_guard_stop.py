"""A motion stage of an object task that the collision guard stopped within the stage's
tolerance of its end is reached (a last correction near the table that the guard's
bounds could not prove clear, seen live at a pick's approach); farther away the task
fails with the guard's reason."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from schemas.control import EndCause, GoalResult, ResultStatus
from schemas.goals import LineMotion
from schemas.sequencing import StepKind, TaskStep
from services.sequencer.object_stages import APPROACH_TOLERANCE_M, Stage
from services.sequencer.stage_steps import StageContext, StageReach
from services.sequencer.step import Phase

STOPPED = "collision guard stopped: forearm 29.2 mm from table (environment: needs 15 mm) ahead"


class Owner:
    """The object step, as a stage's step reports to it."""

    def __init__(self) -> None:
        self.ctx = SimpleNamespace()
        self.replanning = False
        self.ended: list[str] = []

    def stage_done(self) -> list[object]:
        self.ended.append("done")
        return []

    def stage_failed(self, reason: str) -> list[object]:
        self.ended.append(f"failed: {reason}")
        return []


def _stopped(final_error: float, tolerance: float, cause: EndCause = EndCause.COLLISION) -> str:
    owner = Owner()
    stage = Stage("approach", reach_tolerance=tolerance)
    spec = TaskStep(kind=StepKind.REACH, goal=LineMotion(xyz=[0.0, 0.0, 0.05]))
    step = StageReach(spec, StageContext(owner), stage)  # type: ignore[arg-type]
    step.goal_id, step.phase = "g1", Phase.ACTIVE
    result = GoalResult(stamp_ns=1, seq=1, goal_id="g1", kind="trajectory",
                        status=ResultStatus.ABORTED, cause=cause, reason=STOPPED,
                        final_error=final_error)  # fmt: skip
    step.on_result(result)
    assert len(owner.ended) == 1
    return owner.ended[0]


@pytest.mark.parametrize(
    ("final_error", "tolerance", "ended"),
    [
        (0.0009, APPROACH_TOLERANCE_M, "done"),  # the approach's 5 mm
        (0.0049, APPROACH_TOLERANCE_M, "done"),
        (0.0051, APPROACH_TOLERANCE_M, "failed"),
        (0.0015, 0.0, "done"),  # any stage: the goal's own 2 mm
        (0.0030, 0.0, "failed"),
        (0.0500, APPROACH_TOLERANCE_M, "failed"),  # stopped on the way: no
    ],
)
def test_a_guard_stop_near_the_end_is_reached_and_far_from_it_fails(
    final_error: float, tolerance: float, ended: str
) -> None:
    got = _stopped(final_error, tolerance)
    assert got.startswith(ended), got
    if ended == "failed":
        assert got.endswith(STOPPED), got


def test_other_aborts_near_the_end_still_fail() -> None:
    assert _stopped(0.001, APPROACH_TOLERANCE_M, EndCause.HEARTBEAT_LOST).startswith("failed")
