"""Liveliness in recordings: a service appearing and vanishing is recorded on the
``liveliness`` channel (live, on a loopback router), and every reader of a recording
(export, info, plot, regression checks, replay's schedule) copes with that channel."""

from __future__ import annotations

import json
import os
import socket
import time
from pathlib import Path

import jsonschema
import msgpack
import pytest
import zenoh

from manus.config import DEFAULT_ARM
from manus.node import Node
from manus.session import ZenohSettings
from manus_stack.cli import main
from manus_stack.regression import check_controller, check_planner
from schemas.keys import Keys, channel_type
from schemas.liveliness import LivelinessChange
from services.recorder.errors import RecordingError
from services.recorder.plot import load_plot_data
from services.recorder.reading import Recording, decode
from services.recorder.replay import schedule
from services.recorder.shell import RecorderShell
from services.recorder.writer import RecordingWriter
from tests.conftest import eventually

SQUARE = Path(__file__).resolve().parent / "data" / "thesis_square.mcap"


def changes(path: Path) -> list[LivelinessChange]:
    out = []
    for rec in Recording(path).messages(["liveliness"]):
        msg = decode(rec)
        assert isinstance(msg, LivelinessChange)
        assert rec.log_ns == rec.publish_ns == msg.stamp_ns  # log time = receive time
        out.append(msg)
    return out


def test_token_keys_are_parsed_into_service_host_and_pid() -> None:
    def parse(suffix: str, alive: bool = True) -> tuple[object, ...]:
        c = LivelinessChange.from_token(f"m/{suffix}", suffix, alive=alive, stamp_ns=5, seq=2)
        assert LivelinessChange.decode(c.encode()) == c
        return (c.kind, c.service, c.host, c.pid, c.alive, c.key)

    assert parse("alive/planner") == ("alive", "planner", None, None, True, "m/alive/planner")
    assert parse("where/can_bridge/arm-pc/4711", False) == (
        "where",
        "can_bridge",
        "arm-pc",
        4711,
        False,
        "m/where/can_bridge/arm-pc/4711",
    )
    assert parse("where/planner/host/notapid")[:2] == ("other", "")
    assert parse("alive/x/y")[:2] == ("other", "")
    assert parse("something/else")[:2] == ("other", "")
    assert channel_type("liveliness") is LivelinessChange
    assert Keys("arm1").liveliness == "arm1/liveliness"


def test_a_node_that_comes_and_goes_is_recorded_appearing_then_vanishing(
    zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    out = tmp_path / "lively.mcap"
    with RecorderShell(zenoh_settings, out) as recorder:
        eventually(lambda: recorder.liveliness_changes >= 2, what="the recorder's own tokens")
        with Node("planner", zenoh_settings):
            eventually(lambda: recorder.liveliness_changes >= 4, what="the planner's tokens up")
        eventually(lambda: recorder.liveliness_changes >= 6, what="the planner's tokens gone")
        # The channel is the recorder's: a sample published on its key is not recorded.
        with Node("odd", zenoh_settings, liveliness=False) as odd:
            odd.session.put(odd.keys.liveliness, b"\x80")
            eventually(lambda: recorder.reserved_dropped == 1, what="the sample dropped")
        time.sleep(0.2)
    rec = Recording(out)
    channel = rec.info.channels["test/liveliness"]
    assert channel.schema_name == "manus/LivelinessChange/1"
    assert channel.schema == json.loads(json.dumps(LivelinessChange.json_schema()))
    assert {c.suffix for c in rec.info.channels.values()} == {"liveliness"}

    got = changes(out)
    assert [c.seq for c in got] == list(range(len(got))) == list(range(6))
    assert [c.stamp_ns for c in got] == sorted(c.stamp_ns for c in got)
    where = Keys("test").where("planner", socket.gethostname(), os.getpid())
    planner = [(c.key, c.kind, c.alive) for c in got if c.service == "planner"]
    assert sorted(planner[:2]) == [
        ("test/alive/planner", "alive", True),
        (where, "where", True),
    ]  # both up, then both gone
    assert sorted(planner[2:]) == [
        ("test/alive/planner", "alive", False),
        (where, "where", False),
    ]
    (planner_where,) = [c for c in got if c.kind == "where" and c.service == "planner" and c.alive]
    assert planner_where.pid == os.getpid() and planner_where.host
    # The recorder's own tokens were up first (history); their vanishing is not recorded.
    assert sorted((c.kind, c.alive) for c in got[:2]) == [("alive", True), ("where", True)]
    assert all(c.service == "recorder" for c in got[:2])
    assert [c for c in got[2:] if c.service != "planner"] == []


def test_a_restart_that_overlaps_shows_in_the_where_tokens(
    zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    """Zenoh merges tokens of one key: with two bridges up at once, alive/can_bridge stays
    up when the first one goes; its where token (its own pid) shows that it went."""
    out = tmp_path / "restart.mcap"
    keys = Keys("test")

    held: list[zenoh.LivelinessToken] = []

    def bridge(pid: int) -> Node:  # a bridge process, by its tokens; gone with its session
        node = Node("x", zenoh_settings, liveliness=False)
        live = node.session.liveliness()
        held.extend(
            live.declare_token(key)
            for key in (keys.alive("can_bridge"), keys.where("can_bridge", "arm", pid))
        )
        return node

    with RecorderShell(zenoh_settings, out) as recorder:
        eventually(lambda: recorder.liveliness_changes >= 2, what="the recorder's own tokens")
        old = bridge(111)
        eventually(lambda: recorder.liveliness_changes >= 4, what="the old bridge up")
        new = bridge(222)
        eventually(lambda: recorder.liveliness_changes >= 5, what="the new bridge up")
        old.close()
        eventually(lambda: recorder.liveliness_changes >= 6, what="the old bridge gone")
        new.close()
        eventually(lambda: recorder.liveliness_changes >= 8, what="the new bridge gone")
        time.sleep(0.2)
    got = [(c.kind, c.pid, c.alive) for c in changes(out) if c.service == "can_bridge"]
    assert sorted(got[:2]) == [("alive", None, True), ("where", 111, True)]
    assert got[2:4] == [("where", 222, True), ("where", 111, False)]
    assert sorted(got[4:]) == [("alive", None, False), ("where", 222, False)]


def _square_with_liveliness(path: Path) -> int:
    """tests/data/thesis_square.mcap plus a bridge that dies and comes back; returns the
    number of liveliness changes written."""
    keys = Keys("manus")
    src = list(Recording(SQUARE).messages())
    t0, t1 = src[0].log_ns, src[-1].log_ns
    events = [
        (t0, keys.alive("can_bridge"), True),
        (t0, keys.where("can_bridge", "arm", 10), True),
        ((t0 + t1) // 2, keys.where("can_bridge", "arm", 10), False),
        ((t0 + t1) // 2, keys.alive("can_bridge"), False),
        ((t0 + t1) // 2 + 1, keys.alive("can_bridge"), True),
        ((t0 + t1) // 2 + 1, keys.where("can_bridge", "arm", 11), True),
    ]
    with RecordingWriter(path, source="test") as writer:
        for seq, (t, key, alive) in enumerate(events):
            change = LivelinessChange.from_token(
                key, keys.suffix(key), alive=alive, stamp_ns=t, seq=seq
            )
            writer.write("liveliness", change, t)
        for r in src:
            writer.write_payload(r.key, r.payload, r.log_ns, r.publish_ns)
    return len(events)


def test_every_reader_copes_with_the_liveliness_channel(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "square_lively.mcap"
    n = _square_with_liveliness(path)
    rec = Recording(path)
    assert rec.info.messages == Recording(SQUARE).info.messages + n

    assert main(["export", str(path), "--info"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["channels"]["liveliness"] == {"type": "manus/LivelinessChange/1", "messages": n}

    out = tmp_path / "lively.json.mcap"
    assert main(["export", str(path), "--json", "-o", str(out)]) == 0
    capsys.readouterr()
    schema = Recording(out).info.channels["manus/liveliness"].schema
    exported = [json.loads(r.payload) for r in Recording(out).messages(["liveliness"])]
    for value in exported:
        jsonschema.Draft202012Validator(schema).validate(value)
    assert [(v["kind"], v["pid"], v["alive"]) for v in exported] == [
        ("alive", None, True),
        ("where", 10, True),
        ("where", 10, False),
        ("alive", None, False),
        ("alive", None, True),
        ("where", 11, True),
    ]
    assert [msgpack.unpackb(r.payload) for r in rec.messages(["liveliness"])] == exported

    plain, lively = load_plot_data(SQUARE, DEFAULT_ARM), load_plot_data(path, DEFAULT_ARM)
    assert lively.executed.tolist() == plain.executed.tolist()
    assert check_controller(path).ok and check_planner(path).ok

    # Replay never publishes it: not as samples, not as tokens.
    items = schedule(rec)
    assert len(items) == len(schedule(Recording(SQUARE)))
    assert "liveliness" not in {i.rec.suffix for i in items}
    with pytest.raises(RecordingError, match="nothing to replay"):
        schedule(rec, ["liveliness"])
