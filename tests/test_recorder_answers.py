"""Answers from a recording, without Zenoh: recorded requests paired with their replies,
a live request matched exactly, else the next unused reply, else an error."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from schemas import endpoints as ep
from schemas.endpoints import ESTOP, FLIGHT_TRIGGER, LIVELINESS, PLAYBACK_CONTROL
from schemas.keys import channel_types
from schemas.planning import PlanRequest
from services.recorder.answers import Answer, Exchange, RecordedReplies, pair_exchanges
from services.recorder.errors import RecordingError
from services.recorder.reading import Recorded, Recording
from services.recorder.replay import schedule, service_outputs_table, service_queryables_table

DATA = Path(__file__).resolve().parent / "data"
SQUARE = DATA / "thesis_square.mcap"


def rec(part: str, log_ns: int, publish_ns: int, payload: bytes, seq: int = 0) -> Recorded:
    suffix = f"trace/planner/plan/{part}"
    return Recorded(log_ns, publish_ns, seq, f"m/{suffix}", suffix, payload)


def test_replies_pair_with_their_requests_by_query_time() -> None:
    # Two queries in flight: B's reply is recorded before A's.
    requests = [rec("request", 10, 10, b"A"), rec("request", 11, 11, b"B", 1)]
    replies = [rec("reply", 12, 11, b"rB"), rec("reply", 13, 10, b"rA", 1)]
    assert pair_exchanges(requests, replies) == [
        Exchange(b"B", b"rB", 11, 0),
        Exchange(b"A", b"rA", 10, 1),
    ]


def test_without_the_query_time_a_reply_pairs_with_the_earliest_open_request() -> None:
    # Lock-step recordings: the reply is logged at its own time, after its request.
    requests = [rec("request", 100, 100, b"A"), rec("request", 400, 400, b"B", 1)]
    replies = [rec("reply", 300, 300, b"rA"), rec("reply", 600, 600, b"rB", 1)]
    assert [(e.request, e.reply) for e in pair_exchanges(requests, replies)] == [
        (b"A", b"rA"),
        (b"B", b"rB"),
    ]
    # An exact partner wins over an earlier open request (A was refused: no reply).
    requests = [rec("request", 100, 100, b"A"), rec("request", 200, 200, b"B", 1)]
    assert pair_exchanges(requests, [rec("reply", 250, 200, b"rB")]) == [
        Exchange(b"B", b"rB", 200, 0)
    ]
    # A reply whose request came before the recording: kept, without a request.
    assert pair_exchanges([], [rec("reply", 5, 1, b"r")]) == [Exchange(None, b"r", 1, 0)]
    # A request recorded after the reply is not its partner.
    assert pair_exchanges([rec("request", 9, 9, b"A")], [rec("reply", 5, 1, b"r")]) == [
        Exchange(None, b"r", 1, 0)
    ]


def replies(*pairs: tuple[bytes | None, bytes]) -> RecordedReplies:
    exchanges = [Exchange(q, r, 10 * k, k) for k, (q, r) in enumerate(pairs)]
    return RecordedReplies({"planner/plan": exchanges}, "run.mcap")


def test_exact_match_first_then_fallback_in_order_then_an_error() -> None:
    answers = replies((b"A", b"rA"), (b"B", b"rB"), (b"A", b"rA2"), (None, b"rX"))
    assert answers.answer("planner/plan", b"B") == Answer(b"rB", True, 1, "")
    assert answers.answer("planner/plan", b"A") == Answer(b"rA", True, 0, "")
    assert answers.answer("planner/plan", b"A") == Answer(b"rA2", True, 2, "")
    assert answers.remaining("planner/plan") == 1
    # no identical request left: the next unused reply, in recorded order
    assert answers.answer("planner/plan", b"B") == Answer(b"rX", False, 3, "")
    assert answers.remaining("planner/plan") == 0
    last = answers.answer("planner/plan", b"A")
    assert last.reply is None and last.rank == -1 and not last.exact
    assert last.error == (
        "run.mcap: no recorded reply left for planner/plan (all 4 used; the replay answers "
        "each recorded reply once)"
    )
    stats = answers.stats["planner/plan"]
    assert (stats.exact, stats.fallback, stats.exhausted) == (3, 1, 1)


def test_fallback_skips_used_replies_and_keeps_exact_ones_for_later() -> None:
    answers = replies((b"A", b"rA"), (b"B", b"rB"), (b"C", b"rC"))
    assert answers.answer("planner/plan", b"Z").reply == b"rA"  # fallback: the first
    assert answers.answer("planner/plan", b"C").reply == b"rC"  # exact, out of order
    assert answers.answer("planner/plan", b"Z") == Answer(b"rB", False, 1, "")
    assert answers.answer("planner/plan", b"A").error.startswith("run.mcap: no recorded")


def test_a_queryable_without_recorded_replies_answers_with_an_error() -> None:
    answers = RecordedReplies({"bridge/command": []}, "x.mcap")
    assert answers.answer("bridge/command", b"\x80").error.startswith(
        "x.mcap: no recorded reply left for bridge/command (none recorded"
    )
    assert answers.answer("no/such", b"").reply is None
    assert answers.stats["bridge/command"].exhausted == 1


@given(
    recorded=st.lists(st.sampled_from([b"a", b"b", b"c", b"d"]), max_size=12),
    asked=st.lists(st.sampled_from([b"a", b"b", b"c", b"x"]), max_size=16),
)
def test_each_reply_is_given_once_and_identical_requests_come_first(
    recorded: list[bytes], asked: list[bytes]
) -> None:
    pairs = [(q, b"r" + q + bytes([k])) for k, q in enumerate(recorded)]
    answers = replies(*pairs)
    got = [answers.answer("planner/plan", q) for q in asked]
    given_ = [a.reply for a in got if a.reply is not None]
    assert len(given_) == len(set(given_)) == min(len(asked), len(recorded))
    assert all((a.reply is None) == bool(a.error) for a in got)
    for q, a in zip(asked, got, strict=True):
        if a.exact:
            assert a.reply is not None and a.reply[1:2] == q
    # asking the recorded requests in recorded order gives back every reply, in order
    again = replies(*pairs)
    assert [again.answer("planner/plan", q) for q, _ in pairs] == [
        Answer(r, True, k, "") for k, (_, r) in enumerate(pairs)
    ]


def test_exchanges_of_the_thesis_recording() -> None:
    recording = Recording(SQUARE)
    queryables = ["planner/plan", "controller/goal", "controller/gripper"]
    queryables += ["controller/cancel", "controller/speed_scale"]
    answers = RecordedReplies.from_recording(recording, queryables)
    assert answers.source == str(SQUARE)
    assert {q: answers.recorded(q) for q in answers.queryables} == {
        "planner/plan": 1,
        "controller/goal": 1,  # lock-step: request and reply at different times
        "controller/gripper": 0,
        "controller/cancel": 0,
        "controller/speed_scale": 0,
    }
    (request,) = recording.messages(["trace/planner/plan/request"])
    (reply,) = recording.messages(["trace/planner/plan/reply"])
    assert PlanRequest.decode(request.payload).encode() == request.payload
    assert answers.answer("planner/plan", request.payload) == Answer(reply.payload, True, 0, "")


def test_standing_in_for_the_planner_publishes_its_scene_states_only() -> None:
    recording = Recording(SQUARE)
    SERVICE_OUTPUTS, SERVICE_QUERYABLES = service_outputs_table(), service_queryables_table()
    assert SERVICE_OUTPUTS["planner"] == ("planner/scene_state", "planner/objects")
    scheduled = schedule(recording, as_service="planner")  # (no objects in this one)
    assert scheduled and {s.rec.suffix for s in scheduled} == {"planner/scene_state"}
    assert set(SERVICE_QUERYABLES) <= set(SERVICE_OUTPUTS)
    with pytest.raises(RecordingError, match="nothing to replay"):
        schedule(recording, ["state/**"], as_service="planner")  # asked for, not there
    with pytest.raises(RecordingError, match="'dancer': not one of"):
        schedule(recording, as_service="dancer")


def test_the_stand_in_tables_cover_every_key_of_the_schemas() -> None:
    """Every published key has one publishing service (estop and the flight recorder's
    trigger: anyone; liveliness: the recorder's channel; jog: the supervisor, no service),
    every queryable one serving service (but the replay's own control, answered by the
    replay about itself)."""
    SERVICE_OUTPUTS, SERVICE_QUERYABLES = service_outputs_table(), service_queryables_table()
    names = set(channel_types())
    supervisors = {e.suffix for e in ep.TABLE if e.owner == ep.SUPERVISOR}
    published = {n for n in names if "#" not in n} - {ESTOP, LIVELINESS, FLIGHT_TRIGGER}
    published -= supervisors
    outputs = [s for out in SERVICE_OUTPUTS.values() for s in out]
    assert sorted(outputs) == sorted(published)
    each = {e.suffix for e in ep.TABLE if e.owner == ep.EACH_SERVICE}  # health/<service>
    queryables = {n.split("#")[0] for n in names if "#" in n} - each - {PLAYBACK_CONTROL}
    served = [q for qs in SERVICE_QUERYABLES.values() for q in qs]
    assert sorted(served) == sorted(queryables)
