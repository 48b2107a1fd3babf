"""A jog client written from the published JSON Schema alone drives the controller.

The client below uses only ``zenoh``, ``msgpack`` and ``schemas/supervisor.schema.json``
(every payload it reads is validated against it): no project code. It tells what the jog
does from typed fields only (``state``, ``cause``, ``limits``, ``caps``), never from the
words of ``reason``. The arm is the lock-step rig of :mod:`tests.jog_bus` (simulator,
bridge and controller cores), whose jog endpoints are on the test's Zenoh router.
"""

from __future__ import annotations

import json
import queue
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jsonschema
import msgpack
import pytest
import zenoh

from tests.jog_bus import JogBus

SCHEMA = json.loads(
    (Path(__file__).resolve().parent.parent / "schemas" / "supervisor.schema.json").read_text()
)
PREFIX = "test"  # the zenoh_settings fixture's prefix


def validator(name: str) -> jsonschema.Draft202012Validator:
    """A validator of the message type ``name`` of the supervisor document."""
    return jsonschema.Draft202012Validator(SCHEMA["$defs"][name])


class Client:
    """The jog client: publishes commands, reads the jog state, sets the level."""

    def __init__(self, endpoint: str) -> None:
        config = zenoh.Config()
        config.insert_json5("mode", '"client"')
        config.insert_json5("connect/endpoints", json.dumps([endpoint]))
        config.insert_json5("scouting/multicast/enabled", "false")
        self.session = zenoh.open(config)
        self.states: queue.Queue[dict[str, Any]] = queue.Queue()
        self.seen: list[dict[str, Any]] = []
        self.seq = 0
        self._state = validator("JogState")
        self._command = validator("JogCommand")
        self._sub = self.session.declare_subscriber(
            f"{PREFIX}/controller/jog_state", self._on_state
        )
        self._pub = self.session.declare_publisher(f"{PREFIX}/jog")

    def _on_state(self, sample: zenoh.Sample) -> None:
        self.states.put(msgpack.unpackb(sample.payload.to_bytes(), raw=False))

    def send(self, **fields: Any) -> None:
        """One JogCommand, checked against the schema before it leaves."""
        self.seq += 1
        cmd = {"stamp_ns": time.time_ns(), "seq": self.seq, "source": "schema client"}
        cmd |= fields
        self._command.validate(cmd)
        self._pub.put(msgpack.packb(cmd, use_bin_type=True))

    def read(self, count: int, timeout: float = 5.0) -> list[dict[str, Any]]:
        """The next ``count`` states, each checked against the schema."""
        got = [self.states.get(timeout=timeout) for _ in range(count)]
        for state in got:
            self._state.validate(state)
        self.seen += got
        return got

    def set_level(self, level: int) -> dict[str, Any]:
        """``controller/jog_level``: the GoalAck."""
        payload = msgpack.packb({"level": level}, use_bin_type=True)
        replies = self.session.get(f"{PREFIX}/controller/jog_level", payload=payload, timeout=5.0)
        for reply in replies:
            assert reply.ok is not None, "an error reply"
            ack: dict[str, Any] = msgpack.unpackb(reply.ok.payload.to_bytes(), raw=False)
            validator("GoalAck").validate(ack)
            return ack
        raise AssertionError("no reply to jog_level")

    def close(self) -> None:
        self.session.close()  # its subscriber and publisher with it


def describe(state: dict[str, Any]) -> str:
    """What the jog does, from the typed fields only."""
    if state["state"] == "stopped":
        return f"stopped: {state['cause']}"
    if state["state"] == "idle":
        return "idle"
    guard = [lim for lim in state["limits"] if lim["kind"] == "collision"]
    if guard and guard[0]["scale"] == 0.0:
        lim = guard[0]
        return f"stopped by the guard near the {lim['object']} at {lim['distance'] * 1e3:.0f} mm"
    capped = [lim for lim in state["limits"] if lim["kind"] == "speed_cap"]
    if capped:
        lim = capped[0]
        cap = state["caps"][lim["object"]]
        return f"running, {lim['object']} capped at {cap * 1e3:.0f} mm/s (scale {lim['scale']:.2f})"
    return "running" if not state["limits"] else "running, held back"


@pytest.fixture
def rig(zenoh_settings: Any) -> Iterator[JogBus]:
    bus = JogBus(zenoh_settings)
    try:
        yield bus
    finally:
        bus.close()


@pytest.fixture
def client(router_endpoint: str) -> Iterator[Client]:
    c = Client(router_endpoint)
    try:
        yield c
    finally:
        c.close()


def push(rig: JogBus, client: Client, seconds: float, **fields: Any) -> list[dict[str, Any]]:
    """Publish the same command every 60 ms of simulated time for ``seconds``; the states."""
    got: list[dict[str, Any]] = []
    for _ in range(round(seconds / 0.06)):
        client.send(**fields)
        got += client.read(rig.advance(0.06))
    return got


def test_a_schema_only_client_tells_a_guard_stop_near_the_head_from_running(
    rig: JogBus, client: Client
) -> None:
    assert client.set_level(5)["accepted"]
    toward = rig.toward_head
    states = push(rig, client, 8.0, kind="twist", units="unitless", linear=toward)
    seen = [describe(s) for s in states]
    assert "running" in seen[:20], seen[:20]
    last = seen[-1]
    assert last.startswith("stopped by the guard near the head at "), last
    mm = float(last.split(" at ")[1].removesuffix(" mm"))
    assert 50.0 <= mm < 80.0, mm
    assert states[-1]["scale"] == 0.0 and states[-1]["active"]
    # the words stay put while the state does: the last 30 states carry one reason
    assert len({s["reason"] for s in states[-30:]}) == 1


def test_a_capped_command_is_reported_and_a_stop_is_shown_to_a_client_still_pushing(
    rig: JogBus, client: Client
) -> None:
    assert client.set_level(3)["accepted"]
    states = push(rig, client, 0.6, kind="twist", units="si", linear=[0.0, 0.12, 0.0])
    assert describe(states[-1]) == "running, linear capped at 90 mm/s (scale 0.75)"
    assert states[-1]["caps"]["linear"] == pytest.approx(0.09)
    # the sender pauses past the deadman, then pushes again: held back, and shown so
    for _ in range(5):
        client.read(rig.advance(0.06, expect=0))
    stopped = client.seen[-1]
    assert (stopped["state"], stopped["cause"]) == ("stopped", "deadman")
    held = push(rig, client, 0.6, kind="twist", units="si", linear=[0.0, 0.12, 0.0])
    assert len(held) >= 5
    assert {describe(s) for s in held} == {"stopped: deadman"}
    assert held[-1]["refused"] == stopped["refused"] + 1  # the stop counts one refusal
    released = push(rig, client, 0.12, kind="stop", units="si")
    assert (released[-1]["state"], released[-1]["cause"]) == ("idle", "released")
    assert released[-1]["folded"] is False
