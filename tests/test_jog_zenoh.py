"""The jog on the bus: the real controller shell on a loopback router gets the stream,
answers the level, and a payload that does not decode (an unknown frame, NaN, garbage)
is refused, counted and stops the jog, never a crash."""

from __future__ import annotations

import math

import msgpack
import pytest

from manus.node import Node
from manus.session import ZenohSettings, open_session
from schemas import endpoints as ep
from schemas.control import GoalAck
from schemas.jog import JogCommand, JogLevel
from services.controller.jog import JogSource
from services.controller.shell import ControllerShell
from tests.conftest import eventually, matched_publisher


def _fields(**kw: object) -> dict[str, object]:
    base: dict[str, object] = {"stamp_ns": 1, "seq": 1, "source": "test", "kind": "twist",
                               "units": "unitless", "linear": [0.5, 0.0, 0.0]}  # fmt: skip
    return base | kw


@pytest.mark.parametrize(
    "payload",
    [
        msgpack.packb(_fields(frame="tool")),
        msgpack.packb(_fields(kind="wiggle")),
        msgpack.packb(_fields(linear=[math.nan, 0.0, 0.0])),
        msgpack.packb(_fields(linear=[math.inf, 0.0, 0.0])),
        b"\xc1 not msgpack at all",
    ],
    ids=["unknown-frame", "unknown-kind", "nan", "inf", "not-msgpack"],
)
def test_bad_jog_payloads_are_counted_and_stop_the_jog(
    zenoh_settings: ZenohSettings, payload: bytes
) -> None:
    with ControllerShell(zenoh_settings) as controller, open_session(zenoh_settings) as session:
        key = controller.node.keys(ep.JOG)
        # not before the router knows the controller's subscription: a sample that
        # overtakes it is dropped (this test once waited 10 s for a refusal that never came)
        pub = matched_publisher(session, key)
        pub.put(payload)
        eventually(lambda: controller.core.source(JogSource).refused == 1, 10.0, "the refusal")
        assert controller.core.source(JogSource).reason.startswith("stopped: bad jog payload")
        assert controller.node.bad_payloads[key] == 1
        # a good command still gets through the decoder (held back: the stop stays, and
        # so do its words)
        words = controller.core.source(JogSource).reason
        pub.put(JogCommand(**_fields(seq=2)).encode())  # type: ignore[arg-type]
        eventually(lambda: controller.sent[ep.JOG_TAKEN] == 2, 10.0, "the good one decoded")
        jog = controller.core.source(JogSource)
        assert jog.refused == 1 and jog.reason == words


def test_the_level_is_set_on_the_bus(zenoh_settings: ZenohSettings) -> None:
    with ControllerShell(zenoh_settings) as controller, Node("t", zenoh_settings) as node:
        ack = node.query(node.keys(ep.JOG_LEVEL), JogLevel(level=5), GoalAck)
        assert ack.accepted and controller.core.source(JogSource).level == 5
        ack = node.query(node.keys(ep.JOG_LEVEL), JogLevel(level=9), GoalAck)
        assert not ack.accepted and ack.reason == "level 9 outside 1..5"
