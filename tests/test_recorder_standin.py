"""``manus replay --as SERVICE`` on a loopback router: the stand-in's liveliness tokens,
live queries answered from the recording (exact, fallback, none left), its mirrors, and
the command as a process."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from manus.node import Node, QueryError
from manus.session import ZenohSettings
from manus_stack.cli import main
from schemas import endpoints as ep
from schemas.commands import ArmCommand
from schemas.liveliness import LivelinessChange
from schemas.planning import PlanReply, PlanRequest
from services.recorder.reading import Recording
from services.recorder.replay import Replayer
from services.recorder.shell import RecorderShell
from services.recorder.writer import RecordingWriter
from tests.conftest import eventually

DATA = Path(__file__).resolve().parent / "data"
MANUS = str(Path(sys.executable).parent / "manus")


def plan_exchange(name: str) -> tuple[bytes, bytes]:
    """The recorded plan request and reply of tests/data/<name>.mcap."""
    rec = Recording(DATA / f"{name}.mcap")
    (request,) = rec.messages(["trace/planner/plan/request"])
    (reply,) = rec.messages(["trace/planner/plan/reply"])
    return request.payload, reply.payload


SQUARE = plan_exchange("thesis_square")
CIRCLE = plan_exchange("thesis_circle")


def two_plans(path: Path) -> Path:
    """A live-style recording of two planner queries (square, then circle): mirrors with
    the query time as publish time, and a refused request (no reply mirrored)."""
    with RecordingWriter(path, source="test") as writer:
        for k, (request, reply) in enumerate((SQUARE, CIRCLE)):
            t = 1_000_000_000 * (k + 1)
            writer.write_payload("manus/trace/planner/plan/request", request, t, t)
            writer.write_payload("manus/trace/planner/plan/reply", reply, t + 3_000_000, t)
        square = PlanRequest.decode(SQUARE[0])
        refused = dataclasses.replace(square, start=[9.0] * 6)
        writer.write_payload("manus/trace/planner/plan/request", refused.encode(), 5 * 10**9)
    return path


def ask(node: Node, payload: bytes, timeout: float = 5.0) -> bytes | str:
    """The raw reply to a plan query: its bytes, or the error text."""
    for reply in node.session.get(node.keys(ep.PLAN), payload=payload, timeout=timeout):
        if reply.ok is not None:
            return reply.ok.payload.to_bytes()
        assert reply.err is not None
        return "error: " + reply.err.payload.to_bytes().decode()
    return "no reply"


def test_standing_in_for_the_planner_answers_live_queries_from_the_recording(
    zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    path = two_plans(tmp_path / "plans.mcap")
    other = dataclasses.replace(PlanRequest.decode(CIRCLE[0]), start=[0.1] * 6).encode()
    with (
        RecorderShell(zenoh_settings, tmp_path / "during.mcap") as recorder,
        Node("client", zenoh_settings, liveliness=False) as client,
    ):
        assert "planner" not in client.alive_services(timeout=0.5)
        with Replayer(zenoh_settings, as_service="planner", recording=Recording(path)) as stand:
            assert stand.stand_in is not None
            eventually(lambda: "planner" in client.alive_services(), what="alive/planner")
            host = socket.gethostname()
            assert (host, os.getpid()) in client.service_hosts()["planner"]
            # a typed query, as the sequencer asks: the circle's recorded reply, exactly,
            # although the square's comes first in the recording
            got = client.query(client.keys(ep.PLAN), PlanRequest.decode(CIRCLE[0]), PlanReply)
            assert got.encode() == CIRCLE[1]
            refused = ask(client, b"\xc1")  # not a PlanRequest: refused, nothing used
            assert isinstance(refused, str) and refused.startswith("error: planner (replay): ")
            assert "manus/PlanRequest/2" in refused
            assert ask(client, other) == SQUARE[1]  # no identical request left: fallback
            last = ask(client, SQUARE[0])
            assert isinstance(last, str) and last.startswith(f"error: {path}: no recorded")
            assert "planner/plan (all 2 used" in last
            try:
                client.query(client.keys(ep.PLAN), PlanRequest.decode(SQUARE[0]), PlanReply)
            except QueryError as exc:
                assert str(path) in str(exc) and "planner/plan" in str(exc)
            else:
                raise AssertionError("a fifth query got a reply")
            stats = stand.stand_in.replies.stats["planner/plan"]
            assert (stats.exact, stats.fallback, stats.exhausted) == (1, 1, 2)
            assert stand.stand_in.bad_requests == 1
            eventually(lambda: recorder.samples_recorded >= 6, what="the live mirrors")
        eventually(lambda: "planner" not in client.alive_services(), what="alive/planner gone")
        time.sleep(0.2)
    during = Recording(tmp_path / "during.mcap")
    requests = list(during.messages(["trace/planner/plan/request"]))
    replies = list(during.messages(["trace/planner/plan/reply"]))
    # each live exchange mirrored once (refused requests are not); the recorded ones never
    assert [r.payload for r in replies] == [CIRCLE[1], SQUARE[1]]
    assert [r.payload for r in requests] == [CIRCLE[0], other, SQUARE[0], SQUARE[0]]
    assert {r.publish_ns for r in replies} <= {r.publish_ns for r in requests}
    changes = [c for _, c in during.decoded(["liveliness"]) if isinstance(c, LivelinessChange)]
    planner = [(c.kind, c.alive) for c in changes if c.service == "planner"]
    assert sorted(planner[:2]) == [("alive", True), ("where", True)]
    assert sorted(planner[2:]) == [("alive", False), ("where", False)]


def test_manus_replay_as_planner_answers_until_stopped(
    router_endpoint: str, zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    path = two_plans(tmp_path / "plans.mcap")
    args = ["replay", str(path), "--as", "planner", "--connect", router_endpoint]
    proc = subprocess.Popen(
        [MANUS, *args, "--prefix", "test"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        with Node("client", zenoh_settings, liveliness=False) as client:
            eventually(lambda: "planner" in client.alive_services(), 30.0, "alive/planner")
            assert ask(client, SQUARE[0]) == SQUARE[1]
            assert ask(client, SQUARE[0]) == CIRCLE[1]  # fallback
            assert proc.poll() is None  # nothing to publish: up until stopped
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert (
        "replay: 0 messages of" in err and "as planner; answering planner/plan (2 recorded)" in err
    )
    stats = json.loads(err.split("stats: ", 1)[1])
    assert stats["messages"] == 0
    assert stats["answers"] == {
        "planner/plan": {"exact": 1, "fallback": 1, "exhausted": 0},
        "planner/scene": {"exact": 0, "fallback": 0, "exhausted": 0},
        "planner/attach": {"exact": 0, "fallback": 0, "exhausted": 0},
    }
    # --hold bounds it; without --as it means nothing
    assert main([*args, "--prefix", "test", "--hold", "0.2"]) == 0
    assert main(["replay", str(path), "--hold", "1"]) == 1


def test_standing_in_for_the_bridge_declares_its_queryable_and_token(
    zenoh_settings: ZenohSettings,
) -> None:
    square = Recording(DATA / "thesis_square.mcap")
    with (
        Node("client", zenoh_settings, liveliness=False) as client,
        Replayer(zenoh_settings, as_service="can_bridge", recording=square),
    ):
        eventually(lambda: "can_bridge" in client.alive_services(), what="alive/can_bridge")
        errors = []
        for reply in client.session.get(client.keys(ep.BRIDGE_COMMAND), payload=b"\x80"):
            assert reply.err is not None
            errors.append(reply.err.payload.to_bytes().decode())
        assert len(errors) == 1 and "ArmCommand" in errors[0]  # refused as the bridge would
        replies = list(
            client.session.get(client.keys(ep.BRIDGE_COMMAND), payload=ArmCommand("stop").encode())
        )
        assert len(replies) == 1 and replies[0].err is not None
        text = replies[0].err.payload.to_bytes().decode()
        assert "no recorded reply left for bridge/command (none recorded" in text
