"""A query the recorder logged on the other side of a joint state than the controller took
it (two publishers: the bridge's states, the controller's mirrored request): the regression
check feeds it where the controller took it, as its ``controller/query_taken`` record says.
"""

from __future__ import annotations

from pathlib import Path

from manus_stack.regression import check_controller
from schemas import endpoints as ep
from schemas.base import Message
from schemas.control import QueryTaken
from schemas.state import JointState
from services.recorder.reading import Recording, decode
from services.recorder.writer import RecordingWriter

ROOT = Path(__file__).resolve().parent.parent
SQUARE = ROOT / "tests" / "data" / "thesis_square.mcap"
GOAL_REQUEST = ep.GOAL.trace("request")


def _goal_logged_late(out: Path, *, keep_records: bool) -> Path:
    """The square's recording with the goal's mirrored request logged just after the joint
    state that followed it (the order a loaded recorder may see), with or without the
    controller's records of where it took its queries."""
    rows = [(r.suffix, decode(r), r.log_ns) for r in Recording(SQUARE).messages()]
    at = next(i for i, (s, _, _) in enumerate(rows) if s == GOAL_REQUEST)
    later = next(t for s, m, t in rows[at + 1 :] if isinstance(m, JointState))
    with RecordingWriter(out, source="reordered") as writer:
        for suffix, msg, t in rows:
            if suffix == ep.QUERY_TAKEN and not keep_records:
                continue
            writer.write(suffix, msg, later + 1 if suffix == GOAL_REQUEST else t)
    return out


def test_the_recording_holds_where_the_goal_was_taken() -> None:
    taken: list[Message] = [
        decode(r) for r in Recording(SQUARE).messages() if r.suffix == ep.QUERY_TAKEN
    ]
    goals = [m for m in taken if isinstance(m, QueryTaken) and m.query == ep.GOAL.suffix]
    assert len(goals) == 1 and goals[0].after_seq >= 0


def test_a_goal_logged_after_the_next_joint_state_is_fed_where_it_was_taken(
    tmp_path: Path,
) -> None:
    result = check_controller(_goal_logged_late(tmp_path / "late.mcap", keep_records=True))
    assert result.ok, result.difference
    assert result.compared > 300


def test_without_the_records_the_same_recording_differs(tmp_path: Path) -> None:
    # what the records are for: fed at its log time, the goal starts a cycle late
    result = check_controller(_goal_logged_late(tmp_path / "bare.mcap", keep_records=False))
    assert not result.ok and result.difference is not None
