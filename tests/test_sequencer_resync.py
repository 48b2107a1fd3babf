"""A goal refused while the bridge resyncs (a frame lost or late) is sent again once the
bridge runs, within ``resync_wait_s``; otherwise the task fails with the refusal."""

from __future__ import annotations

from schemas.control import GoalAck, Refusal, TrajectoryGoal
from tests.test_sequencer_core import NS, Rig, bridge_state, square_task

NOT_RUNNING = "the bridge is in phase 'resync', not 'running' (clear it or wait for it first)"


def _refuse(rig: Rig) -> None:
    """The controller refuses the last goal sent: the bridge is not running."""
    query = rig.sent[-1]
    assert isinstance(query.request, TrajectoryGoal)
    ack = GoalAck(accepted=False, goal_id=query.request.goal_id, reason=NOT_RUNNING,
                  refusal=Refusal.NOT_READY)  # fmt: skip
    rig.feed(rig.core.on_reply(query.token, ack, "", rig.now))


def _resyncing() -> Rig:
    rig = Rig()
    rig.auto_ack = False
    rig.start(square_task())
    rig.now = NS // 10
    rig.feed(rig.core.on_bridge_state(bridge_state("resync", 2, "sync late"), rig.now))
    _refuse(rig)
    return rig


def test_a_goal_refused_in_a_resync_is_sent_again_once_the_bridge_runs() -> None:
    rig = _resyncing()
    assert rig.core.state == "running" and len(rig.goals()) == 1
    rig.now += NS // 10
    rig.feed(rig.core.on_tick(rig.now))
    assert len(rig.goals()) == 1  # nothing sent while the bridge resyncs
    rig.now += NS // 10
    rig.feed(rig.core.on_bridge_state(bridge_state("running", 3, "two clean cycles"), rig.now))
    goals = rig.goals()
    assert len(goals) == 2 and goals[1] == goals[0]  # the same goal, once more
    assert isinstance(goals[1], TrajectoryGoal)
    ack = GoalAck(accepted=True, goal_id=goals[1].goal_id)
    rig.feed(rig.core.on_reply(rig.sent[-1].token, ack, "", rig.now))
    rig.result("succeeded")
    assert rig.core.state == "running" and rig.core.step == 1, rig.core.reason  # the next step


def test_a_bridge_already_running_again_gets_the_goal_at_once() -> None:
    rig = Rig()
    rig.auto_ack = False
    rig.start(square_task())
    _refuse(rig)  # the controller heard the resync; the sequencer heard only "running"
    assert rig.core.state == "running" and len(rig.goals()) == 2


def test_the_wait_is_bounded_and_a_stop_ends_it_at_once() -> None:
    rig = _resyncing()
    rig.now += NS + NS // 10  # past resync_wait_s (1 s) from the refusal
    rig.feed(rig.core.on_tick(rig.now))
    assert rig.core.state == "failed"
    assert rig.core.reason.endswith(
        f"controller refused the goal: {NOT_RUNNING} (still so 1 s later)"
    )
    assert len(rig.goals()) == 1

    rig = _resyncing()
    rig.feed(rig.core.on_bridge_state(bridge_state("stopped", 3, "stop requested"), rig.now))
    assert (
        rig.core.state == "failed" and "then the bridge went to phase 'stopped'" in rig.core.reason
    )

    rig = Rig()
    rig.auto_ack = False
    rig.start(square_task())
    rig.feed(rig.core.on_bridge_state(bridge_state("stopped", 2), rig.now))
    _refuse(rig)  # a stopped bridge does not run again by itself: no wait
    assert rig.core.state == "failed" and len(rig.goals()) == 1


def test_goals_refused_again_wait_no_longer_than_the_first_refusal_allows() -> None:
    rig = Rig()
    rig.auto_ack = False
    rig.start(square_task())
    for _ in range(5):  # the controller keeps refusing while the sequencer sees "running"
        _refuse(rig)
        rig.now += NS // 4
    assert rig.core.state == "failed" and len(rig.goals()) <= 5
