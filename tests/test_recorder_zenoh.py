"""The recorder and the replayer on a loopback router: no message lost at 10x the bus
rate, queries recorded through the Node mirror, a live controller driven by a replayed
bridge, and ``manus record`` as a process that is stopped or killed."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import zenoh

from manus.config import UNFOLDED_Q_DEG
from manus.node import Node, QueryError
from manus.session import ZenohSettings
from manus.viapoints import load_path
from manus_stack.cli import main
from manus_stack.regression import check_planner
from schemas import endpoints as ep
from schemas.commands import EStop
from schemas.control import GoalAck, TrajectoryGoal
from schemas.liveliness import LivelinessChange
from schemas.planning import PlanReply, PlanRequest, ViaPointPath
from services.controller.shell import ControllerShell
from services.planner.shell import PlannerShell
from services.recorder.reading import Recording, decode
from services.recorder.recover import recover
from services.recorder.replay import Replayer, matching, schedule
from services.recorder.shell import RecorderShell
from tests.conftest import eventually, progressing

ROOT = Path(__file__).resolve().parent.parent
SQUARE = ROOT / "tests" / "data" / "thesis_square.mcap"
MANUS = str(Path(sys.executable).parent / "manus")


def test_no_message_lost_at_ten_times_the_bus_rate(
    zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    items = schedule(Recording(SQUARE))  # a running stack's traffic, replayed 10x faster
    out = tmp_path / "load.mcap"
    with RecorderShell(zenoh_settings, out) as recorder, Replayer(zenoh_settings) as replayer:
        suffixes = sorted({i.rec.suffix for i in items})
        assert replayer.wait_for_subscribers(suffixes), "the recorder did not subscribe"
        stats = replayer.play(items, rate=10.0)
        # Load slows the recording, never stops it: the wait is bounded by its progress.
        progressing(lambda: recorder.samples_recorded, len(items), what="messages recorded")
    assert stats.messages == len(items) > 3000
    got = Recording(out)
    samples = [r for r in got.messages() if r.suffix != "liveliness"]
    assert recorder.received == len(samples) == len(items)
    assert got.info.prefix == "test"
    for suffix in suffixes:  # every message, byte for byte, in order, on its own channel
        sent = [i.rec.payload for i in items if i.rec.suffix == suffix]
        assert [r.payload for r in got.messages([suffix])] == sent
    # Query mirrors keep their pairing time (the attachment) through replay and record.
    plan = [(r.suffix, r.publish_ns) for r in got.messages(["trace/planner/plan/request"])]
    original = [r.publish_ns for r in Recording(SQUARE).messages(["trace/planner/plan/request"])]
    assert [p for _, p in plan] == original


def test_live_planner_queries_are_recorded_and_replay_through_the_core(
    zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    out = tmp_path / "plans.mcap"
    start = [math.radians(q) for q in UNFOLDED_Q_DEG]
    square = load_path(ROOT / "paths" / "thesis_square.txt")
    with (
        RecorderShell(zenoh_settings, out) as recorder,
        PlannerShell(zenoh_settings),
        Node("client", zenoh_settings, liveliness=False) as client,
    ):

        def answered() -> bool:
            try:
                request = PlanRequest(ViaPointPath(path=square), start=start)
                client.query(client.keys(ep.PLAN), request, PlanReply, timeout=1.0)
            except QueryError:
                return False
            return True

        eventually(answered, what="planner answers")
        client.query(
            client.keys(ep.PLAN), PlanRequest(ViaPointPath(path=square)), PlanReply
        )  # refused: no state
        eventually(lambda: recorder.samples_recorded >= 4, what="mirrors recorded")
        assert recorder.samples_recorded == 4
    rec = Recording(out)
    requests = list(rec.messages(["trace/planner/plan/request"]))
    replies = list(rec.messages(["trace/planner/plan/reply"]))
    assert len(requests) == len(replies) == 2
    assert [r.publish_ns for r in requests] == [r.publish_ns for r in replies]
    assert all(r.log_ns >= q.publish_ns for q, r in zip(requests, replies, strict=True))
    first, second = (decode(r) for r in replies)
    assert isinstance(first, PlanReply) and first.ok
    assert isinstance(second, PlanReply) and second.error is not None
    result = check_planner(out)
    assert result.ok and result.compared == 2, str(result.difference)


def test_replay_as_bridge_drives_a_live_controller_to_the_recorded_commands(
    zenoh_settings: ZenohSettings,
) -> None:
    rec = Recording(SQUARE)
    items = schedule(rec, as_service="can_bridge")
    (goal_rec,) = rec.messages(["trace/controller/goal/request"])
    goal = decode(goal_rec)
    assert isinstance(goal, TrajectoryGoal)
    recorded = [r for r in rec.messages(["cmd/joint_velocity"])]
    before = [i for i in items if i.rec.log_ns < goal_rec.log_ns]
    after = items[len(before) :]
    n_before = sum(1 for r in recorded if r.log_ns < goal_rec.log_ns)
    got: list[bytes] = []
    lock = threading.Lock()

    def on_command(sample: zenoh.Sample, rx_ns: int) -> None:
        with lock:
            got.append(sample.payload.to_bytes())

    with (
        ControllerShell(zenoh_settings),
        Node("listener", zenoh_settings, liveliness=False) as listener,
        Replayer(zenoh_settings) as replayer,
    ):
        listener.subscribe_raw(listener.keys(ep.JOINT_VELOCITY), on_command)
        assert replayer.wait_for_subscribers(["state/joints", "state/status"])
        time.sleep(0.2)  # the listener's subscription reaches the router too
        replayer.play(before, rate=None)
        eventually(lambda: len(got) >= n_before, what="commands before the goal")
        ack = listener.query(listener.keys(ep.GOAL), goal, GoalAck)
        assert ack.accepted, ack.reason
        replayer.play(after, rate=None)
        eventually(lambda: len(got) >= len(recorded), timeout=20.0, what="every command")
        time.sleep(0.1)
    assert got == [r.payload for r in recorded]  # bit for bit, in order


def _start_recorder(endpoint: str, out: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [
            MANUS,
            "record",
            "-o",
            str(out),
            "--connect",
            endpoint,
            "--prefix",
            "test",
            "--flush-ms",
            "100",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def _publish(settings: ZenohSettings, count: int) -> None:
    with Node("pub", settings, liveliness=False) as node:
        pub = node.session.declare_publisher(
            node.keys(ep.ESTOP), congestion_control=zenoh.CongestionControl.BLOCK
        )
        eventually(lambda: matching(pub), what="the recorder subscribed")
        for i in range(count):
            msg = EStop(stamp_ns=i + 1, seq=i, engaged=False, source="test")
            pub.put(msg.encode())
            time.sleep(0.002)
        pub.undeclare()


def test_manus_record_process_stops_cleanly_and_survives_kill(
    router_endpoint: str, zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    clean = tmp_path / "clean.mcap"
    proc = _start_recorder(router_endpoint, clean)
    try:
        _publish(zenoh_settings, 100)
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "recorder: recording test/** to" in err and '"received": 100' in err
    got = Recording(clean)
    assert Counter(r.suffix for r in got.messages()) == {"estop": 100, "liveliness": 2}
    # its own tokens, up from the start: which process wrote the file
    own = [c for r in got.messages(["liveliness"]) if isinstance(c := decode(r), LivelinessChange)]
    assert sorted((c.kind, c.service, c.alive, c.pid) for c in own) == [
        ("alive", "recorder", True, None),
        ("where", "recorder", True, proc.pid),
    ]

    crashed = tmp_path / "crashed.mcap"
    proc = _start_recorder(router_endpoint, crashed)
    try:
        _publish(zenoh_settings, 100)
        time.sleep(1.0)  # ten flush intervals
        os.kill(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    stats = recover(crashed, tmp_path / "rescued.mcap")
    rescued = Recording(tmp_path / "rescued.mcap")
    assert stats.messages == rescued.info.messages == 102
    assert Counter(r.suffix for r in rescued.messages()) == {"estop": 100, "liveliness": 2}
    assert [decode(r).seq for r in rescued.messages(["estop"])] == list(range(100))  # type: ignore[attr-defined]


def test_manus_replay_command_publishes_the_selection(
    router_endpoint: str, zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    out = tmp_path / "replayed.mcap"
    want = [r.payload for r in Recording(SQUARE).messages(["state/joints"])]
    total = len(schedule(Recording(SQUARE), ["state/**"], "can_bridge"))
    with RecorderShell(zenoh_settings, out) as recorder:
        with Node("probe", zenoh_settings, liveliness=False) as probe:
            pub = probe.session.declare_publisher(probe.keys(ep.JOINTS))
            eventually(lambda: matching(pub), what="the recorder subscribed")
            pub.undeclare()
        args = ["replay", str(SQUARE), "--max", "--only", "state/**", "--as", "can_bridge"]
        assert main([*args, "--connect", router_endpoint, "--prefix", "test"]) == 0
        eventually(lambda: recorder.samples_recorded >= total, what="replayed state")
    got = Recording(out)
    assert {c.suffix for c in got.info.channels.values()} == {
        "state/joints",
        "state/status",
        "state/bridge",
        "liveliness",
    }
    assert sum(1 for r in got.messages() if r.suffix != "liveliness") == total
    assert [r.payload for r in got.messages(["state/joints"])] == want
    assert main(["replay", str(SQUARE), "--only", "no/such/key"]) == 1
