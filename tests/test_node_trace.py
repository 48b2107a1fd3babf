"""The query mirror of Node.queryable: requests and replies published on trace keys."""

from __future__ import annotations

import threading
import time

import zenoh

from manus.node import Node, QueryError
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.commands import ArmCommand, ArmCommandReply
from schemas.keys import Keys, channel_name, channel_type
from schemas.planning import PlanReply, PlanRequest


def _wait(check: object, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not check():  # type: ignore[operator]
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.02)


def test_trace_keys_map_to_request_and_reply_types() -> None:
    keys = Keys("p")
    assert keys.trace("planner/plan", "request") == "p/trace/planner/plan/request"
    assert channel_name("trace/planner/plan/reply") == "planner/plan#reply"
    assert channel_name("state/joints") == "state/joints"
    assert channel_name("trace/reply") == "trace/reply"  # no queryable named
    assert channel_type("trace/planner/plan/request") is PlanRequest
    assert channel_type("trace/planner/plan/reply") is PlanReply
    assert channel_type("trace/bridge/command/reply") is ArmCommandReply
    assert channel_type("no/such/key") is None


def _serve_and_ask(settings: ZenohSettings, *, mirror: bool) -> list[zenoh.Sample]:
    got: list[zenoh.Sample] = []
    lock = threading.Lock()

    def on_sample(sample: zenoh.Sample, rx_ns: int) -> None:
        with lock:
            got.append(sample)

    def handler(req: ArmCommand) -> ArmCommandReply:
        return ArmCommandReply(ok=True, phase="stopped", message=f"did {req.action}")

    with (
        Node("server", settings) as server,
        Node("client", settings, liveliness=False) as client,
        Node("listener", settings, liveliness=False) as listener,
    ):
        listener.subscribe_raw(listener.keys("trace/**"), on_sample)
        server.queryable(server.keys(ep.BRIDGE_COMMAND), ArmCommand, handler, mirror=mirror)
        reply = None
        deadline = time.monotonic() + 10.0
        while reply is None:
            try:
                request = ArmCommand("stop", "test")
                key = client.keys(ep.BRIDGE_COMMAND)
                reply = client.query(key, request, ArmCommandReply, timeout=1.0)
            except QueryError:  # the queryable takes a moment to reach the router
                assert time.monotonic() < deadline
        assert reply.message == "did stop"
        if mirror:
            _wait(lambda: len(got) >= 2)
        else:
            time.sleep(0.3)  # give a (wrong) mirror time to arrive
    return got


def test_queryable_mirrors_request_and_reply(zenoh_settings: ZenohSettings) -> None:
    got = _serve_and_ask(zenoh_settings, mirror=True)
    keys = [str(s.key_expr) for s in got]
    assert keys == ["test/trace/bridge/command/request", "test/trace/bridge/command/reply"]
    request = ArmCommand.decode(got[0].payload.to_bytes())
    reply = ArmCommandReply.decode(got[1].payload.to_bytes())
    assert request == ArmCommand("stop", "test") and reply.phase == "stopped"
    stamps = [s.attachment.to_bytes() if s.attachment is not None else b"" for s in got]
    assert len(stamps[0]) == 8 and stamps[0] == stamps[1]
    assert abs(int.from_bytes(stamps[0], "little") - time.time_ns()) < 60 * 10**9


def test_queryable_mirror_can_be_switched_off(zenoh_settings: ZenohSettings) -> None:
    assert _serve_and_ask(zenoh_settings, mirror=False) == []
