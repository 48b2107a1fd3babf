"""An ordered node takes its samples and queries in the order they arrived (live, loopback).

zenoh-python runs each subscriber's and each queryable's Python callback in a thread of
its own, so a query could overtake a sample that arrived before it. The controller saw
the end of a fold that way: the sequencer, having seen the bridge ``running``, sent its
next goal, and the goal's thread took the node's lock before the thread of
``state/bridge`` did ("the bridge is in phase 'folding_out', not 'running'")."""

from __future__ import annotations

import time

from manus.node import Node
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.control import CancelGoal, GoalAck, GripperGoal, Heartbeat
from services.can_bridge.health import Health
from services.controller.shell import ControllerShell
from tests.conftest import matched_publisher

SAMPLES = 30


def _count_then_query(settings: ZenohSettings, *, ordered: bool) -> int:
    """A node counts samples (each takes 2 ms under its lock) and answers a query with the
    count; another publishes ``SAMPLES`` samples, then queries at once: what the query saw."""
    seen = 0

    def on_sample(msg: Heartbeat, rx_ns: int) -> None:
        nonlocal seen
        time.sleep(0.002)  # the core's work, under the node's lock
        seen += 1

    def on_query(req: CancelGoal) -> GoalAck:
        return GoalAck(accepted=True, goal_id=req.goal_id, reason=str(seen))

    with Node("ordered", settings, ordered=ordered) as node, Node("client", settings) as client:
        node.subscribe(node.keys("samples"), Heartbeat, on_sample)
        node.queryable(node.keys("ask"), CancelGoal, on_query, mirror=False)
        pub = matched_publisher(client.session, client.keys("samples"))
        for i in range(SAMPLES):
            pub.put(Heartbeat(stamp_ns=i, seq=i, source="t", ref_seq=i, ref_stamp_ns=i).encode())
        reply = client.query(client.keys("ask"), CancelGoal(goal_id="q"), GoalAck, timeout=5.0)
    return int(reply.reason)


def test_an_ordered_node_answers_a_query_after_the_samples_that_came_before_it(
    zenoh_settings: ZenohSettings,
) -> None:
    assert _count_then_query(zenoh_settings, ordered=True) == SAMPLES


def _fold_ends_then_goal(settings: ZenohSettings, folding: int = 20) -> GoalAck:
    """The bridge folds (``folding`` states), then runs; a gripper goal comes at once."""
    with ControllerShell(settings), Node("bridge-and-sequencer", settings) as peer:
        states = matched_publisher(peer.session, peer.keys(ep.BRIDGE_STATE))
        health = Health()
        for seq in range(folding + 1):
            phase = "folding_out" if seq < folding else "running"
            state = health.state(stamp_ns=seq, seq=seq, phase=phase, estop=False, detail="")
            states.put(state.encode())
        goal = GripperGoal(goal_id="g", opening=0.04)
        return peer.query(peer.keys(ep.GRIPPER_GOAL), goal, GoalAck, timeout=5.0)


def test_the_controller_sees_the_folds_end_before_the_next_goal(
    zenoh_settings: ZenohSettings,
) -> None:
    for _ in range(3):  # unordered, 3 of 10 were refused
        ack = _fold_ends_then_goal(zenoh_settings)
        assert ack.accepted, ack.reason
